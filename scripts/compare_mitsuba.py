#!/usr/bin/env python3
"""cvtrace against Mitsuba 3 on the same scene, machine and run: throughput and image mean.

Run it through `scripts/compare_mitsuba.sh` (or `make compare-mitsuba`), which installs
Mitsuba 3 in a virtual environment and the LLVM its vectorised variant needs.

Two workloads, both 256x256, box filter, max depth 8 (Mitsuba's convention, which cvtrace
follows), Russian roulette from depth 5:
  cvtrace-cbox  cvtrace's scenes/cornell-box, converted to a Mitsuba scene (Lambertian
                triangles and the emissive quad; the converter rejects anything else);
  mitsuba-cbox  Mitsuba's own mi.cornell_box(), converted to glTF for cvtrace (its rectangles
                and cubes become triangles).
For each, every renderer (cvtrace with `--traversal robust`, printed as `cvtrace`, and with
`--traversal fast`, its default, printed as `cvtrace-fast`; then the Mitsuba variants) renders the same spp in turn, `--repeats` times, and the script
prints samples per CPU-second (process CPU time: user + system over all threads) and the
image means, which must agree to Monte Carlo noise if both render the same thing.
On cvtrace-cbox, Embree's own `pathtracer` tutorial (Debian's embree-tools) renders the box it
was made from (its cornell_box.ecs, a point light) in the same loop: its rate is spp - 1 samples
per pixel over the CPU time beyond a 1-spp run, which carries the loading.
"""
import argparse
import json
import math
import os
import resource
import statistics
import struct
import subprocess
import sys
import tempfile
import time

import mitsuba as mi

SIDE = 256
MAX_DEPTH = 8
RR_DEPTH = 5


def read_gltf(path):
    """(gltf json, accessor reader) for a .gltf with one external buffer."""
    g = json.load(open(path))
    if len(g.get('buffers', [])) != 1 or 'uri' not in g['buffers'][0]:
        sys.exit(f"{path}: expected one external buffer")
    data = open(os.path.join(os.path.dirname(path), g['buffers'][0]['uri']), 'rb').read()

    def accessor(i):
        a = g['accessors'][i]
        view = g['bufferViews'][a['bufferView']]
        if view.get('byteStride'):
            sys.exit(f"{path}: interleaved buffer views are not supported by this converter")
        offset = view.get('byteOffset', 0) + a.get('byteOffset', 0)
        count = {'VEC3': 3, 'SCALAR': 1}[a['type']] * a['count']
        fmt = {5126: 'f', 5125: 'I', 5123: 'H'}[a['componentType']]
        return list(struct.unpack_from(f'<{count}{fmt}', data, offset))

    return g, accessor


def quat_rotate(q, v):
    x, y, z, w = q
    # v + 2 w (q×v) + 2 q×(q×v)
    cx, cy, cz = y * v[2] - z * v[1], z * v[0] - x * v[2], x * v[1] - y * v[0]
    ccx, ccy, ccz = y * cz - z * cy, z * cx - x * cz, x * cy - y * cx
    return [v[0] + 2 * (w * cx + ccx), v[1] + 2 * (w * cy + ccy), v[2] + 2 * (w * cz + ccz)]


def gltf_to_mitsuba(path, workdir):
    """A Mitsuba scene dict for the subset of glTF cvtrace's Cornell box uses."""
    g, accessor = read_gltf(path)
    scene = {'type': 'scene', 'integrator': {'type': 'path', 'max_depth': MAX_DEPTH, 'rr_depth': RR_DEPTH}}
    for k, node in enumerate(g['nodes']):
        if 'matrix' in node or 'scale' in node or node.get('children'):
            sys.exit(f"{path}: node {k}: only translation + rotation without children is supported")
        if 'camera' in node:
            cam = g['cameras'][node['camera']]['perspective']
            eye = node.get('translation', [0, 0, 0])
            q = node.get('rotation', [0, 0, 0, 1])
            forward, up = quat_rotate(q, [0, 0, -1]), quat_rotate(q, [0, 1, 0])
            scene['sensor'] = {
                'type': 'perspective', 'fov_axis': 'y', 'fov': math.degrees(cam['yfov']),
                'to_world': mi.ScalarTransform4f().look_at(origin=eye, target=[e + f for e, f in zip(eye, forward)], up=up),
                'film': {'type': 'hdrfilm', 'width': SIDE, 'height': SIDE, 'rfilter': {'type': 'box'}},
                'sampler': {'type': 'independent'},
            }
            continue
        if 'mesh' not in node:
            continue
        if node.get('translation') or node.get('rotation'):
            sys.exit(f"{path}: node {k}: mesh nodes must not be transformed")
        for j, prim in enumerate(g['meshes'][node['mesh']]['primitives']):
            mat = g['materials'][prim['material']]
            ext = mat.get('extensions', {})
            pbr = mat.get('pbrMetallicRoughness', {})
            if ext.get('KHR_materials_specular', {}).get('specularFactor', 1.0) != 0.0 or pbr.get('metallicFactor', 1.0) != 0.0 \
                    or 'baseColorTexture' in pbr or 'KHR_materials_transmission' in ext:
                sys.exit(f"{path}: material {mat.get('name')}: only untextured Lambertian (specularFactor 0, metallic 0) is supported")
            pos, idx = accessor(prim['attributes']['POSITION']), accessor(prim['indices'])
            obj = os.path.join(workdir, f"mesh{k}_{j}.obj")
            with open(obj, 'w') as f:
                f.writelines(f"v {pos[i]!r} {pos[i + 1]!r} {pos[i + 2]!r}\n" for i in range(0, len(pos), 3))
                f.writelines(f"f {idx[i] + 1} {idx[i + 1] + 1} {idx[i + 2] + 1}\n" for i in range(0, len(idx), 3))
            bsdf = {'type': 'diffuse', 'reflectance': {'type': 'rgb', 'value': pbr.get('baseColorFactor', [1, 1, 1, 1])[:3]}}
            shape = {'type': 'obj', 'filename': obj, 'face_normals': True,
                     'bsdf': {'type': 'twosided', 'bsdf': bsdf} if mat.get('doubleSided') else bsdf}
            if any(mat.get('emissiveFactor', [0, 0, 0])):
                strength = ext.get('KHR_materials_emissive_strength', {}).get('emissiveStrength', 1.0)
                shape['emitter'] = {'type': 'area', 'radiance': {'type': 'rgb', 'value': [strength * c for c in mat['emissiveFactor']]}}
            scene[f"mesh{k}_{j}"] = shape
    if 'sensor' not in scene:
        sys.exit(f"{path}: no camera node")
    return scene


def mitsuba_cbox_to_gltf(workdir):
    """Mitsuba's mi.cornell_box() as a glTF (triangles, Lambertian, emissive rectangle)."""
    mi.set_variant('scalar_rgb')
    d = mi.cornell_box()
    rect = ([[-1, -1, 0], [1, -1, 0], [1, 1, 0], [-1, 1, 0]], [[0, 1, 2], [0, 2, 3]])
    cube_v, cube_f = [], []
    for axis in range(3):
        for side in (-1, 1):
            u, w = (axis + 1) % 3, (axis + 2) % 3
            base = len(cube_v)
            for a, b in [(-1, -1), (1, -1), (1, 1), (-1, 1)]:
                p = [0, 0, 0]
                p[axis], p[u], p[w] = side, a, b
                cube_v.append(p)
            tris = [[0, 1, 2], [0, 2, 3]] if side > 0 else [[0, 2, 1], [0, 3, 2]]
            cube_f += [[base + i for i in t] for t in tris]
    materials, index = [], {}
    for name in ['white', 'green', 'red']:
        index[name] = len(materials)
        materials.append({'name': name, 'doubleSided': False,
                          'pbrMetallicRoughness': {'baseColorFactor': d[name]['reflectance']['value'] + [1.0], 'metallicFactor': 0.0},
                          'extensions': {'KHR_materials_specular': {'specularFactor': 0.0}}})
    le = d['light']['emitter']['radiance']['value']
    index['light'] = len(materials)
    materials.append({'name': 'light', 'doubleSided': False, 'emissiveFactor': [c / max(le) for c in le],
                      'pbrMetallicRoughness': {'baseColorFactor': d['white']['reflectance']['value'] + [1.0], 'metallicFactor': 0.0},
                      'extensions': {'KHR_materials_specular': {'specularFactor': 0.0},
                                     'KHR_materials_emissive_strength': {'emissiveStrength': max(le)}}})
    blob, accessors, views, meshes, nodes = bytearray(), [], [], [], []
    for key, v in d.items():
        if not isinstance(v, dict) or v.get('type') not in ('rectangle', 'cube'):
            continue
        verts, faces = rect if v['type'] == 'rectangle' else (cube_v, cube_f)
        # Mitsuba applies its own transform: matrix indexing changed between Dr.Jit versions.
        pos = [[float(c) for c in v['to_world'] @ mi.ScalarPoint3f(*p)] for p in verts]
        for data, fmt, typ, comp in [(sum(pos, []), 'f', 'VEC3', 5126), (sum(faces, []), 'I', 'SCALAR', 5125)]:
            start = len(blob)
            blob += struct.pack(f'<{len(data)}{fmt}', *data)
            views.append({'buffer': 0, 'byteOffset': start, 'byteLength': len(blob) - start})
            acc = {'bufferView': len(views) - 1, 'componentType': comp, 'count': len(data) // (3 if typ == 'VEC3' else 1), 'type': typ}
            if typ == 'VEC3':
                acc['min'] = [min(p[i] for p in pos) for i in range(3)]
                acc['max'] = [max(p[i] for p in pos) for i in range(3)]
            accessors.append(acc)
        mat = 'light' if 'emitter' in v else v['bsdf']['id']
        meshes.append({'name': key, 'primitives': [{'attributes': {'POSITION': len(accessors) - 2}, 'indices': len(accessors) - 1,
                                                     'material': index[mat]}]})
        nodes.append({'name': key, 'mesh': len(meshes) - 1})
    sensor = d['sensor']
    origin = [float(c) for c in sensor['to_world'] @ mi.ScalarPoint3f(0, 0, 0)]
    # Mitsuba's sensor looks down its local +z, here world -z: a glTF camera's default view.
    nodes.append({'name': 'camera', 'camera': 0, 'translation': origin})
    g = {'asset': {'version': '2.0', 'generator': 'cvtrace scripts/compare_mitsuba.py from mi.cornell_box()'},
         'extensionsUsed': ['KHR_materials_specular', 'KHR_materials_emissive_strength'],
         'scene': 0, 'scenes': [{'nodes': list(range(len(nodes)))}], 'nodes': nodes, 'meshes': meshes, 'materials': materials,
         'cameras': [{'type': 'perspective', 'perspective': {'yfov': math.radians(sensor['fov']), 'aspectRatio': 1.0, 'znear': 0.001}}],
         'accessors': accessors, 'bufferViews': views, 'buffers': [{'uri': 'scene.bin', 'byteLength': len(blob)}]}
    open(os.path.join(workdir, 'scene.bin'), 'wb').write(blob)
    path = os.path.join(workdir, 'scene.gltf')
    json.dump(g, open(path, 'w'), indent=1)
    return path


def image_mean(path):
    out = subprocess.run(['oiiotool', '--stats', path], capture_output=True, text=True, check=True).stdout
    line = next(l for l in out.splitlines() if 'Stats Avg' in l)
    return [float(x) for x in line.split(':')[1].split()[:3]]


def children_cpu():
    r = resource.getrusage(resource.RUSAGE_CHILDREN)
    return r.ru_utime + r.ru_stime


def run_cvtrace(binary, gltf, spp, threads, out, traversal):
    cmd = [binary, '--threads', str(threads), '--log', 'warn', 'render', gltf, '--reference', '--spp', str(spp), '--traversal', traversal,
           '--pass-spp', str(spp), '--width', str(SIDE), '--height', str(SIDE), '--max-depth', str(MAX_DEPTH),
           '--rr-depth', str(RR_DEPTH), '--force', '-o', out]
    c0 = children_cpu()
    subprocess.run(cmd, check=True)
    return children_cpu() - c0


EMBREE_TUTORIAL = '/usr/bin/pathtracer'
EMBREE_CBOX = '/usr/share/doc/embree3/models/cornell_box.ecs'


def run_embree_tutorial(spp, threads, work):
    """CPU seconds of spp - 1 samples per pixel of Embree's pathtracer on its Cornell box."""
    def cpu(n):
        # --max-path-length 7 is max depth 8 in Mitsuba's convention (1 = primary + shadow).
        cmd = [EMBREE_TUTORIAL, '-c', EMBREE_CBOX, '--size', str(SIDE), str(SIDE), '--spp', str(n),
               '--max-path-length', str(MAX_DEPTH - 1), '--threads', str(threads), '-o', os.path.join(work, 'embree.ppm')]
        c0 = children_cpu()
        subprocess.run(cmd, check=True, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        return children_cpu() - c0
    return cpu(spp) - cpu(1)


def run_mitsuba(variant, scene_dict, spp, threads, seed):
    import drjit as dr
    mi.set_variant(variant)
    dr.set_thread_count(threads)
    scene = mi.load_dict(scene_dict)
    dr.eval(mi.render(scene, spp=4))  # compiles the kernels (LLVM) outside the timing
    c0 = time.process_time()
    img = mi.render(scene, spp=spp, seed=seed)
    dr.eval(img)
    dr.sync_thread()
    cpu = time.process_time() - c0
    # In memory: Mitsuba's file writers hang once dr.set_thread_count has been called.
    return cpu, [float(x) for x in img.numpy().reshape(-1, 3).mean(axis=0)]


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument('--cvtrace', default='target/release/cvtrace')
    ap.add_argument('--spp', type=int, default=64)
    ap.add_argument('--threads', type=int, default=1, help='render threads of every renderer (default 1: CPU time without scheduling noise)')
    ap.add_argument('--repeats', type=int, default=3)
    ap.add_argument('--variants', default='llvm_ad_rgb,scalar_rgb', help='Mitsuba variants to run')
    args = ap.parse_args()
    root = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
    with tempfile.TemporaryDirectory(prefix='cvtrace-vs-mitsuba-') as work:
        mi.set_variant('scalar_rgb')
        workloads = {
            'cvtrace-cbox': os.path.join(root, 'scenes/cornell-box/scene.gltf'),
            'mitsuba-cbox': mitsuba_cbox_to_gltf(work),
        }
        print(f"Mitsuba {mi.__version__}, {SIDE}x{SIDE}, {args.spp} spp, max depth {MAX_DEPTH}, {args.threads} thread(s), "
              f"{args.repeats} repeats; M samples per CPU-second (median [min, max]) and image mean RGB")
        samples = SIDE * SIDE * args.spp
        for name, gltf in workloads.items():
            mi.set_variant('scalar_rgb')
            scene_dict = gltf_to_mitsuba(gltf, work)
            rates = {'cvtrace': [], 'cvtrace-fast': []}
            rates.update({v: [] for v in args.variants.split(',')})
            tutorial = name == 'cvtrace-cbox' and os.path.exists(EMBREE_TUTORIAL) and os.path.exists(EMBREE_CBOX)
            if tutorial:
                rates['embree-tutorial'] = []
            means = {}
            for rep in range(args.repeats):
                for renderer in rates:
                    if renderer == 'embree-tutorial':
                        rates[renderer].append(SIDE * SIDE * (args.spp - 1) / run_embree_tutorial(args.spp, args.threads, work) / 1e6)
                        continue
                    if renderer.startswith('cvtrace'):
                        out = os.path.join(work, f"{name}.exr")
                        traversal = 'fast' if renderer == 'cvtrace-fast' else 'robust'
                        cpu = run_cvtrace(args.cvtrace, gltf, args.spp, args.threads, out, traversal)
                        mean = image_mean(out)
                    else:
                        cpu, mean = run_mitsuba(renderer, scene_dict, args.spp, args.threads, rep + 1)
                    rates[renderer].append(samples / cpu / 1e6)
                    means.setdefault(renderer, []).append(mean)
            print(f"\n{name}:")
            base = statistics.median(rates['cvtrace'])
            for renderer, r in rates.items():
                # The tutorial renders another light, so its mean is not comparable.
                m = [statistics.fmean(c) for c in zip(*means[renderer])] if renderer in means else None
                mean = f"mean {m[0]:.5f} {m[1]:.5f} {m[2]:.5f}" if m else "(its own box, point light)"
                print(f"  {renderer:15s} {statistics.median(r):5.2f} [{min(r):.2f}, {max(r):.2f}]  "
                      f"x{statistics.median(r) / base:4.2f} of cvtrace   {mean}")


if __name__ == '__main__':
    main()

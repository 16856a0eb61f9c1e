#!/usr/bin/env python3
"""cvtrace against Mitsuba 3 on the same scene, machine and run: throughput and image mean.

Run it through `scripts/compare_mitsuba.sh` (or `make compare-mitsuba`), which installs
Mitsuba 3 in a virtual environment and the LLVM its vectorised variant needs.

Three workloads (`--scenes` picks some), box filter, Russian roulette from depth 5:
  cvtrace-cbox  cvtrace's scenes/cornell-box, converted to a Mitsuba scene (Lambertian
                triangles and the emissive quad), 256x256, max depth 8 (Mitsuba's convention,
                which cvtrace follows);
  mitsuba-cbox  Mitsuba's own mi.cornell_box(), converted to glTF for cvtrace (its rectangles
                and cubes become triangles), 256x256, max depth 8;
  glossy-room   cvtrace's scenes/glossy-room (textured glossy dielectrics, rough metals, a spot,
                a point light and an emissive panel), its materials converted to Mitsuba's
                `principled` BSDF, 256x144, unlimited depth as its sidecar sets. principled is not
                glTF's model (see `convert_material`), so its image mean differs from cvtrace's
                by more than noise; an extra row, `llvm_ad_rgb/gltf`, renders the same scene
                with cvtrace's own model as a Python BSDF (`gltfpbr`), whose mean must agree.
For each, every renderer (cvtrace with `--traversal robust`, printed as `cvtrace`, and with
`--traversal fast`, its default, printed as `cvtrace-fast`; then the Mitsuba variants) renders the same spp in turn, `--repeats` times
with seeds 1, 2, ..., and the script prints samples per CPU-second (process CPU time: user + system
over all threads), the image means over the repeats, and each mean's relative difference from
cvtrace-fast's with the difference over its standard error (from the spread over the repeats),
which stays within a few units if both render the same thing.
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


class Workload:
    """A scene as cvtrace reads it (glTF) and the size and path depth both renderers use."""

    def __init__(self, gltf, width, height, max_depth):
        self.gltf, self.width, self.height, self.max_depth = gltf, width, height, max_depth


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
        if a.get('normalized') or a.get('sparse'):
            sys.exit(f"{path}: accessor {i}: normalized or sparse accessors are not supported by this converter")
        offset = view.get('byteOffset', 0) + a.get('byteOffset', 0)
        count = {'VEC3': 3, 'VEC2': 2, 'SCALAR': 1}[a['type']] * a['count']
        fmt = {5126: 'f', 5125: 'I', 5123: 'H', 5121: 'B'}[a['componentType']]
        return list(struct.unpack_from(f'<{count}{fmt}', data, offset))

    return g, accessor


def quat_rotate(q, v):
    x, y, z, w = q
    # v + 2 w (q×v) + 2 q×(q×v)
    cx, cy, cz = y * v[2] - z * v[1], z * v[0] - x * v[2], x * v[1] - y * v[0]
    ccx, ccy, ccz = y * cz - z * cy, z * cx - x * cz, x * cy - y * cx
    return [v[0] + 2 * (w * cx + ccx), v[1] + 2 * (w * cy + ccy), v[2] + 2 * (w * cz + ccz)]


def node_matrix(node):
    """A node's local transform as a row-major 4×4 (glTF: T·R·S, or its column-major `matrix`)."""
    if 'matrix' in node:
        m = node['matrix']
        return [[m[c * 4 + r] for c in range(4)] for r in range(4)]
    t, q, s = node.get('translation', [0, 0, 0]), node.get('rotation', [0, 0, 0, 1]), node.get('scale', [1, 1, 1])
    cols = [[c * s[i] for c in quat_rotate(q, [float(i == 0), float(i == 1), float(i == 2)])] for i in range(3)]
    return [[cols[0][r], cols[1][r], cols[2][r], t[r]] for r in range(3)] + [[0.0, 0.0, 0.0, 1.0]]


def mat_mul(a, b):
    return [[sum(a[r][k] * b[k][c] for k in range(4)) for c in range(4)] for r in range(4)]


def transform_point(m, p):
    return [m[r][0] * p[0] + m[r][1] * p[1] + m[r][2] * p[2] + m[r][3] for r in range(3)]


def transform_vector(m, v):
    return [m[r][0] * v[0] + m[r][1] * v[1] + m[r][2] * v[2] for r in range(3)]


def normal_matrix(m):
    """The inverse transpose of m's upper 3×3 (normals stay perpendicular under non-uniform scale)."""
    a = [row[:3] for row in m[:3]]
    cof = [[a[(r + 1) % 3][(c + 1) % 3] * a[(r + 2) % 3][(c + 2) % 3] - a[(r + 1) % 3][(c + 2) % 3] * a[(r + 2) % 3][(c + 1) % 3]
            for c in range(3)] for r in range(3)]
    det = sum(a[0][c] * cof[0][c] for c in range(3))
    return [[cof[r][c] / det for c in range(3)] + [0.0] for r in range(3)] + [[0.0, 0.0, 0.0, 1.0]]


def unit(v):
    n = math.sqrt(sum(c * c for c in v))
    return [c / n for c in v] if n > 0 else v


def world_nodes(g):
    """(node index, node, world matrix) for every node of the default scene, parents first."""
    identity = [[float(r == c) for c in range(4)] for r in range(4)]
    stack = [(i, identity) for i in reversed(g['scenes'][g.get('scene', 0)]['nodes'])]
    while stack:
        i, parent = stack.pop()
        node = g['nodes'][i]
        world = mat_mul(parent, node_matrix(node))
        yield i, node, world
        stack += [(c, world) for c in reversed(node.get('children', []))]


def spot_profile(workdir, name, inner, outer, n=256):
    """A PFM image that turns Mitsuba's spot falloff into glTF's.

    Mitsuba's `spot` ramps linearly in angle from `beam_width` to `cutoff_angle`; glTF (and
    cvtrace) ramps with the square of a linear ramp in cosine. Mitsuba multiplies the falloff by
    a texture projected over the cutoff cone (uv = 0.5 + 0.5·tan(θ)/tan(cutoff) along x and y),
    so a texture holding the ratio of the two profiles gives glTF's falloff, up to the texture's
    resolution and bilinear filtering.
    """
    cos_i, cos_o, tan_o = math.cos(inner), math.cos(outer), math.tan(outer)
    rows = []
    for y in range(n):
        row = []
        for x in range(n):
            u, v = (x + 0.5) / n, (y + 0.5) / n
            theta = math.atan(math.hypot(2 * u - 1, 2 * v - 1) * tan_o)
            mitsuba = 1.0 if theta <= inner else (outer - theta) / (outer - inner)
            t = min(max((math.cos(theta) - cos_o) / (cos_i - cos_o), 0.0), 1.0)
            ratio = t * t / mitsuba if theta < outer else 0.0
            row += [ratio] * 3
        rows.append(row)
    path = os.path.join(workdir, f"{name}.pfm")
    with open(path, 'wb') as f:
        f.write(f"PF\n{n} {n}\n-1.0\n".encode())
        for row in reversed(rows):  # PFM stores the bottom row first; the profile is symmetric anyway
            f.write(struct.pack(f'<{len(row)}f', *row))
    return path


def register_gltf_bsdf():
    """Registers `gltfpbr` for the current variant: cvtrace's own material model in Mitsuba, to
    tell the conversion's errors from the difference between that model and `principled`."""
    class GltfPbr(mi.BSDF):
        """cvtrace's glTF metallic-roughness model (crates/render/src/transport/bsdf/pbr.rs), opaque
        lobes only, as a Mitsuba BSDF: Lambert weighted by 1 − F(n·wo) under a GGX lobe with
        Schlick Fresnel (dielectric F0 = 0.04·specularFactor, F90 = specularFactor, blended with the
        metal's F0 = base colour, F90 = 1 by metallic) and height-correlated Smith masking."""

        def __init__(self, props):
            mi.BSDF.__init__(self, props)
            base = props['base_color']
            # A bitmap arrives as a texture, an 'rgb' value as a plain colour.
            self.base = base if hasattr(base, 'eval') else mi.Color3f(base)
            self.roughness = props.get('roughness', 1.0)
            self.metallic = props.get('metallic', 0.0)
            self.specular = props.get('specular', 1.0)
            flags = mi.BSDFFlags.DiffuseReflection | mi.BSDFFlags.GlossyReflection | mi.BSDFFlags.FrontSide
            self.m_components = [flags]
            self.m_flags = flags

        def _lobes(self, si, active):
            import drjit as dr
            base = self.base.eval(si, active) if hasattr(self.base, 'eval') else self.base
            m, s = self.metallic, self.specular
            cos_o = dr.clip(mi.Frame3f.cos_theta(si.wi), 0.0, 1.0)
            w5 = dr.power(1.0 - cos_o, 5)
            f0d = 0.04 * s
            diffuse = base * ((1.0 - m) * (1.0 - (f0d + (s - f0d) * w5)))
            f0 = f0d * (1.0 - m) + base * m
            f90 = s * (1.0 - m) + m
            lum = lambda c: 0.2126 * c[0] + 0.7152 * c[1] + 0.0722 * c[2]
            w_d = lum(diffuse)
            w_s = lum(f0 + (f90 - f0) * w5)
            p_d = dr.select(w_d + w_s > 0, w_d / (w_d + w_s), 0.0)
            return diffuse, f0, f90, p_d

        def _alpha(self):
            return max(self.roughness * self.roughness, 1e-3)

        def _eval_pdf(self, si, wo, active):
            import drjit as dr
            diffuse, f0, f90, p_d = self._lobes(si, active)
            a = self._alpha()
            cos_o, cos_i = mi.Frame3f.cos_theta(si.wi), mi.Frame3f.cos_theta(wo)
            ok = active & (cos_o > 0) & (cos_i > 0)
            h = dr.normalize(si.wi + wo)
            distr = mi.MicrofacetDistribution(mi.MicrofacetType.GGX, a, True)
            d = distr.eval(h)
            lam = lambda w: 0.5 * (dr.sqrt(1.0 + a * a * mi.Frame3f.tan_theta_2(w)) - 1.0)
            g2 = dr.rcp(1.0 + lam(si.wi) + lam(wo))
            g1 = dr.rcp(1.0 + lam(si.wi))
            F = f0 + (f90 - f0) * dr.power(1.0 - dr.clip(dr.dot(si.wi, h), 0.0, 1.0), 5)
            value = diffuse * (dr.inv_pi * cos_i) + F * (d * g2 / (4.0 * cos_o))
            pdf = p_d * dr.inv_pi * cos_i + (1.0 - p_d) * g1 * d / (4.0 * cos_o)
            return dr.select(ok, value, 0.0), dr.select(ok, pdf, 0.0)

        def eval(self, ctx, si, wo, active=True):
            return self._eval_pdf(si, wo, active)[0]

        def pdf(self, ctx, si, wo, active=True):
            return self._eval_pdf(si, wo, active)[1]

        def eval_pdf(self, ctx, si, wo, active=True):
            return self._eval_pdf(si, wo, active)

        def sample(self, ctx, si, sample1, sample2, active=True):
            import drjit as dr
            _, _, _, p_d = self._lobes(si, active)
            distr = mi.MicrofacetDistribution(mi.MicrofacetType.GGX, self._alpha(), True)
            h, _ = distr.sample(si.wi, sample2)
            spec_dir = mi.reflect(si.wi, h)
            wo = dr.select(sample1 < p_d, mi.warp.square_to_cosine_hemisphere(sample2), spec_dir)
            value, pdf = self._eval_pdf(si, wo, active)
            bs = dr.zeros(mi.BSDFSample3f)
            bs.wo, bs.pdf, bs.eta = wo, pdf, 1.0
            bs.sampled_component = 0
            bs.sampled_type = dr.select(sample1 < p_d, mi.UInt32(+mi.BSDFFlags.DiffuseReflection), mi.UInt32(+mi.BSDFFlags.GlossyReflection))
            ok = active & (pdf > 0)
            return bs, dr.select(ok, value / pdf, 0.0)

        def traverse(self, callback):
            pass

        def to_string(self):
            return 'GltfPbr[]'

    mi.register_bsdf('gltfpbr', lambda props: GltfPbr(props))


def convert_material(path, mat, g, model='principled'):
    """Mitsuba BSDF for a glTF metallic-roughness material, as close to cvtrace's model as Mitsuba allows.

    Lambertian materials (untextured or textured, `specularFactor` 0, not metallic) become
    `diffuse`, which is exactly cvtrace's model. Anything with a specular layer becomes
    `principled`: base colour, `roughness` (both square it into GGX's alpha), `metallic`
    (Schlick with F0 = base colour, as cvtrace's metal), and `specular` = 0.5·specularFactor so that
    its dielectric F0 = 0.08·specular equals cvtrace's 0.04·specularFactor. What cannot be matched
    (`model='gltf'` gives `gltfpbr`, cvtrace's model, instead):
    principled's dielectric Fresnel is the exact one for the implied IOR (cvtrace: Schlick with
    F90 = specularFactor, which for factors below 1 is darker at grazing angles), its diffuse lobe is
    Burley's (retro-reflection, no (1 − F) energy split; cvtrace: Lambert weighted by
    1 − F(n·wo)), and its masking is separable Smith (cvtrace: height-correlated).
    """
    ext = mat.get('extensions', {})
    pbr = mat.get('pbrMetallicRoughness', {})
    spec_ext = ext.get('KHR_materials_specular', {})
    unsupported = [k for k in ('KHR_materials_transmission', 'KHR_materials_volume', 'KHR_materials_clearcoat') if k in ext]
    unsupported += [k for k in ('metallicRoughnessTexture',) if k in pbr]
    unsupported += [k for k in ('specularTexture', 'specularColorTexture') if k in spec_ext]
    unsupported += ['specularColorFactor'] if spec_ext.get('specularColorFactor', [1, 1, 1]) != [1, 1, 1] else []
    unsupported += ['emissiveTexture'] if 'emissiveTexture' in mat else []
    if unsupported:
        sys.exit(f"{path}: material {mat.get('name')}: {', '.join(unsupported)} not supported by this converter")
    factor = pbr.get('baseColorFactor', [1, 1, 1, 1])[:3]
    if 'baseColorTexture' in pbr:
        if factor != [1, 1, 1] or pbr['baseColorTexture'].get('texCoord', 0) != 0:
            sys.exit(f"{path}: material {mat.get('name')}: a texture needs baseColorFactor 1 and TEXCOORD_0 here")
        image = g['images'][g['textures'][pbr['baseColorTexture']['index']]['source']]
        # An 8-bit PNG is sRGB-decoded at load (raw false), as cvtrace decodes colour textures;
        # both filter bilinearly and repeat.
        base = {'type': 'bitmap', 'filename': os.path.join(os.path.dirname(path), image['uri']),
                'filter_type': 'bilinear', 'wrap_mode': 'repeat', 'raw': False}
    else:
        base = {'type': 'rgb', 'value': factor}
    metallic = pbr.get('metallicFactor', 1.0)
    specular = spec_ext.get('specularFactor', 1.0)
    if metallic == 0.0 and specular == 0.0:
        return {'type': 'diffuse', 'reflectance': base}
    if model == 'gltf':
        return {'type': 'gltfpbr', 'base_color': base, 'roughness': pbr.get('roughnessFactor', 1.0),
                'metallic': float(metallic), 'specular': float(specular)}
    bsdf = {'type': 'principled', 'base_color': base, 'roughness': pbr.get('roughnessFactor', 1.0),
            'specular': 0.5 * specular}
    if metallic > 0.0:
        bsdf['metallic'] = metallic
    return bsdf


def gltf_to_mitsuba(path, workdir, width, height, max_depth, model='principled'):
    """A Mitsuba scene dict for the subset of glTF cvtrace's bundled scenes use.

    Triangle meshes (positions, normals, TEXCOORD_0, node transforms), the perspective camera,
    metallic-roughness materials (see `convert_material`), emissive materials as one-sided area
    emitters, and KHR_lights_punctual lights: point and spot intensity in W/sr, directional
    irradiance, as cvtrace reads glTF's photometric units. Anything else is rejected.
    """
    g, accessor = read_gltf(path)
    scene = {'type': 'scene', 'integrator': {'type': 'path', 'max_depth': max_depth, 'rr_depth': RR_DEPTH}}
    lights = g.get('extensions', {}).get('KHR_lights_punctual', {}).get('lights', [])
    for k, node, world in world_nodes(g):
        if 'camera' in node:
            cam = g['cameras'][node['camera']]
            if cam['type'] != 'perspective':
                sys.exit(f"{path}: node {k}: only perspective cameras are supported")
            eye = transform_point(world, [0, 0, 0])
            forward, up = unit(transform_vector(world, [0, 0, -1])), unit(transform_vector(world, [0, 1, 0]))
            # cvtrace's vertical field of view is the glTF yfov at any image aspect, as Mitsuba's fov_axis 'y'.
            scene['sensor'] = {
                'type': 'perspective', 'fov_axis': 'y', 'fov': math.degrees(cam['perspective']['yfov']),
                'to_world': mi.ScalarTransform4f().look_at(origin=eye, target=[e + f for e, f in zip(eye, forward)], up=up),
                'film': {'type': 'hdrfilm', 'width': width, 'height': height, 'rfilter': {'type': 'box'}},
                'sampler': {'type': 'independent'},
            }
        if 'KHR_lights_punctual' in node.get('extensions', {}):
            light = lights[node['extensions']['KHR_lights_punctual']['light']]
            value = [light.get('intensity', 1.0) * c for c in light.get('color', [1, 1, 1])]
            pos, direction = transform_point(world, [0, 0, 0]), unit(transform_vector(world, [0, 0, -1]))
            up = [0, 1, 0] if abs(direction[1]) < 0.9 else [1, 0, 0]
            name = f"light{k}"
            if light['type'] == 'point':
                scene[name] = {'type': 'point', 'position': pos, 'intensity': {'type': 'rgb', 'value': value}}
            elif light['type'] == 'spot':
                inner, outer = light['spot'].get('innerConeAngle', 0.0), light['spot'].get('outerConeAngle', math.pi / 4)
                scene[name] = {'type': 'spot', 'intensity': {'type': 'rgb', 'value': value},
                               'cutoff_angle': math.degrees(outer), 'beam_width': math.degrees(inner),
                               'texture': {'type': 'bitmap', 'filename': spot_profile(workdir, name, inner, outer), 'raw': True,
                                           'filter_type': 'bilinear', 'wrap_mode': 'clamp'},
                               'to_world': mi.ScalarTransform4f().look_at(origin=pos, target=[p + d for p, d in zip(pos, direction)], up=up)}
            else:
                scene[name] = {'type': 'directional', 'direction': direction, 'irradiance': {'type': 'rgb', 'value': value}}
        if 'mesh' not in node:
            continue
        nmat = normal_matrix(world)
        for j, prim in enumerate(g['meshes'][node['mesh']]['primitives']):
            if prim.get('mode', 4) != 4:
                sys.exit(f"{path}: mesh {node['mesh']}: only triangle lists are supported")
            mat = g['materials'][prim['material']]
            attr = prim['attributes']
            pos = accessor(attr['POSITION'])
            pos = [transform_point(world, pos[i:i + 3]) for i in range(0, len(pos), 3)]
            idx = accessor(prim['indices']) if 'indices' in prim else list(range(len(pos)))
            emissive = any(mat.get('emissiveFactor', [0, 0, 0]))
            # An emitter's side is its winding's (cvtrace emits along the geometric normal), so it
            # gets no vertex normals; Mitsuba computes face normals where a mesh has none.
            normals = None if emissive or 'NORMAL' not in attr else accessor(attr['NORMAL'])
            uvs = accessor(attr['TEXCOORD_0']) if 'TEXCOORD_0' in attr else None
            obj = os.path.join(workdir, f"mesh{k}_{j}.obj")
            with open(obj, 'w') as f:
                f.writelines(f"v {p[0]!r} {p[1]!r} {p[2]!r}\n" for p in pos)
                if normals:
                    for i in range(0, len(normals), 3):
                        n = unit(transform_vector(nmat, normals[i:i + 3]))
                        f.write(f"vn {n[0]!r} {n[1]!r} {n[2]!r}\n")
                if uvs:
                    f.writelines(f"vt {uvs[i]!r} {uvs[i + 1]!r}\n" for i in range(0, len(uvs), 2))
                # OBJ's v/vt/vn indices; the vertex's own index for all three.
                tag = (lambda i: f"{i}/{i}/{i}") if normals and uvs else (lambda i: f"{i}//{i}") if normals else \
                      (lambda i: f"{i}/{i}") if uvs else str
                f.writelines(f"f {tag(idx[i] + 1)} {tag(idx[i + 1] + 1)} {tag(idx[i + 2] + 1)}\n" for i in range(0, len(idx), 3))
            bsdf = convert_material(path, mat, g, model)
            # glTF's v runs down the image from its top row, as Mitsuba's bitmap lookups do: no flip.
            shape = {'type': 'obj', 'filename': obj, 'face_normals': normals is None, 'flip_tex_coords': False,
                     'bsdf': {'type': 'twosided', 'bsdf': bsdf} if mat.get('doubleSided') else bsdf}
            if emissive:
                strength = mat.get('extensions', {}).get('KHR_materials_emissive_strength', {}).get('emissiveStrength', 1.0)
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


def run_cvtrace(binary, gltf, workload, spp, threads, out, traversal, seed):
    cmd = [binary, '--threads', str(threads), '--log', 'warn', 'render', gltf, '--reference', '--spp', str(spp), '--traversal', traversal,
           '--pass-spp', str(spp), '--width', str(workload.width), '--height', str(workload.height),
           f'--max-depth={workload.max_depth}', '--rr-depth', str(RR_DEPTH), '--seed', str(seed), '--force', '-o', out]
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
    register_gltf_bsdf()
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


def mean_and_error(means):
    """Per-channel mean over repeats and its standard error (None from one repeat)."""
    m = [statistics.fmean(c) for c in zip(*means)]
    se = [statistics.stdev(c) / math.sqrt(len(c)) for c in zip(*means)] if len(means) > 1 else None
    return m, se


WORKLOADS = ['cvtrace-cbox', 'mitsuba-cbox', 'glossy-room']


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument('--cvtrace', default='target/release/cvtrace')
    ap.add_argument('--spp', type=int, default=64)
    ap.add_argument('--threads', type=int, default=1, help='render threads of every renderer (default 1: CPU time without scheduling noise)')
    ap.add_argument('--repeats', type=int, default=3)
    ap.add_argument('--variants', default='llvm_ad_rgb,scalar_rgb', help='Mitsuba variants to run')
    ap.add_argument('--scenes', default=','.join(WORKLOADS), help=f'workloads to run (default: all of {",".join(WORKLOADS)})')
    ap.add_argument('--no-gltf-model', action='store_true',
                    help="on glossy-room, skip the extra llvm_ad_rgb/gltf row (cvtrace's own material model in Mitsuba)")
    args = ap.parse_args()
    names = args.scenes.split(',')
    if unknown := [n for n in names if n not in WORKLOADS]:
        sys.exit(f"unknown workload(s) {', '.join(unknown)}; known: {', '.join(WORKLOADS)}")
    root = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
    with tempfile.TemporaryDirectory(prefix='cvtrace-vs-mitsuba-') as work:
        mi.set_variant('scalar_rgb')
        workloads = {}
        if 'cvtrace-cbox' in names:
            workloads['cvtrace-cbox'] = Workload(os.path.join(root, 'scenes/cornell-box/scene.gltf'), SIDE, SIDE, MAX_DEPTH)
        if 'mitsuba-cbox' in names:
            workloads['mitsuba-cbox'] = Workload(mitsuba_cbox_to_gltf(work), SIDE, SIDE, MAX_DEPTH)
        if 'glossy-room' in names:
            # 16:9 like the scene's own 320x180; unlimited depth (Russian roulette from depth 5) as
            # its scene.cvtrace.toml sets.
            workloads['glossy-room'] = Workload(os.path.join(root, 'scenes/glossy-room/scene.gltf'), 256, 144, -1)
        # Converted before any render: Mitsuba's file I/O misbehaves once dr.set_thread_count has been called.
        scene_dicts = {}
        for name, w in workloads.items():
            os.makedirs(os.path.join(work, name), exist_ok=True)
            scene_dicts[name, 'principled'] = gltf_to_mitsuba(w.gltf, os.path.join(work, name), w.width, w.height, w.max_depth)
            if name == 'glossy-room':
                scene_dicts[name, 'gltf'] = gltf_to_mitsuba(w.gltf, os.path.join(work, name), w.width, w.height, w.max_depth, 'gltf')
        print(f"Mitsuba {mi.__version__}, {args.spp} spp, {args.threads} thread(s), {args.repeats} repeats (seeds 1..{args.repeats}); "
              f"M samples per CPU-second (median [min, max]) and image mean RGB over the repeats")
        for name, w in workloads.items():
            samples = w.width * w.height * args.spp
            rates = {'cvtrace': [], 'cvtrace-fast': []}
            rates.update({v: [] for v in args.variants.split(',')})
            if (name, 'gltf') in scene_dicts and 'llvm_ad_rgb' in rates and not args.no_gltf_model:
                rates['llvm_ad_rgb/gltf'] = []
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
                        cpu = run_cvtrace(args.cvtrace, w.gltf, w, args.spp, args.threads, out, traversal, rep + 1)
                        mean = image_mean(out)
                    else:
                        variant, _, model = renderer.partition('/')
                        cpu, mean = run_mitsuba(variant, scene_dicts[name, model or 'principled'], args.spp, args.threads, rep + 1)
                    rates[renderer].append(samples / cpu / 1e6)
                    means.setdefault(renderer, []).append(mean)
            depth = 'unlimited' if w.max_depth < 0 else w.max_depth
            print(f"\n{name} ({w.width}x{w.height}, max depth {depth}):")
            base = statistics.median(rates['cvtrace'])
            for renderer, r in rates.items():
                # The tutorial renders another light, so its mean is not comparable.
                if renderer in means:
                    m, se = mean_and_error(means[renderer])
                    mean = f"mean {m[0]:.5f} {m[1]:.5f} {m[2]:.5f}"
                else:
                    mean = "(its own box, point light)"
                print(f"  {renderer:17s} {statistics.median(r):5.2f} [{min(r):.2f}, {max(r):.2f}]  "
                      f"x{statistics.median(r) / base:4.2f} of cvtrace   {mean}")
            # Each renderer's mean against cvtrace's default (fast) traversal. The noise is the
            # standard error over the repeats' seeds; from 3 repeats that estimate is itself rough
            # (Student's t with about 4 degrees of freedom: |z| up to about 3 is noise at 95%).
            # cvtrace's two traversals render the same seeds, so their difference is not noise.
            ref, ref_se = mean_and_error(means['cvtrace-fast'])
            print("  image mean against cvtrace-fast, per channel: relative difference (difference / its standard error;"
                  " from 3 to 5 repeats, |z| < 3 is noise)")
            for renderer in means:
                if renderer == 'cvtrace-fast':
                    continue
                m, se = mean_and_error(means[renderer])
                cells = []
                for c in range(3):
                    rel = (m[c] - ref[c]) / ref[c]
                    noise = math.hypot(se[c], ref_se[c]) if se and ref_se else 0.0
                    z = f"{(m[c] - ref[c]) / noise:+6.1f}" if noise > 0 else "   n/a"
                    cells.append(f"{100 * rel:+6.2f}% ({z})")
                err = f"   noise (1 s.e.) {100 * math.hypot(se[0], ref_se[0]) / ref[0]:.2f}% R" if se and ref_se else ""
                print(f"    {renderer:17s} {'  '.join(cells)}{err}")


if __name__ == '__main__':
    main()

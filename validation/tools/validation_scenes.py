#!/usr/bin/env python3
"""Builds the validation scenes: scenes the estimator defaults are measured on and never tuned on.

Usage (from the repository root, after validation/tools/fetch_validation_sources.sh):
    python3 validation/tools/validation_scenes.py [--src DIR] NAME [NAME ...]
    python3 validation/tools/validation_scenes.py [--src DIR] all        # every scene into validation/<name>

DIR defaults to /tmp/cvtrace-validation-sources, laid out as the fetch script leaves it. Each
scene folder gets scene.gltf + scene.bin, PNG textures where the scene has them, a lat-long sky
(sky.exr, written with oiiotool) where it has one, and scene.cvtrace.toml. SOURCE.md files are
written by hand and are not touched.

Only the standard library is used (plus the `oiiotool` binary for the sky maps, as
scenes/tools/import_scenes.py does), and the output is deterministic: the same sources give the same
bytes. Units are metres, +Y up. The conventions are those of scenes/tools/author_scenes.py: every
triangle is wound counter-clockwise around the normal it is meant to have (scanned meshes are
re-oriented so that their signed volume is positive, i.e. they face outwards), emitters are
one-sided and face where their light goes, materials are glTF metallic-roughness with
KHR_materials_specular / transmission / ior / emissive_strength, the sun is a
KHR_lights_punctual directional light and the sky an environment map in the sidecar.
"""
import json
import math
import os
import struct
import subprocess
import sys
import tempfile
import xml.etree.ElementTree as ET

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "..", "scenes", "tools"))
import author_scenes as au  # noqa: E402  (Geom, quad, box, lathe, sphere, textures, look_rotation)

DEFAULT_SRC = "/tmp/cvtrace-validation-sources"

# Where each source file lies under the fetch script's destination folder.
SIONNA = "sionna_rt-2.2.0/sionna/rt/scenes"
CGAL = "libcgal-demo-5.5.1-2/data/meshes"
GENESIS = "genesis_world-1.4.5/genesis/assets/meshes"

RENDER = {"width": 640, "height": 360, "max_depth": -1, "rr_depth": 5}

add, sub, mul, dot, cross, normalize, length = au.add, au.sub, au.mul, au.dot, au.cross, au.normalize, au.length


# ---------------------------------------------------------------------------------------------
# Readers for the source formats
# ---------------------------------------------------------------------------------------------


def read_ply(path):
    """Binary little-endian PLY: vertex x, y, z (other float properties skipped), polygon faces."""
    with open(path, "rb") as f:
        data = f.read()
    end = data.index(b"end_header\n") + len(b"end_header\n")
    header = data[:end].decode("ascii").splitlines()
    assert "format binary_little_endian 1.0" in header, path
    elements, cur = [], None
    for line in header:
        w = line.split()
        if w[0] == "element":
            cur = [w[1], int(w[2]), []]
            elements.append(cur)
        elif w[0] == "property":
            cur[2].append(w[1:])
    sizes = {"float": 4, "uchar": 1, "int": 4, "uint": 4}
    off = end
    verts, faces = [], []
    for name, count, props in elements:
        if name == "vertex":
            assert all(p[0] == "float" for p in props) and [p[1] for p in props[:3]] == ["x", "y", "z"], path
            n = len(props)
            vals = struct.unpack_from("<%df" % (n * count), data, off)
            off += 4 * n * count
            verts = [vals[i * n:i * n + 3] for i in range(count)]
        elif name == "face":
            assert props == [["list", "uchar", "int", "vertex_indices"]], path
            for _ in range(count):
                k = data[off]
                faces.append(struct.unpack_from("<%di" % k, data, off + 1))
                off += 1 + 4 * k
        else:
            raise ValueError(f"{path}: unexpected element {name}")
    return verts, faces


def read_off(path):
    with open(path, encoding="ascii") as f:
        words = [w for line in f for w in line.split("#")[0].split()]
    assert words[0] == "OFF", path
    nv, nf = int(words[1]), int(words[2])
    i = 4
    verts = []
    for _ in range(nv):
        verts.append((float(words[i]), float(words[i + 1]), float(words[i + 2])))
        i += 3
    faces = []
    for _ in range(nf):
        k = int(words[i])
        faces.append(tuple(int(w) for w in words[i + 1:i + 1 + k]))
        i += 1 + k
    # OFF allows per-face colours after the indices; reading them as indices would go wrong
    # silently, so a file with anything left over is refused.
    assert i == len(words), f"{path}: per-face colours or trailing data are not supported"
    return verts, faces


def read_obj(path):
    verts, faces = [], []
    with open(path, encoding="utf-8") as f:
        for line in f:
            w = line.split()
            if not w:
                continue
            if w[0] == "v":
                verts.append((float(w[1]), float(w[2]), float(w[3])))
            elif w[0] == "f":
                faces.append(tuple(int(t.split("/")[0]) - 1 for t in w[1:]))
    return verts, faces


def fan(faces):
    return [(f[0], f[i], f[i + 1]) for f in faces for i in range(1, len(f) - 1)]


# ---------------------------------------------------------------------------------------------
# Mesh: shared vertices, optional smooth normals and UVs
# ---------------------------------------------------------------------------------------------


class Mesh:
    def __init__(self, p=None, t=None, n=None, uv=None):
        self.p, self.t, self.n, self.uv = p or [], t or [], n, uv

    @staticmethod
    def of_geom(g):
        return Mesh(list(g.p), list(g.t), list(g.n), list(g.uv))

    def extend(self, other):
        """Appends `other`. Normals must be on both or neither; UVs survive only if every part
        has them (a scanned mesh has none, and untextured materials do not need them)."""
        if not self.p:
            self.n = None if other.n is None else []
            self.uv = None if other.uv is None else []
        assert (self.n is None) == (other.n is None), "mixing meshes with and without normals"
        if other.uv is None:
            self.uv = None
        off = len(self.p)
        self.p += other.p
        self.t += [(a + off, b + off, c + off) for a, b, c in other.t]
        if self.n is not None:
            self.n += other.n
        if self.uv is not None:
            self.uv += other.uv
        return self


def clean(verts, tris):
    """Drops degenerate and unused geometry; keeps the order of what remains."""
    keep = []
    for a, b, c in tris:
        if a == b or b == c or a == c:
            continue
        if length(cross(sub(verts[b], verts[a]), sub(verts[c], verts[a]))) < 1e-14:
            continue
        keep.append((a, b, c))
    used = {}
    for tri in keep:
        for v in tri:
            if v not in used:
                used[v] = len(used)
    order = sorted(used, key=used.get)
    return [verts[v] for v in order], [(used[a], used[b], used[c]) for a, b, c in keep]


def signed_volume(p, t):
    return sum(dot(p[a], cross(p[b], p[c])) for a, b, c in t) / 6.0


def smooth_normals(p, t):
    acc = [[0.0, 0.0, 0.0] for _ in p]
    for a, b, c in t:
        g = cross(sub(p[b], p[a]), sub(p[c], p[a]))  # area-weighted
        for v in (a, b, c):
            acc[v][0] += g[0]
            acc[v][1] += g[1]
            acc[v][2] += g[2]
    out = []
    for v in acc:
        n = normalize(v)
        out.append(n if n != (0.0, 0.0, 0.0) else (0.0, 1.0, 0.0))
    return out


def scanned(verts, faces, height, base=(0.0, 0.0, 0.0), yaw=0.0):
    """A +Y-up scanned mesh made outward-facing, smooth-shaded, turned `yaw` degrees about +Y,
    scaled to `height` metres and standing with its lowest point on `base` (centred in x and z).
    The meshes used are closed (or nearly: a few boundary edges), so the sign of the volume tells
    which way they are wound."""
    p, t = clean(verts, fan(faces))
    if signed_volume(p, t) < 0:
        t = [(a, c, b) for a, b, c in t]
    a = math.radians(yaw)
    ca, sa = math.cos(a), math.sin(a)
    p = [(ca * x + sa * z, y, -sa * x + ca * z) for x, y, z in p]
    lo = [min(q[k] for q in p) for k in range(3)]
    hi = [max(q[k] for q in p) for k in range(3)]
    s = height / (hi[1] - lo[1])
    cx, cz = (lo[0] + hi[0]) / 2, (lo[2] + hi[2]) / 2
    p = [(base[0] + (x - cx) * s, base[1] + (y - lo[1]) * s, base[2] + (z - cz) * s) for x, y, z in p]
    return Mesh(p, t, smooth_normals(p, t), None)


def bounds(m):
    lo = [min(q[k] for q in m.p) for k in range(3)]
    hi = [max(q[k] for q in m.p) for k in range(3)]
    return lo, hi


# ---------------------------------------------------------------------------------------------
# Materials (glTF dicts)
# ---------------------------------------------------------------------------------------------


def r6(v):
    return [round(float(x), 6) + 0.0 for x in v]


def mat(name, color=(0.8, 0.8, 0.8), metallic=0.0, roughness=1.0, specular=None, transmission=None, ior=None,
        emission=None, base_tex=None, mr_tex=None):
    """specular 0 makes a pure Lambertian; None keeps glTF's dielectric layer (F0 = 0.04)."""
    m = {"name": name, "doubleSided": emission is None,
         "pbrMetallicRoughness": {"baseColorFactor": r6(list(color) + [1.0]), "metallicFactor": float(metallic),
                                  "roughnessFactor": float(roughness)}}
    if base_tex is not None:
        m["pbrMetallicRoughness"]["baseColorTexture"] = {"index": base_tex}
    if mr_tex is not None:
        m["pbrMetallicRoughness"]["metallicRoughnessTexture"] = {"index": mr_tex}
    ext = {}
    if specular is not None:
        ext["KHR_materials_specular"] = {"specularFactor": float(specular)}
    if transmission is not None:
        ext["KHR_materials_transmission"] = {"transmissionFactor": float(transmission)}
        ext["KHR_materials_ior"] = {"ior": float(ior if ior is not None else 1.5)}
    if emission is not None:
        s = max(emission)
        m["emissiveFactor"] = r6([c / s for c in emission])
        ext["KHR_materials_emissive_strength"] = {"emissiveStrength": round(float(s), 6)}
        ext.setdefault("KHR_materials_specular", {"specularFactor": 0.0})
        m["pbrMetallicRoughness"]["baseColorFactor"] = [0.0, 0.0, 0.0, 1.0]
    if ext:
        m["extensions"] = ext
    return m


def lambert(name, color):
    return mat(name, color, specular=0.0)


def glass(name, ior=1.5, roughness=0.0, tint=(1.0, 1.0, 1.0)):
    return mat(name, tint, roughness=roughness, transmission=1.0, ior=ior)


def metal(name, f0, roughness):
    return mat(name, f0, metallic=1.0, roughness=roughness)


# ---------------------------------------------------------------------------------------------
# Scene and writer
# ---------------------------------------------------------------------------------------------


class Scene:
    def __init__(self, name, copyright_note, reference_spp):
        self.name = name
        self.copyright = copyright_note
        self.reference_spp = reference_spp
        self.materials = []  # glTF dicts
        self.groups = {}  # material index -> Mesh
        self.group_order = []
        self.images = []  # (file name, bytes)
        self.lights = []  # (light dict, translation, rotation or None)
        self.camera = None  # (eye, target, yfov degrees)
        self.environment = None  # list of (key, toml value)
        self.sky = None  # function d -> rgb radiance, written to sky.exr
        self.comment = []

    def material(self, m):
        self.materials.append(m)
        return len(self.materials) - 1

    def image(self, filename, data):
        self.images.append((filename, data))
        return len(self.images) - 1

    def add(self, material, mesh):
        if material not in self.groups:
            self.groups[material] = Mesh()
            self.group_order.append(material)
        if isinstance(mesh, au.Geom):
            mesh = Mesh.of_geom(mesh)
        self.groups[material].extend(mesh)
        textured = "baseColorTexture" in self.materials[material]["pbrMetallicRoughness"]
        assert not textured or self.groups[material].uv is not None, "a textured material needs UVs"

    def light(self, light, position, target=None, direction=None):
        rot = None
        if direction is not None:
            target = add(position, direction)
        if target is not None:
            d = normalize(sub(target, position))
            up = (0.0, 1.0, 0.0) if abs(d[1]) < 0.99 else (1.0, 0.0, 0.0)
            rot = au.cornell_to_gltf.look_rotation(position, target, up, digits=9)
        self.lights.append((light, position, rot))

    def sun(self, toward_sun, irradiance):
        """A directional light shining from the direction `toward_sun` (pointing at the sun)."""
        s = max(irradiance)
        d = normalize(toward_sun)
        self.light({"type": "directional", "color": r6([c / s for c in irradiance]), "intensity": round(s, 6)},
                   (0.0, 0.0, 0.0), direction=mul(d, -1.0))

    def triangles(self):
        return sum(len(m.t) for m in self.groups.values())

    def write(self, out_dir):
        os.makedirs(out_dir, exist_ok=True)
        buffer = au.BinaryBuffer()
        blob, views, view = buffer.blob, buffer.views, buffer.view
        f32 = au.f32
        accessors, meshes, nodes = [], [], []

        for mi in self.group_order:
            m = self.groups[mi]
            pos = struct.pack("<%df" % (3 * len(m.p)), *[c for q in m.p for c in q])
            lo = [min(f32(q[k]) for q in m.p) for k in range(3)]
            hi = [max(f32(q[k]) for q in m.p) for k in range(3)]
            attrs = {"POSITION": len(accessors)}
            accessors.append({"bufferView": view(pos, 34962), "componentType": 5126, "count": len(m.p),
                              "type": "VEC3", "min": lo, "max": hi})
            if m.n is not None:
                attrs["NORMAL"] = len(accessors)
                data = struct.pack("<%df" % (3 * len(m.n)), *[c for q in m.n for c in q])
                accessors.append({"bufferView": view(data, 34962), "componentType": 5126, "count": len(m.n),
                                  "type": "VEC3"})
            if m.uv is not None:
                attrs["TEXCOORD_0"] = len(accessors)
                data = struct.pack("<%df" % (2 * len(m.uv)), *[c for q in m.uv for c in q])
                accessors.append({"bufferView": view(data, 34962), "componentType": 5126, "count": len(m.uv),
                                  "type": "VEC2"})
            idx = struct.pack("<%dI" % (3 * len(m.t)), *[i for tri in m.t for i in tri])
            accessors.append({"bufferView": view(idx, 34963), "componentType": 5125, "count": 3 * len(m.t),
                              "type": "SCALAR"})
            name = self.materials[mi]["name"]
            meshes.append({"name": name, "primitives": [{"attributes": attrs, "indices": len(accessors) - 1,
                                                         "material": mi, "mode": 4}]})
            nodes.append({"name": name, "mesh": len(meshes) - 1})

        eye, target, yfov = self.camera
        nodes.append({"name": "camera", "camera": 0, "translation": [round(c, 9) + 0.0 for c in eye],
                      "rotation": au.look_rotation(eye, target)})
        ext_used = set()
        for m in self.materials:
            ext_used.update(m.get("extensions", {}).keys())
        gltf = {
            "asset": {"version": "2.0", "generator": f"cvtrace scripts/validation_scenes.py {self.name}",
                      "copyright": self.copyright,
                      "extras": {"defaultResolution": [RENDER["width"], RENDER["height"]]}},
            "scene": 0,
        }
        if self.lights:
            ext_used.add("KHR_lights_punctual")
            gl_lights = []
            for i, (light, position, rot) in enumerate(self.lights):
                gl_lights.append(dict(name=f"{light['type']} {i}", **light))
                node = {"name": f"light {i}", "translation": [round(c, 9) + 0.0 for c in position],
                        "extensions": {"KHR_lights_punctual": {"light": i}}}
                if rot is not None:
                    node["rotation"] = rot
                nodes.append(node)
            gltf["extensions"] = {"KHR_lights_punctual": {"lights": gl_lights}}
        gltf["extensionsUsed"] = sorted(ext_used)
        gltf.update({
            "scenes": [{"name": self.name, "nodes": list(range(len(nodes)))}],
            "nodes": nodes,
            "cameras": [{"name": "camera", "type": "perspective", "perspective": {
                "yfov": round(math.radians(yfov), 9), "aspectRatio": RENDER["width"] / RENDER["height"],
                "znear": 0.01}}],
            "meshes": meshes,
            "materials": self.materials,
            "accessors": accessors,
            "bufferViews": views,
            "buffers": [{"uri": "scene.bin", "byteLength": len(blob)}],
        })
        if self.images:
            gltf["images"] = [{"uri": f} for f, _ in self.images]
            gltf["samplers"] = [{"magFilter": 9729, "minFilter": 9987, "wrapS": 10497, "wrapT": 10497}]
            gltf["textures"] = [{"sampler": 0, "source": i} for i in range(len(self.images))]
        with open(os.path.join(out_dir, "scene.gltf"), "w", encoding="utf-8") as f:
            json.dump(gltf, f, indent=1)
            f.write("\n")
        with open(os.path.join(out_dir, "scene.bin"), "wb") as f:
            f.write(blob)
        for fname, data in self.images:
            with open(os.path.join(out_dir, fname), "wb") as f:
                f.write(data)
        if self.sky is not None:
            write_sky(self.sky, os.path.join(out_dir, "sky.exr"))
        lines = [f"# Render defaults of the validation scene {self.name} (written by validation/tools/validation_scenes.py)."]
        lines += [f"# {c}" for c in self.comment]
        lines.append("[render]")
        for k in ("width", "height", "max_depth", "rr_depth"):
            lines.append(f"{k} = {RENDER[k]}")
        lines.append(f"reference_spp = {self.reference_spp}")
        if self.environment:
            lines += ["", "[environment]"] + [f"{k} = {v}" for k, v in self.environment]
        with open(os.path.join(out_dir, "scene.cvtrace.toml"), "w", encoding="utf-8") as f:
            f.write("\n".join(lines) + "\n")
        print(f"{self.name}: {self.triangles()} triangles, {len(self.materials)} materials, {len(self.images)} textures, "
              f"{len(self.lights)} punctual lights, bin {len(blob)} bytes -> {out_dir}")


# ---------------------------------------------------------------------------------------------
# Sky maps
# ---------------------------------------------------------------------------------------------

# Texels are looked up nearest-neighbour: 1024 x 512 (0.35 degrees a row) with a gradient of
# finite slope at the horizon keeps the rows from showing as bands in a wide sky.
SKY_W, SKY_H = 1024, 512


def make_sky(sun_dir, zenith, horizon, ground, glow):
    """A clear-sky gradient with a glow around the sun (the sun itself is a directional light)."""
    sd = normalize(sun_dir)

    def radiance(d):
        y = d[1]
        if y >= 0:
            t = 1.0 - (1.0 - y) ** 2.5
            base = [horizon[k] * (1 - t) + zenith[k] * t for k in range(3)]
            ang = math.degrees(math.acos(max(-1.0, min(1.0, dot(d, sd)))))
            g = math.exp(-ang / 10.0) + 0.35 * math.exp(-ang / 45.0)
            return [base[k] + g * glow[k] for k in range(3)]
        t = min(1.0, -y * 6.0)
        return [horizon[k] * (1 - t) + ground[k] * t for k in range(3)]

    return radiance


def write_sky(radiance, path):
    """Lat-long map in cvtrace's convention (u = 0.5 + atan2(x, -z) / 2pi, v = acos(y) / pi, row 0
    at the top), 2x2 supersampled, through a PFM to a half-float ZIP EXR with fixed metadata."""
    rows = []
    for j in range(SKY_H):
        row = []
        for i in range(SKY_W):
            acc = [0.0, 0.0, 0.0]
            for sj in range(2):
                for si in range(2):
                    phi = ((i + (si + 0.5) / 2) / SKY_W - 0.5) * 2 * math.pi
                    theta = (j + (sj + 0.5) / 2) / SKY_H * math.pi
                    d = (math.sin(theta) * math.sin(phi), math.cos(theta), -math.sin(theta) * math.cos(phi))
                    r = radiance(d)
                    acc = [acc[k] + r[k] / 4 for k in range(3)]
            row += acc
        rows.append(struct.pack("<%df" % (3 * SKY_W), *row))
    with tempfile.TemporaryDirectory() as tmp:
        pfm = os.path.join(tmp, "sky.pfm")
        with open(pfm, "wb") as f:
            f.write(b"PF\n%d %d\n-1.0\n" % (SKY_W, SKY_H))
            for r in reversed(rows):
                f.write(r)
        subprocess.run(["oiiotool", "--nosoftwareattrib", pfm, "--attrib", "DateTime", "2000:01:01 00:00:00",
                        "-d", "half", "--compression", "zip", "-o", path], check=True)


# ---------------------------------------------------------------------------------------------
# Building blocks
# ---------------------------------------------------------------------------------------------


def room(lo, hi, tile=1.0, skip=()):
    """Inward-facing box shell, one Geom per face name, for separate materials."""
    out = {}
    for name in ("-x", "+x", "-y", "+y", "-z", "+z"):
        if name in skip:
            continue
        others = tuple(n for n in ("-x", "+x", "-y", "+y", "-z", "+z") if n != name)
        out[name] = au.box(lo, hi, inward=True, tile=tile, skip=others)
    return out


def wall_with_hole(axis_x, z0, z1, y0, y1, hz0, hz1, hy0, hy1, normal_x, tile=1.0):
    """A wall in the plane x = axis_x spanning z0..z1, y0..y1 with a rectangular opening; the
    side facing `normal_x` (+1 or -1) is the room's."""
    g = au.Geom()
    n = (float(normal_x), 0.0, 0.0)
    x = axis_x
    for (za, zb, ya, yb) in ((z0, z1, y0, hy0), (z0, z1, hy1, y1), (z0, hz0, hy0, hy1), (hz1, z1, hy0, hy1)):
        if zb - za > 1e-9 and yb - ya > 1e-9:
            g.extend(au.quad((x, ya, za), (x, ya, zb), (x, yb, zb), (x, yb, za), n, tile=tile))
    return g


def tube(a, b, radius, segments=6):
    """An open thin cylinder from a to b with smooth normals (for wires and rods)."""
    g = au.Geom()
    axis = normalize(sub(b, a))
    ref = (0.0, 1.0, 0.0) if abs(axis[1]) < 0.9 else (1.0, 0.0, 0.0)
    u = normalize(cross(axis, ref))
    v = cross(axis, u)
    ring_a, ring_b = [], []
    for k in range(segments):
        th = 2 * math.pi * k / segments
        n = add(mul(u, math.cos(th)), mul(v, math.sin(th)))
        ring_a.append(g.vert(add(a, mul(n, radius)), n, (k / segments, 0.0)))
        ring_b.append(g.vert(add(b, mul(n, radius)), n, (k / segments, 1.0)))
    for k in range(segments):
        k1 = (k + 1) % segments
        g.tri(ring_a[k], ring_a[k1], ring_b[k1])
        g.tri(ring_a[k], ring_b[k1], ring_b[k])
    return g


def oriented_box(center, size, yaw=0.0, pitch=0.0):
    """A box of `size` rotated `pitch` degrees about x, then `yaw` about y, then moved to center."""
    hx, hy, hz = size[0] / 2, size[1] / 2, size[2] / 2
    g = au.box((-hx, -hy, -hz), (hx, hy, hz))
    p, y = math.radians(pitch), math.radians(yaw)
    cp, sp, cy, sy = math.cos(p), math.sin(p), math.cos(y), math.sin(y)

    def rv(v):
        x1, y1, z1 = v[0], cp * v[1] - sp * v[2], sp * v[1] + cp * v[2]
        return (cy * x1 + sy * z1, y1, -sy * x1 + cy * z1)

    return g.transformed(lambda q: add(rv(q), center), rv)


def icosphere_edges(subdiv):
    """Vertices and unique edges of a subdivided icosahedron on the unit sphere."""
    t = (1 + 5 ** 0.5) / 2
    vs = [normalize(v) for v in [(-1, t, 0), (1, t, 0), (-1, -t, 0), (1, -t, 0), (0, -1, t), (0, 1, t),
                                 (0, -1, -t), (0, 1, -t), (t, 0, -1), (t, 0, 1), (-t, 0, -1), (-t, 0, 1)]]
    fs = [(0, 11, 5), (0, 5, 1), (0, 1, 7), (0, 7, 10), (0, 10, 11), (1, 5, 9), (5, 11, 4), (11, 10, 2), (10, 7, 6),
          (7, 1, 8), (3, 9, 4), (3, 4, 2), (3, 2, 6), (3, 6, 8), (3, 8, 9), (4, 9, 5), (2, 4, 11), (6, 2, 10),
          (8, 6, 7), (9, 8, 1)]
    for _ in range(subdiv):
        mid = {}

        def m(a, b):
            key = (min(a, b), max(a, b))
            if key not in mid:
                vs.append(normalize(mul(add(vs[a], vs[b]), 0.5)))
                mid[key] = len(vs) - 1
            return mid[key]

        nf = []
        for a, b, c in fs:
            ab, bc, ca = m(a, b), m(b, c), m(c, a)
            nf += [(a, ab, ca), (b, bc, ab), (c, ca, bc), (ab, bc, ca)]
        fs = nf
    edges = sorted({(min(a, b), max(a, b)) for f in fs for a, b in ((f[0], f[1]), (f[1], f[2]), (f[2], f[0]))})
    return vs, edges


# ---------------------------------------------------------------------------------------------
# Outdoor: sionna-rt's OpenStreetMap city models under sun and sky
# ---------------------------------------------------------------------------------------------

# The radio materials of the city models (ITU names) replaced by visible-light ones.
CITY_MATERIALS = {
    "marble": ("facades", (0.62, 0.57, 0.50), 0.85),  # walls: light plaster and stone
    "metal": ("roofs", (0.42, 0.17, 0.10), 0.55),  # roofs: terracotta tiles
    "brick": ("brick", (0.46, 0.23, 0.15), 0.9),
    "wood": ("wood", (0.36, 0.23, 0.13), 0.7),
    "concrete": ("ground", (0.28, 0.28, 0.27), 0.95),
}


def load_city(src, city):
    """Meshes of a sionna-rt city scene by radio material, in metres, +Y up (the source is +Z up)."""
    folder = os.path.join(src, SIONNA, city)
    root = ET.parse(os.path.join(folder, f"{city}.xml")).getroot()
    kinds = {b.get("id"): b.find("string[@name='type']").get("value") for b in root.iter("bsdf")}
    groups = {}
    for shape in root.iter("shape"):
        fname = shape.find("string[@name='filename']").get("value")
        bsdf = kinds[shape.find("ref").get("id")]
        verts, faces = read_ply(os.path.join(folder, fname))
        verts = [(x, z, -y) for x, y, z in verts]
        p, t = clean(verts, fan(faces))
        groups.setdefault(bsdf, Mesh()).extend(Mesh(p, t))
    return groups


def build_city(src, city, name, camera, sun_elev, sun_azim, sun_e, sky, spp, note, materials=None):
    sc = Scene(name, "City model from sionna-rt 2.2.0 (Apache-2.0; geometry from OpenStreetMap, "
                     "(c) OpenStreetMap contributors, ODbL), materials replaced; see SOURCE.md", spp)
    groups = load_city(src, city)
    for bsdf in sorted(groups):
        label, colour, rough = dict(CITY_MATERIALS, **(materials or {}))[bsdf]
        sc.add(sc.material(mat(label, colour, roughness=rough)), groups[bsdf])
    el, az = math.radians(sun_elev), math.radians(sun_azim)
    to_sun = (math.cos(el) * math.sin(az), math.sin(el), -math.cos(el) * math.cos(az))
    sc.sun(to_sun, sun_e)
    sc.sky = make_sky(to_sun, *sky)
    sc.environment = [("map", '"sky.exr"'), ("strength", "1.0")]
    sc.camera = camera
    sc.comment = [note]
    return sc


def build_city_munich(src):
    return build_city(src, "munich", "city-munich",
                      camera=((-330.0, 140.0, 260.0), (0.0, 0.0, 0.0), 38.0),
                      sun_elev=38.0, sun_azim=200.0, sun_e=(3.5, 3.3, 2.95),
                      sky=((0.18, 0.32, 0.75), (0.75, 0.82, 0.95), (0.25, 0.24, 0.22), (0.6, 0.55, 0.45)),
                      spp=12288, note="Sun: directional light (KHR_lights_punctual); sky: sky.exr without the sun disc.")


def build_city_etoile(src):
    return build_city(src, "etoile", "city-etoile",
                      camera=((250.0, 70.0, 260.0), (0.0, 10.0, 0.0), 40.0),
                      sun_elev=12.0, sun_azim=250.0, sun_e=(4.0, 2.9, 1.7),
                      sky=((0.14, 0.24, 0.6), (0.9, 0.7, 0.5), (0.22, 0.2, 0.18), (1.2, 0.7, 0.35)),
                      spp=12288, note="Low evening sun: directional light; sky: sky.exr without the sun disc.")



# ---------------------------------------------------------------------------------------------
# Scanned objects
# ---------------------------------------------------------------------------------------------


def cgal_mesh(src, name):
    return read_off(os.path.join(src, CGAL, name))


def genesis_dragon(src):
    return read_obj(os.path.join(src, GENESIS, "dragon.obj"))


def studio(sc, size=6.0, back=-1.6, height=3.0, colour=(0.6, 0.6, 0.6)):
    """A floor and a back wall (a photographer's backdrop), both Lambertian."""
    m = sc.material(lambert("backdrop", colour))
    h = size / 2
    sc.add(m, au.quad((-h, 0, back), (h, 0, back), (h, 0, h), (-h, 0, h), (0, 1, 0), tile=1.0))
    sc.add(m, au.quad((-h, 0, back), (-h, height, back), (h, height, back), (h, 0, back), (0, 0, 1), tile=1.0))


def emissive_quad(sc, name, center, size, facing, radiance):
    """A one-sided rectangular emitter of `size` (w, h) centred at `center`, emitting along `facing`."""
    n = normalize(facing)
    ref = (0.0, 1.0, 0.0) if abs(n[1]) < 0.9 else (0.0, 0.0, 1.0)
    u = normalize(cross(ref, n))
    v = cross(n, u)
    hu, hv = mul(u, size[0] / 2), mul(v, size[1] / 2)
    c = center
    g = au.quad(sub(sub(c, hu), hv), sub(add(c, hu), hv), add(add(c, hu), hv), add(sub(c, hu), hv), n)
    sc.add(sc.material(mat(name, emission=radiance)), g)


def build_bunny_glass(src):
    sc = Scene("bunny-glass", "Stanford bunny (CGAL 5.5.1 data, Debian libcgal-demo 5.5.1-2); see SOURCE.md", 16384)
    studio(sc)
    bunny = scanned(*cgal_mesh(src, "bunny00.off"), height=0.32, base=(-0.2, 0.0, 0.0), yaw=20.0)
    sc.add(sc.material(mat("glossy red plastic", (0.55, 0.05, 0.03), roughness=0.12)), bunny)
    g = sc.material(glass("clear glass"))
    sc.add(g, au.sphere((0.2, 0.12, 0.12), 0.12, rings=48, segments=96))
    sc.add(g, au.cylinder((0.33, 0.0, -0.22), 0.07, 0.0, 0.3, segments=96))
    emissive_quad(sc, "softbox", (-0.6, 1.3, 0.7), (0.7, 0.7), sub((0.0, 0.1, 0.0), (-0.6, 1.3, 0.7)),
                  (12.0, 11.5, 10.5))
    sc.environment = [("color", "[0.03, 0.035, 0.04]"), ("strength", "1.0")]
    sc.camera = ((0.05, 0.42, 1.35), (0.02, 0.13, 0.0), 26.0)
    sc.comment = ["Light: the softbox (an emissive quad) and a dim constant environment."]
    return sc


def tex_planks_small():
    return au.tex_planks(size=256, planks=6, seed=31)


def build_armadillo_room(src):
    sc = Scene("armadillo-room", "Stanford armadillo (CGAL 5.5.1 data, Debian libcgal-demo 5.5.1-2); see SOURCE.md", 16384)
    lo, hi = (-2.5, 0.0, -3.0), (2.5, 2.8, 2.0)
    faces = room(lo, hi, skip=("+x",))
    wall = sc.material(lambert("plaster", (0.75, 0.73, 0.69)))
    floor_tex = sc.image("planks.png", tex_planks_small())
    floor = sc.material(mat("oak floor", (1, 1, 1), roughness=0.45, base_tex=floor_tex))
    for name, g in faces.items():
        if name == "-y":
            sc.add(floor, au.box(lo, hi, inward=True, tile=1.5, skip=("-x", "+x", "+y", "-z", "+z")))
        else:
            sc.add(wall, g)
    # The +x wall with a window; the light comes from the sky and the sun outside.
    sc.add(wall, wall_with_hole(2.5, -3.0, 2.0, 0.0, 2.8, -2.2, -0.4, 0.8, 2.3, -1))
    sc.add(sc.material(lambert("plinth", (0.2, 0.2, 0.22))), au.box((-0.3, 0.0, -1.5), (0.3, 0.6, -0.9)))
    arm = scanned(*cgal_mesh(src, "armadillo.off"), height=0.75, base=(0.0, 0.6, -1.2), yaw=200.0)
    sc.add(sc.material(metal("polished gold", (1.0, 0.78, 0.34), 0.22)), arm)
    emissive_quad(sc, "ceiling panel", (-0.8, 2.79, 0.0), (0.8, 0.8), (0, -1, 0), (10.0, 9.7, 9.0))
    to_sun = normalize((0.75, 0.5, -0.35))
    sc.sun(to_sun, (4.5, 4.2, 3.8))
    sc.sky = make_sky(to_sun, (0.18, 0.32, 0.75), (0.75, 0.82, 0.95), (0.25, 0.24, 0.22), (0.6, 0.55, 0.45))
    sc.environment = [("map", '"sky.exr"'), ("strength", "1.0")]
    sc.camera = ((-1.3, 1.45, 1.4), (0.0, 0.95, -1.2), 42.0)
    sc.comment = ["Light: sun (directional) and sky through the window, one ceiling panel."]
    return sc


# Procedural PBR textures: f(u, v) -> (linear base colour, roughness, metallic)


def srgb8(c):
    return tuple(max(0, min(255, int(round(255 * (12.92 * x if x <= 0.0031308 else 1.055 * x ** (1 / 2.4) - 0.055)))))
                 for x in c)


def pbr_textures(f, w=256, h=128):
    base, mr = [], []
    for y in range(h):
        for x in range(w):
            c, r, m = f((x + 0.5) / w, (y + 0.5) / h)
            base.append(srgb8(c))
            mr.append((255, max(0, min(255, int(round(255 * r)))), max(0, min(255, int(round(255 * m))))))
    return au.png_bytes(w, h, base), au.png_bytes(w, h, mr)


def lerp(a, b, t):
    return tuple(x + (y - x) * t for x, y in zip(a, b))


def smooth(e0, e1, x):
    t = max(0.0, min(1.0, (x - e0) / (e1 - e0)))
    return t * t * (3 - 2 * t)


def pbr_checker(u, v):
    k = (int(u * 12) + int(v * 6)) % 2
    return ((0.8, 0.8, 0.78), 0.25, 0.0) if k else ((0.05, 0.09, 0.25), 0.6, 0.0)


def pbr_rust(u, v):
    n = au.fbm(u, v, 8, 4, 3, 4)
    t = smooth(0.38, 0.5, n)
    c = lerp((0.56, 0.57, 0.58), lerp((0.42, 0.17, 0.06), (0.25, 0.09, 0.03), au.fbm(u, v, 32, 16, 5, 2)), t)
    return c, 0.25 + 0.65 * t, 1.0 - t


def pbr_marble(u, v):
    n = au.fbm(u, v, 4, 2, 7, 4)
    vein = abs(math.sin(2 * math.pi * (3 * u + 1.5 * v + 2.5 * n)))
    d = smooth(0.0, 0.12, vein)
    return lerp((0.18, 0.17, 0.16), (0.85, 0.84, 0.8), d), 0.06, 0.0


def pbr_brick(u, v):
    rows, cols = 12, 16
    r = int(v * rows)
    fu = u * cols + (0.5 if r % 2 else 0.0)
    bu, bv = fu - math.floor(fu), v * rows - r
    mortar = min(bu, 1 - bu) < 0.06 or min(bv, 1 - bv) < 0.1
    if mortar:
        return (0.55, 0.53, 0.5), 0.95, 0.0
    tone = au.hash01(int(math.floor(fu)) % cols, r, 9)
    return lerp((0.32, 0.1, 0.05), (0.5, 0.2, 0.1), tone), 0.85, 0.0


def pbr_brushed_gold(u, v):
    band = int(v * 8) % 2
    streak = au.fbm(u, v, 2, 64, 13, 2)
    return (1.0, 0.76, 0.33), (0.12 if band else 0.45) + 0.1 * (streak - 0.5), 1.0


def pbr_wood(u, v):
    n = au.fbm(u, v, 4, 8, 17, 3)
    g = 0.5 + 0.5 * math.sin(2 * math.pi * (20 * v + 3 * n))
    return lerp((0.18, 0.08, 0.03), (0.42, 0.22, 0.1), g), 0.35, 0.0


def pbr_dots(u, v):
    fu, fv = u * 16 - math.floor(u * 16) - 0.5, v * 8 - math.floor(v * 8) - 0.5
    if fu * fu + fv * fv < 0.09:
        return (0.95, 0.64, 0.54), 0.2, 1.0  # copper
    return (0.85, 0.85, 0.82), 0.5, 0.0


def pbr_chipped(u, v):
    n = au.fbm(u, v, 6, 3, 21, 4)
    t = smooth(0.58, 0.62, n)
    return lerp((0.08, 0.35, 0.12), (0.91, 0.92, 0.92), t), 0.55 - 0.3 * t, t


PBR = [("checker", pbr_checker), ("rust", pbr_rust), ("marble", pbr_marble), ("brick", pbr_brick),
       ("brushed-gold", pbr_brushed_gold), ("wood", pbr_wood), ("copper-dots", pbr_dots), ("chipped-paint", pbr_chipped)]


def build_pbr_grid(src):
    sc = Scene("pbr-grid", "cvtrace project, MIT OR Apache-2.0 (procedural)", 16384)
    radius = 0.28
    for i, (name, f) in enumerate(PBR):
        b, m = pbr_textures(f)
        tb, tm = sc.image(f"{name}.png", b), sc.image(f"{name}-mr.png", m)
        material = sc.material(mat(name, (1, 1, 1), metallic=1.0, roughness=1.0, base_tex=tb, mr_tex=tm))
        col, row = i % 4, i // 4
        c = ((col - 1.5) * 0.72, radius, (row - 0.5) * 0.8)
        g = Mesh.of_geom(au.sphere(c, radius, rings=48, segments=96))
        g.uv = [(uu, vv / (math.pi * radius)) for uu, vv in g.uv]
        sc.add(material, g)
    tiles = au.tex_tiles(256, 4, 3, [(150, 146, 138), (120, 116, 110)], (70, 68, 64), 41)
    floor = sc.material(mat("tiled floor", (1, 1, 1), roughness=0.7, base_tex=sc.image("tiles.png", tiles)))
    sc.add(floor, au.quad((-6, 0, -6), (6, 0, -6), (6, 0, 6), (-6, 0, 6), (0, 1, 0), tile=1.0))
    to_sun = normalize((-0.5, 0.75, 0.6))
    sc.sun(to_sun, (3.5, 3.3, 3.0))
    sc.sky = make_sky(to_sun, (0.18, 0.32, 0.75), (0.75, 0.82, 0.95), (0.25, 0.24, 0.22), (0.6, 0.55, 0.45))
    sc.environment = [("map", '"sky.exr"'), ("strength", "1.0")]
    sc.camera = ((0.0, 1.5, 2.9), (0.0, 0.2, 0.0), 36.0)
    sc.comment = ["Light: sun (directional) and sky.exr."]
    return sc


def build_thin_blinds(src):
    sc = Scene("thin-blinds", "cvtrace project, MIT OR Apache-2.0 (procedural)", 16384)
    lo, hi = (-2.0, 0.0, -2.5), (2.0, 2.7, 2.5)
    wall = sc.material(lambert("plaster", (0.72, 0.7, 0.66)))
    floor = sc.material(mat("oak floor", (1, 1, 1), roughness=0.5, base_tex=sc.image("planks.png", tex_planks_small())))
    for name, g in room(lo, hi, skip=("-z",)).items():
        if name == "-y":
            sc.add(floor, au.box(lo, hi, inward=True, tile=1.5, skip=("-x", "+x", "+y", "-z", "+z")))
        else:
            sc.add(wall, g)
    # Back wall (z = -2.5) with a window 2 m wide; the room side faces +z.
    g = au.Geom()
    for (xa, xb, ya, yb) in ((-2, 2, 0, 0.8), (-2, 2, 2.2, 2.7), (-2, -1, 0.8, 2.2), (1, 2, 0.8, 2.2)):
        g.extend(au.quad((xa, ya, -2.5), (xb, ya, -2.5), (xb, yb, -2.5), (xa, yb, -2.5), (0, 0, 1)))
    sc.add(wall, g)
    # Venetian blinds: 1.5 mm aluminium slats, 25 mm deep, every 35 mm, tilted 35 degrees across
    # the sun's rays, so that they block about three quarters of it and leave stripes.
    slat = sc.material(mat("painted aluminium slats", (0.85, 0.85, 0.83), roughness=0.4))
    blinds = au.Geom()
    y = 0.83
    while y < 2.19:
        blinds.extend(oriented_box((0.0, y, -2.44), (2.02, 0.0015, 0.025), pitch=-35.0))
        y += 0.035
    sc.add(slat, blinds)
    for x in (-0.9, 0.9):  # the cords
        sc.add(slat, tube((x, 0.8, -2.44), (x, 2.2, -2.44), 0.001, 6))
    # A wire sphere (an icosphere's edges as 4 mm painted rods) on a small table in
    # the sunlight, which the slats cut into stripes.
    table = sc.material(lambert("table", (0.25, 0.16, 0.1)))
    sc.add(table, au.box((-0.9, 0.0, -0.6), (-0.1, 0.55, 0.2)))
    steel = sc.material(mat("white-painted steel wire", (0.8, 0.8, 0.78), roughness=0.4))
    vs, edges = icosphere_edges(2)
    c, r = (-0.5, 0.55 + 0.3, -0.2), 0.3
    wires = au.Geom()
    for a, b in edges:
        wires.extend(tube(add(c, mul(vs[a], r)), add(c, mul(vs[b], r)), 0.004, 6))
    sc.add(steel, wires)
    to_sun = normalize((0.35, 0.55, -1.0))
    sc.sun(to_sun, (7.0, 6.6, 5.9))
    sc.sky = make_sky(to_sun, (0.18, 0.32, 0.75), (0.75, 0.82, 0.95), (0.25, 0.24, 0.22), (0.6, 0.55, 0.45))
    sc.environment = [("map", '"sky.exr"'), ("strength", "1.0")]
    sc.camera = ((-0.4, 1.35, 2.2), (0.1, 0.9, -2.5), 50.0)
    sc.comment = ["Light: sun (directional) and sky.exr through the blinds of the window."]
    return sc


def build_small_emitters(src):
    sc = Scene("small-emitters", "Stanford dragon (genesis-world 1.4.5, Apache-2.0); see SOURCE.md", 32768)
    lo, hi = (-2.0, 0.0, -2.0), (2.0, 2.6, 2.0)
    wall = sc.material(lambert("wall", (0.55, 0.52, 0.48)))
    floor = sc.material(mat("oak floor", (1, 1, 1), roughness=0.5, base_tex=sc.image("planks.png", tex_planks_small())))
    for name, g in room(lo, hi).items():
        if name == "-y":
            sc.add(floor, au.box(lo, hi, inward=True, tile=1.5, skip=("-x", "+x", "+y", "-z", "+z")))
        else:
            sc.add(wall, g)
    sc.add(sc.material(lambert("plinth", (0.3, 0.3, 0.32))), au.box((-0.35, 0.0, -0.75), (0.35, 0.5, -0.25)))
    dragon = scanned(*genesis_dragon(src), height=0.5, base=(0.0, 0.5, -0.5), yaw=0.0)
    sc.add(sc.material(mat("white glaze", (0.75, 0.73, 0.68), roughness=0.3)), dragon)
    bulb = sc.material(mat("bulb", emission=(130.0, 85.0, 40.0)))
    bulbs = au.Geom()
    # Two strings of fairy lights sagging across the back wall, 1.2 cm bulbs.
    for k, (y0, sag) in enumerate(((2.2, 0.35), (1.7, 0.25))):
        n = 22
        for i in range(n):
            t = (i + 0.5) / n
            x = -1.8 + 3.6 * t
            y = y0 - sag * 4 * t * (1 - t)
            bulbs.extend(au.sphere((x, y, -1.9), 0.012, rings=6, segments=10))
    sc.add(bulb, bulbs)
    # Three tiny, much brighter lamps around the dragon: its key light.
    lamps = au.Geom()
    for p in ((-0.5, 0.62, -0.2), (0.45, 0.75, -0.65), (0.1, 1.0, 0.1)):
        lamps.extend(au.sphere(p, 0.01, rings=6, segments=10))
    sc.add(sc.material(mat("lamp", emission=(1500.0, 1300.0, 1000.0))), lamps)
    sc.camera = ((0.0, 1.05, 1.2), (0.0, 0.85, -0.6), 50.0)
    sc.comment = ["Light: 47 emissive spheres of 1-1.2 cm radius and nothing else."]
    return sc


def build_caustics(src):
    sc = Scene("caustics", "Stanford dragon (genesis-world 1.4.5, Apache-2.0); see SOURCE.md", 32768)
    studio(sc, colour=(0.75, 0.75, 0.75))
    g = sc.material(glass("clear glass"))
    dragon = scanned(*genesis_dragon(src), height=0.3, base=(-0.28, 0.0, -0.05), yaw=30.0)
    sc.add(g, dragon)
    sc.add(g, au.sphere((0.28, 0.11, 0.18), 0.11, rings=48, segments=96))
    # A polished gold ring: the classic cardioid caustic on the floor inside it.
    ring = au.lathe([[(0.14, 0.0), (0.15, 0.0)], [(0.15, 0.0), (0.15, 0.06)], [(0.15, 0.06), (0.14, 0.06)],
                     [(0.14, 0.06), (0.14, 0.0)]], 128, center=(0.22, 0.0, -0.3))
    sc.add(sc.material(metal("polished gold", (1.0, 0.8, 0.4), 0.02)), ring)
    # 6 cm: small enough for sharp caustics, large enough that BSDF-sampled paths through the
    # glass find it often enough for a reference to converge.
    lamp = au.sphere((-0.9, 0.7, -0.9), 0.06, rings=16, segments=32)
    sc.add(sc.material(mat("lamp", emission=(375.0, 350.0, 312.5))), lamp)
    sc.environment = [("color", "[0.01, 0.01, 0.012]"), ("strength", "1.0")]
    sc.camera = ((0.1, 0.75, 1.3), (0.0, 0.08, -0.08), 34.0)
    sc.comment = ["Light: one 6 cm spherical lamp and a very dim constant environment; most light"
                  " on the floor arrives through glass or off the ring."]
    return sc


def build_bounce_interior(src):
    sc = Scene("bounce-interior", "ChineseDragon (CGAL 5.5.1 data, Debian libcgal-demo 5.5.1-2); see SOURCE.md", 16384)
    lo, hi = (-3.0, 0.0, -3.0), (3.0, 2.8, 3.0)
    wall = sc.material(lambert("warm white paint", (0.8, 0.77, 0.72)))
    ceiling = sc.material(lambert("ceiling", (0.85, 0.85, 0.85)))
    floor = sc.material(mat("oak floor", (1, 1, 1), roughness=0.5, base_tex=sc.image("planks.png", tex_planks_small())))
    for name, g in room(lo, hi).items():
        if name == "-y":
            sc.add(floor, au.box(lo, hi, inward=True, tile=1.5, skip=("-x", "+x", "+y", "-z", "+z")))
        else:
            sc.add(ceiling if name == "+y" else wall, g)
    sofa = sc.material(lambert("sofa fabric", (0.18, 0.26, 0.45)))
    for b in (((0.4, 0.0, -2.9), (2.6, 0.42, -2.0)), ((0.4, 0.42, -2.9), (2.6, 0.9, -2.65)),
              ((0.4, 0.42, -2.65), (0.6, 0.62, -2.0)), ((2.4, 0.42, -2.65), (2.6, 0.62, -2.0))):
        sc.add(sofa, au.box(*b))
    table = sc.material(mat("table", (0.35, 0.2, 0.1), roughness=0.4))
    sc.add(table, au.box((-1.2, 0.0, -1.9), (0.0, 0.45, -1.1)))
    dragon = scanned(*cgal_mesh(src, "ChineseDragon-10kv.off"), height=0.3, base=(-0.6, 0.45, -1.5), yaw=0.0)
    sc.add(sc.material(lambert("terracotta", (0.6, 0.32, 0.2))), dragon)
    # Two torchieres: spot lights aimed at the ceiling from lamps in two corners. Nothing the
    # camera sees is lit directly except the ceiling above them.
    stand = sc.material(metal("lamp stand", (0.3, 0.3, 0.3), 0.4))
    shade = sc.material(lambert("lamp shade", (0.2, 0.2, 0.2)))
    for x, z in ((2.5, -2.5), (-2.5, 0.5)):
        sc.add(stand, au.cylinder((x, 0.0, z), 0.015, 0.0, 1.75))
        sc.add(shade, au.lathe([[(0.05, 1.75), (0.2, 1.9)]], 32, center=(x, 0.0, z)))
        sc.light({"type": "spot", "color": [1.0, 0.85, 0.65], "intensity": 60.0,
                  "spot": {"innerConeAngle": 0.6, "outerConeAngle": 0.9}}, (x, 1.8, z), direction=(0.0, 1.0, 0.0))
    sc.camera = ((-2.3, 1.5, 2.4), (0.8, 0.8, -1.8), 55.0)
    sc.comment = ["Light: two spot lights aimed at the ceiling in a closed room; all that the camera"
                  " sees but the ceiling above them is lit by bounced light."]
    return sc


def build_city_san_francisco(src):
    return build_city(src, "san_francisco", "city-san-francisco",
                      camera=((-450.0, 300.0, 650.0), (120.0, 40.0, -50.0), 36.0),
                      sun_elev=30.0, sun_azim=160.0, sun_e=(3.5, 3.3, 2.95),
                      sky=((0.16, 0.3, 0.72), (0.72, 0.8, 0.94), (0.25, 0.24, 0.22), (0.6, 0.55, 0.45)),
                      spp=12288, note="Sun: directional light (KHR_lights_punctual); sky: sky.exr without the sun disc.",
                      materials={"marble": ("facades", (0.66, 0.64, 0.6), 0.85),
                                 "metal": ("roofs", (0.3, 0.3, 0.32), 0.8),
                                 "concrete": ("terrain", (0.33, 0.34, 0.29), 0.95)})


SCENES = {
    "city-munich": build_city_munich,
    "city-etoile": build_city_etoile,
    "city-san-francisco": build_city_san_francisco,
    "bunny-glass": build_bunny_glass,
    "armadillo-room": build_armadillo_room,
    "pbr-grid": build_pbr_grid,
    "thin-blinds": build_thin_blinds,
    "small-emitters": build_small_emitters,
    "caustics": build_caustics,
    "bounce-interior": build_bounce_interior,
}


def main(argv):
    src = DEFAULT_SRC
    if len(argv) >= 2 and argv[0] == "--src":
        src, argv = argv[1], argv[2:]
    names = list(SCENES) if argv == ["all"] else argv
    if not names or any(n not in SCENES for n in names):
        sys.exit(__doc__ + "\nscenes: " + " ".join(SCENES))
    root = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..")
    for n in names:
        SCENES[n](src).write(os.path.normpath(os.path.join(root, n)))


if __name__ == "__main__":
    main(sys.argv[1:])

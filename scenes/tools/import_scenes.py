#!/usr/bin/env python3
"""Converts the third-party models of issue 5 into cvtrace scenes (glTF 2.0 + sidecar).

Stdlib-only and deterministic (same input bytes -> same output bytes). One sub-command per
scene; SRC_DIR is the folder `scenes/tools/fetch_scene_sources.sh` filled:

    python3 scenes/tools/import_scenes.py sponza  SRC_DIR scenes/sponza
    python3 scenes/tools/import_scenes.py engine  SRC_DIR scenes/engine
    python3 scenes/tools/import_scenes.py head    SRC_DIR scenes/head
    python3 scenes/tools/import_scenes.py teapots SRC_DIR scenes/teapots

Each writes OUT_DIR/scene.gltf + scene.bin (+ textures / environment map) and
OUT_DIR/scene.cvtrace.toml. The teapots scene also needs `oiiotool` (OpenImageIO) to turn the
generated sky.pfm into sky.exr; the exact command is printed and recorded in its SOURCE.md.
Light units follow the project convention: glTF photometric units are read 1:1 as linear-RGB
radiometric units (emissive radiance = emissiveFactor x emissive_strength; sun irradiance =
color x intensity).
"""
import argparse
import json
import math
import os
import struct
import subprocess
import sys

# --------------------------------------------------------------------------------------------
# Small vector / matrix helpers (column-major 4x4 matrices as flat lists, as glTF stores them)

IDENTITY = [1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0]


def add(a, b):
    return [a[0] + b[0], a[1] + b[1], a[2] + b[2]]


def sub(a, b):
    return [a[0] - b[0], a[1] - b[1], a[2] - b[2]]


def scale(a, s):
    return [a[0] * s, a[1] * s, a[2] * s]


def dot(a, b):
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]


def cross(a, b):
    return [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]]


def normalize(a):
    n = math.sqrt(dot(a, a))
    return [a[0] / n, a[1] / n, a[2] / n] if n > 0 else [0.0, 0.0, 0.0]


def node_matrix(nd):
    if "matrix" in nd:
        return [float(v) for v in nd["matrix"]]
    t = nd.get("translation", [0, 0, 0])
    x, y, z, w = nd.get("rotation", [0, 0, 0, 1])
    s = nd.get("scale", [1, 1, 1])
    r = [1 - 2 * (y * y + z * z), 2 * (x * y + z * w), 2 * (x * z - y * w),
         2 * (x * y - z * w), 1 - 2 * (x * x + z * z), 2 * (y * z + x * w),
         2 * (x * z + y * w), 2 * (y * z - x * w), 1 - 2 * (x * x + y * y)]
    return [r[0] * s[0], r[1] * s[0], r[2] * s[0], 0.0, r[3] * s[1], r[4] * s[1], r[5] * s[1], 0.0,
            r[6] * s[2], r[7] * s[2], r[8] * s[2], 0.0, t[0], t[1], t[2], 1.0]


def mat_mul(a, b):
    return [sum(a[k * 4 + r] * b[c * 4 + k] for k in range(4)) for c in range(4) for r in range(4)]


def mat_point(m, p):
    return [m[r] * p[0] + m[4 + r] * p[1] + m[8 + r] * p[2] + m[12 + r] for r in range(3)]


def look_at_quaternion(eye, target, up=(0.0, 1.0, 0.0)):
    """Rotation (x, y, z, w) turning a glTF camera (looking down -Z, up +Y) towards target."""
    f = normalize(sub(target, eye))
    r = normalize(cross(f, list(up)))
    u = cross(r, f)
    b = scale(f, -1.0)
    # Rotation matrix with columns r, u, b -> quaternion.
    m00, m01, m02 = r[0], u[0], b[0]
    m10, m11, m12 = r[1], u[1], b[1]
    m20, m21, m22 = r[2], u[2], b[2]
    tr = m00 + m11 + m22
    if tr > 0:
        s = math.sqrt(tr + 1.0) * 2
        q = [(m21 - m12) / s, (m02 - m20) / s, (m10 - m01) / s, 0.25 * s]
    elif m00 > m11 and m00 > m22:
        s = math.sqrt(1.0 + m00 - m11 - m22) * 2
        q = [0.25 * s, (m01 + m10) / s, (m02 + m20) / s, (m21 - m12) / s]
    elif m11 > m22:
        s = math.sqrt(1.0 + m11 - m00 - m22) * 2
        q = [(m01 + m10) / s, 0.25 * s, (m12 + m21) / s, (m02 - m20) / s]
    else:
        s = math.sqrt(1.0 + m22 - m00 - m11) * 2
        q = [(m02 + m20) / s, (m12 + m21) / s, 0.25 * s, (m10 - m01) / s]
    return rounded(q, 7)


def rounded(v, digits=6):
    if isinstance(v, (list, tuple)):
        return [rounded(x, digits) for x in v]
    r = round(float(v), digits)
    return 0.0 if r == 0 else r


# --------------------------------------------------------------------------------------------
# glTF writer


class Gltf:
    """Accumulates a glTF document and its single binary buffer."""

    def __init__(self, doc=None, blob=b""):
        self.doc = doc if doc is not None else {"asset": {"version": "2.0"}}
        self.bin = bytearray(blob)
        for key in ("bufferViews", "accessors", "meshes", "materials", "nodes"):
            self.doc.setdefault(key, [])

    def _list(self, key):
        return self.doc.setdefault(key, [])

    def view(self, data, target=None):
        while len(self.bin) % 4:
            self.bin.append(0)
        v = {"buffer": 0, "byteOffset": len(self.bin), "byteLength": len(data)}
        if target is not None:
            v["target"] = target
        self.bin += data
        self.doc["bufferViews"].append(v)
        return len(self.doc["bufferViews"]) - 1

    def accessor(self, values, kind):
        """values: list of tuples (VEC2/VEC3 floats) or ints (SCALAR indices, uint32)."""
        if kind == "SCALAR":
            data = struct.pack("<%dI" % len(values), *values)
            acc = {"bufferView": self.view(data, 34963), "componentType": 5125, "count": len(values),
                   "type": "SCALAR"}
        else:
            n = len(values[0])
            flat = [float(c) for v in values for c in v]
            data = struct.pack("<%df" % len(flat), *flat)
            acc = {"bufferView": self.view(data, 34962), "componentType": 5126, "count": len(values),
                   "type": kind}
            if kind == "VEC3":
                # min/max of the float32 values actually stored (POSITION needs them).
                stored = struct.unpack("<%df" % len(flat), data)
                acc["min"] = [min(stored[i::n]) for i in range(n)]
                acc["max"] = [max(stored[i::n]) for i in range(n)]
        self.doc["accessors"].append(acc)
        return len(self.doc["accessors"]) - 1

    def material(self, m):
        self.doc["materials"].append(m)
        return len(self.doc["materials"]) - 1

    def mesh(self, name, prims):
        """prims: list of (positions, normals or None, uvs or None, indices, material)."""
        out = []
        for pos, nrm, uv, idx, mat in prims:
            attrs = {"POSITION": self.accessor(pos, "VEC3")}
            if nrm is not None:
                attrs["NORMAL"] = self.accessor(nrm, "VEC3")
            if uv is not None:
                attrs["TEXCOORD_0"] = self.accessor(uv, "VEC2")
            out.append({"attributes": attrs, "indices": self.accessor(idx, "SCALAR"), "material": mat, "mode": 4})
        self.doc["meshes"].append({"name": name, "primitives": out})
        return len(self.doc["meshes"]) - 1

    def node(self, nd):
        self.doc["nodes"].append(nd)
        return len(self.doc["nodes"]) - 1

    def camera_node(self, name, eye, target, yfov_deg, aspect=16 / 9):
        cams = self._list("cameras")
        cams.append({"name": name, "type": "perspective",
                     "perspective": {"aspectRatio": rounded(aspect), "yfov": rounded(math.radians(yfov_deg)),
                                     "znear": 0.01, "zfar": 1000.0}})
        return self.node({"name": name, "camera": len(cams) - 1, "translation": rounded(eye),
                          "rotation": look_at_quaternion(eye, target)})

    def write(self, out_dir, stem="scene"):
        os.makedirs(out_dir, exist_ok=True)
        while len(self.bin) % 4:
            self.bin.append(0)
        self.doc["buffers"] = [{"uri": stem + ".bin", "byteLength": len(self.bin)}]
        for key in ("bufferViews", "accessors", "meshes", "materials", "nodes"):
            if not self.doc[key]:
                del self.doc[key]
        used = set()
        for m in self.doc.get("materials", []):
            used.update(m.get("extensions", {}).keys())
        for n in self.doc.get("nodes", []):
            used.update(n.get("extensions", {}).keys())
        used.update(self.doc.get("extensions", {}).keys())
        if used:
            self.doc["extensionsUsed"] = sorted(used)
        else:
            self.doc.pop("extensionsUsed", None)
        with open(os.path.join(out_dir, stem + ".bin"), "wb") as f:
            f.write(self.bin)
        with open(os.path.join(out_dir, stem + ".gltf"), "w", encoding="utf-8", newline="\n") as f:
            f.write(json.dumps(self.doc, indent=1, ensure_ascii=False))
            f.write("\n")


def read_glb(path):
    data = open(path, "rb").read()
    magic, version, _length = struct.unpack_from("<III", data, 0)
    if magic != 0x46546C67 or version != 2:
        sys.exit("%s: not a glTF 2.0 binary" % path)
    json_len, _ = struct.unpack_from("<II", data, 12)
    doc = json.loads(data[20:20 + json_len].decode("utf-8"))
    off = 20 + json_len
    bin_len, _ = struct.unpack_from("<II", data, off)
    return doc, data[off + 8:off + 8 + bin_len]


def glb_bounds(doc, blob, roots, root_matrix=IDENTITY):
    """World-space bounds of every mesh vertex under `roots` (float32 VEC3 positions)."""
    lo, hi = [1e30] * 3, [-1e30] * 3

    def walk(n, m):
        nd = doc["nodes"][n]
        m = mat_mul(m, node_matrix(nd))
        if "mesh" in nd:
            for prim in doc["meshes"][nd["mesh"]]["primitives"]:
                acc = doc["accessors"][prim["attributes"]["POSITION"]]
                bv = doc["bufferViews"][acc["bufferView"]]
                off = bv.get("byteOffset", 0) + acc.get("byteOffset", 0)
                stride = bv.get("byteStride", 12)
                for i in range(acc["count"]):
                    p = mat_point(m, struct.unpack_from("<3f", blob, off + i * stride))
                    for k in range(3):
                        lo[k], hi[k] = min(lo[k], p[k]), max(hi[k], p[k])
        for c in nd.get("children", []):
            walk(c, m)

    for r in roots:
        walk(r, root_matrix)
    return lo, hi


# --------------------------------------------------------------------------------------------
# Materials and simple geometry


def diffuse(name, color, double_sided=True):
    return {"name": name, "doubleSided": double_sided,
            "pbrMetallicRoughness": {"baseColorFactor": rounded(list(color) + [1.0]), "metallicFactor": 0.0,
                                     "roughnessFactor": 1.0},
            "extensions": {"KHR_materials_specular": {"specularFactor": 0.0}}}


def dielectric(name, color, roughness, double_sided=True):
    """Base colour under a dielectric specular layer (glTF's default F0 = 0.04)."""
    return {"name": name, "doubleSided": double_sided,
            "pbrMetallicRoughness": {"baseColorFactor": rounded(list(color) + [1.0]), "metallicFactor": 0.0,
                                     "roughnessFactor": roughness}}


def metal(name, f0, roughness, double_sided=True):
    return {"name": name, "doubleSided": double_sided,
            "pbrMetallicRoughness": {"baseColorFactor": rounded(list(f0) + [1.0]), "metallicFactor": 1.0,
                                     "roughnessFactor": roughness}}


def glass(name, roughness, ior=1.5, tint=(1.0, 1.0, 1.0)):
    return {"name": name, "doubleSided": True,
            "pbrMetallicRoughness": {"baseColorFactor": rounded(list(tint) + [1.0]), "metallicFactor": 0.0,
                                     "roughnessFactor": roughness},
            "extensions": {"KHR_materials_transmission": {"transmissionFactor": 1.0},
                           "KHR_materials_ior": {"ior": ior}}}


def emitter(name, color, strength):
    """One-sided area light: emits from the counter-clockwise (front) side only."""
    return {"name": name, "doubleSided": False,
            "pbrMetallicRoughness": {"baseColorFactor": [0.0, 0.0, 0.0, 1.0], "metallicFactor": 0.0,
                                     "roughnessFactor": 1.0},
            "emissiveFactor": rounded(color),
            "extensions": {"KHR_materials_emissive_strength": {"emissiveStrength": strength},
                           "KHR_materials_specular": {"specularFactor": 0.0}}}


class MeshBuilder:
    """Flat-shaded triangles collected per material."""

    def __init__(self):
        self.groups = {}

    def _group(self, mat):
        return self.groups.setdefault(mat, ([], [], []))

    def quad(self, mat, c, u, v):
        """Rectangle centred at c with half-edges u, v; front face (CCW) towards u x v."""
        pos, nrm, idx = self._group(mat)
        n = normalize(cross(u, v))
        base = len(pos)
        for su, sv in ((-1, -1), (1, -1), (1, 1), (-1, 1)):
            pos.append(rounded(add(c, add(scale(u, su), scale(v, sv)))))
            nrm.append(rounded(n))
        idx += [base, base + 1, base + 2, base, base + 2, base + 3]

    def box(self, mat, lo, hi, outward=True, skip=()):
        """Axis-aligned box; faces point out (or in for a room). skip: face names to leave out."""
        cx, cy, cz = [(lo[i] + hi[i]) / 2 for i in range(3)]
        hx, hy, hz = [(hi[i] - lo[i]) / 2 for i in range(3)]
        s = 1 if outward else -1
        faces = {
            "+x": ([cx + hx, cy, cz], [0, 0, -hz * s], [0, hy, 0]),
            "-x": ([cx - hx, cy, cz], [0, 0, hz * s], [0, hy, 0]),
            "+y": ([cx, cy + hy, cz], [hx * s, 0, 0], [0, 0, -hz]),
            "-y": ([cx, cy - hy, cz], [hx * s, 0, 0], [0, 0, hz]),
            "+z": ([cx, cy, cz + hz], [hx * s, 0, 0], [0, hy, 0]),
            "-z": ([cx, cy, cz - hz], [-hx * s, 0, 0], [0, hy, 0]),
        }
        for name in ("+x", "-x", "+y", "-y", "+z", "-z"):
            if name not in skip:
                self.quad(mat, *faces[name])

    def triangles(self):
        return sum(len(g[2]) // 3 for g in self.groups.values())

    def add_to(self, g, name):
        prims = [(pos, nrm, None, idx, mat) for mat, (pos, nrm, idx) in sorted(self.groups.items())]
        return g.mesh(name, prims)


# Samples per pixel of each committed reference (scene.ref.exr), recorded as the scene's default.
REFERENCE_SPP = {"sponza": 12288, "engine": 12288, "head": 28672, "teapots": 40960}


def write_sidecar(out_dir, scene, environment=None, comment=None):
    lines = []
    if comment:
        lines += ["# " + c for c in comment.splitlines()]
    lines += ["[render]", "width = 320", "height = 180", "max_depth = -1", "rr_depth = 5",
              "reference_spp = %d" % REFERENCE_SPP[scene]]
    if environment:
        lines += ["", "[environment]"]
        for k, v in environment:
            lines.append("%s = %s" % (k, v))
    with open(os.path.join(out_dir, "scene.cvtrace.toml"), "w", encoding="utf-8", newline="\n") as f:
        f.write("\n".join(lines) + "\n")


def count_triangles(doc):
    """Triangles of the default scene, counting every mesh instance."""
    total = 0

    def walk(n):
        nonlocal total
        nd = doc["nodes"][n]
        if "mesh" in nd:
            for p in doc["meshes"][nd["mesh"]]["primitives"]:
                acc = p.get("indices", p["attributes"]["POSITION"])
                total += doc["accessors"][acc]["count"] // 3
        for c in nd.get("children", []):
            walk(c)

    for r in doc["scenes"][doc.get("scene", 0)]["nodes"]:
        walk(r)
    return total


# --------------------------------------------------------------------------------------------
# engine: Khronos' 2CylinderEngine (assimp-testmodels) in a studio

ENGINE_GLB = "assimp/usr/share/assimp/models/glTF2/2CylinderEngine-glTF-Binary/2CylinderEngine.glb"

# Source material name (COLLADA2GLTF "Material_NN", one flat colour each) -> new material.
ENGINE_MATERIALS = {
    "Material_16": lambda n: dielectric(n + " (blue paint)", (0.05, 0.12, 0.45), 0.35),  # source (0, 0, 0.85)
    "Material_17": lambda n: metal(n + " (brass)", (0.91, 0.73, 0.40), 0.3),  # source orange (0.85, 0.56, 0)
    "Material_18": lambda n: dielectric(n + " (red paint)", (0.55, 0.04, 0.03), 0.3),  # source (0.85, 0, 0)
    "Material_19": lambda n: metal(n + " (polished aluminium)", (0.91, 0.92, 0.92), 0.2),  # source grey 0.85
    "Material_20": lambda n: metal(n + " (brushed steel)", (0.62, 0.62, 0.61), 0.35),  # source grey 0.85
    "Material_21": lambda n: dielectric(n + " (black enamel)", (0.02, 0.02, 0.02), 0.25),  # source black
    "Material_22": lambda n: dielectric(n + " (teal paint)", (0.03, 0.25, 0.25), 0.4),  # source (0, 0.43, 0.43)
    "Material_23": lambda n: metal(n + " (cast iron, blued)", (0.45, 0.5, 0.58), 0.45),  # source (0, 0.56, 0.85)
}

ENGINE_ROOM = {"half_x": 2.5, "half_z": 2.0, "height": 2.6}


def cmd_engine(src, out):
    doc, blob = read_glb(os.path.join(src, ENGINE_GLB))
    # The source's root list is [81 (its camera), 0 (the engine)]. Drop the camera node (the last
    # node, referenced by nothing else) and its camera; ours is added below.
    cam_node = doc["scenes"][0]["nodes"][0]
    assert cam_node == len(doc["nodes"]) - 1 and "camera" in doc["nodes"][cam_node]
    doc["nodes"].pop()
    del doc["cameras"]
    engine_root = doc["scenes"][0]["nodes"][1]
    lo, hi = glb_bounds(doc, blob, [engine_root])
    # Units are millimetres (the engine is ~0.74 m long): scale to metres, centre it on the
    # origin in x/z and stand its lowest point on the floor (y = 0).
    # Turned 180 degrees about y (x -> -x, z -> -z) so the brass gear train faces the camera.
    s = 0.001
    t = [(lo[0] + hi[0]) / 2 * s, -lo[1] * s, (lo[2] + hi[2]) / 2 * s]
    doc["materials"] = [ENGINE_MATERIALS[m["name"]](m["name"]) for m in doc["materials"]]

    g = Gltf(doc, blob)
    g.doc["asset"] = {"version": "2.0", "generator": "cvtrace scripts/import_scenes.py engine",
                      "copyright": "2CylinderEngine: see SOURCE.md", "extras": {"defaultResolution": [320, 180]}}
    wall = g.material(diffuse("wall (light grey)", (0.7, 0.7, 0.68)))
    accent = g.material(diffuse("wall (warm beige)", (0.66, 0.5, 0.38)))
    floor = g.material(dielectric("floor (grey epoxy)", (0.32, 0.31, 0.3), 0.5))
    plinth = g.material(dielectric("plinth (grey lacquer)", (0.45, 0.45, 0.45), 0.3))
    panel = g.material(emitter("ceiling panel", (1.0, 0.95, 0.88), 8.0))
    softbox = g.material(emitter("softbox", (1.0, 1.0, 1.0), 14.0))

    r = ENGINE_ROOM
    mb = MeshBuilder()
    mb.box(wall, [-r["half_x"], 0.0, -r["half_z"]], [r["half_x"], r["height"], r["half_z"]], outward=False,
           skip=("-y", "-x"))
    # The left wall is a warm colour, for some colour bleeding.
    mb.quad(accent, [-r["half_x"], r["height"] / 2, 0.0], [0.0, 0.0, -r["half_z"]], [0.0, r["height"] / 2, 0.0])
    mb.quad(floor, [0.0, 0.0, 0.0], [r["half_x"], 0.0, 0.0], [0.0, 0.0, -r["half_z"]])
    # Low plinth the engine stands on.
    plinth_h = 0.12
    mb.box(plinth, [-0.55, 0.0, -0.3], [0.55, plinth_h, 0.3], skip=("-y",))
    # Ceiling panel, 1.6 x 1.0 m, 2 cm below the ceiling, facing down.
    mb.quad(panel, [0.0, r["height"] - 0.02, 0.0], [0.8, 0.0, 0.0], [0.0, 0.0, 0.5])
    # Softbox: 1.0 x 0.8 m, left of the engine, tilted towards it.
    sb_c = [-1.9, 1.3, 0.6]
    aim = normalize(sub([0.0, 0.35, 0.0], sb_c))
    su = scale(normalize(cross([0.0, 1.0, 0.0], aim)), 0.5)
    sv = scale(normalize(cross(aim, su)), 0.4)
    mb.quad(softbox, sb_c, su, sv)
    assert dot(normalize(cross(su, sv)), aim) > 0.99
    room_mesh = mb.add_to(g, "studio")

    t[1] += plinth_h
    eng = g.node({"name": "engine (mm -> m, turned 180 deg)", "children": [engine_root], "scale": [s, s, s],
                  "rotation": [0.0, 1.0, 0.0, 0.0], "translation": rounded(t)})
    room = g.node({"name": "studio", "mesh": room_mesh})
    cam = g.camera_node("camera", [0.95, 0.68, 1.1], [0.0, 0.28, 0.0], 36.0)
    g.doc["scenes"] = [{"name": "engine", "nodes": [cam, eng, room]}]
    g.doc["scene"] = 0
    g.write(out)
    write_sidecar(out, "engine")
    print("engine: %d triangles (engine %d, studio %d)" % (count_triangles(g.doc), count_triangles(g.doc) -
                                                           mb.triangles(), mb.triangles()))


def read_accessor(doc, blob, index):
    """Tuples (VEC2/VEC3 float) or ints (SCALAR) of a tightly indexed, non-sparse accessor."""
    acc = doc["accessors"][index]
    bv = doc["bufferViews"][acc["bufferView"]]
    n = {"SCALAR": 1, "VEC2": 2, "VEC3": 3, "VEC4": 4}[acc["type"]]
    fmt = {5126: "f", 5125: "I", 5123: "H", 5121: "B"}[acc["componentType"]]
    size = struct.calcsize("<" + fmt)
    stride = bv.get("byteStride", n * size)
    off = bv.get("byteOffset", 0) + acc.get("byteOffset", 0)
    out = [struct.unpack_from("<%d%s" % (n, fmt), blob, off + i * stride) for i in range(acc["count"])]
    return [v[0] for v in out] if n == 1 else out


# --------------------------------------------------------------------------------------------
# head: the textured head of easy-gltf's tests, on a pedestal in a small room

HEAD_GLB = "easy-gltf-1.1.5/tests/head.glb"


def cmd_head(src, out):
    doc, blob = read_glb(os.path.join(src, HEAD_GLB))
    head_node = doc["nodes"][0]
    assert head_node["mesh"] == 0 and len(doc["meshes"]) == 1 and len(doc["meshes"][0]["primitives"]) == 1
    prim = doc["meshes"][0]["primitives"][0]
    lo, hi = glb_bounds(doc, blob, [0])

    g = Gltf()
    g.doc["asset"] = {"version": "2.0", "generator": "cvtrace scripts/import_scenes.py head",
                      "copyright": "head: easy-gltf 1.1.5 tests/head.glb (MIT), see SOURCE.md",
                      "extras": {"defaultResolution": [320, 180]}}
    # The base-colour texture (PNG in the source's buffer view 4) becomes a file next to the glTF.
    img = doc["images"][0]
    assert img["mimeType"] == "image/png"
    bv = doc["bufferViews"][img["bufferView"]]
    png = blob[bv.get("byteOffset", 0):bv.get("byteOffset", 0) + bv["byteLength"]]
    os.makedirs(out, exist_ok=True)
    with open(os.path.join(out, "head_diffuse.png"), "wb") as f:
        f.write(png)
    g.doc["images"] = [{"name": "african_head_diffuse", "uri": "head_diffuse.png", "mimeType": "image/png"}]
    g.doc["samplers"] = [{"magFilter": 9729, "minFilter": 9987, "wrapS": 10497, "wrapT": 10497}]
    g.doc["textures"] = [{"source": 0, "sampler": 0}]
    src_mat = doc["materials"][0]
    skin = g.material({"name": "head (" + src_mat["name"] + ")", "doubleSided": True,
                       "pbrMetallicRoughness": {"baseColorTexture": {"index": 0, "texCoord": 0},
                                                "metallicFactor": 0.0, "roughnessFactor": 0.5}})
    attrs = prim["attributes"]
    head_mesh = g.mesh("head", [(read_accessor(doc, blob, attrs["POSITION"]), read_accessor(doc, blob, attrs["NORMAL"]),
                                 read_accessor(doc, blob, attrs["TEXCOORD_0"]),
                                 read_accessor(doc, blob, prim["indices"]), skin)])

    wall = g.material(diffuse("wall (off-white plaster)", (0.72, 0.7, 0.66)))
    back = g.material(diffuse("back wall (muted green)", (0.36, 0.46, 0.38)))
    floor = g.material(dielectric("floor (oak)", (0.42, 0.27, 0.15), 0.45))
    stone = g.material(dielectric("pedestal (light marble)", (0.6, 0.59, 0.57), 0.25))
    wood = g.material(dielectric("shelf (walnut)", (0.25, 0.15, 0.08), 0.4))
    books = [g.material(diffuse("book (%s)" % n, c)) for n, c in
             (("red", (0.5, 0.08, 0.06)), ("blue", (0.08, 0.14, 0.4)), ("ochre", (0.6, 0.45, 0.15)))]
    frame = g.material(dielectric("window frame (white paint)", (0.8, 0.8, 0.78), 0.4))
    window = g.material(emitter("window (daylight)", (0.9, 0.95, 1.0), 12.0))

    hx, hz, h = 1.5, 1.5, 2.6
    mb = MeshBuilder()
    mb.box(wall, [-hx, 0.0, -hz], [hx, h, hz], outward=False, skip=("-y", "-z"))
    mb.quad(back, [0.0, h / 2, -hz], [hx, 0.0, 0.0], [0.0, h / 2, 0.0])
    mb.quad(floor, [0.0, 0.0, 0.0], [hx, 0.0, 0.0], [0.0, 0.0, -hz])
    # Window in the right (+x) wall: an emitting pane 1 cm inside the wall, facing -x, with a
    # frame and a cross of mullions 5 cm in front of it that cast soft shadows.
    wc, ww, wh = [hx - 0.01, 1.55, -0.1], 0.45, 0.6  # centre, half width (z), half height
    mb.quad(window, wc, [0.0, 0.0, ww], [0.0, wh, 0.0])
    fx0, fx1, t = hx - 0.08, hx - 0.005, 0.035
    mb.box(frame, [fx0, wc[1] - wh - t, wc[2] - ww - t], [fx1, wc[1] - wh, wc[2] + ww + t])  # sill
    mb.box(frame, [fx0, wc[1] + wh, wc[2] - ww - t], [fx1, wc[1] + wh + t, wc[2] + ww + t])  # head
    mb.box(frame, [fx0, wc[1] - wh, wc[2] - ww - t], [fx1, wc[1] + wh, wc[2] - ww])
    mb.box(frame, [fx0, wc[1] - wh, wc[2] + ww], [fx1, wc[1] + wh, wc[2] + ww + t])
    m = 0.012
    mb.box(frame, [fx0, wc[1] - wh, wc[2] - m], [fx1, wc[1] + wh, wc[2] + m])  # mullion
    mb.box(frame, [fx0, wc[1] - m, wc[2] - ww], [fx1, wc[1] + m, wc[2] + ww])  # transom
    # Pedestal in the middle of the room.
    top = 1.25
    mb.box(stone, [-0.16, 0.0, -0.16], [0.16, top, 0.16], skip=("-y",))
    # Shelf on the back wall with a few books.
    sy = 1.45
    mb.box(wood, [-1.2, sy - 0.03, -hz], [-0.2, sy, -hz + 0.28], skip=("-z",))
    x = -1.15
    for i, (w, bh) in enumerate(((0.05, 0.24), (0.04, 0.21), (0.06, 0.26), (0.035, 0.22), (0.05, 0.25), (0.045, 0.2))):
        mb.box(books[i % 3], [x, sy, -hz + 0.04], [x + w, sy + bh, -hz + 0.24], skip=("-y",))
        x += w + 0.004
    # A book lying flat at the right end of the shelf.
    mb.box(books[1], [-0.6, sy, -hz + 0.05], [-0.32, sy + 0.045, -hz + 0.25], skip=("-y",))
    room_mesh = mb.add_to(g, "room")

    s = 0.075  # the head is ~3.5 units tall -> ~0.26 m
    head_xf = {k: head_node[k] for k in ("rotation", "translation", "scale", "matrix") if k in head_node}
    inner = g.node(dict({"name": head_node["name"], "mesh": head_mesh}, **head_xf))
    t = [-(lo[0] + hi[0]) / 2 * s, top - lo[1] * s, -(lo[2] + hi[2]) / 2 * s]
    outer = g.node({"name": "head (units -> m, on the pedestal)", "children": [inner], "scale": [s, s, s],
                    "translation": rounded(t)})
    room = g.node({"name": "room", "mesh": room_mesh})
    cam = g.camera_node("camera", [-0.3, 1.46, 0.8], [0.08, 1.39, -0.2], 34.0)
    g.doc["scenes"] = [{"name": "head", "nodes": [cam, outer, room]}]
    g.doc["scene"] = 0
    g.write(out)
    write_sidecar(out, "head")
    n = count_triangles(g.doc)
    print("head: %d triangles (head %d, room %d)" % (n, n - mb.triangles(), mb.triangles()))


# --------------------------------------------------------------------------------------------
# sponza: the Dabrovic Sponza atrium from obj-rs' test fixtures, lit by a sun and the sky

SPONZA_OBJ = "obj-rs-0.7.4/tests/fixtures/sponza.obj"


def read_obj(path):
    """Positions, UVs and faces [(material, [(v, vt or None), ...])] of an OBJ file, in file order.

    Handles negative (relative) indices; `usemtl` names are kept as the material key."""
    pos, uv, faces = [], [], []
    mtl = "default"
    with open(path, "r", encoding="latin-1") as f:
        for line in f:
            parts = line.split()
            if not parts:
                continue
            tag = parts[0]
            if tag == "v":
                pos.append(tuple(float(x) for x in parts[1:4]))
            elif tag == "vt":
                uv.append(tuple(float(x) for x in parts[1:3]))
            elif tag == "usemtl":
                mtl = parts[1]
            elif tag == "f":
                corners = []
                for c in parts[1:]:
                    fields = c.split("/")
                    vi = int(fields[0])
                    vi = vi - 1 if vi > 0 else len(pos) + vi
                    ti = None
                    if len(fields) > 1 and fields[1]:
                        ti = int(fields[1])
                        ti = ti - 1 if ti > 0 else len(uv) + ti
                    corners.append((vi, ti))
                faces.append((mtl, corners))
    return pos, uv, faces


def newell_normal(pts):
    n = [0.0, 0.0, 0.0]
    for i in range(len(pts)):
        a, b = pts[i], pts[(i + 1) % len(pts)]
        n[0] += (a[1] - b[1]) * (a[2] + b[2])
        n[1] += (a[2] - b[2]) * (a[0] + b[0])
        n[2] += (a[0] - b[0]) * (a[1] + b[1])
    return n


def triangulate(pts):
    """Ear clipping of a simple (possibly concave) planar polygon; returns index triples in the
    polygon's own winding. n-2 triangles for n corners."""
    n = len(pts)
    if n == 3:
        return [(0, 1, 2)]
    nrm = newell_normal(pts)
    ax = max(range(3), key=lambda k: abs(nrm[k]))
    i0, i1 = [(1, 2), (2, 0), (0, 1)][ax]
    sign = 1.0 if nrm[ax] >= 0 else -1.0
    p2 = [(p[i0], p[i1]) for p in pts]

    def area2(a, b, c):
        return ((p2[b][0] - p2[a][0]) * (p2[c][1] - p2[a][1]) - (p2[b][1] - p2[a][1]) * (p2[c][0] - p2[a][0])) * sign

    def inside(p, a, b, c):
        return area2(a, b, p) >= 0 and area2(b, c, p) >= 0 and area2(c, a, p) >= 0

    idx = list(range(n))
    tris = []
    guard = 0
    while len(idx) > 3:
        m = len(idx)
        for k in range(m):
            a, b, c = idx[(k - 1) % m], idx[k], idx[(k + 1) % m]
            if area2(a, b, c) <= 1e-12:
                continue
            if any(inside(j, a, b, c) for j in idx if j not in (a, b, c) and p2[j] not in (p2[a], p2[b], p2[c])):
                continue
            tris.append((a, b, c))
            del idx[k]
            break
        else:
            # No proper ear (degenerate/collinear corners): clip the first corner anyway.
            tris.append((idx[-1], idx[0], idx[1]))
            del idx[0]
        guard += 1
        assert guard < 10 * n
    tris.append(tuple(idx))
    return tris


# usemtl name (Croatian: zid wall, pod floor, stup/stub column, baza base, kapitel capital, kut
# corner, luk arch, svod vault, vijenac cornice, ploha face, prozor window, krug circle, vrata
# door, kocka block, reljef relief, vani outside; _00/_01/_02 ground/first/second storey)
# -> material class. The source has no .mtl, so these are our choices.
SPONZA_CLASSES = {
    "sp_00_pod": "floor",
    "sp_00_zid": "wall", "sp_00_svod_zid": "wall", "sp_zid_vani": "wall", "sp_vijenac_ploha": "wall",
    "sp_00_svod": "vault",
    "sp_00_stup": "column", "sp_00_stup_kut": "column", "sp_01_stup": "column", "sp_01_stub": "column",
    "sp_01_stub_kut": "column",
    "sp_00_stup_kapitel": "trim", "sp_00_stup_kapitel_kut": "trim", "sp_01_stup_kapitel": "trim",
    "sp_01_stub_kapitel": "trim", "sp_01_stub_kapitel_kut": "trim", "sp_01_stup_baza": "trim",
    "sp_01_stub_baza": "trim", "sp_01_stub_baza_kut": "trim", "sp_svod_kapitel": "trim", "sp_vijenac": "trim",
    "sp_00_luk_mali": "arch", "sp_00_luk_mali_V": "arch", "sp_00_luk_veliki": "arch",
    "sp_00_lukveliki_V": "arch", "sp_01_luk_Va": "arch", "sp_01_luk_a": "arch", "sp_01_luk_veliki": "arch",
    "sp_01_luk_veliki_V": "arch",
    "sp_00_prozor": "frame", "sp_02_prozor": "frame", "sp_02_prozor_krug": "frame",
    "sp_00_vrata_kocka": "door", "sp_00_vrata_krug": "frame",
    "sp_02_reljef": "relief",
}

SPONZA_MATERIALS = {
    # Light stone, diffuse with a slight rough specular layer (glTF's default F0 0.04).
    "wall": lambda: dielectric("wall (warm plaster)", (0.6, 0.53, 0.45), 0.8),
    "vault": lambda: dielectric("vault (light plaster)", (0.68, 0.63, 0.55), 0.85),
    "arch": lambda: dielectric("arch (limestone)", (0.66, 0.6, 0.5), 0.7),
    "column": lambda: dielectric("column (polished marble)", (0.72, 0.68, 0.6), 0.35),
    "trim": lambda: dielectric("capital/base/cornice (limestone)", (0.6, 0.55, 0.46), 0.65),
    "frame": lambda: dielectric("window/door surround (sandstone)", (0.55, 0.45, 0.33), 0.7),
    # Glossy: polished stone floor.
    "floor": lambda: dielectric("floor (polished stone tiles)", (0.42, 0.38, 0.33), 0.25),
    "door": lambda: dielectric("door (dark oak)", (0.22, 0.13, 0.07), 0.5),
    # One metal: the relief panel as bronze.
    "relief": lambda: metal("relief (bronze)", (0.7, 0.5, 0.3), 0.35),
}

SPONZA_CREASE_DEG = 35.0

# Sun: direction the light travels (from high above the -x end, slightly towards +z).
SPONZA_SUN_DIR = (0.62, -1.0, 0.1)
SPONZA_SUN = {"color": (1.0, 0.88, 0.72), "intensity": 30.0}
SPONZA_SKY = {"color": (0.45, 0.6, 1.0), "strength": 2.0}


def sun_rotation(direction):
    """Quaternion turning local -Z into `direction` (glTF punctual lights shine along -Z)."""
    d = normalize(list(direction))
    up = [0.0, 1.0, 0.0] if abs(d[1]) < 0.99 else [1.0, 0.0, 0.0]
    return look_at_quaternion([0.0, 0.0, 0.0], d, up)


def cmd_sponza(src, out):
    pos, _uv, faces = read_obj(os.path.join(src, SPONZA_OBJ))
    classes = sorted(set(SPONZA_CLASSES.values()))
    g = Gltf()
    g.doc["asset"] = {"version": "2.0", "generator": "cvtrace scripts/import_scenes.py sponza",
                      "copyright": "Sponza atrium by Marko Dabrovic (obj-rs 0.7.4 test fixture), see SOURCE.md",
                      "extras": {"defaultResolution": [320, 180]}}
    mat_index = {c: g.material(SPONZA_MATERIALS[c]()) for c in classes}
    # One primitive per source material group (usemtl name), in first-use order; vertices are
    # shared within a primitive where position and normal agree.
    # Smooth vertex normals with a crease angle: a polygon corner averages the (area-weighted)
    # normals of the polygons around its vertex that are within SPONZA_CREASE_DEG of its own, so
    # curved vaults, arches and column shafts shade smoothly while edges stay sharp.
    face_n = [newell_normal([pos[v] for v, _ in corners]) for _, corners in faces]
    unit_n = [normalize(n) for n in face_n]
    around = [[] for _ in pos]
    for f, (_, corners) in enumerate(faces):
        for v, _ in corners:
            around[v].append(f)
    cos_crease = math.cos(math.radians(SPONZA_CREASE_DEG))

    def corner_normal(f, v):
        acc = [0.0, 0.0, 0.0]
        for o in around[v]:
            if dot(unit_n[o], unit_n[f]) >= cos_crease:
                acc = add(acc, face_n[o])
        return tuple(rounded(normalize(acc), 5))

    order, groups = [], {}
    for f, (name, corners) in enumerate(faces):
        if name not in groups:
            groups[name] = ([], [], {}, [])
            order.append(name)
        gp, gn, remap, idx = groups[name]
        pts = [pos[v] for v, _ in corners]
        local = []
        for v, _ in corners:
            n = corner_normal(f, v)
            key = (v, n)
            if key not in remap:
                remap[key] = len(gp)
                gp.append(pos[v])
                gn.append(n)
            local.append(remap[key])
        for a, b, c in triangulate(pts):
            idx += [local[a], local[b], local[c]]
    prims = [(groups[n][0], groups[n][1], None, groups[n][3], mat_index[SPONZA_CLASSES[n]]) for n in order]
    # The primitives keep their source group names in the mesh's extras.
    mesh = g.mesh("sponza", prims)
    g.doc["meshes"][mesh]["extras"] = {"sourceGroups": order}
    sponza = g.node({"name": "sponza", "mesh": mesh})
    g.doc["extensions"] = {"KHR_lights_punctual": {"lights": [
        {"name": "sun", "type": "directional", "color": rounded(SPONZA_SUN["color"]),
         "intensity": SPONZA_SUN["intensity"]}]}}
    sun = g.node({"name": "sun", "rotation": sun_rotation(SPONZA_SUN_DIR),
                  "extensions": {"KHR_lights_punctual": {"light": 0}}})
    # Human height (1.7 m) in the -x end of the atrium, looking along it towards +x.
    cam = g.camera_node("camera", [-9.6, 1.7, 0.9], [4.0, 4.2, -0.2], 52.0)
    g.doc["scenes"] = [{"name": "sponza", "nodes": [cam, sponza, sun]}]
    g.doc["scene"] = 0
    g.write(out)
    write_sidecar(out, "sponza", environment=[("color", rounded(SPONZA_SKY["color"])), ("strength", SPONZA_SKY["strength"])],
                  comment="Sky: constant bluish radiance seen through the open roof (the sun is a\n"
                          "KHR_lights_punctual directional light in scene.gltf).")
    print("sponza: %d triangles" % count_triangles(g.doc))


# --------------------------------------------------------------------------------------------
# teapots: the Utah teapot (npm `teapot`) in a glass/metal material study

TEAPOT_JS = "package/teapot.js"
TEAPOT_SCALE = 0.014  # the model is 15.75 units tall -> 0.22 m

# Procedural sky (world directions, +y up): sun direction (towards the sun) and radiances.
SKY = {
    "width": 256, "height": 128,
    "sun_dir": (0.8, 0.58, 0.12),  # 35 deg up, through the window in the +x wall
    "sun_radius_deg": 5.0, "sun_radiance": (300.0, 270.0, 225.0),
    "zenith": (0.22, 0.4, 0.9), "horizon": (0.85, 0.9, 1.0), "ground": (0.28, 0.25, 0.21),
}


def read_teapot(path):
    text = open(path, "r", encoding="utf-8").read()

    def array(name):
        key = "exports.%s=" % name
        start = text.index(key) + len(key)
        end = text.index("]];", start) + 2
        return json.loads(text[start:end])

    return [tuple(p) for p in array("positions")], [tuple(c) for c in array("cells")]


def smooth_normals(pos, tris):
    """Area-weighted vertex normals, accumulated over vertices at the same position (the
    patches' seam vertices are duplicated in the source, which would otherwise show creases)."""
    key = {}
    welded = [key.setdefault(p, i) for i, p in enumerate(pos)]
    acc = [[0.0, 0.0, 0.0] for _ in pos]
    for a, b, c in tris:
        n = cross(sub(pos[b], pos[a]), sub(pos[c], pos[a]))  # length = 2 x area
        for v in (a, b, c):
            w = acc[welded[v]]
            w[0] += n[0]
            w[1] += n[1]
            w[2] += n[2]
    return [rounded(normalize(acc[welded[i]]), 6) for i in range(len(pos))]


def sky_radiance(d):
    sd = normalize(list(SKY["sun_dir"]))
    cosang = max(-1.0, min(1.0, dot(d, sd)))
    ang = math.degrees(math.acos(cosang))
    y = d[1]
    if y >= 0:
        t = math.sqrt(y)
        base = [SKY["horizon"][k] * (1 - t) + SKY["zenith"][k] * t for k in range(3)]
        glow = 1.5 * math.exp(-ang / 12.0) + 0.4 * math.exp(-ang / 40.0)
        base = [base[k] + glow * SKY["sun_radiance"][k] / SKY["sun_radiance"][0] for k in range(3)]
    else:
        t = min(1.0, -y * 8.0)
        base = [SKY["horizon"][k] * (1 - t) + SKY["ground"][k] * t for k in range(3)]
    if ang < SKY["sun_radius_deg"]:
        base = [base[k] + SKY["sun_radiance"][k] for k in range(3)]
    return base


def write_sky_pfm(path):
    """Lat-long map (cvtrace convention: u = 0.5 + atan2(x, -z) / 2pi, v = acos(y) / pi, row 0 at
    the top), 3x3 supersampled, as a little-endian colour PFM (rows stored bottom to top)."""
    w, h = SKY["width"], SKY["height"]
    rows = []
    for j in range(h):
        row = []
        for i in range(w):
            acc = [0.0, 0.0, 0.0]
            for sj in range(3):
                for si in range(3):
                    u = (i + (si + 0.5) / 3) / w
                    v = (j + (sj + 0.5) / 3) / h
                    phi = (u - 0.5) * 2 * math.pi
                    theta = v * math.pi
                    d = [math.sin(theta) * math.sin(phi), math.cos(theta), -math.sin(theta) * math.cos(phi)]
                    r = sky_radiance(d)
                    acc = [acc[k] + r[k] / 9 for k in range(3)]
            row += acc
        rows.append(struct.pack("<%df" % (3 * w), *row))
    with open(path, "wb") as f:
        f.write(b"PF\n%d %d\n-1.0\n" % (w, h))
        for r in reversed(rows):
            f.write(r)


# Fixed metadata (no Software/ImageHistory, a constant DateTime) keeps the EXR bytes deterministic.
OIIOTOOL_SKY = ["oiiotool", "--nosoftwareattrib", "sky.pfm", "--attrib", "DateTime", "2000:01:01 00:00:00",
                "-d", "half", "--compression", "zip", "-o", "sky.exr"]


def cmd_teapots(src, out):
    pos, cells = read_teapot(os.path.join(src, TEAPOT_JS))
    nrm = smooth_normals(pos, cells)
    lo = [min(p[k] for p in pos) for k in range(3)]
    hi = [max(p[k] for p in pos) for k in range(3)]
    g = Gltf()
    g.doc["asset"] = {"version": "2.0", "generator": "cvtrace scripts/import_scenes.py teapots",
                      "copyright": "Utah teapot (Martin Newell, 1975; npm teapot 1.0.0, public domain), see SOURCE.md",
                      "extras": {"defaultResolution": [320, 180]}}
    m_glass = g.material(glass("clear glass", 0.0, 1.5))
    m_gold = g.material(metal("rough gold", (1.0, 0.77, 0.34), 0.3))
    m_copper = g.material(metal("polished copper", (0.96, 0.64, 0.54), 0.08))
    # One set of accessors shared by three meshes that differ only in their material.
    p_acc = g.accessor(pos, "VEC3")
    n_acc = g.accessor(nrm, "VEC3")
    i_acc = g.accessor([i for c in cells for i in c], "SCALAR")
    teapot_meshes = []
    for name, m in (("teapot (clear glass)", m_glass), ("teapot (rough gold)", m_gold),
                    ("teapot (polished copper)", m_copper)):
        g.doc["meshes"].append({"name": name, "primitives": [
            {"attributes": {"POSITION": p_acc, "NORMAL": n_acc}, "indices": i_acc, "material": m, "mode": 4}]})
        teapot_meshes.append(len(g.doc["meshes"]) - 1)

    wall = g.material(diffuse("wall (white paint)", (0.78, 0.77, 0.74)))
    back = g.material(diffuse("back wall (pale blue-grey)", (0.5, 0.56, 0.62)))
    floor = g.material(dielectric("floor (light wood)", (0.5, 0.36, 0.22), 0.4))
    table = g.material(dielectric("table top (oiled oak)", (0.4, 0.28, 0.17), 0.3))
    legs = g.material(metal("table legs (brushed steel)", (0.6, 0.6, 0.6), 0.35))
    reveal = g.material(diffuse("window reveal (white paint)", (0.78, 0.77, 0.74)))
    panel = g.material(emitter("ceiling panel", (1.0, 0.96, 0.9), 5.0))

    hx, hz, h = 2.0, 2.0, 2.7
    mb = MeshBuilder()
    mb.box(wall, [-hx, 0.0, -hz], [hx, h, hz], outward=False, skip=("-y", "-z", "+x"))
    mb.quad(back, [0.0, h / 2, -hz], [hx, 0.0, 0.0], [0.0, h / 2, 0.0])
    mb.quad(floor, [0.0, 0.0, 0.0], [hx, 0.0, 0.0], [0.0, 0.0, -hz])
    # +x wall with a large window opening (no glass): z in [-1.3, 1.1], y in [0.8, 2.3], 0.2 m deep.
    wz0, wz1, wy0, wy1, d = -1.3, 1.1, 0.8, 2.3, 0.2

    def xwall(z0, z1, y0, y1):  # inner face, facing -x
        mb.quad(wall, [hx, (y0 + y1) / 2, (z0 + z1) / 2], [0.0, 0.0, (z1 - z0) / 2], [0.0, (y1 - y0) / 2, 0.0])

    xwall(-hz, wz0, 0.0, h)
    xwall(wz1, hz, 0.0, h)
    xwall(wz0, wz1, 0.0, wy0)
    xwall(wz0, wz1, wy1, h)
    # Reveals (sill, head, jambs) from the inner face to the outer face of the wall.
    mb.quad(reveal, [hx + d / 2, wy0, (wz0 + wz1) / 2], [d / 2, 0.0, 0.0], [0.0, 0.0, -(wz1 - wz0) / 2])
    mb.quad(reveal, [hx + d / 2, wy1, (wz0 + wz1) / 2], [d / 2, 0.0, 0.0], [0.0, 0.0, (wz1 - wz0) / 2])
    mb.quad(reveal, [hx + d / 2, (wy0 + wy1) / 2, wz0], [d / 2, 0.0, 0.0], [0.0, (wy1 - wy0) / 2, 0.0])
    mb.quad(reveal, [hx + d / 2, (wy0 + wy1) / 2, wz1], [d / 2, 0.0, 0.0], [0.0, -(wy1 - wy0) / 2, 0.0])
    # Outer face of that wall (seen from outside only through reflections; keeps the wall solid).
    mb.box(wall, [hx, 0.0, -hz], [hx + d, h, hz], skip=("-x", "+y", "-y", "+z", "-z", "+x"))
    for z0, z1, y0, y1 in ((-hz, wz0, 0.0, h), (wz1, hz, 0.0, h), (wz0, wz1, 0.0, wy0), (wz0, wz1, wy1, h)):
        mb.quad(wall, [hx + d, (y0 + y1) / 2, (z0 + z1) / 2], [0.0, 0.0, -(z1 - z0) / 2], [0.0, (y1 - y0) / 2, 0.0])
    # Ceiling panel 1.2 x 1.2 m facing down.
    mb.quad(panel, [-0.4, h - 0.02, 0.0], [0.6, 0.0, 0.0], [0.0, 0.0, 0.6])
    # Table 1.5 x 0.8 m, 0.75 m high.
    top = 0.75
    mb.box(table, [-0.75, top - 0.04, -0.4], [0.75, top, 0.4])
    for x in (-0.7, 0.66):
        for z in (-0.36, 0.32):
            mb.box(legs, [x, 0.0, z], [x + 0.04, top - 0.04, z + 0.04], skip=("+y", "-y"))
    room_mesh = mb.add_to(g, "room")

    s = TEAPOT_SCALE
    cx = (lo[0] + hi[0]) / 2
    nodes = []
    for mesh, x, z, yaw in zip(teapot_meshes, (0.0, -0.5, 0.5), (0.08, -0.12, -0.1), (-25.0, 30.0, 150.0)):
        a = math.radians(yaw) / 2
        nodes.append(g.node({"name": g.doc["meshes"][mesh]["name"], "mesh": mesh,
                             "translation": rounded([x - cx * s * math.cos(2 * a), top - lo[1] * s,
                                                     z + cx * s * math.sin(2 * a)]),
                             "rotation": rounded([0.0, math.sin(a), 0.0, math.cos(a)], 7),
                             "scale": [s, s, s]}))
    room = g.node({"name": "room", "mesh": room_mesh})
    cam = g.camera_node("camera", [-0.12, 1.2, 1.35], [0.0, 0.84, -0.05], 40.0)
    g.doc["scenes"] = [{"name": "teapots", "nodes": [cam] + nodes + [room]}]
    g.doc["scene"] = 0
    g.write(out)
    write_sky_pfm(os.path.join(out, "sky.pfm"))
    print("(cd %s && %s)" % (out, " ".join(a if " " not in a else '"%s"' % a for a in OIIOTOOL_SKY)))
    subprocess.run(OIIOTOOL_SKY, cwd=out, check=True)
    os.remove(os.path.join(out, "sky.pfm"))
    write_sidecar(out, "teapots", environment=[("map", '"sky.exr"'), ("strength", 1.0)],
                  comment="Sky: procedural lat-long map (gradient sky, sun disc) written by\n"
                          "scenes/tools/import_scenes.py teapots; seen through the window in the +x wall.")
    n = count_triangles(g.doc)
    print("teapots: %d triangles (3 x %d teapot, %d room)" % (n, len(cells), mb.triangles()))


# --------------------------------------------------------------------------------------------

COMMANDS = ("sponza", "engine", "head", "teapots")


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("scene", choices=COMMANDS)
    ap.add_argument("src_dir", help="folder filled by scenes/tools/fetch_scene_sources.sh")
    ap.add_argument("out_dir", help="scene folder to write, e.g. scenes/engine")
    a = ap.parse_args()
    globals()["cmd_" + a.scene](a.src_dir, a.out_dir)


if __name__ == "__main__":
    main()

#!/usr/bin/env python3
"""Converts Embree's Cornell box (OBJ + MTL + ECS camera) into the glTF 2.0 scene cvtrace ships.

Usage (from the repository root):
    python3 scenes/tools/cornell_to_gltf.py /usr/share/doc/embree3/models/cornell_box.obj scenes/cornell-box

What it does, and why (see scenes/cornell-box/SOURCE.md):
  * geometry is copied unchanged; quads become two triangles (0 1 2, 0 2 3);
  * the ceiling light face, commented out in the OBJ (`#f` under `o light`), is enabled,
    and the front wall stays disabled (the camera looks through it);
  * every face is wound so its geometric normal points where light leaves it: room
    surfaces and the light into the room, block faces out of their block. glTF is
    right-handed with counter-clockwise front faces, and cvtrace emits only from the front;
  * materials are pure Lambertian: baseColor = Kd, metallic 0, roughness 1,
    KHR_materials_specular specularFactor 0;
  * the light emits (17, 12, 4): glTF's emissiveFactor must be <= 1, so it is stored as
    (17, 12, 4) / 17 with KHR_materials_emissive_strength 17;
  * the camera comes from the .ecs file (-vp eye, -vi target, -vu up, -fov vertical degrees).

Only the standard library is used. Output is deterministic (same input, same bytes).
"""
import json
import math
import os
import struct
import sys

# Objects whose commented-out faces (`#f ...`) are enabled.
ENABLED_COMMENTED_OBJECTS = {"light"}
# Objects that are solids: their faces must point away from their own centre.
SOLID_OBJECTS = {"short_block", "tall_block"}
# The emitter: material name -> linear RGB radiance.
EMISSION = {"light": (17.0, 12.0, 4.0)}


def parse_mtl(path):
    materials, current = {}, None
    with open(path, encoding="utf-8") as f:
        for line in f:
            tok = line.split()
            if not tok:
                continue
            if tok[0] == "newmtl":
                current = tok[1]
                materials[current] = {"Kd": (1.0, 1.0, 1.0)}
            elif tok[0] == "Kd" and current is not None:
                materials[current]["Kd"] = tuple(float(x) for x in tok[1:4])
    return materials


def parse_obj(path):
    """Returns (mtllib, vertices, faces) with faces as (object, material, [vertex indices])."""
    vertices, faces = [], []
    obj, mtl, mtllib = "default", None, None
    with open(path, encoding="utf-8") as f:
        for lineno, line in enumerate(f, 1):
            tok = line.split()
            if not tok:
                continue
            head = tok[0]
            if head == "#f" and obj in ENABLED_COMMENTED_OBJECTS:
                head = "f"
            if head == "mtllib":
                mtllib = tok[1]
            elif head == "o":
                obj = tok[1]
            elif head == "usemtl":
                mtl = tok[1]
            elif head == "v":
                vertices.append(tuple(float(x) for x in tok[1:4]))
            elif head == "f":
                idx = []
                for t in tok[1:]:
                    i = int(t.split("/")[0])
                    idx.append(i - 1 if i > 0 else len(vertices) + i)
                if any(i < 0 or i >= len(vertices) for i in idx):
                    sys.exit(f"{path}:{lineno}: face index out of range")
                faces.append((obj, mtl, idx))
    return mtllib, vertices, faces


def parse_ecs(path):
    tok = open(path, encoding="utf-8").read().split()
    def vec(flag):
        i = tok.index(flag)
        return tuple(float(x) for x in tok[i + 1:i + 4])
    return vec("-vp"), vec("-vi"), vec("-vu"), float(tok[tok.index("-fov") + 1])


def sub(a, b):
    return tuple(x - y for x, y in zip(a, b))


def dot(a, b):
    return sum(x * y for x, y in zip(a, b))


def cross(a, b):
    return (a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0])


def normalize(a):
    n = math.sqrt(dot(a, a))
    return tuple(x / n for x in a)


def newell_normal(pts):
    """Area-weighted normal of a (possibly slightly non-planar) polygon, right-handed CCW."""
    n = [0.0, 0.0, 0.0]
    for i, p in enumerate(pts):
        q = pts[(i + 1) % len(pts)]
        n[0] += (p[1] - q[1]) * (p[2] + q[2])
        n[1] += (p[2] - q[2]) * (p[0] + q[0])
        n[2] += (p[0] - q[0]) * (p[1] + q[1])
    return tuple(n)


def centroid(pts):
    return tuple(sum(c) / len(pts) for c in zip(*pts))


def look_rotation(eye, target, up=(0.0, 1.0, 0.0), digits=12):
    """Quaternion (x, y, z, w) turning glTF's camera/light frame (looks down -Z, up +Y) to look at
    target. Also used by author_scenes.py."""
    f = normalize(sub(target, eye))
    r = normalize(cross(f, up))
    u = cross(r, f)
    # Columns of the rotation matrix: local X -> r, local Y -> u, local Z -> -f.
    m = [[r[0], u[0], -f[0]], [r[1], u[1], -f[1]], [r[2], u[2], -f[2]]]
    tr = m[0][0] + m[1][1] + m[2][2]
    if tr > 0:
        s = math.sqrt(tr + 1.0) * 2
        q = ((m[2][1] - m[1][2]) / s, (m[0][2] - m[2][0]) / s, (m[1][0] - m[0][1]) / s, 0.25 * s)
    elif m[0][0] > m[1][1] and m[0][0] > m[2][2]:
        s = math.sqrt(1.0 + m[0][0] - m[1][1] - m[2][2]) * 2
        q = (0.25 * s, (m[0][1] + m[1][0]) / s, (m[0][2] + m[2][0]) / s, (m[2][1] - m[1][2]) / s)
    elif m[1][1] > m[2][2]:
        s = math.sqrt(1.0 + m[1][1] - m[0][0] - m[2][2]) * 2
        q = ((m[0][1] + m[1][0]) / s, 0.25 * s, (m[1][2] + m[2][1]) / s, (m[0][2] - m[2][0]) / s)
    else:
        s = math.sqrt(1.0 + m[2][2] - m[0][0] - m[1][1]) * 2
        q = ((m[0][2] + m[2][0]) / s, (m[1][2] + m[2][1]) / s, 0.25 * s, (m[1][0] - m[0][1]) / s)
    # Round away float noise so the file is stable and readable (e.g. exactly (0, 1, 0, 0)).
    return [round(c, digits) + 0.0 for c in q]


def orient_faces(vertices, faces):
    """Winds each face so its normal points where its light goes (see module doc)."""
    room_pts = [vertices[i] for o, _, idx in faces if o not in SOLID_OBJECTS for i in idx]
    room_centre = centroid(room_pts)
    solid_centre = {}
    for name in SOLID_OBJECTS:
        pts = [vertices[i] for o, _, idx in faces if o == name for i in idx]
        if pts:
            solid_centre[name] = centroid(pts)
    out, flipped = [], 0
    for obj, mtl, idx in faces:
        pts = [vertices[i] for i in idx]
        c = centroid(pts)
        want = sub(c, solid_centre[obj]) if obj in SOLID_OBJECTS else sub(room_centre, c)
        if dot(newell_normal(pts), want) < 0:
            idx = list(reversed(idx))
            flipped += 1
        out.append((obj, mtl, idx))
    return out, flipped


def build(obj_path, out_dir):
    base = os.path.dirname(obj_path)
    mtllib, vertices, faces = parse_obj(obj_path)
    materials = parse_mtl(os.path.join(base, mtllib))
    eye, target, up, fov = parse_ecs(os.path.splitext(obj_path)[0] + ".ecs")
    faces, flipped = orient_faces(vertices, faces)

    mat_names = []
    for _, mtl, _ in faces:
        if mtl not in mat_names:
            mat_names.append(mtl)
    gl_materials = []
    for name in mat_names:
        kd = materials[name]["Kd"]
        m = {
            "name": name,
            "pbrMetallicRoughness": {"baseColorFactor": [*kd, 1.0], "metallicFactor": 0.0, "roughnessFactor": 1.0},
            "extensions": {"KHR_materials_specular": {"specularFactor": 0.0}},
            "doubleSided": name not in EMISSION,
        }
        if name in EMISSION:
            le = EMISSION[name]
            strength = max(le)
            m["emissiveFactor"] = [c / strength for c in le]
            m["extensions"]["KHR_materials_emissive_strength"] = {"emissiveStrength": strength}
        gl_materials.append(m)

    # One mesh per OBJ object, one primitive per material; vertices are not shared between
    # faces so every primitive has flat geometric normals.
    objects = []
    for obj, _, _ in faces:
        if obj not in objects:
            objects.append(obj)
    blob = bytearray()
    accessors, views, meshes, nodes = [], [], [], []

    def add_view(data, target):
        while len(blob) % 4:
            blob.append(0)
        views.append({"buffer": 0, "byteOffset": len(blob), "byteLength": len(data), "target": target})
        blob.extend(data)
        return len(views) - 1

    for obj in objects:
        prims = []
        for mi, mname in enumerate(mat_names):
            polys = [idx for o, m, idx in faces if o == obj and m == mname]
            if not polys:
                continue
            pos, tri = [], []
            for idx in polys:
                first = len(pos)
                pos.extend(vertices[i] for i in idx)
                for k in range(1, len(idx) - 1):
                    tri.append((first, first + k, first + k + 1))
            pos_bytes = b"".join(struct.pack("<3f", *p) for p in pos)
            idx_bytes = b"".join(struct.pack("<3I", *t) for t in tri)
            pv = add_view(pos_bytes, 34962)
            iv = add_view(idx_bytes, 34963)
            f32 = [struct.unpack("<f", struct.pack("<f", c))[0] for p in pos for c in p]
            lo = [min(f32[a::3]) for a in range(3)]
            hi = [max(f32[a::3]) for a in range(3)]
            accessors.append({"bufferView": pv, "componentType": 5126, "count": len(pos), "type": "VEC3", "min": lo, "max": hi})
            accessors.append({"bufferView": iv, "componentType": 5125, "count": 3 * len(tri), "type": "SCALAR"})
            prims.append({"attributes": {"POSITION": len(accessors) - 2}, "indices": len(accessors) - 1, "material": mi, "mode": 4})
        meshes.append({"name": obj, "primitives": prims})
        nodes.append({"name": obj, "mesh": len(meshes) - 1})

    nodes.append({
        "name": "camera",
        "camera": 0,
        "translation": list(eye),
        "rotation": look_rotation(eye, target, up),
    })
    gltf = {
        "asset": {
            "version": "2.0",
            "generator": "cvtrace scripts/cornell_to_gltf.py",
            "copyright": "Cornell box model from Intel Embree (Apache-2.0), converted for cvtrace",
            "extras": {"source": "embree3 models/cornell_box.obj", "defaultResolution": [256, 256]},
        },
        "extensionsUsed": ["KHR_materials_specular", "KHR_materials_emissive_strength"],
        "scene": 0,
        "scenes": [{"name": "cornell-box", "nodes": list(range(len(nodes)))}],
        "nodes": nodes,
        "meshes": meshes,
        "materials": gl_materials,
        "cameras": [{
            "name": "ecs",
            "type": "perspective",
            "perspective": {"yfov": math.radians(fov), "aspectRatio": 1.0, "znear": 1.0, "zfar": 10000.0},
        }],
        "accessors": accessors,
        "bufferViews": views,
        "buffers": [{"uri": "scene.bin", "byteLength": len(blob)}],
    }
    os.makedirs(out_dir, exist_ok=True)
    with open(os.path.join(out_dir, "scene.bin"), "wb") as f:
        f.write(bytes(blob))
    with open(os.path.join(out_dir, "scene.gltf"), "w", encoding="utf-8") as f:
        json.dump(gltf, f, indent=1)
        f.write("\n")
    tris = sum(len(idx) - 2 for _, _, idx in faces)
    print(f"wrote {out_dir}/scene.gltf: {len(faces)} faces ({flipped} re-wound), {tris} triangles, "
          f"{len(mat_names)} materials, camera eye {eye} target {target} fov {fov}")


if __name__ == "__main__":
    if len(sys.argv) != 3:
        sys.exit("usage: cornell_to_gltf.py CORNELL_BOX.obj OUT_DIR")
    build(sys.argv[1], sys.argv[2])

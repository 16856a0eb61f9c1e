#!/usr/bin/env python3
"""Builds the scenes authored for cvtrace (issue 5): door-ajar, glass-of-water, glossy-room.

Usage (from the repository root):
    python3 scenes/tools/author_scenes.py door-ajar scenes/door-ajar
    python3 scenes/tools/author_scenes.py glass-of-water scenes/glass-of-water
    python3 scenes/tools/author_scenes.py glossy-room scenes/glossy-room
    python3 scenes/tools/author_scenes.py all            # all three into scenes/<name>

Each scene folder gets scene.gltf + scene.bin, procedural PNG textures and scene.cvtrace.toml
(render defaults). Geometry is built here from boxes, quads and lathe (surface of revolution)
profiles; textures are procedural (hash-based value noise) and written as 8-bit sRGB PNGs with
zlib. Units are metres, +Y up. Only the standard library is used and the output is
deterministic: the same command writes the same bytes.

Conventions the renderer relies on:
  * every triangle is wound counter-clockwise around the normal the builder intends (the
    winding is checked against the intended normal and fixed per triangle), so room shells face
    inwards, solids face outwards (closed transmissive solids are glass with an inside) and
    emitters face where their light goes (cvtrace's emitters are one-sided);
  * lathe surfaces carry smooth vertex normals along each smooth run of the profile, split at
    sharp corners;
  * materials are glTF metallic-roughness with KHR_materials_specular (0 = pure Lambert),
    KHR_materials_transmission + KHR_materials_ior, KHR_materials_emissive_strength;
    point and spot lights are KHR_lights_punctual (intensity in cvtrace's units, see
    docs/ and the scenes' SOURCE.md).
"""
import json
import math
import os
import struct
import sys
import zlib

import cornell_to_gltf  # look_rotation; the script's folder is on sys.path

# ---------------------------------------------------------------------------------------------
# Small vector helpers
# ---------------------------------------------------------------------------------------------


def add(a, b):
    return (a[0] + b[0], a[1] + b[1], a[2] + b[2])


def sub(a, b):
    return (a[0] - b[0], a[1] - b[1], a[2] - b[2])


def mul(a, s):
    return (a[0] * s, a[1] * s, a[2] * s)


def dot(a, b):
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]


def cross(a, b):
    return (a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0])


def length(a):
    return math.sqrt(dot(a, a))


def normalize(a):
    n = length(a)
    return (a[0] / n, a[1] / n, a[2] / n) if n > 0 else (0.0, 0.0, 0.0)


def look_rotation(eye, target, up=(0.0, 1.0, 0.0)):
    """Quaternion (x, y, z, w) turning glTF's camera/light frame to look at target (9 digits)."""
    return cornell_to_gltf.look_rotation(eye, target, up, digits=9)


# ---------------------------------------------------------------------------------------------
# Geometry: a mesh is (positions, normals, uvs, triangles) with intended normals per vertex
# ---------------------------------------------------------------------------------------------


class Geom:
    def __init__(self):
        self.p, self.n, self.uv, self.t = [], [], [], []

    def vert(self, p, n, uv):
        self.p.append(tuple(float(c) for c in p))
        self.n.append(normalize(n))
        self.uv.append((float(uv[0]), float(uv[1])))
        return len(self.p) - 1

    def tri(self, a, b, c):
        """Adds a triangle wound CCW around the intended (vertex) normals; drops degenerate ones."""
        pa, pb, pc = self.p[a], self.p[b], self.p[c]
        g = cross(sub(pb, pa), sub(pc, pa))
        if length(g) < 1e-12:
            return
        want = add(add(self.n[a], self.n[b]), self.n[c])
        if dot(g, want) < 0:
            b, c = c, b
        self.t.append((a, b, c))

    def extend(self, other):
        off = len(self.p)
        self.p += other.p
        self.n += other.n
        self.uv += other.uv
        self.t += [(a + off, b + off, c + off) for a, b, c in other.t]
        return self

    def transformed(self, fp, fn):
        g = Geom()
        g.p = [fp(p) for p in self.p]
        g.n = [normalize(fn(n)) for n in self.n]
        g.uv = list(self.uv)
        g.t = list(self.t)
        return g


def quad(p0, p1, p2, p3, normal, tile=1.0, uv0=(0.0, 0.0)):
    """A planar quad p0 p1 p2 p3 (in order around it) facing `normal`; UVs in metres / tile."""
    g = Geom()
    eu = sub(p1, p0)
    ev = sub(p3, p0)
    lu, lv = length(eu), length(ev)
    uvs = [(0, 0), (lu, 0), (lu, lv), (0, lv)]
    idx = [g.vert(p, normal, (uv0[0] + u / tile, uv0[1] + v / tile)) for p, (u, v) in zip((p0, p1, p2, p3), uvs)]
    g.tri(idx[0], idx[1], idx[2])
    g.tri(idx[0], idx[2], idx[3])
    return g


def box(lo, hi, inward=False, tile=1.0, skip=()):
    """Axis-aligned box; faces named -x +x -y +y -z +z can be skipped. UVs are planar per face."""
    (x0, y0, z0), (x1, y1, z1) = lo, hi
    s = -1.0 if inward else 1.0
    g = Geom()
    faces = {
        "-x": ([(x0, y0, z0), (x0, y0, z1), (x0, y1, z1), (x0, y1, z0)], (-s, 0, 0)),
        "+x": ([(x1, y0, z1), (x1, y0, z0), (x1, y1, z0), (x1, y1, z1)], (s, 0, 0)),
        "-y": ([(x0, y0, z0), (x1, y0, z0), (x1, y0, z1), (x0, y0, z1)], (0, -s, 0)),
        "+y": ([(x0, y1, z1), (x1, y1, z1), (x1, y1, z0), (x0, y1, z0)], (0, s, 0)),
        "-z": ([(x1, y0, z0), (x0, y0, z0), (x0, y1, z0), (x1, y1, z0)], (0, 0, -s)),
        "+z": ([(x0, y0, z1), (x1, y0, z1), (x1, y1, z1), (x0, y1, z1)], (0, 0, s)),
    }
    for name in ("-x", "+x", "-y", "+y", "-z", "+z"):
        if name in skip:
            continue
        pts, n = faces[name]
        g.extend(quad(*pts, n, tile=tile))
    return g


def rot_y(geom, degrees, pivot=(0.0, 0.0, 0.0), move=(0.0, 0.0, 0.0)):
    """Rotates about the vertical axis through `pivot` (right-handed, +Y up), then translates."""
    a = math.radians(degrees)
    c, s = math.cos(a), math.sin(a)

    def rv(v):
        return (c * v[0] + s * v[2], v[1], -s * v[0] + c * v[2])

    def fp(p):
        q = rv(sub(p, pivot))
        return add(add(q, pivot), move)

    return geom.transformed(fp, rv)


def translate(geom, d):
    return geom.transformed(lambda p: add(p, d), lambda n: n)


def arc(center, radius, a0, a1, steps):
    """Points (r, y) on a circular arc in the profile plane, angles in degrees (0 = +r, 90 = +y)."""
    out = []
    for i in range(steps + 1):
        a = math.radians(a0 + (a1 - a0) * i / steps)
        out.append((center[0] + radius * math.cos(a), center[1] + radius * math.sin(a)))
    return out


def dedupe(pts):
    out = []
    for p in pts:
        if not out or abs(out[-1][0] - p[0]) > 1e-9 or abs(out[-1][1] - p[1]) > 1e-9:
            out.append(p)
    return out


def lathe(runs, segments, center=(0.0, 0.0, 0.0), normals=None):
    """Surface of revolution about the vertical axis through `center`.

    `runs` is a list of smooth polylines of (r, y) points, each continuing where the previous one
    ended (vertices are split between runs: sharp corners). Traversing the profile, the surface's
    outside is on the right: the normal of a segment with direction (dr, dy) is (dy, -dr). So a
    closed solid is described from the bottom centre, outwards, up the outside, over the top and
    back to the axis. Vertex normals average the adjacent segment normals within a run, or
    `normals(r, y)` gives them analytically.
    """
    g = Geom()
    cx, cy, cz = center
    v_acc = 0.0
    for run in runs:
        run = dedupe(run)
        m = len(run)
        seg_n = []
        for i in range(m - 1):
            dr, dy = run[i + 1][0] - run[i][0], run[i + 1][1] - run[i][1]
            ln = math.hypot(dr, dy)
            seg_n.append((dy / ln, -dr / ln))
        prof_n = []
        for i in range(m):
            if normals is not None:
                prof_n.append(normals(*run[i]))
                continue
            acc = [0.0, 0.0]
            for j in (i - 1, i):
                if 0 <= j < m - 1:
                    acc[0] += seg_n[j][0]
                    acc[1] += seg_n[j][1]
            ln = math.hypot(*acc)
            prof_n.append((acc[0] / ln, acc[1] / ln))
        vs = []
        for i in range(m):
            if i > 0:
                v_acc += math.hypot(run[i][0] - run[i - 1][0], run[i][1] - run[i - 1][1])
            vs.append(v_acc)
        rows = []
        for i, (r, y) in enumerate(run):
            nr, ny = prof_n[i]
            row = []
            for k in range(segments + 1):
                th = 2 * math.pi * (k % segments) / segments
                c, s = math.cos(th), math.sin(th)
                p = (cx + r * c, cy + y, cz - r * s)
                n = (nr * c, ny, -nr * s)
                row.append(g.vert(p, n, (k / segments, vs[i])))
            rows.append(row)
        for i in range(m - 1):
            for k in range(segments):
                a, b, c_, d = rows[i][k], rows[i][k + 1], rows[i + 1][k + 1], rows[i + 1][k]
                g.tri(a, b, c_)
                g.tri(a, c_, d)
    return g


def sphere(center, radius, rings=24, segments=48):
    pts = arc((0.0, 0.0), radius, -90, 90, rings)
    pts = [(abs(r) if abs(r) > 1e-12 else 0.0, y) for r, y in pts]

    def nrm(r, y):
        return (r / radius, y / radius)

    return lathe([pts], segments, center, normals=nrm)


def cylinder(center, radius, y0, y1, segments=32):
    """Closed cylinder with flat caps (sharp edges)."""
    return lathe([[(0, y0), (radius, y0)], [(radius, y0), (radius, y1)], [(radius, y1), (0, y1)]], segments, center)


# ---------------------------------------------------------------------------------------------
# Procedural textures (8-bit sRGB PNG)
# ---------------------------------------------------------------------------------------------


def png_bytes(width, height, pixels):
    """pixels: flat list of (r, g, b) tuples in 0..255, rows top to bottom."""
    raw = bytearray()
    for y in range(height):
        raw.append(0)
        for x in range(width):
            raw.extend(pixels[y * width + x])

    def chunk(tag, data):
        return struct.pack(">I", len(data)) + tag + data + struct.pack(">I", zlib.crc32(tag + data) & 0xFFFFFFFF)

    ihdr = struct.pack(">IIBBBBB", width, height, 8, 2, 0, 0, 0)
    return b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", ihdr) + chunk(b"IDAT", zlib.compress(bytes(raw), 9)) + chunk(b"IEND", b"")


def hash01(ix, iy, seed):
    h = (ix * 374761393 + iy * 668265263 + seed * 144665123 + 1013904223) & 0xFFFFFFFF
    h = ((h ^ (h >> 13)) * 1274126177) & 0xFFFFFFFF
    h ^= h >> 16
    return (h & 0xFFFF) / 65535.0


def vnoise(x, y, px, py, seed):
    """Value noise, periodic with period (px, py) lattice cells."""
    ix, iy = math.floor(x), math.floor(y)
    fx, fy = x - ix, y - iy
    fx = fx * fx * (3 - 2 * fx)
    fy = fy * fy * (3 - 2 * fy)
    x0, x1 = ix % px, (ix + 1) % px
    y0, y1 = iy % py, (iy + 1) % py
    a = hash01(x0, y0, seed)
    b = hash01(x1, y0, seed)
    c = hash01(x0, y1, seed)
    d = hash01(x1, y1, seed)
    return (a + (b - a) * fx) + ((c + (d - c) * fx) - (a + (b - a) * fx)) * fy


def fbm(u, v, fu, fv, seed, octaves=3):
    """Periodic fractal noise over the unit square (u, v in [0, 1)), base frequencies fu, fv."""
    s, amp, tot = 0.0, 1.0, 0.0
    for o in range(octaves):
        m = 1 << o
        s += amp * vnoise(u * fu * m, v * fv * m, fu * m, fv * m, seed + o)
        tot += amp
        amp *= 0.5
    return s / tot


def clamp8(c):
    return tuple(max(0, min(255, int(round(x)))) for x in c)


def lerp3(a, b, t):
    return tuple(x + (y - x) * t for x, y in zip(a, b))


def tex_planks(size=512, planks=8, seed=11, light=(196, 142, 92), dark=(138, 90, 52)):
    """Wood floor planks running along u; `planks` rows across v; one staggered joint per row."""
    px = []
    joints = [hash01(i, 0, seed + 100) for i in range(planks)]
    tones = [hash01(i, 1, seed + 101) for i in range(planks)]
    for y in range(size):
        v = y / size
        row = min(planks - 1, int(v * planks))
        lv = v * planks - row
        for x in range(size):
            u = x / size
            # Plank tone (per row and per plank piece).
            piece = 0 if (u - joints[row]) % 1.0 < 0.5 else 1
            t = 0.5 * tones[row] + 0.5 * hash01(row, piece, seed + 7)
            base = lerp3(dark, light, 0.25 + 0.6 * t)
            # Grain: wavy lines along u.
            w = fbm(u, v, 4, planks * 2, seed + row, 3)
            grain = 0.5 + 0.5 * math.sin(2 * math.pi * (lv * 5 + 2.5 * w + 3 * piece))
            fine = fbm(u, v, 64, 8 * planks, seed + 50, 2)
            k = 0.82 + 0.12 * grain + 0.1 * (fine - 0.5)
            c = mul(base, k)
            # Gaps between rows and at the joints.
            d_row = min(lv, 1 - lv) * size / planks
            d_joint = min((u - joints[row]) % 0.5, 0.5 - (u - joints[row]) % 0.5) * size
            if d_row < 1.2 or d_joint < 1.0:
                c = mul(c, 0.45)
            px.append(clamp8(c))
    return png_bytes(size, size, px)


def tex_wood_grain(width=512, height=256, seed=23, light=(120, 72, 40), dark=(78, 44, 22)):
    """Continuous wood grain along u (a table top veneer)."""
    px = []
    for y in range(height):
        v = y / height
        for x in range(width):
            u = x / width
            w = fbm(u, v, 3, 6, seed, 3)
            rings = 0.5 + 0.5 * math.sin(2 * math.pi * (v * 9 + 3.0 * w))
            rings = rings ** 3
            fine = fbm(u, v, 96, 24, seed + 9, 2)
            c = lerp3(light, dark, 0.55 * rings + 0.25 * fine)
            px.append(clamp8(c))
    return png_bytes(width, height, px)


def tex_tiles(size, n, grout_px, colours, grout, seed, checker=True, mottle=0.08):
    """n x n square tiles with grout lines; checker alternates colours[0] / colours[1]."""
    px = []
    cell = size / n
    for y in range(size):
        ty = int(y // cell)
        ly = y - ty * cell
        for x in range(size):
            tx = int(x // cell)
            lx = x - tx * cell
            if checker:
                base = colours[(tx + ty) % 2]
            else:
                base = colours[int(hash01(tx, ty, seed) * len(colours)) % len(colours)]
            var = 0.94 + 0.08 * hash01(tx, ty, seed + 1)
            m = fbm(x / size, y / size, 16, 16, seed + 2, 3)
            c = mul(base, var * (1 - mottle / 2 + mottle * m))
            d = min(lx, cell - 1 - lx, ly, cell - 1 - ly)
            if d < grout_px:
                c = grout
            elif d < grout_px + 1:
                c = lerp3(grout, c, 0.5)
            px.append(clamp8(c))
    return png_bytes(size, size, px)


def tex_painting(width=160, height=120):
    """A small landscape for the picture frame: sky gradient, sun, two rows of hills."""
    px = []
    for y in range(height):
        v = y / height
        for x in range(width):
            u = x / width
            c = lerp3((70, 120, 190), (235, 190, 140), v / 0.62)
            if math.hypot(u - 0.72, v - 0.3) < 0.07:
                c = (250, 225, 150)
            h1 = 0.52 + 0.06 * math.sin(u * 7.0 + 1.0) + 0.03 * math.sin(u * 17.0)
            h2 = 0.66 + 0.05 * math.sin(u * 5.0 + 3.0) + 0.02 * math.sin(u * 23.0 + 1.0)
            if v > h1:
                c = lerp3((80, 110, 90), (60, 90, 70), fbm(u, v, 8, 8, 5, 2))
            if v > h2:
                c = lerp3((120, 140, 60), (90, 110, 40), fbm(u, v, 12, 12, 6, 2))
            px.append(clamp8(c))
    return png_bytes(width, height, px)


# ---------------------------------------------------------------------------------------------
# glTF writer
# ---------------------------------------------------------------------------------------------


def f32(x):
    """x rounded to the float32 the file stores, as the accessors' min and max must be."""
    return struct.unpack("<f", struct.pack("<f", x))[0]


class BinaryBuffer:
    """The bytes of scene.bin and their buffer views, each view aligned to 4 bytes."""

    def __init__(self):
        self.blob = bytearray()
        self.views = []

    def view(self, data, target):
        while len(self.blob) % 4:
            self.blob.append(0)
        self.views.append({"buffer": 0, "byteOffset": len(self.blob), "byteLength": len(data), "target": target})
        self.blob.extend(data)
        return len(self.views) - 1


class Scene:
    def __init__(self, name):
        self.name = name
        self.objects = []  # (name, material name, Geom)
        self.materials = {}  # name -> glTF material dict
        self.material_order = []
        self.images = {}  # file name -> png bytes
        self.image_order = []
        self.lights = []  # (name, light dict, translation, rotation)
        self.camera = None
        self.render = {}
        self.environment = None

    def image(self, filename, data):
        if filename not in self.images:
            self.images[filename] = data
            self.image_order.append(filename)
        return self.image_order.index(filename)

    def material(self, name, color=(0.8, 0.8, 0.8), metallic=0.0, roughness=1.0, specular=None, transmission=None,
                 ior=None, emission=None, texture=None):
        m = {
            "name": name,
            "pbrMetallicRoughness": {
                "baseColorFactor": [float(c) for c in color] + [1.0],
                "metallicFactor": float(metallic),
                "roughnessFactor": float(roughness),
            },
            "doubleSided": emission is None,
        }
        ext = {}
        if texture is not None:
            m["pbrMetallicRoughness"]["baseColorTexture"] = {"index": self.image(*texture)}
        if specular is not None:
            ext["KHR_materials_specular"] = {"specularFactor": float(specular)}
        if transmission is not None:
            ext["KHR_materials_transmission"] = {"transmissionFactor": float(transmission)}
        if ior is not None:
            ext["KHR_materials_ior"] = {"ior": float(ior)}
        if emission is not None:
            s = max(emission)
            m["emissiveFactor"] = [c / s for c in emission]
            if s != 1.0:
                ext["KHR_materials_emissive_strength"] = {"emissiveStrength": float(s)}
        if ext:
            m["extensions"] = ext
        self.materials[name] = m
        self.material_order.append(name)
        return name

    def add(self, name, material, geom):
        assert material in self.materials, material
        self.objects.append((name, material, geom))

    def light(self, name, light, position, target, up=(0.0, 1.0, 0.0)):
        self.lights.append((name, light, position, look_rotation(position, target, up) if target else None))

    def triangle_count(self):
        return sum(len(g.t) for _, _, g in self.objects)

    def write(self, out_dir):
        os.makedirs(out_dir, exist_ok=True)
        buffer = BinaryBuffer()
        blob, views, add_view = buffer.blob, buffer.views, buffer.view
        accessors, meshes, nodes = [], [], []

        for name, mat, g in self.objects:
            pos = b"".join(struct.pack("<3f", *p) for p in g.p)
            nrm = b"".join(struct.pack("<3f", *n) for n in g.n)
            uv = b"".join(struct.pack("<2f", *t) for t in g.uv)
            idx = b"".join(struct.pack("<3I", *t) for t in g.t)
            lo = [min(f32(p[a]) for p in g.p) for a in range(3)]
            hi = [max(f32(p[a]) for p in g.p) for a in range(3)]
            a0 = len(accessors)
            accessors.append({"bufferView": add_view(pos, 34962), "componentType": 5126, "count": len(g.p), "type": "VEC3",
                              "min": lo, "max": hi})
            accessors.append({"bufferView": add_view(nrm, 34962), "componentType": 5126, "count": len(g.n), "type": "VEC3"})
            accessors.append({"bufferView": add_view(uv, 34962), "componentType": 5126, "count": len(g.uv), "type": "VEC2"})
            accessors.append({"bufferView": add_view(idx, 34963), "componentType": 5125, "count": 3 * len(g.t),
                              "type": "SCALAR"})
            meshes.append({"name": name, "primitives": [{
                "attributes": {"POSITION": a0, "NORMAL": a0 + 1, "TEXCOORD_0": a0 + 2},
                "indices": a0 + 3, "material": self.material_order.index(mat), "mode": 4}]})
            nodes.append({"name": name, "mesh": len(meshes) - 1})

        eye, target, yfov = self.camera
        nodes.append({"name": "camera", "camera": 0, "translation": [round(c, 9) + 0.0 for c in eye], "rotation": look_rotation(eye, target)})
        ext_used = set()
        for m in self.materials.values():
            ext_used.update(m.get("extensions", {}).keys())
        root_ext = {}
        if self.lights:
            ext_used.add("KHR_lights_punctual")
            gl_lights = []
            for i, (name, light, position, rotation) in enumerate(self.lights):
                gl_lights.append(dict(name=name, **light))
                node = {"name": name, "translation": [round(c, 9) + 0.0 for c in position], "extensions": {"KHR_lights_punctual": {"light": i}}}
                if rotation is not None:
                    node["rotation"] = rotation
                nodes.append(node)
            root_ext["KHR_lights_punctual"] = {"lights": gl_lights}

        gltf = {
            "asset": {
                "version": "2.0",
                "generator": "cvtrace scripts/author_scenes.py",
                "copyright": "cvtrace project, MIT OR Apache-2.0",
                "extras": {"defaultResolution": [self.render["width"], self.render["height"]]},
            },
            "extensionsUsed": sorted(ext_used),
            "scene": 0,
            "scenes": [{"name": self.name, "nodes": list(range(len(nodes)))}],
            "nodes": nodes,
            "cameras": [{"name": "camera", "type": "perspective", "perspective": {
                "yfov": round(math.radians(yfov), 9), "aspectRatio": self.render["width"] / self.render["height"],
                "znear": 0.01}}],
            "meshes": meshes,
            "materials": [self.materials[n] for n in self.material_order],
            "accessors": accessors,
            "bufferViews": views,
            "buffers": [{"uri": "scene.bin", "byteLength": len(blob)}],
        }
        if self.image_order:
            gltf["images"] = [{"uri": f} for f in self.image_order]
            gltf["samplers"] = [{"magFilter": 9729, "minFilter": 9987, "wrapS": 10497, "wrapT": 10497}]
            gltf["textures"] = [{"sampler": 0, "source": i} for i in range(len(self.image_order))]
        if root_ext:
            gltf["extensions"] = root_ext
        with open(os.path.join(out_dir, "scene.gltf"), "w", encoding="utf-8") as f:
            json.dump(gltf, f, indent=1)
            f.write("\n")
        with open(os.path.join(out_dir, "scene.bin"), "wb") as f:
            f.write(blob)
        for name in self.image_order:
            with open(os.path.join(out_dir, name), "wb") as f:
                f.write(self.images[name])
        lines = ["# Render defaults of this scene (written by scenes/tools/author_scenes.py).", "[render]"]
        for k in ("width", "height", "max_depth", "rr_depth"):
            lines.append(f"{k} = {self.render[k]}")
        lines.append(f"reference_spp = {REFERENCE_SPP[self.name]}")
        if self.environment:
            lines += ["", "[environment]"] + [f"{k} = {v}" for k, v in self.environment]
        with open(os.path.join(out_dir, "scene.cvtrace.toml"), "w", encoding="utf-8") as f:
            f.write("\n".join(lines) + "\n")
        tris = self.triangle_count()
        print(f"{self.name}: {len(self.objects)} objects, {tris} triangles, {len(self.material_order)} materials, "
              f"{len(self.image_order)} textures, {len(self.lights)} punctual lights, bin {len(blob)} bytes -> {out_dir}")


RENDER = {"width": 320, "height": 180, "max_depth": -1, "rr_depth": 5}
# Samples per pixel of each committed reference (scene.ref.exr), recorded as the scene's default.
REFERENCE_SPP = {"door-ajar": 36864, "glass-of-water": 49152, "glossy-room": 49152}


# ---------------------------------------------------------------------------------------------
# Scene 1: door-ajar
# ---------------------------------------------------------------------------------------------

DOOR_ANGLE = 20.0  # degrees the door stands open (into the room)
DOOR_LIGHT = 450.0  # radiance of the corridor's wall light


def build_door_ajar():
    s = Scene("door-ajar")
    s.render = dict(RENDER)
    # Room x in [-2.5, 2.5], z in [-2, 2], y in [0, 2.7]; the door is in the back wall (z = -2),
    # the corridor behind it is x in [-0.5, 4], z in [-3.6, -2.12] (wall 12 cm thick).
    X0, X1, Z0, Z1, H = -2.5, 2.5, -2.0, 2.0, 2.7
    T = 0.12
    ZC = Z0 - T  # corridor side of the partition wall
    CX0, CX1, CZ0 = -0.5, 4.0, -3.6
    DX0, DX1, DH = 1.2, 2.1, 2.05  # door opening

    s.material("wall", (0.74, 0.71, 0.66), specular=0.0)
    s.material("ceiling", (0.82, 0.82, 0.80), specular=0.0)
    s.material("floor_wood", (1, 1, 1), roughness=0.45, specular=0.5, texture=("planks.png", tex_planks()))
    s.material("corridor_wall", (0.80, 0.78, 0.72), specular=0.0)
    s.material("corridor_floor", (0.45, 0.43, 0.40), roughness=0.6, specular=0.5)
    s.material("door_paint", (0.80, 0.79, 0.76), roughness=0.4, specular=0.5)
    s.material("table_wood", (1, 1, 1), roughness=0.35, specular=0.6, texture=("wood.png", tex_wood_grain()))
    s.material("shelf_wood", (0.55, 0.42, 0.30), roughness=0.6, specular=0.4)
    s.material("sofa_fabric", (0.22, 0.33, 0.38), specular=0.0)
    s.material("cushion", (0.62, 0.38, 0.18), specular=0.0)
    s.material("frame", (0.12, 0.10, 0.08), roughness=0.4, specular=0.5)
    s.material("canvas", (1, 1, 1), roughness=0.8, specular=0.3, texture=("painting.png", tex_painting()))
    s.material("rug", (0.55, 0.20, 0.16), specular=0.0)
    s.material("pot", (0.70, 0.35, 0.22), roughness=0.5, specular=0.5)
    book_colours = [(0.55, 0.12, 0.10), (0.12, 0.25, 0.45), (0.70, 0.62, 0.40), (0.15, 0.35, 0.20),
                    (0.35, 0.30, 0.28), (0.60, 0.45, 0.15)]
    for i, c in enumerate(book_colours):
        s.material(f"book{i}", c, roughness=0.7, specular=0.3)
    s.material("light", (0, 0, 0), emission=(DOOR_LIGHT, DOOR_LIGHT * 0.93, DOOR_LIGHT * 0.82))

    # Room shell (faces inwards); the back wall has the door opening.
    s.add("room_floor", "floor_wood", quad((X0, 0, Z0), (X1, 0, Z0), (X1, 0, Z1), (X0, 0, Z1), (0, 1, 0), tile=1.2))
    s.add("room_ceiling", "ceiling", quad((X0, H, Z0), (X1, H, Z0), (X1, H, Z1), (X0, H, Z1), (0, -1, 0)))
    walls = Geom()
    walls.extend(quad((X0, 0, Z0), (X0, 0, Z1), (X0, H, Z1), (X0, H, Z0), (1, 0, 0)))
    walls.extend(quad((X1, 0, Z0), (X1, 0, Z1), (X1, H, Z1), (X1, H, Z0), (-1, 0, 0)))
    walls.extend(quad((X0, 0, Z1), (X1, 0, Z1), (X1, H, Z1), (X0, H, Z1), (0, 0, -1)))
    walls.extend(quad((X0, 0, Z0), (DX0, 0, Z0), (DX0, H, Z0), (X0, H, Z0), (0, 0, 1)))
    walls.extend(quad((DX1, 0, Z0), (X1, 0, Z0), (X1, H, Z0), (DX1, H, Z0), (0, 0, 1)))
    walls.extend(quad((DX0, DH, Z0), (DX1, DH, Z0), (DX1, H, Z0), (DX0, H, Z0), (0, 0, 1)))
    # Door reveal (jambs and head), through the wall thickness.
    walls.extend(quad((DX0, 0, ZC), (DX0, 0, Z0), (DX0, DH, Z0), (DX0, DH, ZC), (1, 0, 0)))
    walls.extend(quad((DX1, 0, ZC), (DX1, 0, Z0), (DX1, DH, Z0), (DX1, DH, ZC), (-1, 0, 0)))
    walls.extend(quad((DX0, DH, ZC), (DX1, DH, ZC), (DX1, DH, Z0), (DX0, DH, Z0), (0, -1, 0)))
    s.add("room_walls", "wall", walls)
    # Threshold strip under the door (floor through the wall thickness).
    s.add("threshold", "corridor_floor", quad((DX0, 0, ZC), (DX1, 0, ZC), (DX1, 0, Z0), (DX0, 0, Z0), (0, 1, 0)))

    # Corridor shell (faces inwards); its wall towards the room has the same opening.
    s.add("corridor_floor", "corridor_floor",
          quad((CX0, 0, CZ0), (CX1, 0, CZ0), (CX1, 0, ZC), (CX0, 0, ZC), (0, 1, 0)))
    cw = Geom()
    cw.extend(quad((CX0, H, CZ0), (CX1, H, CZ0), (CX1, H, ZC), (CX0, H, ZC), (0, -1, 0)))
    cw.extend(quad((CX0, 0, CZ0), (CX0, 0, ZC), (CX0, H, ZC), (CX0, H, CZ0), (1, 0, 0)))
    cw.extend(quad((CX1, 0, CZ0), (CX1, 0, ZC), (CX1, H, ZC), (CX1, H, CZ0), (-1, 0, 0)))
    cw.extend(quad((CX0, 0, CZ0), (CX1, 0, CZ0), (CX1, H, CZ0), (CX0, H, CZ0), (0, 0, 1)))
    cw.extend(quad((CX0, 0, ZC), (DX0, 0, ZC), (DX0, H, ZC), (CX0, H, ZC), (0, 0, -1)))
    cw.extend(quad((DX1, 0, ZC), (CX1, 0, ZC), (CX1, H, ZC), (DX1, H, ZC), (0, 0, -1)))
    cw.extend(quad((DX0, DH, ZC), (DX1, DH, ZC), (DX1, H, ZC), (DX0, H, ZC), (0, 0, -1)))
    s.add("corridor_walls", "corridor_wall", cw)
    # The light: a panel on the corridor side of the partition, right of the door, facing away
    # from the door (-Z), so light reaches the room only after bouncing in the corridor.
    s.add("corridor_light", "light",
          quad((2.5, 0.9, ZC - 0.005), (3.7, 0.9, ZC - 0.005), (3.7, 2.3, ZC - 0.005), (2.5, 2.3, ZC - 0.005), (0, 0, -1)))

    # The door, hinged at (DX0, Z0) and opened DOOR_ANGLE degrees into the room.
    door = box((DX0 + 0.005, 0.005, Z0 - 0.04), (DX1 - 0.01, DH - 0.01, Z0))
    s.add("door", "door_paint", rot_y(door, -DOOR_ANGLE, pivot=(DX0 + 0.005, 0, Z0)))
    knob = translate(sphere((0, 0, 0), 0.03, 8, 16), (DX1 - 0.08, 1.0, Z0 + 0.04))
    s.add("door_knob", "frame", rot_y(knob, -DOOR_ANGLE, pivot=(DX0 + 0.005, 0, Z0)))

    # Coffee table in front of the sofa, with a pot and a book on it.
    tx, tz, th = -0.75, -0.55, 0.42
    s.add("table_top", "table_wood", box((tx - 0.55, th - 0.04, tz - 0.3), (tx + 0.55, th, tz + 0.3), tile=1.0))
    legs = Geom()
    for lx in (tx - 0.5, tx + 0.45):
        for lz in (tz - 0.25, tz + 0.2):
            legs.extend(box((lx, 0, lz), (lx + 0.05, th - 0.04, lz + 0.05), skip=("-y", "+y")))
    s.add("table_legs", "shelf_wood", legs)
    s.add("pot", "pot", lathe([[(0, 0), (0.07, 0)], [(0.07, 0), (0.09, 0.05), (0.1, 0.12), (0.085, 0.18)],
                               [(0.085, 0.18), (0.075, 0.18)], [(0.075, 0.18), (0.085, 0.12), (0.06, 0.02), (0, 0.02)]],
                              32, (tx + 0.3, th, tz - 0.05)))
    s.add("table_book", "book1", rot_y(box((tx - 0.35, th, tz - 0.1), (tx - 0.11, th + 0.035, tz + 0.07)), 12,
                                        pivot=(tx - 0.23, 0, tz)))
    # A floor vase between the sofa and the door.
    s.add("floor_pot", "pot", lathe([[(0, 0), (0.12, 0)], [(0.12, 0), (0.16, 0.15), (0.15, 0.35), (0.1, 0.5)],
                                     [(0.1, 0.5), (0.09, 0.5)], [(0.09, 0.5), (0.14, 0.35), (0.11, 0.05), (0, 0.05)]],
                                    32, (0.85, 0, -1.6)))

    # Open shelf against the left wall, with books.
    sx0, sx1, sz0, sz1, sh = X0, X0 + 0.38, -1.95, -0.75, 1.95
    shelf = Geom()
    shelf.extend(box((sx0, 0, sz0), (sx1, sh, sz0 + 0.03), skip=("-x",)))
    shelf.extend(box((sx0, 0, sz1 - 0.03), (sx1, sh, sz1), skip=("-x",)))
    for y in (0.0, 0.45, 0.95, 1.45, sh - 0.03):
        shelf.extend(box((sx0, y + 0.06 if y == 0 else y, sz0 + 0.03), (sx1, (y + 0.06 if y == 0 else y) + 0.03,
                                                                       sz1 - 0.03), skip=("-x",)))
    s.add("shelf", "shelf_wood", shelf)
    books = {i: Geom() for i in range(len(book_colours))}
    k = 0
    for level in (0.09, 0.48, 0.98, 1.48):
        z = sz0 + 0.05
        while True:
            w = 0.025 + 0.03 * hash01(k, 3, 77)
            h = 0.2 + 0.14 * hash01(k, 4, 77)
            d = 0.17 + 0.08 * hash01(k, 5, 77)
            if z + w > sz1 - 0.05 - (0.25 if level == 0.98 else 0.0):
                break
            if hash01(k, 6, 77) < 0.12:
                z += 0.06  # a gap
            else:
                books[k % len(book_colours)].extend(box((sx0 + 0.02, level, z), (sx0 + 0.02 + d, level + h, z + w),
                                                        skip=("-x", "-y")))
                z += w + 0.003
            k += 1
    for i, g in books.items():
        if g.t:
            s.add(f"books{i}", f"book{i}", g)

    # Sofa against the back wall, left of the door: seat, back, arms, two cushions.
    ax0, ax1, az0, az1 = -1.9, 0.3, Z0, Z0 + 0.9
    sofa = Geom()
    sofa.extend(box((ax0 + 0.15, 0.0, az0 + 0.2), (ax1 - 0.15, 0.42, az1), skip=("-y",)))
    sofa.extend(box((ax0, 0.0, az0), (ax1, 0.85, az0 + 0.2), skip=("-y", "-z")))
    sofa.extend(box((ax0, 0.0, az0 + 0.2), (ax0 + 0.15, 0.62, az1), skip=("-y",)))
    sofa.extend(box((ax1 - 0.15, 0.0, az0 + 0.2), (ax1, 0.62, az1), skip=("-y",)))
    s.add("sofa", "sofa_fabric", sofa)
    cushions = Geom()
    cushions.extend(rot_y(box((ax0 + 0.25, 0.42, az0 + 0.2), (ax0 + 0.65, 0.8, az0 + 0.33)), 8, pivot=(ax0 + 0.45, 0, az0 + 0.25)))
    cushions.extend(rot_y(box((ax1 - 0.6, 0.42, az0 + 0.2), (ax1 - 0.22, 0.78, az0 + 0.32)), -10, pivot=(ax1 - 0.4, 0, az0 + 0.25)))
    s.add("cushions", "cushion", cushions)

    # Picture frame above the sofa.
    fx0, fx1, fy0, fy1 = -1.25, -0.35, 1.25, 1.9
    s.add("picture_frame", "frame", box((fx0, fy0, Z0), (fx1, fy1, Z0 + 0.035), skip=("-z",)))
    s.add("picture", "canvas", quad((fx0 + 0.06, fy0 + 0.06, Z0 + 0.037), (fx1 - 0.06, fy0 + 0.06, Z0 + 0.037),
                                   (fx1 - 0.06, fy1 - 0.06, Z0 + 0.037), (fx0 + 0.06, fy1 - 0.06, Z0 + 0.037), (0, 0, 1),
                                   tile=fx1 - fx0 - 0.12))
    # A rug under the table.
    s.add("rug", "rug", box((tx - 1.0, 0.0, tz - 0.7), (tx + 1.0, 0.01, tz + 0.8), skip=("-y",)))

    s.camera = ((-1.0, 1.45, 1.85), (0.0, 0.9, -2.0), 52.0)
    return s


# ---------------------------------------------------------------------------------------------
# Scene 2: glass-of-water
# ---------------------------------------------------------------------------------------------

GLASS_LIGHT = 600.0
FILL_LIGHT = 0.6


def tumbler_profiles():
    """Outer glass, water: a slightly tapered tumbler (r grows from 3.3 to 4.0 cm over 11 cm),
    2.5 mm walls, 10 mm base; water 0.4 mm inside the glass's inner surface, 7.5 cm deep."""
    h, rb, rt, w, b = 0.11, 0.033, 0.040, 0.0025, 0.010
    fillet = 0.002

    def r_out(y):
        return rb + (rt - rb) * y / h

    def r_in(y):
        return r_out(y) - w

    # Outer: bottom disk, fillet to the wall, wall up to the rim, rounded rim, inner wall down,
    # inner fillet, inner bottom back to the axis: one smooth run (all joins are tangent).
    pts = [(0.0, 0.0), (rb - fillet, 0.0)]
    pts += arc((rb - fillet, fillet), fillet, -90, 0, 4)[1:]
    for i in range(1, 11):
        y = fillet + (h - fillet) * i / 10
        pts.append((r_out(y), y))
    pts += arc(((r_out(h) + r_in(h)) / 2, h), w / 2, 0, 180, 8)[1:]
    for i in range(1, 11):
        y = h - (h - b - fillet) * i / 10
        pts.append((r_in(y), y))
    pts += arc((r_in(b) - fillet, b + fillet), fillet, 0, -90, 4)[1:]
    pts.append((0.0, b))
    glass = [pts]

    gap, level = 0.0004, 0.075
    wb = b + gap
    wpts = [(0.0, wb), (r_in(wb) - gap - fillet, wb)]
    wpts += arc((r_in(wb) - gap - fillet, wb + fillet), fillet, -90, 0, 4)[1:]
    for i in range(1, 9):
        y = wb + fillet + (level - wb - fillet) * i / 8
        wpts.append((r_in(y) - gap, y))
    water = [wpts, [(r_in(level) - gap, level), (0.0, level)]]
    return glass, water


def wine_glass_profile():
    """Solid wine glass: foot (r 3.5 cm), stem, tulip bowl (1.4 mm wall), 17 cm tall."""
    foot = [(0.0, 0.0), (0.035, 0.0)]
    edge = [(0.035, 0.0), (0.035, 0.0025)]
    top = [(0.035, 0.0025), (0.026, 0.0035), (0.016, 0.005), (0.009, 0.008), (0.0055, 0.013), (0.004, 0.02)]
    for i in range(1, 8):
        top.append((0.0036, 0.02 + 0.055 * i / 7))
    a, bb, yc, w = 0.042, 0.05, 0.128, 0.0014
    phi0 = -math.degrees(math.acos(0.0042 / a))
    for i in range(0, 21):
        ph = math.radians(phi0 + (45 - phi0) * i / 20)
        top.append((a * math.cos(ph), yc + bb * math.sin(ph)))
    ro, yo = top[-1]
    # Outer lip continues up a little, over the rounded rim, then the inner surface down.
    rim_y = yo + 0.006
    top.append((ro - 0.0004, rim_y))
    top += arc((ro - 0.0004 - w / 2, rim_y), w / 2, 0, 180, 6)[1:]
    ri = ro - 0.0004 - w
    ai, bi, yci = a - w, bb - w, yc
    phi_top = math.degrees(math.acos(min(1.0, ri / ai)))
    # the inner lip goes straight down to where the inner ellipse reaches radius ri
    y_join = yci + bi * math.sin(math.radians(phi_top))
    if y_join < rim_y:
        top.append((ri, y_join))
    for i in range(1, 25):
        ph = math.radians(phi_top + (-90 - phi_top) * i / 24)
        top.append((max(0.0, ai * math.cos(ph)), yci + bi * math.sin(ph)))
    top[-1] = (0.0, top[-1][1])
    return [foot, edge, top]


def build_glass_of_water():
    s = Scene("glass-of-water")
    s.render = dict(RENDER)
    X0, X1, Z0, Z1, H = -2.0, 2.0, -1.75, 1.75, 2.6
    s.material("wall", (0.70, 0.67, 0.60), specular=0.0)
    s.material("ceiling", (0.80, 0.80, 0.78), specular=0.0)
    s.material("floor_wood", (1, 1, 1), roughness=0.5, specular=0.5, texture=("planks.png", tex_planks(seed=5)))
    s.material("table_wood", (1, 1, 1), roughness=0.3, specular=0.6,
               texture=("oak.png", tex_wood_grain(seed=31, light=(212, 182, 146), dark=(168, 128, 90))))
    s.material("table_frame", (0.30, 0.20, 0.12), roughness=0.5, specular=0.5)
    s.material("glass", (1, 1, 1), roughness=0.0, transmission=1.0, ior=1.5)
    s.material("water", (1, 1, 1), roughness=0.0, transmission=1.0, ior=1.33)
    s.material("orange", (0.80, 0.32, 0.04), roughness=0.45, specular=0.5)
    s.material("book_red", (0.50, 0.08, 0.07), roughness=0.6, specular=0.4)
    s.material("book_blue", (0.10, 0.18, 0.35), roughness=0.6, specular=0.4)
    s.material("lamp_housing", (0.08, 0.08, 0.08), roughness=0.4, specular=0.5)
    s.material("light", (0, 0, 0), emission=(GLASS_LIGHT, GLASS_LIGHT * 0.95, GLASS_LIGHT * 0.85))
    s.material("fill", (0, 0, 0), emission=(FILL_LIGHT * 0.9, FILL_LIGHT * 0.95, FILL_LIGHT))

    # Room.
    s.add("floor", "floor_wood", quad((X0, 0, Z0), (X1, 0, Z0), (X1, 0, Z1), (X0, 0, Z1), (0, 1, 0), tile=1.2))
    s.add("ceiling", "ceiling", quad((X0, H, Z0), (X1, H, Z0), (X1, H, Z1), (X0, H, Z1), (0, -1, 0)))
    s.add("walls", "wall", box((X0, 0, Z0), (X1, H, Z1), inward=True, skip=("-y", "+y")))
    # Dim fill: a large diffuse panel on the ceiling behind the camera, facing down.
    s.add("fill_panel", "fill", quad((-1.0, H - 0.01, 0.3), (1.0, H - 0.01, 0.3), (1.0, H - 0.01, 1.5),
                                     (-1.0, H - 0.01, 1.5), (0, -1, 0)))

    # Table near the back wall.
    ty = 0.75
    cx, cz = 0.0, -1.15
    s.add("table_top", "table_wood", box((cx - 0.75, ty - 0.035, cz - 0.45), (cx + 0.75, ty, cz + 0.45), tile=0.7))
    frame = Geom()
    for lx in (cx - 0.7, cx + 0.65):
        for lz in (cz - 0.4, cz + 0.35):
            frame.extend(box((lx, 0, lz), (lx + 0.05, ty - 0.035, lz + 0.05), skip=("-y", "+y")))
    frame.extend(box((cx - 0.68, ty - 0.12, cz - 0.38), (cx + 0.68, ty - 0.035, cz + 0.38), skip=("+y",)))
    s.add("table_frame", "table_frame", frame)

    # Small light: a 10 cm square emitter in a dark housing 1.25 m above the table, facing down.
    lx, ly, lz, half = -0.25, 2.0, -1.35, 0.05
    s.add("lamp", "light", quad((lx - half, ly, lz - half), (lx + half, ly, lz - half), (lx + half, ly, lz + half),
                                (lx - half, ly, lz + half), (0, -1, 0)))
    s.add("lamp_housing", "lamp_housing", box((lx - half - 0.01, ly + 0.001, lz - half - 0.01),
                                              (lx + half + 0.01, ly + 0.08, lz + half + 0.01), skip=("-y",)))
    s.add("lamp_cord", "lamp_housing", cylinder((lx, 0, lz), 0.004, ly + 0.08, H, 8))

    # Glass of water.
    glass, water = tumbler_profiles()
    g_at = (cx - 0.02, ty, cz + 0.02)
    s.add("tumbler", "glass", lathe(glass, 96, g_at))
    s.add("water", "water", lathe(water, 96, g_at))
    # Wine glass (solid glass lathe), to the right and behind.
    s.add("wine_glass", "glass", lathe(wine_glass_profile(), 96, (cx + 0.13, ty, cz - 0.08)))
    # Glass sphere (paperweight), left front.
    s.add("glass_sphere", "glass", sphere((cx - 0.15, ty + 0.03, cz + 0.1), 0.03, 32, 64))
    # Diffuse objects: an orange and two books.
    s.add("orange", "orange", sphere((cx + 0.2, ty + 0.036, cz + 0.12), 0.037, 24, 48))
    bk = (cx - 0.33, cz - 0.12)
    s.add("book_a", "book_blue", rot_y(box((bk[0] - 0.1, ty, bk[1] - 0.14), (bk[0] + 0.1, ty + 0.03, bk[1] + 0.14)), 20,
                                       pivot=(bk[0], 0, bk[1])))
    s.add("book_b", "book_red", rot_y(box((bk[0] - 0.085, ty + 0.03, bk[1] - 0.12), (bk[0] + 0.085, ty + 0.055,
                                                                                      bk[1] + 0.12)), 5,
                                      pivot=(bk[0], 0, bk[1])))

    s.camera = ((0.02, 0.97, -0.56), (-0.01, 0.81, -1.17), 34.0)
    return s


# ---------------------------------------------------------------------------------------------
# Scene 3: glossy-room
# ---------------------------------------------------------------------------------------------

PANEL_LIGHT = 16.0
SPOT_INTENSITY = 40.0
POINT_INTENSITY = 4.0


def chair(x, z, facing, seat_y=0.45):
    """A chair centred at (x, z) whose back is on the side opposite `facing` (degrees about +Y;
    0 = the sitter faces -Z). Returns (lacquered seat and back, chrome legs)."""
    top = Geom()
    top.extend(box((x - 0.22, seat_y - 0.035, z - 0.21), (x + 0.22, seat_y, z + 0.21)))
    top.extend(box((x - 0.22, seat_y + 0.22, z + 0.17), (x + 0.22, seat_y + 0.45, z + 0.2)))
    legs = Geom()
    for lx in (x - 0.19, x + 0.19):
        for lz in (z - 0.18, z + 0.18):
            legs.extend(cylinder((lx, 0, lz), 0.012, 0.0, seat_y - 0.035, 12))
        legs.extend(cylinder((lx, 0, z + 0.185), 0.012, seat_y, seat_y + 0.22, 12))
    return rot_y(top, facing, pivot=(x, 0, z)), rot_y(legs, facing, pivot=(x, 0, z))


def build_glossy_room():
    s = Scene("glossy-room")
    s.render = dict(RENDER)
    X0, X1, Z0, Z1, H = -2.5, 2.5, -2.25, 2.25, 2.7
    s.material("floor_tiles", (1, 1, 1), roughness=0.08, specular=1.0,
               texture=("checker.png", tex_tiles(256, 2, 2, [(226, 220, 204), (52, 58, 70)], (120, 116, 110), 3)))
    s.material("wall_tiles", (1, 1, 1), roughness=0.12, specular=1.0,
               texture=("wall_tiles.png", tex_tiles(256, 4, 3, [(200, 216, 226), (186, 204, 218), (210, 222, 230)],
                                                    (150, 148, 140), 9, checker=False, mottle=0.08)))
    s.material("paint", (0.62, 0.55, 0.47), roughness=0.55, specular=0.5)
    s.material("ceiling", (0.80, 0.80, 0.78), specular=0.0)
    s.material("lacquer_wood", (1, 1, 1), roughness=0.05, specular=1.0, texture=("wood.png", tex_wood_grain(seed=41)))
    s.material("steel", (0.62, 0.62, 0.64), metallic=1.0, roughness=0.3)
    s.material("chrome", (0.80, 0.80, 0.82), metallic=1.0, roughness=0.15)
    s.material("brass", (0.86, 0.66, 0.36), metallic=1.0, roughness=0.25)
    s.material("copper", (0.93, 0.58, 0.45), metallic=1.0, roughness=0.18)
    s.material("gold", (0.95, 0.75, 0.38), metallic=1.0, roughness=0.35)
    s.material("red_lacquer", (0.45, 0.04, 0.03), roughness=0.1, specular=1.0)
    s.material("black_lacquer", (0.03, 0.03, 0.035), roughness=0.12, specular=1.0)
    s.material("dark_gap", (0.02, 0.02, 0.02), specular=0.0)
    s.material("lining", (0.85, 0.82, 0.75), specular=0.0)
    s.material("panel", (0, 0, 0), emission=(PANEL_LIGHT, PANEL_LIGHT * 0.97, PANEL_LIGHT * 0.9))

    # Room shell: glossy checker floor (0.5 m tiles), a glazed-tile back wall (10 cm tiles),
    # satin painted side and front walls, a matte ceiling.
    s.add("floor", "floor_tiles", quad((X0, 0, Z0), (X1, 0, Z0), (X1, 0, Z1), (X0, 0, Z1), (0, 1, 0), tile=1.0))
    s.add("ceiling", "ceiling", quad((X0, H, Z0), (X1, H, Z0), (X1, H, Z1), (X0, H, Z1), (0, -1, 0)))
    s.add("back_wall", "wall_tiles", quad((X0, 0, Z0), (X1, 0, Z0), (X1, H, Z0), (X0, H, Z0), (0, 0, 1), tile=0.4))
    painted = Geom()
    painted.extend(quad((X0, 0, Z0), (X0, 0, Z1), (X0, H, Z1), (X0, H, Z0), (1, 0, 0)))
    painted.extend(quad((X1, 0, Z0), (X1, 0, Z1), (X1, H, Z1), (X1, H, Z0), (-1, 0, 0)))
    painted.extend(quad((X0, 0, Z1), (X1, 0, Z1), (X1, H, Z1), (X0, H, Z1), (0, 0, -1)))
    s.add("painted_walls", "paint", painted)
    # Emissive ceiling panel (a diffuser, facing down) in a steel frame.
    px0, px1, pz0, pz1 = -0.3, 1.3, -0.3, 0.3
    s.add("ceiling_panel", "panel", quad((px0, H - 0.01, pz0), (px1, H - 0.01, pz0), (px1, H - 0.01, pz1),
                                         (px0, H - 0.01, pz1), (0, -1, 0)))
    pf = Geom()
    pf.extend(box((px0 - 0.05, H - 0.02, pz0 - 0.05), (px0, H, pz1 + 0.05), skip=("+y",)))
    pf.extend(box((px1, H - 0.02, pz0 - 0.05), (px1 + 0.05, H, pz1 + 0.05), skip=("+y",)))
    pf.extend(box((px0, H - 0.02, pz0 - 0.05), (px1, H, pz0), skip=("+y",)))
    pf.extend(box((px0, H - 0.02, pz1), (px1, H, pz1 + 0.05), skip=("+y",)))
    s.add("panel_frame", "steel", pf)

    # Lacquered table with chrome legs, two chairs.
    tx, tz, ty = 0.2, -0.3, 0.74
    s.add("table_top", "lacquer_wood", box((tx - 0.8, ty - 0.04, tz - 0.45), (tx + 0.8, ty, tz + 0.45), tile=1.6))
    legs = Geom()
    for lx in (tx - 0.72, tx + 0.72):
        for lz in (tz - 0.37, tz + 0.37):
            legs.extend(cylinder((lx, 0, lz), 0.025, 0.0, ty - 0.04, 24))
    s.add("table_legs", "chrome", legs)
    seats, chair_legs = Geom(), Geom()
    for cx, cz, f in ((tx - 0.35, tz + 0.62, 0.0), (tx + 1.1, tz + 0.05, 75.0)):
        a, b = chair(cx, cz, f)
        seats.extend(a)
        chair_legs.extend(b)
    s.add("chair_seats", "red_lacquer", seats)
    s.add("chair_legs", "chrome", chair_legs)
    # On the table: a copper bowl, a gold vase and a black lacquered sphere.
    bowl = [[(0.0, 0.0), (0.05, 0.0)],
            [(0.05, 0.0)] + [(0.05 + 0.1 * math.sin(math.radians(a)), 0.1 * (1 - math.cos(math.radians(a))) * 0.9)
                             for a in range(10, 91, 8)] + [(0.15, 0.09)],
            [(0.15, 0.09), (0.15, 0.095), (0.144, 0.095)],
            [(0.144, 0.095)] + [(0.144 - 0.094 * (1 - math.sin(math.radians(a))), 0.095 - 0.085 * math.cos(math.radians(a)))
                                for a in range(90, 9, -8)] + [(0.0, 0.01)]]
    s.add("bowl", "copper", lathe(bowl, 64, (tx + 0.3, ty, tz + 0.1)))
    vase_side = []
    for i in range(0, 25):
        t = i / 24
        vase_side.append((0.055 + 0.05 * math.sin(math.pi * t * 1.1) - 0.03 * t, 0.005 + 0.34 * t))
    ro, yt = vase_side[-1]
    lip = [(ro, yt), (ro + 0.01, yt + 0.01), (ro + 0.006, yt + 0.014)]
    inner = [(ro + 0.006, yt + 0.014), (ro - 0.006, yt), (ro - 0.012, yt - 0.06), (0.0, yt - 0.06)]
    s.add("vase", "gold", lathe([[(0.0, 0.0), (0.05, 0.0)], [(0.05, 0.0), (0.055, 0.005)] + vase_side[1:] + lip[1:], inner],
                                64, (tx - 0.4, ty, tz - 0.12)))
    s.add("table_sphere", "black_lacquer", sphere((tx - 0.05, ty + 0.06, tz + 0.18), 0.06, 24, 48))

    # Steel cabinet against the right wall: two doors, chrome handles.
    cx0, cx1, cz0, cz1 = X1 - 0.5, X1, -1.9, -0.5
    cab = Geom()
    cab.extend(box((cx0, 0.08, cz0), (cx1, 1.9, cz1), skip=("+x",)))
    cab.extend(box((cx0 + 0.03, 0.0, cz0 + 0.03), (cx1, 0.08, cz1 - 0.03), skip=("+x", "-y")))
    s.add("cabinet", "steel", cab)
    zm = (cz0 + cz1) / 2
    handles = Geom()
    for hz in (zm - 0.06, zm + 0.06):
        handles.extend(box((cx0 - 0.03, 0.85, hz - 0.01), (cx0, 1.25, hz + 0.01), skip=("+x",)))
    s.add("cabinet_handles", "chrome", handles)
    s.add("cabinet_seam", "dark_gap", quad((cx0 - 0.001, 0.1, zm - 0.004), (cx0 - 0.001, 0.1, zm + 0.004),
                                           (cx0 - 0.001, 1.88, zm + 0.004), (cx0 - 0.001, 1.88, zm - 0.004), (-1, 0, 0)))
    # Brass and copper vessels on the cabinet, a tall copper vase on the floor beside it.
    s.add("cabinet_urn", "brass", lathe([[(0.0, 0.0), (0.06, 0.0)],
                                         [(0.06, 0.0)] + [(0.06 + 0.05 * math.sin(math.pi * i / 10), 0.22 * i / 10)
                                                          for i in range(1, 11)],
                                         [(0.06, 0.22), (0.05, 0.22), (0.05, 0.2), (0.0, 0.2)]],
                                        48, (cx0 + 0.25, 1.9, cz0 + 0.35)))
    fv = [(0.0, 0.0), (0.08, 0.0)]
    fside = [(0.08, 0.0)] + [(0.08 + 0.05 * math.sin(math.pi * i / 16) - 0.045 * i / 16, 0.6 * i / 16) for i in range(1, 17)]
    ro, yt = fside[-1]
    finner = [(ro, yt), (ro - 0.008, yt), (ro - 0.01, yt - 0.08), (0.0, yt - 0.08)]
    s.add("floor_vase", "copper", lathe([fv, fside, finner], 48, (X1 - 0.3, 0.0, 0.0)))

    # Black lacquered sideboard along the back wall, left of centre.
    s.add("sideboard", "black_lacquer", box((-2.3, 0.1, Z0), (-0.7, 0.8, Z0 + 0.45), skip=("-z",)))
    s.add("sideboard_feet", "steel", box((-2.25, 0.0, Z0 + 0.05), (-0.75, 0.1, Z0 + 0.4), skip=("-y",)))
    s.add("sideboard_bowl", "steel", lathe(bowl, 48, (-1.1, 0.8, Z0 + 0.22)))

    # Floor lamp (brass) against the tiled wall, right of the sideboard: base, pole, conical
    # shade (a thin closed shell, open at top and bottom, brass outside and a white diffuse
    # lining inside) around the point light, 5 cm above the top of the pole.
    lx, lz = -0.35, Z0 + 0.4
    s.add("lamp_base", "brass", lathe([[(0, 0), (0.16, 0)], [(0.16, 0), (0.16, 0.015), (0.12, 0.03)],
                                       [(0.12, 0.03), (0.02, 0.04), (0, 0.04)]], 48, (lx, 0, lz)))
    s.add("lamp_pole", "brass", cylinder((lx, 0, lz), 0.012, 0.04, 1.45, 16))
    shade = [[(0.24, 1.35), (0.09, 1.65)], [(0.09, 1.65), (0.084, 1.65)], [(0.233, 1.352), (0.24, 1.35)]]
    lining = [[(0.084, 1.65), (0.233, 1.352)]]
    s.add("lamp_shade", "brass", lathe(shade, 64, (lx, 0, lz)))
    s.add("lamp_shade_lining", "lining", lathe(lining, 64, (lx, 0, lz)))

    # Punctual lights (KHR_lights_punctual): a spot from the ceiling onto the table and a bare
    # bulb (point light) inside the lamp shade.
    s.light("spot", {"type": "spot", "color": [1.0, 0.92, 0.8], "intensity": SPOT_INTENSITY,
                     "spot": {"innerConeAngle": round(math.radians(14), 6), "outerConeAngle": round(math.radians(22), 6)}},
            (-0.4, H - 0.05, 0.9), (tx, ty, tz))
    s.light("lamp_bulb", {"type": "point", "color": [1.0, 0.85, 0.65], "intensity": POINT_INTENSITY},
            (lx, 1.5, lz), None)

    s.camera = ((-1.9, 1.55, 2.0), (0.55, 0.8, -1.0), 50.0)
    return s


BUILDERS = {"door-ajar": build_door_ajar, "glass-of-water": build_glass_of_water, "glossy-room": build_glossy_room}


def main(argv):
    if len(argv) == 2 and argv[1] == "all":
        root = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
        for name, build in BUILDERS.items():
            build().write(os.path.join(root, name))
        return 0
    if len(argv) != 3 or argv[1] not in BUILDERS:
        sys.stderr.write(__doc__.split("\n\n")[1] + "\n")
        return 2
    BUILDERS[argv[1]]().write(argv[2])
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))

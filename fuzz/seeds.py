#!/usr/bin/env python3
"""Writes the seed corpora of the scene and sidecar targets from the bundled scenes (the
file-format seeds are tiny renders; docs/fuzzing.md has the commands). Usage:
    python3 fuzz/seeds.py <out-dir>     # writes <out-dir>/gltf_scene and <out-dir>/sidecar
"""
import base64, json, pathlib, struct, sys, zlib

SEP = b"\n#--cvtrace-fuzz-part--\n"  # crates/fuzz-targets: SEPARATOR
root = pathlib.Path(__file__).resolve().parent.parent
out = pathlib.Path(sys.argv[1])
(out / "gltf_scene").mkdir(parents=True, exist_ok=True)
(out / "sidecar").mkdir(parents=True, exist_ok=True)


def glb(doc, blob):
    doc = dict(doc, buffers=[{"byteLength": len(blob)}])
    j = json.dumps(doc, separators=(",", ":")).encode()
    j += b" " * (-len(j) % 4)
    blob += b"\0" * (-len(blob) % 4)
    body = struct.pack("<II", len(j), 0x4E4F534A) + j + struct.pack("<II", len(blob), 0x004E4942) + blob
    return b"glTF" + struct.pack("<II", 2, 12 + len(body)) + body


def png_2x2():
    raw = b"".join(b"\0" + bytes([200, 120, 40] * 2) for _ in range(2))
    chunk = lambda t, d: struct.pack(">I", len(d)) + t + d + struct.pack(">I", zlib.crc32(t + d))
    return b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", struct.pack(">IIBBBBB", 2, 2, 8, 2, 0, 0, 0)) + chunk(b"IDAT", zlib.compress(raw)) + chunk(b"IEND", b"")


cbox = root / "scenes/cornell-box"
doc = json.loads((cbox / "scene.gltf").read_text())
blob = (cbox / "scene.bin").read_bytes()
sidecars = {p.parent.name: p.read_bytes() for p in sorted(root.glob("scenes/*/scene.cvtrace.toml"))}
(out / "gltf_scene/cornell.glb").write_bytes(glb(doc, blob))
(out / "gltf_scene/cornell-sidecar.glb").write_bytes(glb(doc, blob) + SEP + sidecars["cornell-box"] + b"\n[environment]\ncolor = [0.1, 0.2, 0.3]\n")
embedded = dict(doc, buffers=[{"byteLength": len(blob), "uri": "data:application/octet-stream;base64," + base64.b64encode(blob).decode()}])
(out / "gltf_scene/cornell.gltf").write_bytes(json.dumps(embedded, indent=1).encode() + SEP + sidecars["cornell-box"])
# A textured variant: a 2×2 PNG as the base colour of the first material (the meshes have no
# TEXCOORD_0, so the importer reads the image and samples it at (0, 0)).
textured = json.loads(json.dumps(embedded))
textured["images"] = [{"uri": "data:image/png;base64," + base64.b64encode(png_2x2()).decode()}]
textured["textures"] = [{"source": 0}]
textured["materials"][0].setdefault("pbrMetallicRoughness", {})["baseColorTexture"] = {"index": 0}
(out / "gltf_scene/cornell-textured.gltf").write_bytes(json.dumps(textured).encode())
# The other scenes' JSON alone: their buffers and images are missing, which exercises the
# document checks and the missing-file errors.
for p in sorted(root.glob("scenes/*/scene.gltf")):
    if p.parent.name != "cornell-box":
        (out / f"gltf_scene/{p.parent.name}.gltf").write_bytes(p.read_bytes())
for name, text in sidecars.items():
    (out / f"sidecar/{name}.toml").write_bytes(text)
(out / "sidecar/environment.toml").write_bytes(b'[render]\nspp = 4\nbatches = 2\n\n[environment]\ncolor = [0.6, 0.7, 1.0]\nstrength = 2.5\nrotation = 90.0\n')
(out / "sidecar/map.toml").write_bytes(b'[environment]\nmap = "sky.exr"\nstrength = 1.0\n')

#!/usr/bin/env python3
"""Writes scenes/textured_room.glb: a glTF 2.0 binary with a base-colour texture and a
KHR_lights_punctual point light, written with the Python standard library only (the PNG is
encoded here with zlib, the GLB container with struct/json), so nothing but this script
stands between the numbers below and the file.

Metres, y up (glTF). A closed 4 x 2.7 x 3 m room (x in [0, 4], y in [0, 2.7], z in [0, 3]),
every surface facing inwards:
- node "floor": one quad (two triangles), material "parquet": baseColorFactor 0.9 x a 4 x 4
  RGB PNG (a checker of two wood tones, sRGB-encoded texels);
- node "walls": four walls and the ceiling, material "plaster", baseColorFactor 0.6;
- node "cabinet": a 0.6 x 1.0 x 0.6 m box standing on the floor near a corner (no bottom face), "wood";
- node "bulb": a KHR_lights_punctual point light at (2, 2.2, 1.5), white, 5464 cd
  (= 8 W/sr per channel at the project's 683 lm/W; radiant flux 4 pi x 8 = 100.5 W).

The reader's rule (crates/radiosity/src/io/gltf.rs): rho = baseColorFactor x the mean of the
sRGB-decoded texels. This script prints that mean for checking.

Run: python3 make_textured_room.py [OUT.glb]
"""
import json
import struct
import sys
import zlib

TEXELS = [  # 4 x 4, row by row, sRGB bytes: a checker of two wood tones
    [(200, 150, 100), (150, 100, 60)] * 2,
    [(150, 100, 60), (200, 150, 100)] * 2,
] * 2
FLOOR_FACTOR = 0.9
BULB = (2.0, 2.2, 1.5)
BULB_CD = 5464.0


def png(rows):
    """A truecolour 8-bit PNG (filter 0 on every row)."""
    height, width = len(rows), len(rows[0])
    raw = b"".join(b"\x00" + bytes(c for texel in row for c in texel) for row in rows)

    def chunk(kind, data):
        return (
            struct.pack(">I", len(data))
            + kind
            + data
            + struct.pack(">I", zlib.crc32(kind + data) & 0xFFFFFFFF)
        )

    header = struct.pack(">IIBBBBB", width, height, 8, 2, 0, 0, 0)
    return (
        b"\x89PNG\r\n\x1a\n"
        + chunk(b"IHDR", header)
        + chunk(b"IDAT", zlib.compress(raw, 9))
        + chunk(b"IEND", b"")
    )


def srgb_to_linear(code):
    v = code / 255.0
    return v / 12.92 if v <= 0.04045 else ((v + 0.055) / 1.055) ** 2.4


def quad(a, b, c, d):
    """Corners counter-clockwise seen from the front."""
    return [a, b, c, d]


def room():
    w, h, d = 4.0, 2.7, 3.0
    return [
        quad((0, h, 0), (w, h, 0), (w, h, d), (0, h, d)),  # ceiling, facing -y
        quad((0, 0, 0), (w, 0, 0), (w, h, 0), (0, h, 0)),  # z = 0, facing +z
        quad((0, 0, d), (0, h, d), (w, h, d), (w, 0, d)),  # z = d, facing -z
        quad((0, 0, 0), (0, h, 0), (0, h, d), (0, 0, d)),  # x = 0, facing +x
        quad((w, 0, 0), (w, 0, d), (w, h, d), (w, h, 0)),  # x = w, facing -x
    ]


def cabinet():
    x0, x1, y1, z0, z1 = 3.2, 3.8, 1.0, 0.2, 0.8
    return [
        quad((x0, y1, z0), (x0, y1, z1), (x1, y1, z1), (x1, y1, z0)),  # top, +y
        quad((x0, 0, z0), (x0, y1, z0), (x1, y1, z0), (x1, 0, z0)),  # -z
        quad((x0, 0, z1), (x1, 0, z1), (x1, y1, z1), (x0, y1, z1)),  # +z
        quad((x0, 0, z0), (x0, 0, z1), (x0, y1, z1), (x0, y1, z0)),  # -x
        quad((x1, 0, z0), (x1, y1, z0), (x1, y1, z1), (x1, 0, z1)),  # +x
    ]


def normal(q):
    a, b, c = q[0], q[1], q[2]
    u = [b[i] - a[i] for i in range(3)]
    v = [c[i] - a[i] for i in range(3)]
    return (u[1] * v[2] - u[2] * v[1], u[2] * v[0] - u[0] * v[2], u[0] * v[1] - u[1] * v[0])


def main():
    out = sys.argv[1] if len(sys.argv) > 1 else "textured_room.glb"
    floor = [quad((0, 0, 0), (0, 0, 3.0), (4.0, 0, 3.0), (4.0, 0, 0))]  # facing +y
    assert normal(floor[0])[1] > 0 and normal(room()[0])[1] < 0
    assert normal(cabinet()[0])[1] > 0 and normal(cabinet()[1])[2] < 0

    blob = bytearray()
    views, accessors = [], []

    def add_view(data, target=None):
        while len(blob) % 4:
            blob.append(0)
        view = {"buffer": 0, "byteOffset": len(blob), "byteLength": len(data)}
        if target is not None:
            view["target"] = target
        blob.extend(data)
        views.append(view)
        return len(views) - 1

    def add_accessor(values, kind, component, fmt, target, bounds=False):
        data = b"".join(struct.pack("<" + fmt, *v) if isinstance(v, tuple) else
                        struct.pack("<" + fmt, v) for v in values)
        accessor = {"bufferView": add_view(data, target), "componentType": component,
                    "count": len(values), "type": kind}
        if bounds:
            accessor["min"] = [min(v[i] for v in values) for i in range(3)]
            accessor["max"] = [max(v[i] for v in values) for i in range(3)]
        accessors.append(accessor)
        return len(accessors) - 1

    def mesh(name, quads, material, uv=False):
        positions = [tuple(float(c) for c in p) for q in quads for p in q]
        indices = []
        for k in range(len(quads)):
            indices += [4 * k, 4 * k + 1, 4 * k + 2, 4 * k, 4 * k + 2, 4 * k + 3]
        attributes = {"POSITION": add_accessor(positions, "VEC3", 5126, "3f", 34962, True)}
        if uv:  # the floor's (x, z) / 4 m: the texture spans the floor once
            attributes["TEXCOORD_0"] = add_accessor(
                [(p[0] / 4.0, p[2] / 4.0) for p in positions], "VEC2", 5126, "2f", 34962)
        return {"name": name, "primitives": [{
            "attributes": attributes,
            "indices": add_accessor(indices, "SCALAR", 5123, "H", 34963),
            "material": material, "mode": 4}]}

    meshes = [
        mesh("floor", floor, 0, uv=True),
        mesh("walls", room(), 1),
        mesh("cabinet", cabinet(), 2),
    ]
    image_view = add_view(png(TEXELS))
    while len(blob) % 4:
        blob.append(0)

    def pbr(factor, texture=False):
        m = {"baseColorFactor": [factor[0], factor[1], factor[2], 1.0],
             "metallicFactor": 0.0, "roughnessFactor": 1.0}
        if texture:
            m["baseColorTexture"] = {"index": 0}
        return m

    document = {
        "asset": {"version": "2.0", "generator": "radiosity scenes/tools/make_textured_room.py"},
        "extensionsUsed": ["KHR_lights_punctual"],
        "extensions": {"KHR_lights_punctual": {"lights": [
            {"name": "bulb", "type": "point", "color": [1.0, 1.0, 1.0], "intensity": BULB_CD}
        ]}},
        "scene": 0,
        "scenes": [{"nodes": [0, 1, 2, 3]}],
        "nodes": [
            {"name": "floor", "mesh": 0},
            {"name": "walls", "mesh": 1},
            {"name": "cabinet", "mesh": 2},
            {"name": "bulb", "translation": list(BULB),
             "extensions": {"KHR_lights_punctual": {"light": 0}}},
        ],
        "meshes": meshes,
        "materials": [
            {"name": "parquet", "pbrMetallicRoughness": pbr([FLOOR_FACTOR] * 3, texture=True)},
            {"name": "plaster", "pbrMetallicRoughness": pbr([0.6, 0.6, 0.6])},
            {"name": "wood", "pbrMetallicRoughness": pbr([0.5, 0.35, 0.25])},
        ],
        "textures": [{"source": 0, "sampler": 0}],
        "samplers": [{"magFilter": 9729, "minFilter": 9729}],
        "images": [{"name": "parquet", "bufferView": image_view, "mimeType": "image/png"}],
        "accessors": accessors,
        "bufferViews": views,
        "buffers": [{"byteLength": len(blob)}],
    }
    text = json.dumps(document, separators=(",", ":")).encode()
    text += b" " * (-len(text) % 4)
    body = (struct.pack("<I4s", len(text), b"JSON") + text
            + struct.pack("<I4s", len(blob), b"BIN\x00") + bytes(blob))
    with open(out, "wb") as f:
        f.write(struct.pack("<4sII", b"glTF", 2, 12 + len(body)) + body)

    texels = [t for row in TEXELS for t in row]
    mean = [sum(srgb_to_linear(t[c]) for t in texels) / len(texels) for c in range(3)]
    print(out, "written; floor rho =", [FLOOR_FACTOR * m for m in mean])


if __name__ == "__main__":
    main()

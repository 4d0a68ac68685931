#!/usr/bin/env python3
"""Writes scenes/furnished_room.obj and furnished_room.mtl: a closed, furnished room in
Wavefront OBJ + MTL, built from boxes (standard library only).

Metres, z up. The room is 4 x 3 x 2.7 m (x in [0, 4], y in [0, 3], z in [0, 2.7]); every room
surface faces inwards. A 0.6 x 0.6 m emitting panel sits flush in the ceiling, centred over a
1.2 x 0.8 m table (top at 0.76 m, four legs); two chairs (seat box and back box) stand at the
table's long sides and a 0.9 x 0.35 x 1.8 m shelf against the far wall. Faces hidden in a
contact (box bottoms on the floor, leg tops under the table top, the shelf's back on the wall)
are left out, so the room stays closed with no surface facing another at zero distance.
Materials: Kd is the diffuse reflectance, Ke the emitted radiance in W m^-2 sr^-1 (the panel:
L_e = 100, so its power is pi x 100 x 0.36 = 113.1 W per channel).

Run: python3 make_furnished_room.py [OUT_DIR]   (writes OUT_DIR/furnished_room.{obj,mtl})
"""
import os
import sys

H = 2.7  # ceiling height
PANEL = (1.7, 2.3, 1.2, 1.8)  # x0, x1, y0, y1 of the ceiling panel

MATERIALS = [
    ("floor", (0.30, 0.25, 0.20), (0, 0, 0)),
    ("wall", (0.60, 0.60, 0.55), (0, 0, 0)),
    ("ceiling", (0.80, 0.80, 0.80), (0, 0, 0)),
    ("panel", (0.80, 0.80, 0.80), (100, 100, 100)),
    ("wood", (0.45, 0.30, 0.20), (0, 0, 0)),
    ("fabric", (0.20, 0.30, 0.50), (0, 0, 0)),
]


def sub(a, b):
    return tuple(x - y for x, y in zip(a, b))


def cross(a, b):
    return (a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0])


def dot(a, b):
    return sum(x * y for x, y in zip(a, b))


def facing(corners, normal):
    """The quad's corners ordered counter-clockwise seen from the side `normal` points to."""
    n = cross(sub(corners[1], corners[0]), sub(corners[2], corners[0]))
    return corners if dot(n, normal) > 0 else corners[::-1]


def rect_z(x0, x1, y0, y1, z, up):
    return facing([(x0, y0, z), (x1, y0, z), (x1, y1, z), (x0, y1, z)], (0, 0, 1 if up else -1))


def box(lo, hi, skip=()):
    """Outward faces of an axis-aligned box, except those named in `skip`
    (-x, +x, -y, +y, -z, +z)."""
    (x0, y0, z0), (x1, y1, z1) = lo, hi
    faces = {
        "-x": facing([(x0, y0, z0), (x0, y1, z0), (x0, y1, z1), (x0, y0, z1)], (-1, 0, 0)),
        "+x": facing([(x1, y0, z0), (x1, y1, z0), (x1, y1, z1), (x1, y0, z1)], (1, 0, 0)),
        "-y": facing([(x0, y0, z0), (x1, y0, z0), (x1, y0, z1), (x0, y0, z1)], (0, -1, 0)),
        "+y": facing([(x0, y1, z0), (x1, y1, z0), (x1, y1, z1), (x0, y1, z1)], (0, 1, 0)),
        "-z": rect_z(x0, x1, y0, y1, z0, False),
        "+z": rect_z(x0, x1, y0, y1, z1, True),
    }
    return [f for k, f in faces.items() if k not in skip]


def objects():
    """(object name, material, [quads])."""
    px0, px1, py0, py1 = PANEL
    walls = [
        facing([(0, 0, 0), (4, 0, 0), (4, 0, H), (0, 0, H)], (0, 1, 0)),
        facing([(0, 3, 0), (4, 3, 0), (4, 3, H), (0, 3, H)], (0, -1, 0)),
        facing([(0, 0, 0), (0, 3, 0), (0, 3, H), (0, 0, H)], (1, 0, 0)),
        facing([(4, 0, 0), (4, 3, 0), (4, 3, H), (4, 0, H)], (-1, 0, 0)),
    ]
    ceiling = [
        rect_z(0, 4, 0, py0, H, False),
        rect_z(0, 4, py1, 3, H, False),
        rect_z(0, px0, py0, py1, H, False),
        rect_z(px1, 4, py0, py1, H, False),
    ]
    table = box((1.4, 1.1, 0.72), (2.6, 1.9, 0.76))
    for x, y in [(1.45, 1.15), (2.5, 1.15), (1.45, 1.8), (2.5, 1.8)]:
        table += box((x, y, 0.0), (x + 0.05, y + 0.05, 0.72), skip=("-z", "+z"))
    chairs = []
    for name, y0, back in [("chair_1", 0.5, (0.5, 0.55)), ("chair_2", 2.05, (2.45, 2.5))]:
        quads = box((1.775, y0, 0.0), (2.225, y0 + 0.45, 0.45), skip=("-z",))
        quads += box((1.775, back[0], 0.45), (2.225, back[1], 0.9), skip=("-z",))
        chairs.append((name, "fabric", quads))
    shelf = box((3.0, 2.65, 0.0), (3.9, 3.0, 1.8), skip=("-z", "+y"))
    return [
        ("floor", "floor", [rect_z(0, 4, 0, 3, 0.0, True)]),
        ("walls", "wall", walls),
        ("ceiling", "ceiling", ceiling),
        ("lamp", "panel", [rect_z(px0, px1, py0, py1, H, False)]),
        ("table", "wood", table),
        *chairs,
        ("shelf", "wood", shelf),
    ]


def main():
    out_dir = sys.argv[1] if len(sys.argv) > 1 else "."
    with open(os.path.join(out_dir, "furnished_room.mtl"), "w") as mtl:
        mtl.write("# furnished_room: written by tools/make_furnished_room.py\n")
        mtl.write("# Kd = diffuse reflectance, Ke = emitted radiance W m^-2 sr^-1\n")
        for name, kd, ke in MATERIALS:
            mtl.write(f"\nnewmtl {name}\nKd {kd[0]:g} {kd[1]:g} {kd[2]:g}\n")
            mtl.write(f"Ke {ke[0]:g} {ke[1]:g} {ke[2]:g}\n")
    lines = [
        "# furnished_room: written by tools/make_furnished_room.py",
        "# units: metres, z up; a closed 4 x 3 x 2.7 m room, one emitting ceiling panel",
        "mtllib furnished_room.mtl",
    ]
    count = 0
    for name, material, quads in objects():
        lines += [f"o {name}", f"usemtl {material}"]
        for quad in quads:
            for v in quad:
                lines.append("v " + " ".join(f"{c:.4f}" for c in v))
            lines.append("f " + " ".join(str(count + k) for k in range(1, 5)))
            count += 4
    with open(os.path.join(out_dir, "furnished_room.obj"), "w") as obj:
        obj.write("\n".join(lines) + "\n")


if __name__ == "__main__":
    main()

#!/usr/bin/env python3
"""Convert a Wavefront OBJ + MTL scene (our conventions) to MGF for `io::mgf`.

Usage: obj_to_mgf.py scene.obj [--white E|D65] > scene.mgf

Conventions (see crates/radiosity/src/io/mgf.rs and io/obj.rs): MTL `Kd` is the diffuse
reflectance rho per linear-sRGB channel, `Ke` the emitted radiance L_e in W m^-2 sr^-1 (front
side only), lengths in metres. Each colour c (rho or L_e) is written as the CIE chromaticity
that the loader maps back to c / Y(c) (Y = 0.2126 R + 0.7152 G + 0.0722 B), with
`rd Y(rho)` and `ed pi * 683 * Y(L_e)` (lm/m^2); neutral colours are MGF's default grey.
`--white` must match the loader's `MgfWhite` (default equal-energy E). Every surface is
one-sided (`sides 1`). Numbers are written with Python's shortest round-trip repr, so the
loader reproduces rho and L_e to about 1e-15 and the vertices exactly.
"""
import math
import os
import sys

LUMINANCE = (0.2126, 0.7152, 0.0722)
EFFICACY = 683.0


def mat_vec(m, v):
    return [sum(m[i][j] * v[j] for j in range(3)) for i in range(3)]


def mat_mul(a, b):
    return [[sum(a[i][k] * b[k][j] for k in range(3)) for j in range(3)] for i in range(3)]


def inverse(m):
    (a, b, c), (d, e, f), (g, h, i) = m
    det = a * (e * i - f * h) - b * (d * i - f * g) + c * (d * h - e * g)
    return [
        [(e * i - f * h) / det, (c * h - b * i) / det, (b * f - c * e) / det],
        [(f * g - d * i) / det, (a * i - c * g) / det, (c * d - a * f) / det],
        [(d * h - e * g) / det, (b * g - a * h) / det, (a * e - b * d) / det],
    ]


def srgb_matrices():
    """RGB->XYZ of the sRGB primaries with white D65 (IEC 61966-2-1), and its inverse."""
    col = lambda x, y: [x / y, 1.0, (1.0 - x - y) / y]
    prim = [list(r) for r in zip(col(0.64, 0.33), col(0.30, 0.60), col(0.15, 0.06))]
    scale = mat_vec(inverse(prim), col(0.3127, 0.3290))
    rgb_to_xyz = [[prim[i][j] * scale[j] for j in range(3)] for i in range(3)]
    return rgb_to_xyz, inverse(rgb_to_xyz)


def chromaticity(c, white):
    """CIE (x, y) that the loader turns back into ratios proportional to c."""
    rgb_to_xyz, xyz_to_rgb = srgb_matrices()
    divisor = [1.0, 1.0, 1.0] if white == "D65" else mat_vec(xyz_to_rgb, [1.0, 1.0, 1.0])
    xyz = mat_vec(rgb_to_xyz, [c[k] * divisor[k] for k in range(3)])
    s = sum(xyz)
    return xyz[0] / s, xyz[1] / s


def luminance(c):
    return sum(w * v for w, v in zip(LUMINANCE, c))


def read_mtl(path):
    materials, name = {}, None
    for raw in open(path, encoding="utf-8"):
        w = raw.split()
        if not w:
            continue
        if w[0] == "newmtl":
            name = raw.strip()[len("newmtl"):].strip()
            materials[name] = {"Kd": None, "Ke": [0.0, 0.0, 0.0]}
        elif w[0] in ("Kd", "Ke") and name is not None:
            materials[name][w[0]] = [float(x) for x in w[1:4]]
    return materials


def colour_lines(c, white):
    if c[0] == c[1] == c[2] and white == "E":
        return ["\tc"]
    x, y = chromaticity(c, white)
    return ["\tc", "\t\tcxy %r %r" % (x, y)]


def convert(obj_path, white):
    out = ["# %s converted by obj_to_mgf.py (white point %s)" % (os.path.basename(obj_path), white),
           "# lengths in metres; rd = luminance of rho, ed = pi * 683 * luminance of L_e (lm/m^2)"]
    vertices, faces, libraries = [], [], []
    obj, group, material = None, None, None
    for raw in open(obj_path, encoding="utf-8"):
        w = raw.split()
        if not w or w[0].startswith("#"):
            continue
        rest = raw.strip()[len(w[0]):].strip()
        if w[0] == "v":
            vertices.append(w[1:4])
        elif w[0] == "o":
            obj = rest or None
        elif w[0] == "g":
            group = rest or None
        elif w[0] == "usemtl":
            material = rest
        elif w[0] == "mtllib":
            libraries.append(rest)
        elif w[0] == "f":
            idx = []
            for token in w[1:]:
                i = int(token.split("/")[0])
                idx.append(i if i > 0 else len(vertices) + 1 + i)
            faces.append((obj or group or "object", material, idx))
    materials = {}
    for lib in libraries:
        materials.update(read_mtl(os.path.join(os.path.dirname(obj_path), lib)))
    for name, m in materials.items():
        rho, le = m["Kd"], m["Ke"]
        out.append("m %s =" % name)
        out.append("\tsides 1")
        out += colour_lines(rho, white)
        out.append("\trd %r" % luminance(rho))
        if any(v > 0 for v in le):
            out += colour_lines(le, white)
            out.append("\ted %r" % (math.pi * EFFICACY * luminance(le)))
    for k, v in enumerate(vertices, 1):
        # repr(float(...)) keeps the OBJ's value exactly (both parse to the same double).
        out.append("v v%d =" % k)
        out.append("\tp %s" % " ".join(repr(float(c)) for c in v))
    current = None
    for name, mat, idx in faces:
        if mat != current:
            out.append("m %s" % mat)
            current = mat
        out.append("o %s" % name)
        out.append("\tf %s" % " ".join("v%d" % i for i in idx))
        out.append("o")
    return "\n".join(out) + "\n"


if __name__ == "__main__":
    args = sys.argv[1:]
    white = "E"
    if "--white" in args:
        k = args.index("--white")
        white = args[k + 1].upper()
        del args[k:k + 2]
    if len(args) != 1 or white not in ("E", "D65"):
        sys.exit(__doc__)
    sys.stdout.write(convert(args[0], white))

"""The Cornell floor's area-averaged direct irradiance by deterministic quadrature.

Evidence for tests/reference/PROVENANCE.md ("The floor's direct light"): the midpoint rule
on an N x N bilinear grid over the floor quad and an M x M grid over the lamp, the point
kernel L_e cos(theta_x) cos(theta_y) / r^2 dA, and visibility by a Moller-Trumbore test of
each segment against the blocks' triangles (the only surfaces between floor and lamp).
Needs numpy; reads ../shared/reference/cornell_scene.json (mm). Run:
    python3 floor_direct_quadrature.py 300 16
"""
import json
import sys

import numpy as np

SCENE = sys.argv[3] if len(sys.argv) > 3 else "../../../../../shared/reference/cornell_scene.json"
polys = {p["name"]: p for p in json.load(open(SCENE))["polygons"]}
lamp = np.array(polys["light"]["vertices"])
radiance = np.array(polys["light"]["emission_radiance"])
lamp_normal = np.array(polys["light"]["normal"])
floor = np.array(polys["floor"]["vertices"])
floor_normal = np.array([0.0, 1.0, 0.0])
blockers = []
for name, p in polys.items():
    if "block" in name:
        v = np.array(p["vertices"])
        blockers += [(v[0], v[i], v[i + 1]) for i in range(1, len(v) - 1)]


def grid(quad, n):
    """Midpoints of an n x n bilinear grid over a quad and their area weights."""
    u = (np.arange(n) + 0.5) / n
    a, b = (g.ravel() for g in np.meshgrid(u, u, indexing="ij"))
    a, b = a[:, None], b[:, None]
    points = (1 - a) * (1 - b) * quad[0] + a * (1 - b) * quad[1] + a * b * quad[2] + (1 - a) * b * quad[3]
    du = (1 - b) * (quad[1] - quad[0]) + b * (quad[2] - quad[3])
    dv = (1 - a) * (quad[3] - quad[0]) + a * (quad[2] - quad[1])
    return points, np.linalg.norm(np.cross(du, dv), axis=1) / n / n


def blocked(origin, seg):
    """Whether each segment origin -> origin + seg crosses a blocker's triangle."""
    hit = np.zeros(len(origin), bool)
    for p, q, r in blockers:
        e1, e2 = q - p, r - p
        pv = np.cross(seg, e2)
        det = pv @ e1
        with np.errstate(divide="ignore", invalid="ignore"):
            inv = 1.0 / det
            tv = origin - p
            u = np.sum(tv * pv, 1) * inv
            qv = np.cross(tv, e1)
            v = np.sum(seg * qv, 1) * inv
            t = (qv @ e2) * inv
        hit |= (np.abs(det) > 1e-12) & (u >= 0) & (v >= 0) & (u + v <= 1) & (t > 1e-6) & (t < 1 - 1e-6)
    return hit


n, m = int(sys.argv[1]), int(sys.argv[2])
xs, wx = grid(floor, n)
ys, wy = grid(lamp, m)
h = np.zeros(len(xs))
for y, w in zip(ys, wy):
    d = y - xs
    r2 = np.sum(d * d, 1)
    cos_x = np.maximum(d @ floor_normal, 0) / np.sqrt(r2)
    cos_y = np.maximum(-(d @ lamp_normal), 0) / np.sqrt(r2)
    lifted = xs + floor_normal * 1e-3
    h += cos_x * cos_y / r2 * w * ~blocked(lifted, y - lifted)
mean = (h * wx).sum() / wx.sum()
print("floor direct irradiance (W/m^2):", mean * radiance)

#!/usr/bin/env python3
"""Writes scenes/trimesh_room.glb: a glTF exported by trimesh (a third-party exporter, not
ours), to check that `radiosity` reads glTF written by other tools.

A closed 4 x 2.7 x 3 m room (walls facing inwards), a 1.2 x 0.75 x 0.8 m table and a
0.5 x 0.5 m ceiling panel with emissiveFactor (1, 1, 1) facing down, y up, metres. Node
names: room, table, lamp. Run: python3 make_trimesh_room.py OUT.glb (trimesh 4.x/5.x, numpy).
"""
import sys

import numpy as np
import trimesh
from trimesh.visual.material import PBRMaterial


def node(mesh, colour, emissive=(0.0, 0.0, 0.0)):
    mesh.visual = trimesh.visual.TextureVisuals(
        material=PBRMaterial(
            baseColorFactor=list(colour) + [1.0],
            emissiveFactor=list(emissive),
            metallicFactor=0.0,
            roughnessFactor=1.0,
        )
    )
    return mesh


room = trimesh.creation.box(extents=(4.0, 2.7, 3.0))
room.apply_translation((2.0, 1.35, 1.5))
room.invert()  # normals inwards: the walls are seen from inside
table = trimesh.creation.box(extents=(1.2, 0.75, 0.8))
table.apply_translation((2.0, 0.375, 1.5))
lamp = trimesh.Trimesh(
    vertices=np.array(
        [[1.75, 2.69, 1.25], [2.25, 2.69, 1.25], [2.25, 2.69, 1.75], [1.75, 2.69, 1.75]]
    ),
    faces=np.array([[0, 1, 2], [0, 2, 3]]),  # counter-clockwise seen from below
    process=False,
)
scene = trimesh.Scene()
scene.add_geometry(node(room, (0.7, 0.7, 0.7)), node_name="room", geom_name="room")
scene.add_geometry(node(table, (0.5, 0.35, 0.2)), node_name="table", geom_name="table")
scene.add_geometry(
    node(lamp, (0.8, 0.8, 0.8), (1.0, 1.0, 1.0)), node_name="lamp", geom_name="lamp"
)
out = sys.argv[1] if len(sys.argv) > 1 else "trimesh_room.glb"
scene.export(out)
print(out, "written by trimesh", trimesh.__version__)

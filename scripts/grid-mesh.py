#!/usr/bin/env python3
"""Write one grid mesh of N x N quads (2 N^2 triangles, with normals) as OBJ, ASCII PLY and
binary little-endian PLY, for BENCHMARKS.md's load-time comparison of the formats.

Usage: scripts/grid-mesh.py N OUT_STEM   (writes OUT_STEM.obj, OUT_STEM-ascii.ply, OUT_STEM.ply)
N = 707 gives 999698 triangles (the 1M-triangle class of the Stanford scans).
"""
import struct
import sys

n = int(sys.argv[1])
stem = sys.argv[2]
side = n + 1
verts = [(x / n, y / n, ((x * 7 + y * 13) % 17) / 170.0) for y in range(side) for x in range(side)]
faces = []
for y in range(n):
    for x in range(n):
        a = y * side + x
        faces.append((a, a + 1, a + side + 1))
        faces.append((a, a + side + 1, a + side))

with open(stem + ".obj", "w") as f:
    f.write("".join("v %r %r %r\n" % v for v in verts))
    f.write("".join("vn 0 0 1\n" for _ in verts))
    f.write("".join("f %d//%d %d//%d %d//%d\n" % (a + 1, a + 1, b + 1, b + 1, c + 1, c + 1) for a, b, c in faces))

header = (
    "ply\nformat %s 1.0\nelement vertex %d\nproperty float x\nproperty float y\nproperty float z\n"
    "property float nx\nproperty float ny\nproperty float nz\nelement face %d\n"
    "property list uchar int vertex_indices\nend_header\n"
)
with open(stem + "-ascii.ply", "w") as f:
    f.write(header % ("ascii", len(verts), len(faces)))
    f.write("".join("%r %r %r 0 0 1\n" % v for v in verts))
    f.write("".join("3 %d %d %d\n" % t for t in faces))
with open(stem + ".ply", "wb") as f:
    f.write((header % ("binary_little_endian", len(verts), len(faces))).encode())
    f.write(b"".join(struct.pack("<6f", *v, 0.0, 0.0, 1.0) for v in verts))
    f.write(b"".join(struct.pack("<B3i", 3, *t) for t in faces))

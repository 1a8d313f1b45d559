#!/usr/bin/env python3
"""Write a finely tessellated torus of about N triangles as OBJ (`v` and `f a b c` lines only,
vertices shared as a mesh tool writes them), for the big-mesh load benchmark (BENCHMARKS.md,
issue 18). The files are large (about 40 bytes a triangle): generate them, never commit them.

Usage: scripts/torus-mesh.py N OUT.obj   (N = 4000000 writes a 158 MB file of 4,000,000 triangles)
Needs numpy.
"""
import math
import sys

import numpy as np

n = int(sys.argv[1])
out = sys.argv[2]
# rings x segments quads, two triangles each; rings = 2 segments keeps triangles near square
# on a torus of radii 1 and 0.5.
seg = max(3, int(round(math.sqrt(n / 4))))
rings = max(3, n // (2 * seg))
u = np.arange(rings) * (2 * math.pi / rings)
v = np.arange(seg) * (2 * math.pi / seg)
uu, vv = np.meshgrid(u, v, indexing="ij")
r = 1.0 + 0.5 * np.cos(vv)
verts = np.stack([r * np.cos(uu), r * np.sin(uu), 0.5 * np.sin(vv)], axis=-1).reshape(-1, 3)
i = np.arange(rings)[:, None]
j = np.arange(seg)[None, :]
a = i * seg + j
b = ((i + 1) % rings) * seg + j
c = ((i + 1) % rings) * seg + (j + 1) % seg
d = i * seg + (j + 1) % seg
tris = np.concatenate([np.stack([a, b, c], -1).reshape(-1, 3), np.stack([a, c, d], -1).reshape(-1, 3)]) + 1
with open(out, "w") as f:
    f.write("# torus: %d vertices, %d triangles\n" % (len(verts), len(tris)))
    np.savetxt(f, verts, fmt="v %.6f %.6f %.6f")
    np.savetxt(f, tris, fmt="f %d %d %d")
print("%s: %d vertices, %d triangles" % (out, len(verts), len(tris)))

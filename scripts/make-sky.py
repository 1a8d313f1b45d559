#!/usr/bin/env python3
"""Write the README's environment map, docs/sky.hdr: a small procedural equirectangular sky
(256x128 Radiance RGBE, flat scanlines) in rayscope's convention (centre along -z, +y up).

A blue gradient above the horizon with a bright sun (radiance 40) up and to the right of the
centre, a checkered ground below (so reflections show the map's orientation), and a red band
on the ground at the map's centre (-z). Usage: scripts/make-sky.py [OUT.hdr]
"""
import math
import sys

W, H = 256, 128
SUN = (0.3, 0.45)  # azimuth (radians from -z towards +x) and elevation of the sun


def radiance(u, v):
    phi = (u - 0.5) * 2 * math.pi
    elev = (0.5 - v) * math.pi
    if elev > 0:
        t = min(1.0, elev / (math.pi / 2)) ** 0.5
        sky = [0.9 + (0.25 - 0.9) * t, 0.92 + (0.45 - 0.92) * t, 1.0 + (0.9 - 1.0) * t]
        # Angle to the sun.
        d = [math.cos(elev) * math.sin(phi), math.sin(elev), -math.cos(elev) * math.cos(phi)]
        s = [math.cos(SUN[1]) * math.sin(SUN[0]), math.sin(SUN[1]), -math.cos(SUN[1]) * math.cos(SUN[0])]
        cos = sum(a * b for a, b in zip(d, s))
        if cos > math.cos(math.radians(4)):
            return [40.0, 36.0, 28.0]
        glow = max(0.0, cos) ** 64 * 2.0
        return [c + glow for c in sky]
    if abs(phi) < math.radians(6):
        return [0.8, 0.1, 0.08]
    check = (int((phi + math.pi) / (math.pi / 8)) + int(-elev / (math.pi / 16))) % 2
    return [0.35, 0.3, 0.22] if check else [0.18, 0.16, 0.12]


def rgbe(c):
    m = max(c)
    if m < 1e-32:
        return bytes(4)
    e = math.frexp(m)[1]
    scale = 256.0 / 2.0**e
    return bytes([min(255, int(x * scale)) for x in c] + [e + 128])


def main():
    out = sys.argv[1] if len(sys.argv) > 1 else "docs/sky.hdr"
    data = bytearray(b"#?RADIANCE\nFORMAT=32-bit_rle_rgbe\n\n" + f"-Y {H} +X {W}\n".encode())
    for y in range(H):
        for x in range(W):
            data += rgbe(radiance((x + 0.5) / W, (y + 0.5) / H))
    with open(out, "wb") as f:
        f.write(data)


main()

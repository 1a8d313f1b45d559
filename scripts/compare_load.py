#!/usr/bin/env python3
"""Time loading a big OBJ mesh with rayscope and with Mitsuba 3, and measure peak memory.

    python3 scripts/compare_load.py [--triangles 4000000] [--rayscope target/release/rayscope]
                                    [--base OTHER_RAYSCOPE] [--runs 3] [--keep DIR]

Writes a tessellated torus of about N triangles as OBJ (`v x y z` with six decimals, `f a b c`;
into a temporary folder unless --keep DIR), then runs, alternately, `rayscope render FILE.obj
--width 64 --height 64` (load, BVH and a tiny render; its own load and BVH times, the process's
wall time and peak resident memory, from /usr/bin/time) and Mitsuba 3's `scalar_rgb` loading
the same file as an `obj` shape in a scene (`mi.load_dict`: parse and Embree's BVH; wall time
of the load inside the process, peak resident memory of the whole Python process). Prints the
fastest of --runs for each and the ratios ours / Mitsuba's. Needs `pip install mitsuba`.
"""

import argparse
import math
import os
import re
import subprocess
import sys
import tempfile

MITSUBA = r"""
import sys, time
import mitsuba as mi
mi.set_variant("scalar_rgb")
t0 = time.perf_counter()
scene = mi.load_dict({"type": "scene", "mesh": {"type": "obj", "filename": sys.argv[1]}})
print("load_ms", (time.perf_counter() - t0) * 1e3)
"""


def write_torus(triangles, path):
    """A torus of 2 * nu * nv triangles, nu = 2 nv, as near `triangles` as that allows."""
    nv = max(3, round(math.sqrt(triangles / 4)))
    nu = 2 * nv
    R, r = 1.0, 0.3
    with open(path, "w") as f:
        for i in range(nu):
            a = 2 * math.pi * i / nu
            ca, sa = math.cos(a), math.sin(a)
            f.write("".join(
                "v %.6f %.6f %.6f\n" % ((R + r * math.cos(b)) * ca, r * math.sin(b), (R + r * math.cos(b)) * sa)
                for b in (2 * math.pi * j / nv for j in range(nv))))
        for i in range(nu):
            i1 = (i + 1) % nu
            rows = []
            for j in range(nv):
                j1 = (j + 1) % nv
                a, b, c, d = i * nv + j + 1, i1 * nv + j + 1, i1 * nv + j1 + 1, i * nv + j1 + 1
                rows.append("f %d %d %d\nf %d %d %d\n" % (a, b, c, a, c, d))
            f.write("".join(rows))
    return 2 * nu * nv


def timed(cmd):
    """Run `cmd` under /usr/bin/time -v: its stdout+stderr, wall seconds, peak RSS in MB."""
    p = subprocess.run(["/usr/bin/time", "-v"] + cmd, capture_output=True, text=True)
    if p.returncode != 0:
        sys.exit(f"{' '.join(cmd)} failed:\n{p.stderr}")
    err = p.stderr
    rss = int(re.search(r"Maximum resident set size \(kbytes\): (\d+)", err).group(1)) / 1024
    w = re.search(r"Elapsed \(wall clock\) time \(h:mm:ss or m:ss\): (?:(\d+):)?(\d+):([\d.]+)", err)
    wall = int(w.group(1) or 0) * 3600 + int(w.group(2)) * 60 + float(w.group(3))
    return p.stdout + err, wall, rss


def run_rayscope(binary, obj, out):
    text, wall, rss = timed([binary, "render", obj, "--width", "64", "--height", "64", "-o", out])
    m = re.search(r"load ([\d.]+) ms, BVH ([\d.]+) ms", text)
    load, bvh = float(m.group(1)), float(m.group(2))
    return {"load+BVH (ms)": load + bvh, "BVH (ms)": bvh, "process (s)": wall, "peak RSS (MB)": rss}


def run_mitsuba(obj):
    text, wall, rss = timed([sys.executable, "-c", MITSUBA, obj])
    load = float(re.search(r"load_ms ([\d.]+)", text).group(1))
    # Embree's BVH is built inside the load.
    return {"load+BVH (ms)": load, "BVH (ms)": float("nan"), "process (s)": wall, "peak RSS (MB)": rss}


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--triangles", type=int, default=4_000_000)
    ap.add_argument("--rayscope", default="target/release/rayscope")
    ap.add_argument("--base", help="a second rayscope binary to time alongside")
    ap.add_argument("--runs", type=int, default=3, help="runs of each, alternating; the fastest counts")
    ap.add_argument("--keep", help="write the mesh into this folder and keep it")
    a = ap.parse_args()
    with tempfile.TemporaryDirectory() as work:
        folder = a.keep or work
        obj = os.path.join(folder, f"torus-{a.triangles}.obj")
        if os.path.exists(obj):
            n = sum(1 for line in open(obj) if line.startswith("f "))
        else:
            n = write_torus(a.triangles, obj)
        peers = [("rayscope", lambda: run_rayscope(a.rayscope, obj, os.path.join(work, "x.png")))]
        if a.base:
            peers.append(("rayscope (base)", lambda: run_rayscope(a.base, obj, os.path.join(work, "y.png"))))
        peers.append(("Mitsuba 3 (scalar_rgb)", lambda: run_mitsuba(obj)))
        best = {}
        for _ in range(a.runs):
            for name, fn in peers:
                r = fn()
                print(f"{name}: {r}", file=sys.stderr)
                old = best.get(name)
                best[name] = r if old is None or r["load+BVH (ms)"] < old["load+BVH (ms)"] else old
    size = os.path.getsize(obj) / 1e6 if a.keep else float("nan")
    theirs = best["Mitsuba 3 (scalar_rgb)"]
    print(f"Torus, {n} triangles ({size:.0f} MB OBJ), {os.cpu_count()} threads; fastest of {a.runs} alternating runs.\n")
    print("| loader | load + BVH (ms) | of which BVH (ms) | process wall (s) | peak RSS (MB) | bytes / triangle | load+BVH: ours / Mitsuba |")
    print("|---|---:|---:|---:|---:|---:|---:|")
    for name, r in best.items():
        ratio = r["load+BVH (ms)"] / theirs["load+BVH (ms)"]
        per = r["peak RSS (MB)"] * 1024 * 1024 / n
        print(f"| {name} | {r['load+BVH (ms)']:.0f} | {r['BVH (ms)']:.0f} | {r['process (s)']:.2f} | {r['peak RSS (MB)']:.0f} | {per:.0f} | {ratio:.2f} |")


if __name__ == "__main__":
    main()

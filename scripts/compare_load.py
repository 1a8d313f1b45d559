#!/usr/bin/env python3
"""Load a big OBJ mesh and build its BVH with rayscope and with Mitsuba 3 (Embree inside), and
print the times, the peak resident memory and the ratios ours/theirs (issue 18, goal 2).

    python3 scripts/compare_load.py [--triangles 1000000,4000000] [--rayscope target/release/rayscope]
        [--variants scalar_rgb,llvm_ad_rgb] [--runs 3] [--threads 2] [--dir /tmp/rayscope-load]

The meshes are tori of N triangles written as OBJ by scripts/torus-mesh.py (about 40 bytes a
triangle, kept in --dir between runs, never in the repository). Each measurement is a fresh
process, after one untimed run that brings the file into the page cache:

- rayscope: `rayscope render MESH --width 1 --height 1 --threads T`, whose line on stderr gives
  the load (read, parse, normals, placement) and the BVH build in ms; the peak resident set of
  the process by `/usr/bin/time -f %M` (the whole process: the mesh, the BVH and a 1x1 image).
- Mitsuba 3: a Python process that imports mitsuba, sets the variant, then times
  `mi.load_dict` of a scene holding the OBJ shape (Mitsuba's OBJ parser, its vertex
  deduplication and normals, and the Embree BVH build: Mitsuba builds the scene's
  acceleration structure in the load); the peak resident set by `/usr/bin/time -f %M`
  (Python and the JIT included), and the same process with an empty scene for the baseline.

Needs: a release build of rayscope, numpy, Mitsuba 3 (`pip install mitsuba` in a venv), and
for `llvm_ad_rgb` LLVM (Debian `libllvm19`: Mitsuba 3.9 aborts with 16; found through
DRJIT_LIBLLVM_PATH, set here when unset). Both are pinned by `taskset` to the same --threads cores (Mitsuba's thread pool
and Embree's build use what they find).
"""

import argparse
import os
import re
import statistics
import subprocess
import sys

HERE = os.path.dirname(os.path.abspath(__file__))
# Mitsuba 3.9's JIT needs LLVM newer than 16 (16 aborts: "Cannot select ... fminimum").
LLVM = next((p for p in ("/usr/lib/x86_64-linux-gnu/libLLVM-19.so", "/usr/lib/llvm-19/lib/libLLVM-19.so")
             if os.path.exists(p)), "libLLVM-19.so")

MITSUBA = r"""
import sys, time
import mitsuba as mi
mi.set_variant(sys.argv[1])
threads = int(sys.argv[3])
try:
    mi.set_log_level(mi.LogLevel.Warn)
except Exception:
    pass
scene = {"type": "scene"}
if sys.argv[2] != "-":
    scene["mesh"] = {"type": "obj", "filename": sys.argv[2]}
t = time.perf_counter()
s = mi.load_dict(scene)
elapsed = time.perf_counter() - t
print("MITSUBA_LOAD_S %.6f" % elapsed)
"""


def cores(threads):
    return ",".join(str(i) for i in range(threads))


def timed(cmd, env=None):
    """Run cmd under /usr/bin/time: (stdout+stderr text, peak RSS in MiB)."""
    out = subprocess.run(["/usr/bin/time", "-f", "PEAK_KIB %M"] + cmd, capture_output=True, text=True, env=env)
    text = out.stdout + out.stderr
    if out.returncode != 0:
        sys.exit("failed: %s\n%s" % (" ".join(cmd), text))
    kib = int(re.search(r"PEAK_KIB (\d+)", text).group(1))
    return text, kib / 1024.0


def rayscope_run(binary, mesh, threads):
    cmd = ["taskset", "-c", cores(threads), binary, "render", mesh, "--width", "1", "--height", "1",
           "--threads", str(threads), "-o", "/tmp/rayscope-load-1x1.png"]
    text, peak = timed(cmd)
    m = re.search(r"load ([0-9.]+) ms, BVH ([0-9.]+) ms", text)
    if not m:
        sys.exit("no load time in rayscope's output:\n" + text)
    return float(m.group(1)) / 1e3, float(m.group(2)) / 1e3, peak


def mitsuba_run(python, variant, mesh, threads):
    env = dict(os.environ)
    env.setdefault("DRJIT_LIBLLVM_PATH", LLVM)
    cmd = ["taskset", "-c", cores(threads), python, "-c", MITSUBA, variant, mesh, str(threads)]
    text, peak = timed(cmd, env)
    m = re.search(r"MITSUBA_LOAD_S ([0-9.]+)", text)
    if not m:
        sys.exit("no load time in Mitsuba's output:\n" + text)
    return float(m.group(1)), peak


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--triangles", default="1000000,4000000")
    ap.add_argument("--rayscope", default=os.path.join(HERE, "..", "target", "release", "rayscope"))
    ap.add_argument("--python", default=sys.executable, help="the Python that has mitsuba")
    ap.add_argument("--variants", default="scalar_rgb,llvm_ad_rgb")
    ap.add_argument("--runs", type=int, default=3)
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--dir", default="/tmp/rayscope-load")
    args = ap.parse_args()
    os.makedirs(args.dir, exist_ok=True)
    variants = [v for v in args.variants.split(",") if v]
    print("| triangles | renderer | load s | BVH s | load + BVH s (min of %d) | peak RSS MiB | bytes/triangle |" % args.runs)
    print("|---|---|---|---|---|---|---|")
    for n in (int(x) for x in args.triangles.split(",")):
        mesh = os.path.join(args.dir, "torus-%d.obj" % n)
        if not os.path.exists(mesh):
            subprocess.run([args.python, os.path.join(HERE, "torus-mesh.py"), str(n), mesh], check=True,
                           stdout=subprocess.DEVNULL)
        rayscope_run(args.rayscope, mesh, args.threads)  # the page cache, warm
        ours = [rayscope_run(args.rayscope, mesh, args.threads) for _ in range(args.runs)]
        best = min(ours, key=lambda r: r[0] + r[1])
        peak = max(r[2] for r in ours)
        print("| %d | rayscope | %.3f | %.3f | %.3f | %.0f | %.0f |" % (
            n, best[0], best[1], best[0] + best[1], peak, peak * 1048576 / n))
        for v in variants:
            mitsuba_run(args.python, v, mesh, args.threads)
            theirs = [mitsuba_run(args.python, v, mesh, args.threads) for _ in range(args.runs)]
            _, empty = mitsuba_run(args.python, v, "-", args.threads)
            t = min(r[0] for r in theirs)
            mpeak = max(r[1] for r in theirs)
            print("| %d | Mitsuba 3 %s | - | - | %.3f | %.0f (%.0f without the mesh) | %.0f |" % (
                n, v, t, mpeak, empty, (mpeak - empty) * 1048576 / n))
            print("| %d | ratio rayscope / %s | | | %.2f | %.2f | |" % (n, v, (best[0] + best[1]) / t, peak / mpeak))
        sys.stdout.flush()


if __name__ == "__main__":
    main()

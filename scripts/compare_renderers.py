#!/usr/bin/env python3
"""Render the course's dragon at 800x800, one sample per pixel, with rayscope, POV-Ray and
Mitsuba 3, and print the times (load, acceleration build, render) and the ratios ours/theirs.

    python3 scripts/compare_renderers.py [--assets ../shared/scenes] [--rayscope target/release/rayscope]

Needs: a release build of rayscope (`cargo build --release -p rayscope-cli`), POV-Ray
(Debian `povray`), Mitsuba 3 (`pip install mitsuba`, `scalar_rgb` variant, `direct`
integrator). A renderer that is missing is reported and skipped. Every renderer gets the
same scene: the dragon normalised as the course did (mean of its vertices at the origin,
scaled into the unit sphere), the default trackball camera (fov 50 vertical, distance 3,
rotation (20, 20, 0)), a white point light at (-1, 1, -1), grey diffuse, hard shadows, and
all cores.
"""

import argparse
import math
import os
import re
import shutil
import subprocess
import sys
import tempfile
import time


def load_obj(path):
    verts, faces = [], []
    with open(path) as f:
        for line in f:
            p = line.split()
            if not p:
                continue
            if p[0] == "v":
                verts.append(tuple(float(x) for x in p[1:4]))
            elif p[0] == "f":
                idx = [int(x.split("/")[0]) for x in p[1:]]
                idx = [i - 1 if i > 0 else len(verts) + i for i in idx]
                for k in range(1, len(idx) - 1):
                    faces.append((idx[0], idx[k], idx[k + 1]))
    n = len(verts)
    c = [sum(v[i] for v in verts) / n for i in range(3)]
    r = max(math.dist(v, c) for v in verts)
    return [tuple((v[i] - c[i]) / r for i in range(3)) for v in verts], faces


def camera():
    """The trackball camera's eye, forward and up (glm quat of Euler (20, 20, 0) degrees)."""
    ax, ay, az = (math.radians(a) for a in (20.0, 20.0, 0.0))

    def rot(v):
        x, y, z = v
        # Rz * Ry * Rx, x applied first.
        y, z = y * math.cos(ax) - z * math.sin(ax), y * math.sin(ax) + z * math.cos(ax)
        x, z = x * math.cos(ay) + z * math.sin(ay), -x * math.sin(ay) + z * math.cos(ay)
        x, y = x * math.cos(az) - y * math.sin(az), x * math.sin(az) + y * math.cos(az)
        return (x, y, z)

    return rot((0, 0, -3.0)), rot((0, 0, 1.0)), rot((0, 1.0, 0))


def run_rayscope(binary, assets):
    out = subprocess.run(
        # --repeat: the fastest of several renders in one process, as Mitsuba's are timed
        # (its later runs in this process render with warm caches and threads).
        [binary, "render", "dragon", "--assets", assets, "-o", os.path.join(tempfile.gettempdir(), "cmp-rayscope.png"),
         "--quiet", "--repeat", "5"],
        capture_output=True, text=True, check=True,
    ).stderr
    m = re.search(r"load ([\d.]+) ms, BVH ([\d.]+) ms .* render ([\d.]+) ms", out)
    return {"load": float(m.group(1)), "build": float(m.group(2)), "render": float(m.group(3))}


def run_povray(verts, faces, workdir):
    if not shutil.which("povray"):
        return None
    eye, fwd, up = camera()
    look = tuple(e + f for e, f in zip(eye, fwd))
    pov = os.path.join(workdir, "dragon.pov")
    with open(pov, "w") as f:
        f.write("#version 3.7;\nglobal_settings { assumed_gamma 1.0 max_trace_level 5 }\n")
        # `right -x`: a right-handed view like ours (POV-Ray is left-handed by default).
        f.write("camera { perspective location <%f,%f,%f> look_at <%f,%f,%f> sky <%f,%f,%f>\n" % (*eye, *look, *up))
        f.write("  up y right -x angle %f }\n" % 50.0)
        f.write("light_source { <-1,1,-1> color rgb 1 }\n")
        f.write("mesh2 { vertex_vectors { %d,\n" % len(verts))
        f.write(",\n".join("<%f,%f,%f>" % v for v in verts))
        f.write("}\n face_indices { %d,\n" % len(faces))
        f.write(",\n".join("<%d,%d,%d>" % t for t in faces))
        f.write("}\n texture { pigment { rgb 0.6 } finish { ambient 0 diffuse 1 phong 0 } } }\n")
    res = subprocess.run(
        ["povray", "+I" + pov, "+O" + os.path.join(workdir, "dragon-pov.png"), "+W800", "+H800", "-D", "-A", "+WT%d" % os.cpu_count(), "-V"],
        capture_output=True, text=True,
    )
    text = res.stderr + res.stdout
    def secs(label):
        m = re.search(label + r" Time:.*?\(\s*([\d.]+) seconds\)", text)
        return float(m.group(1)) * 1e3 if m else float("nan")
    # POV-Ray builds the mesh's own hierarchy while parsing it; "Bounding" is its scene-level
    # bounding, "Trace" the rendering.
    return {"load": secs("Parse"), "build": secs("Bounding"), "render": secs("Trace")}


def run_mitsuba(verts, faces, workdir):
    try:
        import mitsuba as mi
    except ImportError:
        return None
    mi.set_variant("scalar_rgb")
    obj = os.path.join(workdir, "dragon-normalised.obj")
    with open(obj, "w") as f:
        for v in verts:
            f.write("v %f %f %f\n" % v)
        for t in faces:
            f.write("f %d %d %d\n" % (t[0] + 1, t[1] + 1, t[2] + 1))
    eye, fwd, up = camera()
    target = tuple(e + d for e, d in zip(eye, fwd))
    t0 = time.perf_counter()
    scene = mi.load_dict({
        "type": "scene",
        "integrator": {"type": "direct", "emitter_samples": 1, "bsdf_samples": 0},
        "sensor": {
            "type": "perspective", "fov": 50.0, "fov_axis": "y",
            "to_world": mi.ScalarTransform4f().look_at(origin=list(eye), target=list(target), up=list(up)),
            "film": {"type": "hdrfilm", "width": 800, "height": 800, "rfilter": {"type": "box"}},
            "sampler": {"type": "independent", "sample_count": 1},
        },
        "dragon": {"type": "obj", "filename": obj, "bsdf": {"type": "diffuse", "reflectance": {"type": "rgb", "value": 0.6}}},
        "light": {"type": "point", "position": [-1.0, 1.0, -1.0], "intensity": {"type": "rgb", "value": 1.0}},
    })
    load = (time.perf_counter() - t0) * 1e3
    t0 = time.perf_counter()
    mi.render(scene, spp=1)
    render = (time.perf_counter() - t0) * 1e3
    # Mitsuba builds its acceleration structure while loading the scene.
    return {"load": load, "build": float("nan"), "render": render}


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--assets", default=os.environ.get("RAYSCOPE_ASSETS", "../shared/scenes"))
    ap.add_argument("--rayscope", default="target/release/rayscope")
    ap.add_argument("--runs", type=int, default=3, help="runs per renderer; the fastest counts")
    a = ap.parse_args()
    dragon = os.path.join(a.assets, "dragon.obj")
    if not os.path.isfile(dragon):
        sys.exit(f"{dragon}: not found; give --assets (the course's scene folder)")
    verts, faces = load_obj(dragon)
    results = {}
    with tempfile.TemporaryDirectory() as work:
        for name, fn in [("rayscope", lambda: run_rayscope(a.rayscope, a.assets)),
                         ("POV-Ray 3.7", lambda: run_povray(verts, faces, work)),
                         ("Mitsuba 3 (scalar_rgb, direct)", lambda: run_mitsuba(verts, faces, work))]:
            best = None
            for _ in range(a.runs):
                r = fn()
                if r is None:
                    break
                if best is None or r["render"] < best["render"]:
                    best = r
            results[name] = best
            print(f"{name}: {'not installed' if best is None else best}", file=sys.stderr)
    ours = results["rayscope"]
    fmt = lambda x: "–" if x != x else f"{x:.1f}"
    print(f"Dragon ({len(faces)} triangles), 800x800, 1 sample per pixel, {os.cpu_count()} threads; fastest of {a.runs} runs.\n")
    print("| renderer | load (ms) | acceleration build (ms) | render (ms) | render: ours / theirs |")
    print("|---|---:|---:|---:|---:|")
    for name, r in results.items():
        if r is None:
            print(f"| {name} | not installed | | | |")
            continue
        ratio = ours["render"] / r["render"]
        print(f"| {name} | {fmt(r['load'])} | {fmt(r['build'])} | {fmt(r['render'])} | {ratio:.2f} |")


if __name__ == "__main__":
    main()

#!/usr/bin/env python3
"""Render course scenes at 800x800, one sample per pixel, with rayscope, POV-Ray and Mitsuba 3
(its scalar and its vectorised LLVM variants), and print the times (load, acceleration build,
render) and the ratios ours/theirs.

    python3 scripts/compare_renderers.py [--assets ../shared/scenes] [--rayscope target/release/rayscope]
        [--scenes dragon,teapot,cornell-box] [--runs 5] [--threads N] [--only NAME,...] [--images DIR]

Needs: a release build of rayscope (`cargo build --release -p rayscope-cli`), POV-Ray
(Debian `povray`), Mitsuba 3 (`pip install mitsuba`) and, for its `llvm_ad_rgb` variant, an
LLVM shared library (Debian `libllvm19`; `DRJIT_LIBLLVM_PATH` names it, set here to
`/usr/lib/x86_64-linux-gnu/libLLVM-19.so` when that file exists and the variable is unset).
A renderer that is missing is reported and skipped.

Every renderer gets the same scene: rayscope exports it (`rayscope scenes --export NAME --format
obj`: its meshes in world space, placed and normalised as the course did, and a scene file with
the camera and the lights), the others read that OBJ, the exported trackball camera (by default
fov 50 vertical, distance 3, rotation (20, 20, 0)), the exported point lights, grey diffuse, hard
shadows, one sample at each pixel's centre, and `--threads` threads (default: all cores).
rayscope renders the course scene itself (each material's Phong shading, the teapot's texture,
mirror reflections): more work than the peers do. The row "rayscope, the peers' work" renders
the exported scene file instead with Lambert shading and no reflections or textures (the
materials' own diffuse colours, lights without distance falloff: the same cost as the peers'
grey Lambertian), and its column compares that with each peer.

Timing: rayscope's render is the fastest of `rayscope render --repeat RUNS` in one process (its
later renders run with warm caches and threads); Mitsuba's scene is loaded once per variant and
rendered once to warm up (the LLVM variant compiles its kernels then, or reads them from its
on-disk cache), then RUNS times in the same process, the fastest counting; POV-Ray, a process per
render, reports its own parse and trace times, the fastest of RUNS processes counting.

CPU time per render (user + system, all threads; the mean of the RUNS renders), beside the
wall-clock times, is steadier on a machine that other work is loading: Mitsuba's is measured in
its process around each render, ours as the CPU time of a process of RUNS + 1 renders less that
of a process of one render, over RUNS. POV-Ray's is not separated from its parsing.
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
import tomllib

# Debian's LLVM that Dr.Jit's LLVM backend runs on (`apt-get install libllvm19`). Dr.Jit reads
# the variable when it is imported, so it is set before the first import of mitsuba.
LIBLLVM = "/usr/lib/x86_64-linux-gnu/libLLVM-19.so"
if "DRJIT_LIBLLVM_PATH" not in os.environ and os.path.exists(LIBLLVM):
    os.environ["DRJIT_LIBLLVM_PATH"] = LIBLLVM

SIZE = 800


class Scene:
    """A scene as rayscope exported it: world-space triangles, camera and point lights."""

    def __init__(self, name, toml, obj, verts, faces, camera, lights):
        self.name = name
        self.toml = toml
        self.obj = obj
        self.verts = verts
        self.faces = faces
        self.camera = camera
        self.lights = lights


def load_obj(path):
    """The vertices and the fan-triangulated faces of an OBJ file."""
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
    return verts, faces


def trackball(desc):
    """A trackball camera's eye, forward and up, and its vertical fov (glm quat of Euler
    degrees: x applied first, then y, then z)."""
    look = desc.get("look_at", [0.0, 0.0, 0.0])
    ax, ay, az = (math.radians(a) for a in desc.get("rotation", [20.0, 20.0, 0.0]))

    def rot(v):
        x, y, z = v
        y, z = y * math.cos(ax) - z * math.sin(ax), y * math.sin(ax) + z * math.cos(ax)
        x, z = x * math.cos(ay) + z * math.sin(ay), -x * math.sin(ay) + z * math.cos(ay)
        x, y = x * math.cos(az) - y * math.sin(az), x * math.sin(az) + y * math.cos(az)
        return (x, y, z)

    back = rot((0.0, 0.0, -desc.get("distance", 3.0)))
    eye = tuple(l + b for l, b in zip(look, back))
    return {"eye": eye, "forward": rot((0.0, 0.0, 1.0)), "up": rot((0.0, 1.0, 0.0)), "fov": desc.get("fov", 50.0)}


def export_scene(binary, assets, name, workdir):
    """Scene `name` as rayscope exports it into `workdir`."""
    out = os.path.join(workdir, name)
    subprocess.run([binary, "scenes", "--export", name, "--format", "obj", out],
                   env=dict(os.environ, RAYSCOPE_ASSETS=assets), check=True, capture_output=True, text=True)
    toml = os.path.join(out, name + ".toml")
    with open(toml, "rb") as f:
        desc = tomllib.load(f)
    cam = desc.get("camera", {})
    if cam.get("kind", "trackball") != "trackball":
        sys.exit(f"{name}: only the trackball camera is compared here")
    lights = [l["position"] for l in desc.get("light", []) if l.get("kind") == "point"]
    if len(lights) != len(desc.get("light", [])):
        sys.exit(f"{name}: only point lights are compared here")
    obj = os.path.join(out, name + ".obj")
    verts, faces = load_obj(obj)
    return Scene(name, toml, obj, verts, faces, trackball(cam), lights)


def run_rayscope(binary, assets, scene, runs, threads, images, peers_work=False):
    """rayscope's course scene, or with `peers_work` the peers' work: the exported scene file
    (the OBJ the peers read) shaded Lambertian, without reflections or textures."""
    if peers_work:
        what, tag = [scene.toml, "--shading-model", "lambert", "--no-reflections", "--no-textures"], "-peers-work"
    else:
        what, tag = [scene.name], ""

    def render(repeat):
        before = os.times()
        err = subprocess.run(
            [binary, "render", *what, "--assets", assets, "--threads", str(threads),
             "-o", os.path.join(images or tempfile.gettempdir(), f"{scene.name}-rayscope{tag}.png"),
             "--quiet", "--repeat", str(repeat)],
            capture_output=True, text=True, check=True,
        ).stderr
        after = os.times()
        cpu = (after.children_user - before.children_user) + (after.children_system - before.children_system)
        return err, cpu

    out, _ = render(runs)
    m = re.search(r"load ([\d.]+) ms, BVH ([\d.]+) ms .* render ([\d.]+) ms", out)
    # CPU time of one render: a process of RUNS + 1 renders against one of a single render
    # (the same load, BVH build and image writing), over RUNS.
    _, one = render(1)
    _, more = render(runs + 1)
    cpu = max(more - one, 0.0) / runs * 1e3
    return {"load": float(m.group(1)), "build": float(m.group(2)), "render": float(m.group(3)), "cpu": cpu}


def run_povray(scene, workdir, runs, threads, images):
    if not shutil.which("povray"):
        return None
    c = scene.camera
    look = tuple(e + f for e, f in zip(c["eye"], c["forward"]))
    pov = os.path.join(workdir, scene.name + ".pov")
    with open(pov, "w") as f:
        f.write("#version 3.7;\nglobal_settings { assumed_gamma 1.0 max_trace_level 5 }\n")
        # `right -x`: a right-handed view like ours (POV-Ray is left-handed by default).
        f.write("camera { perspective location <%f,%f,%f> look_at <%f,%f,%f> sky <%f,%f,%f>\n"
                % (*c["eye"], *look, *c["up"]))
        f.write("  up y right -x angle %f }\n" % c["fov"])
        for p in scene.lights:
            f.write("light_source { <%f,%f,%f> color rgb 1 }\n" % tuple(p))
        f.write("mesh2 { vertex_vectors { %d,\n" % len(scene.verts))
        f.write(",\n".join("<%f,%f,%f>" % v for v in scene.verts))
        f.write("}\n face_indices { %d,\n" % len(scene.faces))
        f.write(",\n".join("<%d,%d,%d>" % t for t in scene.faces))
        f.write("}\n texture { pigment { rgb 0.6 } finish { ambient 0 diffuse 1 phong 0 } } }\n")
    png = os.path.join(images or workdir, f"{scene.name}-povray.png")
    best = None
    for _ in range(runs):
        # +A0 off (-A): one ray per pixel through its centre.
        res = subprocess.run(
            ["povray", "+I" + pov, "+O" + png, f"+W{SIZE}", f"+H{SIZE}", "-D", "-A", f"+WT{threads}", "-V"],
            capture_output=True, text=True,
        )
        text = res.stderr + res.stdout

        def secs(label):
            m = re.search(label + r" Time:.*?\(\s*([\d.]+) seconds\)", text)
            return float(m.group(1)) * 1e3 if m else float("nan")

        # POV-Ray builds the mesh's own hierarchy while parsing it; "Bounding" is its
        # scene-level bounding, "Trace" the rendering.
        r = {"load": secs("Parse"), "build": secs("Bounding"), "render": secs("Trace"), "cpu": float("nan")}
        if best is None or r["render"] < best["render"]:
            best = r
    return best


def run_mitsuba(variant, scene, runs, threads, images):
    """Mitsuba 3's `direct` integrator (one emitter sample, no BSDF sample), the scene loaded
    once, rendered once to warm up, then `runs` times; the fastest render counts."""
    try:
        import drjit as dr
        import mitsuba as mi
    except ImportError:
        return None
    try:
        mi.set_variant(variant)
    except Exception as e:  # the variant's backend is missing (no LLVM library found)
        print(f"Mitsuba 3 {variant}: {e}", file=sys.stderr)
        return None
    # Dr.Jit's thread pool (nanothread) runs both variants' render loops: N threads, the
    # calling one included.
    dr.set_thread_count(threads)
    c = scene.camera
    target = [e + d for e, d in zip(c["eye"], c["forward"])]
    desc = {
        "type": "scene",
        "integrator": {"type": "direct", "emitter_samples": 1, "bsdf_samples": 0},
        "sensor": {
            "type": "perspective", "fov": c["fov"], "fov_axis": "y",
            "to_world": mi.ScalarTransform4f().look_at(origin=list(c["eye"]), target=target, up=list(c["up"])),
            "film": {"type": "hdrfilm", "width": SIZE, "height": SIZE, "rfilter": {"type": "box"}},
            # Unjittered strata, one per pixel: the pixel's centre, as ours and POV-Ray's.
            "sampler": {"type": "stratified", "sample_count": 1, "jitter": False},
        },
        # Flat shading, as ours by default and POV-Ray's `mesh2` without normals.
        "mesh": {"type": "obj", "filename": scene.obj, "face_normals": True,
                 "bsdf": {"type": "diffuse", "reflectance": {"type": "rgb", "value": 0.6}}},
    }
    for i, p in enumerate(scene.lights):
        desc[f"light{i}"] = {"type": "point", "position": list(p), "intensity": {"type": "rgb", "value": 1.0}}
    t0 = time.perf_counter()
    mi_scene = mi.load_dict(desc)
    # Mitsuba builds its acceleration structure (Embree's) while loading the scene.
    load = (time.perf_counter() - t0) * 1e3

    def render():
        t0, c0 = time.perf_counter(), time.process_time()
        img = mi.render(mi_scene, spp=1)
        # The LLVM variant's result is lazy until evaluated: wait for the kernel to finish.
        dr.eval(img)
        dr.sync_thread()
        return img, (time.perf_counter() - t0) * 1e3, (time.process_time() - c0) * 1e3

    img, first, _ = render()
    times = [render()[1:] for _ in range(runs)]
    if images:
        mi.util.write_bitmap(os.path.join(images, f"{scene.name}-mitsuba-{variant}.png"), img)
    return {"load": load, "build": float("nan"), "render": min(t for t, _ in times),
            "cpu": sum(c for _, c in times) / runs, "first": first}


def libllvm_in_use():
    """The LLVM library this process loaded (Dr.Jit's), if any."""
    with open("/proc/self/maps") as f:
        libs = {line.split()[-1] for line in f if "libLLVM" in line}
    return ", ".join(sorted(libs)) or "none"


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--assets", default=os.environ.get("RAYSCOPE_ASSETS", "../shared/scenes"))
    ap.add_argument("--rayscope", default="target/release/rayscope")
    ap.add_argument("--scenes", default="dragon", help="comma-separated rayscope scene names")
    ap.add_argument("--runs", type=int, default=5, help="renders per renderer; the fastest counts")
    ap.add_argument("--threads", type=int, default=os.cpu_count(), help="threads of every renderer")
    ap.add_argument("--only", default="rayscope,rayscope-peers-work,povray,mitsuba-scalar,mitsuba-llvm",
                    help="comma-separated renderers (rayscope always runs: the ratios need it; "
                         "rayscope-peers-work is rayscope doing the peers' work)")
    ap.add_argument("--images", help="folder to keep each renderer's image in")
    a = ap.parse_args()
    only = set(a.only.split(","))
    if a.images:
        os.makedirs(a.images, exist_ok=True)
    peers = [
        ("povray", "POV-Ray 3.7", lambda s, w: run_povray(s, w, a.runs, a.threads, a.images)),
        ("mitsuba-scalar", "Mitsuba 3 (scalar_rgb, direct)",
         lambda s, w: run_mitsuba("scalar_rgb", s, a.runs, a.threads, a.images)),
        ("mitsuba-llvm", "Mitsuba 3 (llvm_ad_rgb, direct)",
         lambda s, w: run_mitsuba("llvm_ad_rgb", s, a.runs, a.threads, a.images)),
    ]
    print(f"{SIZE}x{SIZE}, 1 sample per pixel, {a.threads} threads; fastest of {a.runs} renders.\n")
    print("| scene | renderer | load (ms) | acceleration build (ms) | render (ms) | render: ours / theirs "
          "| render: ours doing their work / theirs | CPU ms per render | CPU: ours / theirs |")
    print("|---|---|---:|---:|---:|---:|---:|---:|---:|")
    fmt = lambda x: "–" if x != x else f"{x:.1f}"
    with tempfile.TemporaryDirectory() as work:
        for name in a.scenes.split(","):
            scene = export_scene(a.rayscope, a.assets, name, work)
            label = f"{name} ({len(scene.faces)} triangles)"
            ours = run_rayscope(a.rayscope, a.assets, scene, a.runs, a.threads, a.images)
            print(f"{label}: rayscope {ours}", file=sys.stderr)
            print(f"| {label} | rayscope | {fmt(ours['load'])} | {fmt(ours['build'])} | {fmt(ours['render'])} | 1.00 "
                  f"| | {fmt(ours['cpu'])} | 1.00 |")
            same = None
            if "rayscope-peers-work" in only:
                same = run_rayscope(a.rayscope, a.assets, scene, a.runs, a.threads, a.images, peers_work=True)
                print(f"{label}: rayscope, the peers' work {same}", file=sys.stderr)
                print(f"| {label} | rayscope, the peers' work (Lambert, no reflections, no textures) "
                      f"| {fmt(same['load'])} | {fmt(same['build'])} | {fmt(same['render'])} "
                      f"| {ours['render'] / same['render']:.2f} | 1.00 | {fmt(same['cpu'])} "
                      f"| {ours['cpu'] / same['cpu']:.2f} |", flush=True)
            for key, title, fn in peers:
                if key not in only:
                    continue
                r = fn(scene, work)
                print(f"{label}: {title}: {'not installed' if r is None else r}", file=sys.stderr)
                if r is None:
                    print(f"| {label} | {title} | not installed | | | | | | |")
                    continue
                ratio = ours["render"] / r["render"]
                same_ratio = f"{same['render'] / r['render']:.2f}" if same else "–"
                cpu = f"{ours['cpu'] / r['cpu']:.2f}" if r["cpu"] == r["cpu"] else "–"
                print(f"| {label} | {title} | {fmt(r['load'])} | {fmt(r['build'])} | {fmt(r['render'])} | {ratio:.2f} "
                      f"| {same_ratio} | {fmt(r['cpu'])} | {cpu} |", flush=True)
    if "mitsuba-llvm" in only:
        print(f"\nLLVM library loaded: {libllvm_in_use()}", file=sys.stderr)


if __name__ == "__main__":
    main()

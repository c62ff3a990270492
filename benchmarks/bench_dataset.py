"""Line-drawing datasets: views per second, workers, memory and the passes inside, each against
its anchor in the same run.

Meshes (generated here, written as PLY): a bumpy latitude-longitude sphere of ~10k triangles
(``uv_sphere(100, 51)``, radius ``1 + 0.1 sin 6x sin 6y sin 6z``) and of ~1M (``uv_sphere(1000,
501)``), each in the dataset's studio (:func:`mi_npr.dataset.scene_xml`), seen from
``sphere:N`` views at 256x256.

- **views/s, compute** (one process, all cores): depth, normals, ids and the lines
  (``mi_npr.kernels.lines``, 1 ray a pixel) of every view, per view (``render_gbuffer`` on each
  view's sensor: the anchor) against many views per launch (``render_views``, groups of
  :func:`mi_npr.render.views_per_launch`), and the launches with the lines' default
  anti-aliasing (``antialiased_lines``, ``line_aa`` 3); they alternate, median of ``--repeat``
  rounds.
- **views/s, files**: ``make_dataset(..., drawings=("lines",))`` in this process, every file and
  manifest row written: one view a launch with the studio's beauty (what a dataset did before
  launches; the anchor) against the defaults (launches, no beauty), with the lines' default
  anti-aliasing (``line_aa`` 3) and with ``line_aa`` 1.
- **Blender**: the same meshes and cameras (the manifest's), headless Cycles at 1 sample with
  Freestyle and the Z, normal and object-index passes in a multilayer EXR, the time of its render
  loop (start-up and import excluded; printed separately); skipped with the reason when
  ``blender`` is not on PATH.
- **2 workers against 1**: LocalClusters of 1 process with 1 Dr.Jit thread, of 1 with 2, and of
  2 with 1 thread each, warmed up, on dataset jobs of over a second each (the beauty at 256 spp,
  one view a job).
- **soak**: ``--soak N`` small jobs (16x16 views of a tetrahedron, lines) in a fresh process, in
  rounds of 100, the resident set size after each round: growth from the first round to the
  last, and the peak.
- **4K memory**: in a fresh process, the peak resident set size (minus the size before) of a
  3840x2160 G-buffer with its lines (``line_aa`` 1 and 3).
- **G-buffer pass** (``gbuffer_layers`` without shading: Z, P, N, ids) against Mitsuba's C++ ``aov``
  integrator (depth, shape_index, sh_normal; ``box`` filter, 1 spp) at 1920x1080, alternating,
  median; **line chain** (``kernels.lines(gb, id_edges=True, crease_angle=0)``) at 640x480 against
  the same chain in OpenCV (``bench_kernels.opencv_lines``), skipped without ``cv2``.

    python benchmarks/bench_dataset.py [--quick] [--repeat N] [--soak N] [--out DIR]

Prints each ratio (ours / anchor; for views/s, > 1 is faster; for times, < 1 is faster) and
writes ``bench_dataset.json``.
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

import _common
import numpy as np

HERE = Path(__file__).resolve().parent
RES = 256
MESHES = {"10k": (100, 51), "1M": (1000, 501)}


def _status_kb(key: str) -> int:
    for line in Path("/proc/self/status").read_text().splitlines():
        if line.startswith(key + ":"):
            return int(line.split()[1])
    raise KeyError(key)


def make_mesh(folder: Path, name: str) -> Path:
    """The bumpy sphere ``name`` of :data:`MESHES` as PLY in ``folder``."""
    from mi_npr.meshes import uv_sphere, write_ply

    path = folder / f"bumpy{name}.ply"
    if not path.exists():
        V, F = uv_sphere(*MESHES[name])
        V = V * (1 + 0.1 * np.sin(6 * V[:, :1]) * np.sin(6 * V[:, 1:2]) * np.sin(6 * V[:, 2:]))
        write_ply(path, V.astype(np.float32), F)
    return path


def studio(mesh: Path, work: Path) -> Any:
    """The mesh's studio scene, loaded at 256x256."""
    from mi_npr import dataset as D
    from mi_npr.session import SceneSession

    m = D.check_mesh(str(mesh), work)
    return SceneSession.open(str(D.write_scene(m, work)), resolution=(RES, RES))


def views_per_second(session: Any, n: int, repeat: int) -> dict[str, Any]:
    """Compute only: per view (anchor) against launches; lines at 1 ray a pixel."""
    import mi_npr
    from mi_npr.antialias import antialiased_lines
    from mi_npr.camera import sensor_for
    from mi_npr.render import render_gbuffer, render_views, views_per_launch
    from mi_npr.session import SceneSession
    from mi_npr.views import cameras, parse_views

    dr = mi_npr.dr
    cams = cameras(parse_views(f"sphere:{n}"), session.scene, session.sensor)
    sensors = [sensor_for(c, session.sensor) for _, c in cams]
    k = views_per_launch(RES, RES)

    def per_view() -> None:
        for s in sensors:
            gb = render_gbuffer(SceneSession(session.scene, s))
            dr.eval(mi_npr.kernels.lines(gb))
        dr.sync_thread()

    def launched() -> None:
        for a in range(0, len(sensors), k):
            for gb in render_views(session, sensors[a : a + k]):
                dr.eval(mi_npr.kernels.lines(gb))
        dr.sync_thread()

    def launched_aa3() -> None:
        for a in range(0, len(sensors), k):
            group = sensors[a : a + k]
            for s, gb in zip(group, render_views(session, group), strict=True):
                dr.eval(antialiased_lines(session.scene, s, gb, 3))
        dr.sync_thread()

    runs = (("per_view", per_view), ("launch", launched), ("launch_line_aa3", launched_aa3))
    times: dict[str, list[float]] = {name: [] for name, _ in runs}
    for _, fn in runs:  # compile
        fn()
    for _ in range(repeat):
        for name, fn in runs:
            t0 = time.perf_counter()
            fn()
            times[name].append(time.perf_counter() - t0)
    out = {name: n / statistics.median(t) for name, t in times.items()}
    return {
        "views": n,
        "views_per_launch": k,
        "per_view_views_s": out["per_view"],
        "launch_views_s": out["launch"],
        "launch_line_aa3_views_s": out["launch_line_aa3"],
        "ratio_launch_vs_per_view": out["launch"] / out["per_view"],
    }


def dataset_rate(mesh: Path, work: Path, n: int) -> dict[str, Any]:
    """Files and manifest included: before (one view a launch, beauty) against the defaults."""
    from mi_npr import dataset as D

    cases = {
        "before_per_view_beauty": {"views_per_launch": 1, "beauty": True},
        "after_defaults": {},
        "after_defaults_line_aa1": {"params": {"line_aa": 1}},
    }
    kw = {"width": RES, "height": RES, "workers": 0, "progress": False, "drawings": ("lines",)}
    out: dict[str, Any] = {"views": n}
    for name, extra in cases.items():
        D.make_dataset([mesh], work / f"warm_{name}", "sphere:2", **kw, **extra)
        target = work / f"ds_{name}"
        t0 = time.perf_counter()
        rows = D.make_dataset([mesh], target, f"sphere:{n}", **kw, **extra)
        seconds = time.perf_counter() - t0
        assert all(r["status"] == "done" for r in rows), rows
        out[f"{name}_views_s"] = n / seconds
        shutil.rmtree(target, ignore_errors=True)
    base = out["before_per_view_beauty_views_s"]
    for name in cases:
        out[f"ratio_{name}_vs_before"] = out[f"{name}_views_s"] / base
    return out


BLENDER_SCRIPT = r"""
import bpy, json, math, sys, time
from mathutils import Matrix, Vector
args = json.loads(sys.argv[sys.argv.index("--") + 1])
bpy.ops.wm.read_factory_settings(use_empty=True)
t0 = time.perf_counter()
bpy.ops.import_mesh.ply(filepath=args["mesh"])
obj = bpy.context.selected_objects[0]
c, s = Vector(args["centre"]), args["scale"]
obj.data.transform(Matrix.Translation(-c))
obj.data.transform(Matrix.Scale(s, 4))
obj.pass_index = 1
scene = bpy.context.scene
scene.render.engine = "CYCLES"
scene.cycles.samples = 1
scene.cycles.device = "CPU"
scene.cycles.use_denoising = False
scene.render.threads_mode = "FIXED"
scene.render.threads = args["threads"]
scene.render.use_persistent_data = True
scene.render.resolution_x = scene.render.resolution_y = args["res"]
scene.render.resolution_percentage = 100
scene.render.use_freestyle = True
layer = scene.view_layers[0]
layer.use_pass_z = layer.use_pass_normal = layer.use_pass_object_index = True
layer.freestyle_settings.as_render_pass = True
if not layer.freestyle_settings.linesets:
    layer.freestyle_settings.linesets.new("lines")
ink = bpy.data.linestyles.new("ink")
for lineset in layer.freestyle_settings.linesets:
    lineset.select_silhouette = lineset.select_border = lineset.select_crease = True
    lineset.linestyle = lineset.linestyle or ink
layer.freestyle_settings.crease_angle = math.radians(134.0)
world = bpy.data.worlds.new("studio")
world.color = (0.3, 0.3, 0.3)
scene.world = world
sun = bpy.data.objects.new("key", bpy.data.lights.new("key", type="SUN"))
sun.rotation_euler = Vector((1.0, 2.0, 1.5)).to_track_quat("Z", "Y").to_euler()
scene.collection.objects.link(sun)
scene.render.image_settings.file_format = "OPEN_EXR_MULTILAYER"
cam_data = bpy.data.cameras.new("cam")
cam_data.sensor_fit = "HORIZONTAL"
cam_data.angle = math.radians(args["fov"])
cam = bpy.data.objects.new("cam", cam_data)
scene.collection.objects.link(cam)
scene.camera = cam
load = time.perf_counter() - t0
t0 = time.perf_counter()
for i, (o, t, up) in enumerate(args["cameras"]):
    cam.location = Vector(o)
    d = Vector(t) - Vector(o)
    cam.rotation_euler = d.to_track_quat("-Z", "Y").to_euler()
    scene.render.filepath = f"{args['out']}/view_{i:03d}.exr"
    bpy.ops.render.render(write_still=True)
loop = time.perf_counter() - t0
print("BENCH " + json.dumps({"load_s": load, "loop_s": loop}))
"""


def blender_rate(mesh: Path, rows: list[dict[str, Any]], work: Path) -> dict[str, Any]:
    """Blender (Cycles + Freestyle) on the mesh from the cameras of ``rows``."""
    exe = shutil.which("blender")
    if exe is None:
        return {"skipped": "blender is not on PATH"}
    row = rows[0]
    cams = [(r["camera"]["origin"], r["camera"]["target"], r["camera"]["up"]) for r in rows]
    args = {
        "mesh": str(mesh),
        "centre": row["normalisation"]["centre"],
        "scale": row["normalisation"]["scale"],
        "cameras": cams,
        "fov": row["camera"]["fov"],
        "res": RES,
        "threads": os.cpu_count() or 2,
        "out": str(work / "blender"),
    }
    script = work / "blender_bench.py"
    script.write_text(BLENDER_SCRIPT)
    t0 = time.perf_counter()
    try:
        p = subprocess.run(
            [exe, "-b", "--factory-startup", "-P", str(script), "--", json.dumps(args)],
            capture_output=True,
            text=True,
            timeout=900,
        )
    except subprocess.TimeoutExpired:
        return {"skipped": "blender ran past 900 s"}
    wall = time.perf_counter() - t0
    lines = [x for x in p.stdout.splitlines() if x.startswith("BENCH ")]
    if p.returncode != 0 or not lines:
        tail = (p.stderr or p.stdout).strip().splitlines()[-3:]
        return {"skipped": f"blender failed (exit {p.returncode}): {' | '.join(tail)}"}
    got = json.loads(lines[-1][6:])
    return {
        "views": len(cams),
        "views_s": len(cams) / got["loop_s"],
        "load_s": got["load_s"],
        "process_s": wall,
    }


def workers_speedup(mesh: Path, work: Path, n: int) -> dict[str, Any]:
    """2 workers against 1 on jobs of over a second (the beauty at 256 spp, one view a job)."""
    from distributed import Client

    import mi_npr
    from mi_npr import dataset as D

    kw = {
        "width": RES,
        "height": RES,
        "spp": 256,
        "beauty": True,
        "views_per_launch": 1,
        "drawings": ("lines",),
        "progress": False,
    }
    out: dict[str, Any] = {"jobs": n}
    for workers, threads in ((1, 1), (1, 2), (2, 1)):
        with mi_npr.batch.local_cluster(workers) as cluster, Client(cluster) as client:
            name = f"workers{workers}x{threads}"
            D.make_dataset([mesh], work / f"warm_{name}", "orbit:2", client=client,
                           threads_per_worker=threads, **kw)  # fmt: skip
            t0 = time.perf_counter()
            rows = D.make_dataset([mesh], work / name, f"orbit:{n}", client=client,
                                  threads_per_worker=threads, **kw)  # fmt: skip
            seconds = time.perf_counter() - t0
        assert all(r["status"] == "done" for r in rows)
        job_s = [json.loads(x)["seconds"] for x in (work / name / "manifest.jsonl")
                 .read_text().splitlines()]  # fmt: skip
        out[f"{name}_s"] = seconds
        out[f"{name}_median_job_s"] = statistics.median(job_s)
    out["speedup_2x1_vs_1x1"] = out["workers1x1_s"] / out["workers2x1_s"]
    out["speedup_2x1_vs_1x2"] = out["workers1x2_s"] / out["workers2x1_s"]
    return out


def soak(work: Path, jobs: int) -> dict[str, Any]:
    """``jobs`` small jobs in rounds of 100: resident set size after each round."""
    from mi_npr import dataset as D

    mesh = work / "tet.obj"
    mesh.write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nf 1 3 2\nf 1 2 4\nf 1 4 3\nf 2 3 4\n")
    kw = {"width": 16, "height": 16, "workers": 0, "progress": False, "drawings": ("lines",)}
    rss, done, r = [], 0, 0
    t0 = time.perf_counter()
    while done < jobs:
        n = min(100, jobs - done)
        target = work / "soak"
        rows = D.make_dataset([mesh], target, f"random:{n}:{r}", **kw)
        assert all(x["status"] == "done" for x in rows)
        shutil.rmtree(target)
        done, r = done + n, r + 1
        rss.append(_status_kb("VmRSS") / 1024)
    first, last = rss[0], rss[-1]
    return {
        "jobs": jobs,
        "seconds": time.perf_counter() - t0,
        "rss_mb_first_round": first,
        "rss_mb_last_round": last,
        "rss_mb_max": max(rss),
        "peak_rss_mb": _status_kb("VmHWM") / 1024,
        "growth_first_to_last": last / first - 1.0,
    }


def _memory_child(mesh: str, work: str, w: int, h: int, aa: int) -> None:
    """In a fresh process: peak RSS of a G-buffer with its lines at w x h."""
    import mi_npr
    from mi_npr import dataset as D
    from mi_npr.antialias import antialiased_lines
    from mi_npr.render import render_views
    from mi_npr.session import SceneSession

    m = D.check_mesh(mesh, Path(work))
    s = SceneSession.open(str(D.write_scene(m, Path(work))), resolution=(w, h))
    Path("/proc/self/clear_refs").write_text("5")
    before = _status_kb("VmRSS")
    gb = render_views(s, [s.sensor])[0]
    ink = antialiased_lines(s.scene, s.sensor, gb, aa)
    mi_npr.dr.eval(ink)
    mi_npr.dr.sync_thread()
    peak = _status_kb("VmHWM")
    print(json.dumps({"peak_mb": (peak - before) / 1024, "rss_before_mb": before / 1024}))


def memory_4k(mesh: Path, work: Path) -> dict[str, Any]:
    out = {}
    for aa in (1, 3):
        p = subprocess.run(
            [sys.executable, __file__, "--memory-child", str(mesh), str(work), "3840", "2160",
             str(aa)],
            capture_output=True, text=True, check=True,
        )  # fmt: skip
        got = json.loads(p.stdout.strip().splitlines()[-1])
        out[f"line_aa{aa}_peak_mb"] = got["peak_mb"]
    out["goal_mb"] = 1024.0
    return out


def gbuffer_vs_aov(mesh: Path, work: Path, repeat: int) -> dict[str, Any]:
    import mi_npr
    from mi_npr import dataset as D
    from mi_npr.render import gbuffer_layers
    from mi_npr.session import SceneSession

    dr = mi_npr.dr
    w, h = 1920, 1080
    m = D.check_mesh(str(mesh), work)
    s = SceneSession.open(str(D.write_scene(m, work)), resolution=(w, h))
    aov = _common.aov_anchor(s.scene, w, h, box=True)

    def ours() -> None:
        dr.eval(*gbuffer_layers(s.scene, s.sensor, s.objects, shade=False).values())
        dr.sync_thread()

    return _alternate({"gbuffer_pass": ours, "aov_box": aov}, repeat, "gbuffer_pass", "aov_box")


def chain_vs_opencv(mesh: Path, work: Path, repeat: int) -> dict[str, Any]:
    try:
        import cv2  # noqa: F401  (the anchor needs it)
    except ImportError:
        return {"skipped": "cv2 is not installed"}
    import bench_kernels

    import mi_npr
    from mi_npr import dataset as D
    from mi_npr.render import render_gbuffer
    from mi_npr.session import SceneSession

    dr = mi_npr.dr
    m = D.check_mesh(str(mesh), work)
    s = SceneSession.open(str(D.write_scene(m, work)), resolution=(640, 480))
    gb = render_gbuffer(s)
    Z, ids = gb.numpy("Z").copy(), gb.numpy("object_id.V").copy()
    layers = {"Z": Z, "object_id.V": ids}

    def ours() -> None:
        dr.eval(mi_npr.kernels.lines(layers, id_edges=True, crease_angle=0))
        dr.sync_thread()

    out = _alternate(
        {"chain": ours, "opencv": lambda: bench_kernels.opencv_lines(Z, ids)},
        repeat,
        "chain",
        "opencv",
    )
    a = np.asarray(mi_npr.kernels.lines(layers, id_edges=True, crease_angle=0))
    out["outputs_agree"] = bool(np.allclose(a, bench_kernels.opencv_lines(Z, ids), atol=1e-6))
    return out


def _alternate(fns: dict[str, Any], repeat: int, ours: str, anchor: str) -> dict[str, Any]:
    times: dict[str, list[float]] = {k: [] for k in fns}
    for fn in fns.values():
        fn()
    for _ in range(repeat):
        for k, fn in fns.items():
            t0 = time.perf_counter()
            fn()
            times[k].append((time.perf_counter() - t0) * 1e3)
    out: dict[str, Any] = {f"{k}_ms": statistics.median(v) for k, v in times.items()}
    out[f"ratio_{ours}_vs_{anchor}"] = out[f"{ours}_ms"] / out[f"{anchor}_ms"]
    return out


def main() -> int:
    if "--soak-child" in sys.argv:  # a fresh process: nothing of the runs before it
        i = sys.argv.index("--soak-child")
        print(json.dumps(soak(Path(sys.argv[i + 1]), int(sys.argv[i + 2]))))
        return 0
    if "--memory-child" in sys.argv:
        i = sys.argv.index("--memory-child")
        mesh, work, w, h, aa = sys.argv[i + 1 : i + 6]
        _memory_child(mesh, work, int(w), int(h), int(aa))
        return 0
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=5)
    ap.add_argument("--quick", action="store_true", help="the 10k mesh only, fewer views")
    ap.add_argument("--soak", type=int, default=300, help="small jobs of the soak (default 300)")
    ap.add_argument("--out", type=Path, default=HERE / "results")
    args = ap.parse_args()

    import mi_npr
    from mi_npr import dataset as D

    results: dict[str, Any] = {}
    with tempfile.TemporaryDirectory() as tmp:
        work = Path(tmp)
        names = ["10k"] if args.quick else list(MESHES)
        for name in names:
            mesh = make_mesh(work, name)
            n = 16 if name == "1M" or args.quick else 32
            session = studio(mesh, work)
            r: dict[str, Any] = {"triangles": int(session.scene.shapes()[0].face_count())}
            r["compute"] = views_per_second(session, n, args.repeat)
            del session
            r["files"] = dataset_rate(mesh, work, n)
            rows = D.make_dataset(
                [mesh], work / f"cams_{name}", f"sphere:{min(n, 16)}", width=8, height=8,
                workers=0, progress=False, drawings=(),
            )  # fmt: skip
            r["blender"] = blender_rate(mesh, rows, work)
            if "views_s" in r["blender"]:
                r["ratio_files_after_vs_blender"] = (
                    r["files"]["after_defaults_views_s"] / r["blender"]["views_s"]
                )
            results[name] = r
            print(f"\n{name} mesh ({r['triangles']} triangles), {RES}x{RES}: views/s")
            c, f, b = r["compute"], r["files"], r["blender"]
            print(f"  compute per view {c['per_view_views_s']:8.1f}   launch "
                  f"{c['launch_views_s']:8.1f}   "
                  f"ratio {c['ratio_launch_vs_per_view']:.2f}   (line_aa 3: "
                  f"{c['launch_line_aa3_views_s']:.1f})")  # fmt: skip
            print(f"  files   before   {f['before_per_view_beauty_views_s']:8.1f}   after  "
                  f"{f['after_defaults_views_s']:8.1f}   ratio "
                  f"{f['ratio_after_defaults_vs_before']:.2f}   (line_aa 1: "
                  f"{f['after_defaults_line_aa1_views_s']:.1f})")  # fmt: skip
            print("  blender " + (f"{b['views_s']:8.2f} (load {b['load_s']:.1f} s); ours/blender "
                  f"{r['ratio_files_after_vs_blender']:.1f}" if "views_s" in b else
                  f"skipped: {b['skipped']}"))  # fmt: skip
        mesh10k = make_mesh(work, "10k")
        if not args.quick:
            results["workers"] = workers_speedup(mesh10k, work, 8)
            wk = results["workers"]
            print(f"\n2 workers (1 thread each) vs 1 worker "
                  f"(jobs ~{wk['workers1x1_median_job_s']:.2f} s): "
                  f"{wk['speedup_2x1_vs_1x1']:.2f}x against 1 thread, "
                  f"{wk['speedup_2x1_vs_1x2']:.2f}x against 2 threads")  # fmt: skip
        p = subprocess.run(
            [sys.executable, __file__, "--soak-child", str(work), str(args.soak)],
            capture_output=True, text=True, check=True,
        )  # fmt: skip
        results["soak"] = json.loads(p.stdout.strip().splitlines()[-1])
        s = results["soak"]
        print(f"\nsoak {s['jobs']} jobs: RSS {s['rss_mb_first_round']:.0f} -> "
              f"{s['rss_mb_last_round']:.0f} MB ({100 * s['growth_first_to_last']:+.1f}%), "
              f"peak {s['peak_rss_mb']:.0f} MB")  # fmt: skip
        results["memory_4k"] = memory_4k(mesh10k, work)
        print(f"4K G-buffer + lines peak: line_aa 1 {results['memory_4k']['line_aa1_peak_mb']:.0f}"
              f" MB, line_aa 3 {results['memory_4k']['line_aa3_peak_mb']:.0f} MB")  # fmt: skip
        results["gbuffer_1920x1080"] = gbuffer_vs_aov(mesh10k, work, args.repeat)
        g = results["gbuffer_1920x1080"]
        print(
            f"G-buffer pass 1920x1080 {g['gbuffer_pass_ms']:.1f} ms, aov (box) "
            f"{g['aov_box_ms']:.1f} ms: ratio {g['ratio_gbuffer_pass_vs_aov_box']:.2f}"
        )
        results["chain_640x480"] = chain_vs_opencv(mesh10k, work, 3 * args.repeat)
        c = results["chain_640x480"]
        if "skipped" in c:
            print(f"line chain vs OpenCV: skipped: {c['skipped']}")
        else:
            print(f"line chain 640x480 {c['chain_ms']:.2f} ms, OpenCV {c['opencv_ms']:.2f} ms: "
                  f"ratio {c['ratio_chain_vs_opencv']:.2f} "
                  f"(agree: {c['outputs_agree']})")  # fmt: skip
    path = _common.write_report(
        "bench_dataset",
        args.out,
        resolution=[RES, RES],
        threads=int(mi_npr.dr.thread_count()),
        results=results,
    )
    print(f"\nwrote {path}")
    return 0


if __name__ == "__main__":
    sys.exit(main())

"""Strokes against Blender Freestyle's SVG export, on the tutorials' Lego model and Cornell box.

Both tools draw the same triangles from the same camera at 640 x 480: the scene is loaded with
Mitsuba (``mi_npr.load_scene``, the tutorials' own ``scene.xml``/``cbox.xml``), every mesh is
written in world space to one OBJ (one ``o`` group per shape; spheres as 96 x 48 UV spheres),
and Blender (Debian's ``blender``, headless) imports that OBJ, looks through the sensor's
``lookat`` and horizontal field of view, and runs Freestyle with the SVG exporter add-on
(``render_freestyle_svg``): visible silhouette, border and crease lines (134 degrees, the
strokes' default), 1 px.

Ours: :func:`mi_npr.strokes.drawing.draw_strokes` with the ``technical`` style and ``max_qi``
0, the visible strokes only (QI 0 and seen through glass), which is what Freestyle's lineset
draws; the drawing's default (``max_qi`` 1, hidden lines dashed) is timed beside it.

Measures:

- **ink agreement**, on the vector lines themselves: both drawings' visible polylines are
  sampled every 0.25 px; ``found`` is the share (by length) of Freestyle's ink with ours within
  1.5 px, ``on_freestyle`` the share of ours with Freestyle's within 1.5 px (goal: both >= 95%);
  the same on the rasters (coverage > 0.5) is stored beside it;
- **strokes**: how many, and their mean length in pixels (goal: fewer and longer than
  Freestyle's), counted over every visible stroke and over the kinds Freestyle draws (all but
  ``intersection``: Freestyle has no intersection lines; the goal is judged on these);
- **time**: our stroke step (extract, style, rasterise; warm median of ``--repeat`` runs, and the
  extraction alone) against Freestyle's line pass, the sum of its own stage timers printed with
  ``--debug-freestyle`` (goal on Lego: at most 1/100, <= 0.4 s);
- **memory**: our process's peak RSS (the scene loaded included) and its rise over the stroke
  step alone (goal <= 1 GB); Blender's peak RSS;
- **SVG size**: ours (visible strokes) against Freestyle's (goal: no larger).

The tutorials come from ``--tutorials DIR`` (a clone of mitsuba-renderer/mitsuba-tutorials;
default ``$MI_NPR_TUTORIALS``). Where Blender or the tutorials are missing, or a large file of
the tutorials is absent (Git LFS), the case is skipped with a message, exit code 0, and a JSON
that says why.

    python benchmarks/bench_strokes.py --tutorials DIR [--quick] [--repeat N] [--out DIR]

Writes ``bench_strokes.json`` and, per scene, ``bench_strokes_<scene>.png`` (Freestyle | ours)
and both SVGs.
"""

from __future__ import annotations

import argparse
import json
import os
import re
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import _common
import numpy as np
from bench_drawing import (
    FREESTYLE_SCENE,
    blender_available,
    camera_matrix,
    freestyle_stages,
    side_by_side,
)

HERE = Path(__file__).resolve().parent
W, H = 640, 480
CREASE = 134.0
TOLERANCE = 1.5
GOALS = {
    "found": 0.95,
    "on_freestyle": 0.95,
    "time_ratio": 0.01,
    "stroke_s": 0.4,
    "peak_gb": 1.0,
    "svg_ratio": 1.0,
}
SCENES = {"lego": "scenes/lego/scene.xml", "cbox": "scenes/cbox.xml"}

# ------------------------------------------------------------------ the scene as one OBJ


def uv_sphere(center: np.ndarray, radius: float, nu: int = 96, nv: int = 48):
    """Vertices and faces of a UV sphere (poles as single vertices)."""
    th = np.linspace(0, np.pi, nv + 1)[1:-1]
    ph = np.linspace(0, 2 * np.pi, nu, endpoint=False)
    t, p = np.meshgrid(th, ph, indexing="ij")
    ring = np.stack([np.sin(t) * np.cos(p), np.cos(t), np.sin(t) * np.sin(p)], -1).reshape(-1, 3)
    v = np.concatenate([[[0, 1, 0]], ring, [[0, -1, 0]]]) * radius + center
    faces = []
    idx = np.arange(ring.shape[0]).reshape(nv - 1, nu) + 1
    nxt = np.roll(idx, -1, axis=1)
    faces.append(np.stack([np.zeros(nu, int), nxt[0], idx[0]], -1))
    a, b, c, d = idx[:-1], nxt[:-1], nxt[1:], idx[1:]
    faces.append(np.stack([a, b, c], -1).reshape(-1, 3))
    faces.append(np.stack([a, c, d], -1).reshape(-1, 3))
    last = len(v) - 1
    faces.append(np.stack([np.full(nu, last), idx[-1], nxt[-1]], -1))
    return v, np.concatenate(faces)


def scene_obj(scene, path: Path) -> dict:
    """Every shape of ``scene`` in world space into one OBJ; what was written and left out."""
    written, left = [], []
    base = 1
    with open(path, "w") as f:
        for i, shape in enumerate(scene.shapes()):
            name = re.sub(r"\W", "_", shape.id() or f"shape_{i}")
            if shape.is_mesh():
                v = np.asarray(shape.vertex_positions_buffer(), np.float64).reshape(-1, 3)
                fc = np.asarray(shape.faces_buffer(), np.int64).reshape(-1, 3)
            elif shape.class_name() == "Sphere":
                bb = shape.bbox()
                lo, hi = np.asarray(bb.min, np.float64), np.asarray(bb.max, np.float64)
                v, fc = uv_sphere((lo + hi) / 2, float((hi - lo).max() / 2))
            else:
                left.append(f"{name} ({shape.class_name()})")
                continue
            f.write(f"o {name}\n")
            f.write(("v %.6f %.6f %.6f\n" * len(v)) % tuple(v.ravel()))
            f.write(("f %d %d %d\n" * len(fc)) % tuple((fc + base).ravel()))
            base += len(v)
            written.append(name)
    return {"objects": written, "left_out": left}


# ------------------------------------------------------------------ Freestyle

BLENDER_SCRIPT = (
    FREESTYLE_SCENE
    + r"""
addon_utils.enable("render_freestyle_svg", default_set=True)
scene.svg_export.use_svg_export = True
scene.svg_export.mode = "FRAME"
r.use_freestyle = True
r.filepath = cfg["png"]
t0 = time.perf_counter()
bpy.ops.render.render(write_still=True)
json.dump({"render_s": time.perf_counter() - t0}, open(cfg["times"], "w"))
"""
)


def run_blender(exe: str, obj: Path, cam: dict, work: Path, threads: int) -> dict:
    """Freestyle's SVG (path), its PNG's alpha, stage timers and Blender's peak RSS."""
    from PIL import Image

    script, cfg = work / "freestyle.py", work / "freestyle.json"
    script.write_text(BLENDER_SCRIPT)
    png, times = work / "freestyle_", work / "times.json"
    cfg.write_text(
        json.dumps(
            {
                "obj": str(obj),
                "fov": cam["fov"],
                "near": cam["near"],
                "far": cam["far"],
                "matrix": camera_matrix(cam),
                "w": W,
                "h": H,
                "png": str(png),
                "times": str(times),
                "threads": threads,
                "crease": CREASE,
            }
        )
    )
    cmd = [exe, "-b", "--factory-startup", "--debug-freestyle", "--python", str(script)]
    log = work / "blender.log"
    with open(log, "w") as out:
        proc = subprocess.Popen([*cmd, "--", str(cfg)], stdout=out, stderr=subprocess.STDOUT)
        _, status, usage = os.wait4(proc.pid, 0)
    proc.returncode = os.waitstatus_to_exitcode(status)
    text = log.read_text(errors="replace")
    pngs, svgs = sorted(work.glob("freestyle_*.png")), sorted(work.glob("freestyle_*.svg"))
    if proc.returncode != 0 or not pngs or not svgs:
        tail = text.strip().splitlines()[-5:]
        raise RuntimeError("blender failed: " + " | ".join(tail))
    alpha = np.asarray(Image.open(pngs[0]).convert("RGBA"), np.float32)[..., 3] / 255.0
    return {
        "svg": svgs[0],
        "alpha": alpha,
        "stages": freestyle_stages(text),
        "peak_rss_mb": usage.ru_maxrss / 1024,
        **json.loads(times.read_text()),
    }


_NUM = re.compile(r"-?\d+(?:\.\d+)?(?:[eE][-+]?\d+)?")


def freestyle_polylines(svg: Path) -> list[np.ndarray]:
    """The polylines of the exporter's ``<path d="M x, y x, y ...">`` elements (pixels, y down)."""
    out = []
    for d in re.findall(r'\sd="([^"]*)"', svg.read_text()):
        xy = np.array([float(v) for v in _NUM.findall(d)], np.float64)
        if len(xy) >= 4:
            out.append(xy[: len(xy) // 2 * 2].reshape(-1, 2))
    return out


# ------------------------------------------------------------------ ours

OURS = r"""
import json, resource, statistics, sys, time
cfg = json.loads(sys.argv[1])
import mi_npr
from mi_npr.io.strokes import stroke_svg
from mi_npr.scene import object_table
from mi_npr.strokes.drawing import STROKES_PARAMS, draw_strokes
from mi_npr.strokes.extract import extract_strokes

def rss_mb():
    with open("/proc/self/status") as f:
        for line in f:
            if line.startswith("VmRSS:"):
                return int(line.split()[1]) / 1024

scene = mi_npr.load_scene(cfg["xml"], width=cfg["w"], height=cfg["h"])
sensor = scene.sensors()[0]
table = object_table(scene)
params = {p.name: p.default for p in STROKES_PARAMS}
# what Freestyle's lineset draws: the visible lines (max_qi 0 casts no ray past the first hit)
params.update(style="technical", hidden=False, crease_angle=cfg["crease"], max_qi=0)
hidden = dict(params, hidden=True, max_qi=1)  # the drawing's default: hidden lines too
before = rss_mb()
t0 = time.perf_counter()
drawing = draw_strokes(scene, sensor, table, params)
cold = time.perf_counter() - t0
peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
warm, extract, with_hidden = [], [], []
for _ in range(cfg["repeat"]):
    t0 = time.perf_counter()
    draw_strokes(scene, sensor, table, params)
    warm.append(time.perf_counter() - t0)
    t0 = time.perf_counter()
    extract_strokes(scene, sensor, table, crease_angle=cfg["crease"], max_qi=0)
    extract.append(time.perf_counter() - t0)
    t0 = time.perf_counter()
    n_hidden = len(draw_strokes(scene, sensor, table, hidden).strokes)
    with_hidden.append(time.perf_counter() - t0)
peak_hidden = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
st = drawing.strokes
visible = [s for s in st if s.qi == 0]
open(cfg["svg"], "w").write(stroke_svg(drawing))
import numpy as np
np.save(cfg["alpha"], drawing.alpha)
json.dump({
    "polylines": [np.concatenate([s.points, s.points[:1]]).tolist() if s.closed
                  else s.points.tolist() for s in visible],
    "polyline_kinds": [s.kind for s in visible],
    "kinds": {k: sum(1 for s in visible if s.kind == k) for k in sorted({s.kind for s in st})},
    "strokes_all": len(st), "strokes_visible": len(visible),
    "cold_s": cold, "warm_s": statistics.median(warm) if warm else cold,
    "extract_s": statistics.median(extract) if extract else None,
    "with_hidden_s": statistics.median(with_hidden) if with_hidden else None,
    "strokes_with_hidden": n_hidden if with_hidden else None,
    "peak_with_hidden_mb": peak_hidden,
    "rss_before_mb": before, "peak_rss_mb": peak,
    "peak_after_repeats_mb": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024,
    "variant": mi_npr.mi.variant(),
}, open(cfg["result"], "w"))
"""


def run_ours(xml: Path, work: Path, repeat: int) -> dict:
    """Our strokes in a fresh process (so that its peak RSS is the stroke step's own)."""
    cfg = {
        "xml": str(xml),
        "w": W,
        "h": H,
        "crease": CREASE,
        "repeat": repeat,
        "svg": str(work / "ours_strokes.svg"),
        "alpha": str(work / "ours_alpha.npy"),
        "result": str(work / "ours.json"),
    }
    proc = subprocess.run(
        [sys.executable, "-c", OURS, json.dumps(cfg)], capture_output=True, text=True
    )
    if proc.returncode != 0:
        tail = (proc.stdout + proc.stderr).strip().splitlines()[-3:]
        raise RuntimeError("mi-npr failed: " + " | ".join(tail))
    out = json.loads((work / "ours.json").read_text())
    out["polylines"] = [np.asarray(p, np.float64) for p in out["polylines"]]
    kinds = out["polyline_kinds"]
    out["freestyle_kinds"] = [
        p for p, k in zip(out["polylines"], kinds, strict=True) if k != "intersection"
    ]
    out["alpha"] = np.load(work / "ours_alpha.npy")
    out["svg"] = work / "ours_strokes.svg"
    return out


# ------------------------------------------------------------------ measures


def samples(polylines: list[np.ndarray], step: float = 0.25) -> np.ndarray:
    """Points every ``step`` px along each polyline (the ends included)."""
    pts = [np.zeros((0, 2))]
    for p in polylines:
        if len(p) < 2:
            continue
        seg = np.diff(p, axis=0)
        n = np.maximum(np.ceil(np.hypot(*seg.T) / step).astype(int), 1)
        t = np.concatenate([np.arange(k) / k for k in n])
        i = np.repeat(np.arange(len(seg)), n)
        pts.append(p[i] + seg[i] * t[:, None])
        pts.append(p[-1:])
    return np.concatenate(pts)


def inside(pts: np.ndarray) -> np.ndarray:
    return pts[(pts[:, 0] >= 0) & (pts[:, 0] <= W) & (pts[:, 1] >= 0) & (pts[:, 1] <= H)]


def vector_agreement(theirs: list[np.ndarray], mine: list[np.ndarray]) -> dict:
    """Shares of each drawing's ink (sampled along its polylines) within TOLERANCE px of the
    other's, and the best constant offset between them (a half-pixel convention shows here)."""
    from scipy.spatial import cKDTree

    a, b = inside(samples(theirs)), inside(samples(mine))
    if not len(a) or not len(b):
        return {"found": None, "on_freestyle": None}
    da, ia = cKDTree(b).query(a)
    db, _ = cKDTree(a).query(b)
    close = da <= TOLERANCE
    offset = (b[ia[close]] - a[close]).mean(axis=0) if close.any() else np.zeros(2)
    return {
        "found": float((da <= TOLERANCE).mean()),
        "on_freestyle": float((db <= TOLERANCE).mean()),
        "median_distance_px": float(np.median(np.concatenate([da, db]))),
        "mean_offset_px": [round(float(v), 3) for v in offset],
    }


def raster_agreement(ref: np.ndarray, mine: np.ndarray) -> dict:
    from scipy.ndimage import distance_transform_edt

    f, o = ref > 0.5, mine > 0.5
    if not f.any() or not o.any():
        return {"found": None, "on_freestyle": None}
    to_o, to_f = distance_transform_edt(~o), distance_transform_edt(~f)
    return {
        "found": float((to_o[f] <= TOLERANCE).mean()),
        "on_freestyle": float((to_f[o] <= TOLERANCE).mean()),
    }


def stroke_stats(polylines: list[np.ndarray]) -> dict:
    lengths = [float(np.hypot(*np.diff(p, axis=0).T).sum()) for p in polylines if len(p) > 1]
    return {
        "strokes": len(polylines),
        "mean_length_px": float(np.mean(lengths)) if lengths else 0.0,
        "total_length_px": float(np.sum(lengths)),
    }


def sensor_camera(xml: Path) -> dict:
    """The scene camera's lookat, horizontal fov and clip planes at W x H."""
    import mi_npr
    from mi_npr.camera.sensor import projection_of

    scene = mi_npr.load_scene(xml, width=W, height=H)
    p = projection_of(scene.sensors()[0])
    cam = {
        "origin": p.origin.tolist(),
        "target": (p.origin + p.forward).tolist(),
        "up": p.up.tolist(),
        "fov": float(p.fov),
        "near": float(p.near_clip),
        "far": float(p.far_clip),
    }
    return cam, scene


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--tutorials", type=Path, default=os.environ.get("MI_NPR_TUTORIALS") or None)
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--quick", action="store_true", help="the Cornell box only, 1 repeat")
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--no-install", action="store_true", help="do not try apt-get")
    ap.add_argument("--out", type=Path, default=HERE / "results")
    args = ap.parse_args()

    exe, why = blender_available(not args.no_install)
    if exe is None:
        return _common.skipped("bench_strokes", args.out, why)
    if args.tutorials is None or not Path(args.tutorials).is_dir():
        return _common.skipped(
            "bench_strokes",
            args.out,
            "no mitsuba-tutorials clone: pass --tutorials DIR or set MI_NPR_TUTORIALS",
        )
    version = subprocess.run([exe, "--version"], capture_output=True, text=True).stdout
    cases = {"cbox": SCENES["cbox"]} if args.quick else SCENES
    repeat = 1 if args.quick else args.repeat
    results = {}
    args.out.mkdir(parents=True, exist_ok=True)
    for name, rel in cases.items():
        xml = Path(args.tutorials) / rel
        with tempfile.TemporaryDirectory() as tmp:
            work = Path(tmp)
            try:
                cam, scene = sensor_camera(xml)
                obj = work / f"{name}.obj"
                written = scene_obj(scene, obj)
                del scene
                theirs = run_blender(exe, obj, cam, work, args.threads)
                mine = run_ours(xml, work, repeat)
            except Exception as e:  # a missing LFS file, a Blender or mi-npr failure: say so
                print(f"bench_strokes: {name}: skipped: {type(e).__name__}: {e}")
                results[name] = {"skipped": f"{type(e).__name__}: {e}"}
                continue
            fs_polys = freestyle_polylines(theirs["svg"])
            fs_s = sum(theirs["stages"].values())
            svg_sizes = (theirs["svg"].stat().st_size, mine["svg"].stat().st_size)
            for src, dst in ((theirs["svg"], "freestyle"), (mine["svg"], "ours")):
                (args.out / f"bench_strokes_{name}_{dst}.svg").write_bytes(src.read_bytes())
        row = {
            "camera": cam,
            "obj": written,
            "vector": vector_agreement(fs_polys, mine["polylines"]),
            "raster": raster_agreement(theirs["alpha"], mine["alpha"]),
            "freestyle": {
                **stroke_stats(fs_polys),
                "line_pass_s": fs_s,
                "stages_s": theirs["stages"],
                "render_s": theirs["render_s"],
                "peak_rss_mb": theirs["peak_rss_mb"],
                "svg_bytes": svg_sizes[0],
            },
            "ours": {
                **stroke_stats(mine["polylines"]),
                "freestyle_kinds": stroke_stats(mine["freestyle_kinds"]),
                "kinds_visible": mine["kinds"],
                "strokes_with_hidden": mine["strokes_with_hidden"],
                "stroke_step_with_hidden_s": mine["with_hidden_s"],
                "peak_rss_with_hidden_mb": mine["peak_with_hidden_mb"],
                "stroke_step_s": mine["warm_s"],
                "stroke_step_cold_s": mine["cold_s"],
                "extract_s": mine["extract_s"],
                "peak_rss_mb": mine["peak_rss_mb"],
                "rss_rise_mb": mine["peak_rss_mb"] - mine["rss_before_mb"],
                "svg_bytes": svg_sizes[1],
                "variant": mine["variant"],
            },
        }
        row["time_ratio"] = mine["warm_s"] / fs_s if fs_s > 0 else None
        row["svg_ratio"] = svg_sizes[1] / svg_sizes[0] if svg_sizes[0] else None
        results[name] = row
        side_by_side(args.out / f"bench_strokes_{name}.png", theirs["alpha"], mine["alpha"])
        v, f, o = row["vector"], row["freestyle"], row["ours"]
        print(
            f"{name}: found {v['found']:.3f}, on Freestyle {v['on_freestyle']:.3f} "
            f"(raster {row['raster']['found']:.3f}/{row['raster']['on_freestyle']:.3f}); "
            f"strokes {o['strokes']} (mean {o['mean_length_px']:.1f} px; without intersection "
            f"lines, which Freestyle does not draw: {o['freestyle_kinds']['strokes']}, "
            f"{o['freestyle_kinds']['mean_length_px']:.1f} px) vs Freestyle "
            f"{f['strokes']} ({f['mean_length_px']:.1f} px); "
            f"stroke step {o['stroke_step_s']:.3f} s "
            f"vs Freestyle's line pass {fs_s:.2f} s (ratio {row['time_ratio']:.4f}); "
            f"peak {o['peak_rss_mb']:.0f} MB (rise {o['rss_rise_mb']:.0f}) vs Blender "
            f"{f['peak_rss_mb']:.0f} MB; SVG {o['svg_bytes']} vs {f['svg_bytes']} bytes"
        )
    path = _common.write_report(
        "bench_strokes",
        args.out,
        blender=version.splitlines()[0] if version else None,
        resolution=[W, H],
        crease_angle=CREASE,
        tolerance_px=TOLERANCE,
        goals=GOALS,
        threads=args.threads,
        peak_rss_self_mb=resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024,
        scenes=results,
    )
    print(f"wrote {path}")
    return 0


if __name__ == "__main__":
    t0 = time.perf_counter()
    rc = main()
    print(f"bench_strokes: {time.perf_counter() - t0:.0f} s")
    sys.exit(rc)

"""Best-view search (depth 4, res 128) on a ~20k-triangle mesh, against a per-view sensor loop.

The mesh is a uv sphere of 100 x 101 (20,000 triangles) with a bumpy radial displacement, seen
by a 640x480, 45 degree perspective sensor (so the ID buffers are 128 x 96).

Cases, each counting the same per-polygon areas and computing the same measure:

- ``best_view``: ``mi_npr.viewpoint.best_view(scene, measure, depth=4, res=128)``: 18
  evaluations in 5 batched launches (6, then 3 per level).
- ``quality_map``: ``mi_npr.viewpoint.quality_map(scene, measure, samples=256, res=128)``: 256
  viewpoints in batched launches (what the quality-sphere picture costs).
- ``loop`` (the anchor): the 18 viewpoints of the search, one ordinary Mitsuba ``perspective``
  sensor each (``lookat``), rendered through mi-npr's exact G-buffer pass
  (``mi_npr.render_gbuffer``, no beauty) and counted with ``numpy.bincount``: what a user
  writes without the batched path.

warm: median of ``--repeat`` runs after one warm-up, in this process.
cold: the first run in a fresh process with an empty Dr.Jit kernel cache (compilation included).

    python benchmarks/bench_viewpoint.py [--quick] [--repeat N] [--measure entropy] [--out DIR]

Prints evaluations per second and total times, the ratios best_view / loop (< 1 is faster), and
writes ``benchmarks/results/bench_viewpoint.json``.
"""

from __future__ import annotations

import argparse
import json
import statistics
import sys
import tempfile
import time
from pathlib import Path

import _common
import numpy as np

HERE = Path(__file__).resolve().parent
CASES = ["best_view", "quality_map", "loop"]
DEPTH, RES, SAMPLES = 4, 128, 256


def bumpy_sphere(n_lon: int = 100, n_lat: int = 101):
    from mi_npr.meshes import uv_sphere

    V, F = uv_sphere(n_lon, n_lat)
    theta = np.arccos(np.clip(V[:, 1], -1, 1))
    phi = np.arctan2(V[:, 2], V[:, 0])
    r = 1.0 + 0.12 * np.sin(5 * theta) * np.cos(4 * phi) + 0.05 * np.cos(9 * phi)
    return (V * r[:, None]).astype(np.float32), F


def _scene(tmp: Path):
    import mi_npr
    from mi_npr.meshes import write_ply

    ply = write_ply(tmp / "bumpy.ply", *bumpy_sphere())
    mi = mi_npr.mi
    return mi.load_dict(
        {
            "type": "scene",
            "sensor": {
                "type": "perspective",
                "fov": 45.0,
                "to_world": mi.ScalarTransform4f().look_at(
                    origin=[0, 1.5, -4], target=[0, 0, 0], up=[0, 1, 0]
                ),
                "film": {"type": "hdrfilm", "width": 640, "height": 480},
            },
            "bumpy": {"type": "ply", "filename": str(ply)},
        },
        optimize=False,
    )


def _setup(case: str, measure: str, tmp: Path):
    """A zero-argument function that runs the case once; returns its number of evaluations."""
    import mi_npr
    from mi_npr.viewpoint import best_view, measures, quality_map

    mi, dr = mi_npr.mi, mi_npr.dr
    scene = _scene(tmp)
    if case == "best_view":
        return lambda: best_view(scene, measure, depth=DEPTH, res=RES).evaluations
    if case == "quality_map":
        return lambda: len(quality_map(scene, measure, samples=SAMPLES, res=RES)[1])
    ref = best_view(scene, measure, depth=DEPTH, res=RES)
    table = mi_npr.object_table(scene)
    n = sum(s.face_count() if s.is_mesh() else 1 for s in table.shapes.values())
    w, h = ref.size
    sensors = []
    for o in ref.viewpoints:
        f = ref.target - o
        up = np.array([0.0, 1.0, 0.0]) if abs(f[1]) < 0.99 * np.linalg.norm(f) else [0, 0, 1.0]
        sensors.append(
            mi.load_dict(
                {
                    "type": "perspective",
                    "fov": ref.fov,
                    "to_world": mi.ScalarTransform4f().look_at(origin=o, target=ref.target, up=up),
                    "film": {"type": "hdrfilm", "width": w, "height": h},
                }
            )
        )

    def run() -> int:
        # Eq. 2 needs the welded topology, which best_view builds on every call too.
        topo = mi_npr.viewpoint.polygons(scene).topology() if measure == "curvature" else None
        for s in sensors:
            gb = mi_npr.render_gbuffer(scene, s)
            poly = np.where(gb["object_id.V"] > 0, gb["prim_id.V"].astype(np.int64) + 1, 0)
            a = np.bincount(poly.ravel(), minlength=n + 1)
            measures.MEASURES[measure](a, topo)
        dr.sync_thread()
        return len(sensors)

    return run


def _timed(fn) -> tuple[float, int]:
    t0 = time.perf_counter()
    n = fn()
    return (time.perf_counter() - t0) * 1e3, n


def _cold_child(case: str, measure: str) -> None:
    with tempfile.TemporaryDirectory() as tmp:
        fn = _setup(case, measure, Path(tmp))
        ms, n = _timed(fn)
    print(json.dumps({"cold_ms": ms, "evaluations": n}))


def measure_cold(case: str, measure: str) -> float:
    return _common.cold_run(__file__, case, measure)["cold_ms"]


def measure_warm(case: str, measure: str, repeat: int) -> tuple[float, int]:
    with tempfile.TemporaryDirectory() as tmp:
        fn = _setup(case, measure, Path(tmp))
        fn()
        runs = [_timed(fn) for _ in range(repeat)]
    return statistics.median(ms for ms, _ in runs), runs[0][1]


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=7)
    ap.add_argument("--quick", action="store_true", help="3 repeats, no cold runs")
    ap.add_argument("--measure", default="entropy", choices=["pb", "curvature", "entropy"])
    ap.add_argument("--out", type=Path, default=HERE / "results")
    ap.add_argument("--cold-child", nargs=2, help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.cold_child:
        _cold_child(*args.cold_child)
        return 0

    repeat = 3 if args.quick else args.repeat
    res: dict = {}
    for case in CASES:
        warm, n = measure_warm(case, args.measure, repeat)
        res[case] = {"evaluations": n, "warm_ms": warm, "warm_evals_per_s": n / warm * 1e3}
        if not args.quick:
            cold = measure_cold(case, args.measure)
            res[case].update(cold_ms=cold, cold_evals_per_s=n / cold * 1e3)
    for mode in ("warm", "cold"):
        if f"{mode}_ms" in res["loop"]:
            res[f"ratio_{mode}_best_view_vs_loop"] = (
                res["best_view"][f"{mode}_ms"] / res["loop"][f"{mode}_ms"]
            )
    print(f"\nbest view, depth {DEPTH}, res {RES}, {args.measure}, 20,000 triangles")
    print(f"  {'case':<14}{'evals':>7}{'warm ms':>10}{'evals/s':>10}{'cold ms':>10}")
    for case in CASES:
        r = res[case]
        cold = f"{r['cold_ms']:>10.1f}" if "cold_ms" in r else f"{'-':>10}"
        print(
            f"  {case:<14}{r['evaluations']:>7}{r['warm_ms']:>10.1f}"
            f"{r['warm_evals_per_s']:>10.1f}{cold}"
        )
    for mode in ("warm", "cold"):
        key = f"ratio_{mode}_best_view_vs_loop"
        if key in res:
            print(f"  ratio best_view / loop ({mode}): {res[key]:.2f}")
    path = _common.write_report(
        "bench_viewpoint",
        args.out,
        mesh="bumpy uv sphere 100 x 101, 20000 triangles",
        depth=DEPTH,
        res=RES,
        measure=args.measure,
        repeat=repeat,
        results=res,
    )
    print(f"\nwrote {path}")
    return 0


if __name__ == "__main__":
    sys.exit(main())

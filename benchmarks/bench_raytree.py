"""npr_raytree (depth 3, all lights) against Mitsuba's C++ ``aov`` integrator, same scene, same run.

Scene: ``scenes_xml/scene1.xml`` at 640x480 (glass, mirror and diffuse spheres; a point light
and a constant environment, so every tree has two shadow rays per node). Cases:

- ``npr_raytree``: ``mi.render`` with ``<integrator type="npr_raytree"/>`` (no nested beauty:
  headlight shading), i.e. the pixel-centre G-buffer pass, the ray trees at the W x H pixel
  centres and the (W + 1) x (H + 1) corners, the edge classes, the overlay and the tensor;
- ``raytree_layers``: :func:`mi_npr.raytree.raytree_layers` alone (trees, hash, edges);
- ``npr_gbuffer``: the G-buffer pass alone, for reference;
- ``aov_box`` / ``aov_gaussian``: Mitsuba's ``aov`` (depth, shape_index, sh_normal) at 1 spp with
  a box filter (its cheapest setting) and with the scene's own gaussian film.

warm: median of ``--repeat`` runs after one warm-up, in this process.
cold: the first render in a fresh process with an empty Dr.Jit kernel cache.

    python benchmarks/bench_raytree.py [--quick] [--repeat N] [--out benchmarks/results]

Prints the times and the ratios npr_raytree / anchor (target: <= 3 warm), writes JSON.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
SCENE = HERE.parent / "scenes_xml" / "scene1.xml"
SIZE = (640, 480)
CASES = ["npr_raytree", "raytree_layers", "npr_gbuffer", "aov_box", "aov_gaussian"]
ANCHORS = ["aov_box", "aov_gaussian"]


def _setup(case: str, w: int, h: int):
    """A zero-argument function that renders once and waits for the result."""
    import mi_npr

    mi, dr = mi_npr.mi, mi_npr.dr
    scene = mi_npr.load_scene(SCENE, width=w, height=h, spp=1)

    def timed(fn):
        def run():
            out = fn()
            dr.eval(out)
            dr.sync_thread()

        return run

    if case == "raytree_layers":
        return timed(lambda: mi_npr.raytree.raytree_layers(scene, 0, 3))
    if case in ("npr_raytree", "npr_gbuffer"):
        integ = mi.load_dict({"type": case, **({"max_depth": 3} if case == "npr_raytree" else {})})
        return timed(lambda: mi.render(scene, integrator=integ))
    aov = mi.load_dict({"type": "aov", "aovs": "dd.y:depth,id:shape_index,nn:sh_normal"})
    sensor = scene.sensors()[0]
    if case == "aov_box":
        import numpy as np

        m = np.asarray(sensor.world_transform().matrix, dtype=np.float64).reshape(4, 4)
        sensor = mi.load_dict(
            {
                "type": "perspective",
                "fov": float(mi.traverse(sensor)["x_fov"][0]),
                "to_world": mi.ScalarTransform4f(m),
                "film": {"type": "hdrfilm", "width": w, "height": h, "rfilter": {"type": "box"}},
                "sampler": {"type": "independent", "sample_count": 1},
            }
        )
    return timed(lambda: mi.render(scene, sensor=sensor, integrator=aov, spp=1))


def _cold_child(case: str, w: int, h: int) -> None:
    fn = _setup(case, w, h)
    t0 = time.perf_counter()
    fn()
    print(json.dumps({"cold_ms": (time.perf_counter() - t0) * 1e3}))


def measure_cold(case: str, w: int, h: int) -> float:
    with tempfile.TemporaryDirectory() as cache:
        env = dict(os.environ, DRJIT_CACHE_DIR=cache)
        out = subprocess.run(
            [sys.executable, __file__, "--cold-child", case, str(w), str(h)],
            capture_output=True,
            text=True,
            env=env,
            check=True,
        )
    return json.loads(out.stdout.strip().splitlines()[-1])["cold_ms"]


def measure_warm(fns: dict, repeat: int) -> dict[str, float]:
    """Median per case; the cases take turns so that a busy machine slows them alike."""
    for fn in fns.values():
        fn()
    times: dict[str, list[float]] = {case: [] for case in fns}
    for _ in range(repeat):
        for case, fn in fns.items():
            t0 = time.perf_counter()
            fn()
            times[case].append((time.perf_counter() - t0) * 1e3)
    return {case: statistics.median(t) for case, t in times.items()}


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=15)
    ap.add_argument("--quick", action="store_true", help="5 repeats, no cold runs")
    ap.add_argument("--out", type=Path, default=HERE / "results")
    ap.add_argument("--cold-child", nargs=3, help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.cold_child:
        _cold_child(args.cold_child[0], int(args.cold_child[1]), int(args.cold_child[2]))
        return 0
    import mi_npr

    w, h = SIZE
    repeat = 5 if args.quick else args.repeat
    warm = measure_warm({case: _setup(case, w, h) for case in CASES}, repeat)
    res: dict = {"width": w, "height": h}
    for case in CASES:
        res[case] = {
            "warm_ms": warm[case],
            "cold_ms": None if args.quick else measure_cold(case, w, h),
        }
    print(f"\n{w}x{h}, scene1.xml, depth 3, 2 lights (ms; ratio = npr_raytree / anchor)")
    print(f"  {'case':<18}{'warm':>10}{'cold':>10}")
    for case in CASES:
        cold = res[case]["cold_ms"]
        print(f"  {case:<18}{warm[case]:>10.1f}{'' if cold is None else f'{cold:10.1f}'}")
    for anchor in ANCHORS:
        for mode in ("warm_ms", "cold_ms"):
            a, b = res["npr_raytree"][mode], res[anchor][mode]
            res[f"ratio_{mode[:4]}_vs_{anchor}"] = None if a is None else a / b
        cold = res[f"ratio_cold_vs_{anchor}"]
        print(
            f"  ratio vs {anchor:<9}{res[f'ratio_warm_vs_{anchor}']:>10.2f}"
            f"{'' if cold is None else f'{cold:10.2f}'}"
        )
    report = {
        "benchmark": "bench_raytree",
        "scene": str(SCENE.relative_to(HERE.parent)),
        "max_depth": 3,
        "date": time.strftime("%Y-%m-%dT%H:%M:%S"),
        "machine": {
            "cpu_count": os.cpu_count(),
            "platform": platform.platform(),
            "python": platform.python_version(),
        },
        "mi_npr": mi_npr.__version__,
        "variant": mi_npr.mi.variant(),
        "llvm": mi_npr.LLVM.chosen.describe() if mi_npr.LLVM and mi_npr.LLVM.chosen else None,
        "repeat": repeat,
        "target": "npr_raytree warm <= 3x aov",
        "results": [res],
    }
    args.out.mkdir(parents=True, exist_ok=True)
    path = args.out / "bench_raytree.json"
    path.write_text(json.dumps(report, indent=2))
    print(f"\nwrote {path}")
    return 0


if __name__ == "__main__":
    sys.exit(main())

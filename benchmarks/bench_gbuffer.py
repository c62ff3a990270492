"""npr_gbuffer against Mitsuba's C++ ``aov`` integrator, same scene, same run, cold and warm.

The anchor is ``aov`` with ``depth``, ``shape_index`` and ``sh_normal`` at 1 spp, rendered
through ``mi.render`` like ours. It is timed twice: with a ``box`` reconstruction filter (its
cheapest setting, the fair anchor since we never filter AOVs) and with the scene's own ``gaussian``
film (what a user gets by default). Ours is ``npr_gbuffer`` without a nested beauty integrator
(headlight shading), through ``mi.render`` (interleaved tensor) and through ``mi_npr.render``
(GBuffer of numpy layers).

warm: median of ``--repeat`` runs after one warm-up, in this process.
cold: the first render in a fresh process with an empty Dr.Jit kernel cache (compilation included).

    python benchmarks/bench_gbuffer.py [--quick] [--repeat N] [--out benchmarks/results]

Prints a table with the ratios ours / anchor (< 1 means faster) and writes JSON.
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
SCENE = HERE.parent / "scenes_xml" / "scene2.xml"
SIZES = [(640, 480), (1920, 1080)]
CASES = ["npr_gbuffer", "npr_gbuffer_gbuffer", "aov_box", "aov_gaussian"]


def _setup(case: str, w: int, h: int):
    """Return a zero-argument function that renders once and waits for the result."""
    import mi_npr

    mi, dr = mi_npr.mi, mi_npr.dr
    scene = mi_npr.load_scene(SCENE, width=w, height=h, spp=1)
    if case.startswith("npr_gbuffer"):
        integ = mi.load_dict({"type": "npr_gbuffer"})
        if case == "npr_gbuffer_gbuffer":
            return lambda: integ.npr_gbuffer(scene)

        def run():
            img = mi.render(scene, integrator=integ)
            dr.eval(img)
            dr.sync_thread()

        return run
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

    def run_aov():
        img = mi.render(scene, sensor=sensor, integrator=aov, spp=1)
        dr.eval(img)
        dr.sync_thread()

    return run_aov


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


def measure_warm(case: str, w: int, h: int, repeat: int) -> float:
    fn = _setup(case, w, h)
    fn()
    times = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        fn()
        times.append((time.perf_counter() - t0) * 1e3)
    return statistics.median(times)


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=15)
    ap.add_argument("--quick", action="store_true", help="640x480 only, 5 repeats")
    ap.add_argument("--out", type=Path, default=HERE / "results")
    ap.add_argument("--cold-child", nargs=3, help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.cold_child:
        _cold_child(args.cold_child[0], int(args.cold_child[1]), int(args.cold_child[2]))
        return 0
    import mi_npr

    sizes = SIZES[:1] if args.quick else SIZES
    repeat = 5 if args.quick else args.repeat
    rows = []
    for w, h in sizes:
        res = {"width": w, "height": h}
        for case in CASES:
            res[case] = {
                "warm_ms": measure_warm(case, w, h, repeat),
                "cold_ms": measure_cold(case, w, h),
            }
        for anchor in ("aov_box", "aov_gaussian"):
            for mode in ("warm_ms", "cold_ms"):
                key = f"ratio_{mode[:4]}_vs_{anchor}"
                res[key] = res["npr_gbuffer"][mode] / res[anchor][mode]
        rows.append(res)
        print(f"\n{w}x{h} (ms; ratio = npr_gbuffer / anchor, < 1 is faster)")
        print(f"  {'case':<22}{'warm':>10}{'cold':>10}")
        for case in CASES:
            print(f"  {case:<22}{res[case]['warm_ms']:>10.1f}{res[case]['cold_ms']:>10.1f}")
        for anchor in ("aov_box", "aov_gaussian"):
            print(
                f"  ratio vs {anchor:<13}{res[f'ratio_warm_vs_{anchor}']:>10.2f}"
                f"{res[f'ratio_cold_vs_{anchor}']:>10.2f}"
            )
    report = {
        "benchmark": "bench_gbuffer",
        "scene": str(SCENE.relative_to(HERE.parent)),
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
        "results": rows,
    }
    args.out.mkdir(parents=True, exist_ok=True)
    path = args.out / "bench_gbuffer.json"
    path.write_text(json.dumps(report, indent=2))
    print(f"\nwrote {path}")
    return 0


if __name__ == "__main__":
    sys.exit(main())

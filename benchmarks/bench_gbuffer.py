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

import statistics
import sys
import time
from pathlib import Path

import _common
from _common import aov_anchor

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
    return aov_anchor(scene, w, h, box=case == "aov_box")


def measure_cold(case: str, w: int, h: int) -> float:
    return _common.measure_cold(__file__, case, w, h)


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
    args = _common.parse_args(__doc__, _setup, "640x480 only, 5 repeats")
    if args is None:
        return 0

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
    path = _common.write_report(
        "bench_gbuffer",
        args.out,
        scene=str(SCENE.relative_to(_common.ROOT)),
        repeat=repeat,
        results=rows,
    )
    print(f"\nwrote {path}")
    return 0


if __name__ == "__main__":
    sys.exit(main())

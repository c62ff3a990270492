"""npr_raytree (depth 3, all lights) against Mitsuba's C++ ``aov`` integrator, same scene, same run.

Scene: ``scenes_xml/scene1.xml`` at 640x480 and 1920x1080 (glass, mirror and diffuse spheres; a
point light and a constant environment, both casting shadow rays (``shadow_lights="all"``), so
every tree has two shadow rays per node). Cases:

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

import statistics
import sys
import time
from pathlib import Path

import _common
from _common import aov_anchor

HERE = Path(__file__).resolve().parent
SCENE = HERE.parent / "scenes_xml" / "scene1.xml"
SIZES = [(640, 480), (1920, 1080)]
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
        return timed(lambda: mi_npr.raytree.raytree_layers(scene, 0, 3, shadow_lights="all"))
    if case in ("npr_raytree", "npr_gbuffer"):
        tree = {"max_depth": 3, "shadow_lights": "all"} if case == "npr_raytree" else {}
        integ = mi.load_dict({"type": case, **tree})
        return timed(lambda: mi.render(scene, integrator=integ))
    return aov_anchor(scene, w, h, box=case == "aov_box")


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


def _measure(args, w: int, h: int, repeat: int) -> dict:
    """Warm (and cold) times of every case at ``w`` x ``h``, and the ratios."""
    warm = measure_warm({case: _setup(case, w, h) for case in CASES}, repeat)
    res: dict = {"width": w, "height": h}
    for case in CASES:
        res[case] = {
            "warm_ms": warm[case],
            "cold_ms": None if args.quick else _common.measure_cold(__file__, case, w, h),
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
    return res


def main() -> int:
    args = _common.parse_args(__doc__, _setup, "5 repeats, no cold runs")
    if args is None:
        return 0

    repeat = 5 if args.quick else args.repeat
    results = []
    for w, h in SIZES:
        results.append(_measure(args, w, h, repeat))
    path = _common.write_report(
        "bench_raytree",
        args.out,
        scene=str(SCENE.relative_to(_common.ROOT)),
        max_depth=3,
        repeat=repeat,
        target="npr_raytree warm <= 2x aov (box filter) at 1920x1080",
        results=results,
    )
    print(f"\nwrote {path}")
    return 0


if __name__ == "__main__":
    sys.exit(main())

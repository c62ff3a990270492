"""Apparent contours at 640x480 on scenes 1-4: buffer mode against OpenCV, ray-cast mode against a
full ID buffer, cold and warm, in the same run.

Buffer mode: ``mi_npr.contours.trace(ids)`` on the G-buffer's ``object_id.V`` (every contour of
every object), against ``cv2.findContours`` (``RETR_LIST``, ``CHAIN_APPROX_NONE``) on each
object's zero-padded mask, timed twice: masks prepared beforehand (``cv2``) and masks built in the
timed call (``cv2_masks``, what a user of OpenCV pays). Also the paper's walk
(``trace_code_direction``). The paper's Table 1 took 100-311 ms per scene; the target is 5 ms.

Ray-cast mode: ``mi_npr.contours.trace_scene(scene)`` (refinement, guard, following, tracing),
against two anchors: ``id_buffer``, the full pixel-centre ID pass (one ray per pixel, the same
intersection and id lookup), which is what buffer mode needs first, and ``gbuffer``, the full
G-buffer pass (``mi_npr.render_gbuffer(scene)`` without a beauty integrator). ``rays_cast / (W*H)``
is reported (target <= 20%); the goal for ``trace_scene / gbuffer`` is <= 0.3, on scenes 1-4 and
on ``meshes400``: 400 small PLY meshes (boxes and spheres, random sizes, on a 20 x 20 jittered
grid) on a ground plane, written with ``mi_npr.meshes.write_ply`` into a temporary folder and
seen obliquely (only the ray-cast cases run on it).

warm: median of ``--repeat`` runs after one warm-up, in this process.
cold: the first run in a fresh process with an empty Dr.Jit kernel cache (compilation included).

    python benchmarks/bench_contours.py [--quick] [--repeat N] [--out benchmarks/results]

Prints a table with the ratios ours / anchor (< 1 means faster) and writes JSON.
"""

from __future__ import annotations

import argparse
import json
import statistics
import sys
import time
from pathlib import Path

import _common

HERE = Path(__file__).resolve().parent
SCENES = ["scene1", "scene2", "scene3", "scene4"]
SIZE = (640, 480)
CASES = [
    "trace",
    "trace_code_direction",
    "cv2",
    "cv2_masks",
    "trace_scene",
    "id_buffer",
    "gbuffer",
]
RAY_CASES = ["trace_scene", "id_buffer", "gbuffer"]
MESHES = "meshes400"


def _scene(name: str, w: int, h: int):
    import mi_npr

    if name == MESHES:
        return meshes_scene(w, h)
    return mi_npr.load_scene(HERE.parent / "scenes_xml" / f"{name}.xml", width=w, height=h, spp=1)


def meshes_scene(w: int, h: int, count: int = 400, seed: int = 1):
    """``count`` small PLY meshes (boxes and spheres, random sizes, on a jittered square grid)
    on a ground plane, seen obliquely; the PLY files live in a temporary folder while loading."""
    import tempfile

    import numpy as np

    import mi_npr
    from mi_npr.meshes import box, uv_sphere, write_ply

    mi = mi_npr.mi
    rng = np.random.default_rng(seed)
    side = int(np.ceil(np.sqrt(count)))
    g = side * 1.2  # half the ground's width
    with tempfile.TemporaryDirectory(prefix="mi_npr_meshes400_") as tmp:
        folder = Path(tmp)
        shapes = {}
        for i in range(count):
            size = float(rng.uniform(0.25, 0.8))
            jitter = rng.uniform(-0.2, 0.2, 2)
            centre = [
                (i % side - side / 2 + 0.5 + jitter[0]) * 1.2,
                size / 2,
                (i // side - side / 2 + 0.5 + jitter[1]) * 1.2,
            ]
            if i % 2:
                V, F = box(size, centre)
            else:
                V, F = uv_sphere(24, 16, size / 2)
                V = V + np.asarray(centre, np.float32)
            shapes[f"m{i:03d}"] = {
                "type": "ply",
                "filename": str(write_ply(folder / f"m{i:03d}.ply", V, F)),
            }
        quad = np.array([[-g, 0, -g], [g, 0, -g], [g, 0, g], [-g, 0, g]], np.float32)
        ground = write_ply(folder / "ground.ply", quad, np.array([[0, 2, 1], [0, 3, 2]]))
        shapes["ground"] = {"type": "ply", "filename": str(ground)}
        eye = mi.ScalarTransform4f().look_at(
            origin=[0, 0.75 * g, -1.25 * g], target=[0, 0, -0.1 * g], up=[0, 1, 0]
        )
        film = {"type": "hdrfilm", "width": w, "height": h}
        camera = {"type": "perspective", "fov": 50, "to_world": eye, "film": film}
        return mi.load_dict({"type": "scene", "camera": camera, **shapes})


def gbuffer_pass(scene):
    """The full G-buffer pass (no beauty), every layer evaluated."""
    import numpy as np

    import mi_npr

    gb = mi_npr.render_gbuffer(scene)
    for name in gb.layers:
        np.asarray(gb[name])
    mi_npr.dr.sync_thread()
    return gb


def _setup(case: str, name: str, w: int, h: int):
    """A zero-argument function that runs the case once (and waits for its result)."""
    import numpy as np

    import mi_npr

    mi, dr = mi_npr.mi, mi_npr.dr
    scene = _scene(name, w, h)
    if case == "trace_scene":
        return lambda: mi_npr.contours.trace_scene(scene)
    if case == "gbuffer":
        return lambda: gbuffer_pass(scene)
    if case == "id_buffer":
        from mi_npr.raycast import pixel_rays

        sensor, table = scene.sensors()[0], mi_npr.object_table(scene)

        def full():
            idx = dr.arange(mi.UInt32, w * h)
            ray = pixel_rays(sensor, mi.Float(idx % w) + 0.5, mi.Float(idx // w) + 0.5)
            ids = table.lookup(scene.ray_intersect_preliminary(ray, coherent=True))
            return ids.numpy()

        return full
    ids = np.asarray(mi_npr.render_gbuffer(scene)["object_id.V"]).copy()
    if case == "trace":
        return lambda: mi_npr.contours.trace(ids)
    if case == "trace_code_direction":
        return lambda: mi_npr.contours.trace(ids, method="code_direction")
    import cv2

    objects = [k for k in np.unique(ids) if k != 0]
    if case == "cv2":
        masks = [np.pad((ids == k).astype(np.uint8), 1) for k in objects]
        return lambda: [cv2.findContours(m, cv2.RETR_LIST, cv2.CHAIN_APPROX_NONE) for m in masks]
    return lambda: [
        cv2.findContours(
            np.pad((ids == k).astype(np.uint8), 1), cv2.RETR_LIST, cv2.CHAIN_APPROX_NONE
        )
        for k in objects
    ]


def _cold_child(case: str, name: str, w: int, h: int) -> None:
    fn = _setup(case, name, w, h)
    t0 = time.perf_counter()
    fn()
    print(json.dumps({"cold_ms": (time.perf_counter() - t0) * 1e3}))


def measure_cold(case: str, name: str, w: int, h: int) -> float:
    return _common.cold_run(__file__, case, name, w, h)["cold_ms"]


def measure_warm(fn, repeat: int) -> float:
    fn()
    times = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        fn()
        times.append((time.perf_counter() - t0) * 1e3)
    return statistics.median(times)


def measure_paired(ours, anchor, repeat: int) -> dict:
    """``ours`` and ``anchor`` run alternately (the machine's load hits both alike): the median
    of the per-pair ratios, and the ratio of the two minima."""
    ours(), anchor()
    a, b = [], []
    for _ in range(repeat):
        for fn, out in ((ours, a), (anchor, b)):
            t0 = time.perf_counter()
            fn()
            out.append((time.perf_counter() - t0) * 1e3)
    return {
        "ours_min_ms": min(a),
        "anchor_min_ms": min(b),
        "median_ratio": statistics.median(x / y for x, y in zip(a, b, strict=True)),
        "min_ratio": min(a) / min(b),
    }


def ray_details(name: str, w: int, h: int, repeat: int) -> dict:
    """Rays cast, contours and the warm per-stage times of ray-cast mode."""
    import mi_npr

    scene = _scene(name, w, h)
    mi_npr.contours.trace_scene(scene)
    runs = [mi_npr.contours.trace_scene(scene)[1] for _ in range(repeat)]
    s = runs[0]
    stages = {k: statistics.median(r.times[k] for r in runs) * 1e3 for k in s.times}
    return {
        "rays_cast": s.rays_cast,
        "ray_fraction": s.ray_fraction,
        "launches": s.launches,
        "rounds": s.rounds,
        "guarded_pixels": s.guarded_pixels,
        "contours": s.contours,
        "stage_ms": stages,
    }


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=15)
    ap.add_argument("--quick", action="store_true", help="5 repeats, no cold runs")
    ap.add_argument("--out", type=Path, default=HERE / "results")
    ap.add_argument("--cold-child", nargs=4, help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.cold_child:
        c, n, w, h = args.cold_child
        _cold_child(c, n, int(w), int(h))
        return 0

    w, h = SIZE
    repeat = 5 if args.quick else args.repeat
    rows = []
    for name in [*SCENES, MESHES]:
        cases = RAY_CASES if name == MESHES else CASES
        res: dict = {"scene": name, "width": w, "height": h}
        for case in cases:
            res[case] = {"warm_ms": measure_warm(_setup(case, name, w, h), repeat)}
            if not args.quick:
                res[case]["cold_ms"] = measure_cold(case, name, w, h)
        res["rays"] = ray_details(name, w, h, repeat)
        res["paired_trace_scene_vs_gbuffer"] = measure_paired(
            _setup("trace_scene", name, w, h), _setup("gbuffer", name, w, h), repeat
        )
        modes = ["warm_ms"] if args.quick else ["warm_ms", "cold_ms"]
        pairs = [("trace_scene", "id_buffer"), ("trace_scene", "gbuffer")]
        if name != MESHES:
            pairs = [("trace", "cv2"), ("trace", "cv2_masks"), *pairs]
        for ours, anchor in pairs:
            for mode in modes:
                res[f"ratio_{mode[:4]}_{ours}_vs_{anchor}"] = res[ours][mode] / res[anchor][mode]
        rows.append(res)
        print(f"\n{name} {w}x{h} (ms; ratio = ours / anchor, < 1 is faster)")
        print(f"  {'case':<22}{'warm':>10}{'cold':>10}")
        for case in cases:
            cold = res[case].get("cold_ms", float("nan"))
            print(f"  {case:<22}{res[case]['warm_ms']:>10.2f}{cold:>10.1f}")
        for key in [k for k in res if k.startswith("ratio_")]:
            print(f"  {key:<38}{res[key]:>8.2f}")
        p = res["paired_trace_scene_vs_gbuffer"]
        print(
            f"  trace_scene / gbuffer, run alternately: median ratio {p['median_ratio']:.2f}, "
            f"minima {p['ours_min_ms']:.2f} / {p['anchor_min_ms']:.2f} ms = {p['min_ratio']:.2f}"
        )
        r = res["rays"]
        print(
            f"  rays cast {r['rays_cast']} = {100 * r['ray_fraction']:.1f}% of W*H "
            f"({r['guarded_pixels']} by the guard), {r['launches']} batches, {r['rounds']} rounds, "
            f"{r['contours']} contours; stages (ms) "
            + ", ".join(f"{k} {v:.2f}" for k, v in r["stage_ms"].items())
        )
    path = _common.write_report(
        "bench_contours",
        args.out,
        scenes=[f"scenes_xml/{n}.xml" for n in SCENES] + [MESHES],
        repeat=repeat,
        targets={"trace_warm_ms": 5.0, "ray_fraction": 0.2, "trace_scene_vs_gbuffer": 0.3},
        results=rows,
    )
    print(f"\nwrote {path}")
    return 0


if __name__ == "__main__":
    sys.exit(main())

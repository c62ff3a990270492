"""Differentiable lines: the backward pass against the forward pass, and the camera from a sketch.

Cases:

- ``forward`` / ``backward`` on ``scene1.xml`` at 640x480: :func:`mi_npr.ad.soft_lines` (2 x 2
  samples a pixel, as :func:`~mi_npr.ad.fit_camera` renders) and the blurred L2 against a
  drawing from a camera 2 degrees away, with the camera's origin and target differentiable.
  ``forward`` times the loss with its AD graph (what an optimisation step pays before
  ``dr.backward``); ``backward`` times ``dr.backward`` alone. The anchor is the exact
  pixel-centre G-buffer and the ``lines`` chain of the same view (``render_gbuffer`` +
  ``kernels.lines``, no beauty), which has no visibility gradients.
- ``fit``: ``N`` generated cases (a random scene of 3-5 spheres and boxes on a floor, a random
  camera looking at it from 6-8 units, its drawing by ``soft_lines`` at 96x72, the start
  orbited 10-20 degrees about the target on a random axis and 10% nearer or farther):
  :func:`~mi_npr.ad.fit_camera` with its defaults. Success: the fitted camera within 1 degree
  (rotation between the frames) and 1% (origin distance over the true distance to the target)
  of the true one. Reported: success rate, the median step at which a case first came within
  both bounds, and time per fit.

warm: median of ``--repeat`` runs after one warm-up, in this process.

    python benchmarks/bench_grad.py [--quick] [--repeat N] [--cases N] [--out DIR]

Prints backward / forward (goal <= 3) and the fit's success rate, and writes
``benchmarks/results/bench_grad.json``.
"""

from __future__ import annotations

import argparse
import statistics
import sys
import time
from pathlib import Path

import _common
import numpy as np

HERE = Path(__file__).resolve().parent
W, H = 640, 480
FIT_SIZE = (96, 72)


def _timed(fn) -> float:
    t0 = time.perf_counter()
    fn()
    return (time.perf_counter() - t0) * 1e3


def grad_times(repeat: int) -> dict:
    import mi_npr
    from mi_npr.ad import Pinhole, blurred_l2, soft_lines
    from mi_npr.camera import camera_of, rotate

    mi, dr = mi_npr.mi, mi_npr.dr
    scene = mi_npr.load_scene(_common.ROOT / "scenes_xml" / "scene1.xml", width=W, height=H)
    sensor = scene.sensors()[0]
    cam = camera_of(sensor)
    o, f = np.array(cam.origin), np.array(cam.forward)
    t = o + 8.0 * f
    o2 = t + rotate(o - t, np.cross(f, cam.up), np.radians(2.0))
    opts = {"n": 2, "sigma": 0.7}
    target = np.asarray(soft_lines(scene, Pinhole.look_at(o2, t, cam.up, cam.fov), (W, H), **opts))

    state = {}

    def forward():
        origin, tgt = mi.Point3f(cam.origin), mi.Point3f(t)
        dr.enable_grad(origin, tgt)
        lines = soft_lines(scene, Pinhole.look_at(origin, tgt, cam.up, cam.fov), (W, H), **opts)
        loss = blurred_l2(lines, target, (8.0, 4.0, 2.0, 1.0))
        dr.eval(loss)
        dr.sync_thread()
        state.update(loss=loss, origin=origin)

    def backward():
        dr.backward(state["loss"])
        dr.eval(dr.grad(state["origin"]))
        dr.sync_thread()

    def anchor():
        gb = mi_npr.render_gbuffer(scene)
        ink = mi_npr.kernels.lines(gb)
        dr.eval(ink)
        dr.sync_thread()

    forward()
    backward()
    anchor()
    fwd, bwd, anc = [], [], []
    for _ in range(repeat):
        fwd.append(_timed(forward))
        bwd.append(_timed(backward))
        anc.append(_timed(anchor))
    res = {
        "forward_ms": statistics.median(fwd),
        "backward_ms": statistics.median(bwd),
        "anchor_gbuffer_lines_ms": statistics.median(anc),
    }
    res["ratio_backward_vs_forward"] = res["backward_ms"] / res["forward_ms"]
    res["ratio_forward_vs_anchor"] = res["forward_ms"] / res["anchor_gbuffer_lines_ms"]
    return res


def random_case(rng: np.random.Generator):
    """A random scene (its sensor at the start camera) and the true camera."""
    import mi_npr
    from mi_npr.camera import Camera, rotate

    mi = mi_npr.mi
    d = 6.0 + 2.0 * rng.random()
    az, el = rng.uniform(0, 2 * np.pi), np.radians(rng.uniform(10.0, 50.0))
    o = d * np.array([np.cos(el) * np.sin(az), np.sin(el), -np.cos(el) * np.cos(az)])
    true = Camera(tuple(o), (0.0, 0.0, 0.0), (0.0, 1.0, 0.0), 40.0)
    axis = np.cross(o, rng.normal(size=3))
    angle = rng.uniform(10.0, 20.0)
    o2 = rotate(o, axis / np.linalg.norm(axis), np.radians(angle)) * (1 + rng.choice([-0.1, 0.1]))
    objects: dict = {}
    for k in range(int(rng.integers(3, 6))):
        p = rng.uniform(-1.0, 1.0, 3) * [1.2, 0.5, 1.2]
        if rng.random() < 0.5:
            objects[f"s{k}"] = {
                "type": "sphere",
                "center": p.tolist(),
                "radius": rng.uniform(0.3, 0.6),
            }
        else:
            T = (
                mi.ScalarTransform4f()
                .translate(p.tolist())
                .rotate(rng.normal(size=3).tolist(), rng.uniform(0, 90))
            )
            objects[f"b{k}"] = {"type": "cube", "to_world": T.scale(float(rng.uniform(0.25, 0.5)))}
    floor = mi.ScalarTransform4f().translate([0, -1.0, 0]).rotate([1, 0, 0], -90).scale(2.5)
    scene = mi.load_dict(
        {
            "type": "scene",
            "sensor": {
                "type": "perspective",
                "fov": 40.0,
                "to_world": mi.ScalarTransform4f().look_at(o2.tolist(), [0, 0, 0], [0, 1, 0]),
                "film": {"type": "hdrfilm", "width": FIT_SIZE[0], "height": FIT_SIZE[1]},
            },
            "floor": {"type": "rectangle", "to_world": floor},
            **objects,
        }
    )
    return scene, true, angle


def fit_cases(n: int, seed: int) -> dict:
    import mi_npr
    from mi_npr.ad import Pinhole, soft_lines
    from mi_npr.ad.fit import LINE_OPTIONS, camera_error, fit_camera

    rng = np.random.default_rng(seed)
    rows = []
    for i in range(n):
        scene, true, angle = random_case(rng)
        c = true
        cam = Pinhole.look_at(c.origin, c.target, c.up, c.fov)
        drawing = np.asarray(soft_lines(scene, cam, FIT_SIZE, **LINE_OPTIONS))
        first: list[int] = []

        def step(k, loss, camera, first=first, true=true):
            deg, dist = camera_error(camera, true)
            if not first and deg < 1.0 and dist < 0.01:
                first.append(k + 1)

        fit = fit_camera(scene, drawing, on_step=step)
        deg, dist = camera_error(fit.camera, true)
        start_deg, start_dist = camera_error(mi_npr.camera.camera_of(scene.sensors()[0]), true)
        ok = deg < 1.0 and dist < 0.01
        rows.append(
            {
                "perturbation_degrees": angle,
                "start_error": [start_deg, start_dist],
                "final_error": [deg, dist],
                "success": ok,
                "first_within": first[0] if first else None,
                "iterations": len(fit.loss),
                "seconds": fit.seconds,
            }
        )
        print(
            f"  case {i:2d}: start {start_deg:5.1f} deg {100 * start_dist:5.1f}%  ->  "
            f"{deg:6.3f} deg {100 * dist:6.3f}%  {'ok' if ok else 'MISSED'}  "
            f"({fit.seconds:.1f} s)",
            flush=True,
        )
    firsts = [r["first_within"] for r in rows if r["first_within"] is not None]
    return {
        "cases": n,
        "size": list(FIT_SIZE),
        "success_rate": sum(r["success"] for r in rows) / n,
        "iterations": rows[0]["iterations"] if rows else 0,
        "median_first_within": statistics.median(firsts) if firsts else None,
        "median_seconds": statistics.median(r["seconds"] for r in rows) if rows else 0.0,
        "rows": rows,
    }


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=5)
    ap.add_argument("--cases", type=int, default=20)
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--quick", action="store_true", help="2 repeats, 4 cases")
    ap.add_argument("--out", type=Path, default=HERE / "results")
    args = ap.parse_args()
    repeat = 2 if args.quick else args.repeat
    cases = 4 if args.quick else args.cases

    grad = grad_times(repeat)
    print(f"\nsoft_lines + blurred L2, scene1 at {W}x{H}, 2 x 2 samples a pixel")
    for k in ("forward_ms", "backward_ms", "anchor_gbuffer_lines_ms"):
        print(f"  {k:<26}{grad[k]:>10.1f}")
    print(f"  backward / forward: {grad['ratio_backward_vs_forward']:.2f} (goal <= 3)")
    print(f"  forward / exact G-buffer + lines: {grad['ratio_forward_vs_anchor']:.1f}")
    print(f"\nfit_camera on {cases} generated cases at {FIT_SIZE[0]}x{FIT_SIZE[1]}")
    fit = fit_cases(cases, args.seed)
    print(
        f"  success (1 deg, 1%): {100 * fit['success_rate']:.0f}%, {fit['iterations']} steps, "
        f"first within after {fit['median_first_within']} (median), "
        f"{fit['median_seconds']:.1f} s a fit (median)"
    )
    path = _common.write_report(
        "bench_grad",
        args.out,
        scene="scene1.xml",
        size=[W, H],
        repeat=repeat,
        results={"gradients": grad, "fit_camera": {k: v for k, v in fit.items() if k != "rows"}},
        cases=fit["rows"],
    )
    print(f"\nwrote {path}")
    return 0


if __name__ == "__main__":
    sys.exit(main())

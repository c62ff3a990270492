"""Every drawing in one render against the plain render: ``mi-npr render --lines
--contours --raytree`` on a public-style scene, 1280 x 720, 16 spp.

Scene: a Cornell-box-like room of one-sided walls (``rectangle`` shapes), a tall and a short box,
a mirror sphere and a glass sphere, a point light and a small area light; its integrator is
``path`` with ``max_depth`` 6, as a public scene's (the tutorials' ``cbox.xml`` is not shipped).

Timed (warm, median of ``--repeat`` runs after one warm-up, each ending with the arrays in
numpy):

- anchor: Mitsuba's own ``integrator.render(scene, sensor)`` of the scene's ``path`` integrator;
- ``plain``: ``mi_npr.pipeline.render_layers`` with no drawing (exact G-buffer + the beauty);
- ``all``: ``render_layers`` with ``lines`` (3 x 3 anti-aliased), ``contours`` and ``raytree``;
- the three drawings one at a time.

Goal: ``all`` <= 1.3 x the anchor.

    python benchmarks/bench_layers.py [--quick] [--repeat N] [--out DIR]
"""

from __future__ import annotations

import statistics
import tempfile
import time
from pathlib import Path

import _common

W, H, SPP = 1280, 720, 16
GOAL = 1.3

ROOM = """<scene version="3.0.0">
<integrator type="path"><integer name="max_depth" value="6"/></integrator>
<sensor type="perspective"><float name="fov" value="50"/>
  <transform name="to_world"><lookat origin="0, 0, 3.6" target="0, 0, 0" up="0, 1, 0"/></transform>
  <sampler type="independent"><integer name="sample_count" value="4"/></sampler>
  <film type="hdrfilm"><integer name="width" value="64"/><integer name="height" value="36"/></film>
</sensor>
<bsdf type="diffuse" id="white"/>
<bsdf type="diffuse" id="red"><rgb name="reflectance" value="0.7, 0.1, 0.1"/></bsdf>
<bsdf type="diffuse" id="green"><rgb name="reflectance" value="0.1, 0.6, 0.1"/></bsdf>
<shape type="rectangle" id="floor"><transform name="to_world"><rotate x="1" angle="-90"/>
  <translate y="-1"/></transform><ref id="white"/></shape>
<shape type="rectangle" id="ceiling"><transform name="to_world"><rotate x="1" angle="90"/>
  <translate y="1"/></transform><ref id="white"/></shape>
<shape type="rectangle" id="back"><transform name="to_world"><translate z="-1"/></transform>
  <ref id="white"/></shape>
<shape type="rectangle" id="left"><transform name="to_world"><rotate y="1" angle="90"/>
  <translate x="-1"/></transform><ref id="red"/></shape>
<shape type="rectangle" id="right"><transform name="to_world"><rotate y="1" angle="-90"/>
  <translate x="1"/></transform><ref id="green"/></shape>
<shape type="cube" id="tall_box"><transform name="to_world"><scale x="0.3" y="0.6" z="0.3"/>
  <rotate y="1" angle="20"/><translate x="-0.4" y="-0.4" z="-0.3"/></transform>
  <ref id="white"/></shape>
<shape type="cube" id="short_box"><transform name="to_world"><scale value="0.3"/>
  <rotate y="1" angle="-15"/><translate x="0.4" y="-0.7" z="0.2"/></transform>
  <ref id="white"/></shape>
<shape type="sphere" id="mirror_ball"><point name="center" x="0.45" y="-0.1" z="0.25"/>
  <float name="radius" value="0.2"/><bsdf type="conductor"/></shape>
<shape type="sphere" id="glass_ball"><point name="center" x="-0.3" y="-0.75" z="0.5"/>
  <float name="radius" value="0.25"/><bsdf type="dielectric"/></shape>
<shape type="rectangle" id="lamp"><transform name="to_world"><scale value="0.25"/>
  <rotate x="1" angle="90"/><translate y="0.99"/></transform>
  <emitter type="area"><rgb name="radiance" value="12"/></emitter></shape>
<emitter type="point" id="bulb"><point name="position" x="0.3" y="0.7" z="0.6"/>
  <rgb name="intensity" value="1.5"/></emitter>
</scene>
"""


def _median(fn, repeat: int) -> float:
    fn()  # warm-up: kernels compiled and cached
    times = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t0)
    return statistics.median(times)


def main() -> None:
    args = _common.parse_args(__doc__, lambda *a: lambda: None, "320 x 180, 2 repeats")
    if args is None:
        return
    import mi_npr
    from mi_npr.gbuffer import to_numpy
    from mi_npr.pipeline import render_layers

    w, h, repeat = (320, 180, 2) if args.quick else (W, H, max(1, min(args.repeat, 3)))
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "room.xml"
        path.write_text(ROOM)
        scene = mi_npr.load_scene(path)
        sensor = scene.sensors()[0]
        mi_npr.session.resize_sensor(sensor, (w, h), SPP)
        integ = scene.integrator()

        def anchor() -> None:
            to_numpy(integ.render(scene, sensor, seed=0, spp=SPP))

        def run(*drawings: str):
            return lambda: render_layers(path, drawings, resolution=(w, h), spp=SPP)

        t = {"anchor_path_render": _median(anchor, repeat)}
        t["plain"] = _median(run(), repeat)
        for d in ("lines", "contours", "raytree"):
            t[d] = _median(run(d), repeat)
        t["all"] = _median(run("lines", "contours", "raytree"), repeat)
    ratios = {k: v / t["anchor_path_render"] for k, v in t.items()}
    for k in t:
        print(f"{k:>20}: {t[k] * 1e3:9.1f} ms  {ratios[k]:5.2f} x anchor")
    ok = ratios["all"] <= GOAL
    print(f"all three drawings: {ratios['all']:.2f} x the plain render (goal <= {GOAL}): {ok}")
    report = _common.write_report(
        "bench_layers",
        args.out,
        scene="public-style room (one-sided walls, boxes, mirror and glass balls), path 6",
        size=[w, h],
        spp=SPP,
        repeat=repeat,
        seconds=t,
        ratio_to_anchor=ratios,
        goal_all_ratio=GOAL,
        goal_met=ok,
        quick=bool(args.quick),
    )
    print(report)


if __name__ == "__main__":
    main()

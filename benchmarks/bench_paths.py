"""Camera paths: a 120-frame exploration of ``scene3.xml`` (entropy, the floor
ignored as in best view) at 320 x 240, 16 spp,
with lines and contours, against the same frames by Mitsuba's ``path`` integrator alone; and
the popping of the four line variants of the thesis's claim (section 5.1) along that path.

Timed (one warm-up frame each, then every frame once; the CPU is shared, so one run):

- anchor: the scene's nested ``path`` integrator (``max_depth`` 8) rendering every camera of
  the path through :func:`mi_npr.camera.sensor_for` (``integrator.render(scene, sensor)``);
- ``frames``: :func:`mi_npr.pipeline.render_layers` of every camera with ``lines`` and
  ``contours`` (exact G-buffer, beauty, both drawings, the contours traced as vector paths),
  in memory;
- ``frames_and_files``: :func:`mi_npr.paths.render_frames`, the whole ``mi-npr path``: the
  same plus every EXR/PNG/SVG, ``path.json`` and ``coherence.json``.

Goal: ``frames`` <= 1.3 x the anchor. Popping (:func:`mi_npr.coherence.popping`, with its
default 3 x 3 tolerance window and without it) along the exploration and along a 90-degree
orbit (G-buffers at 1 spp: popping reads only ``Z`` and ``P``): gray levels + pre-filter +
eq. 5.2 at least 30 % below black/white lines.

    python benchmarks/bench_paths.py [--quick] [--out DIR]
"""

from __future__ import annotations

import tempfile
import time

import _common

W, H, SPP, FRAMES = 320, 240, 16, 120
GOAL = 1.3
SCENE = _common.ROOT / "scenes_xml" / "scene3.xml"


def tmp_orbit() -> str:
    """A directory for the orbit's frames (G-buffers only), removed at exit."""
    import atexit
    import shutil

    d = tempfile.mkdtemp(prefix="bench_paths_")
    atexit.register(shutil.rmtree, d, True)
    return d


def main() -> None:
    args = _common.parse_args(__doc__, lambda *a: lambda: None, "160 x 120, 12 frames")
    if args is None:
        return
    import drjit as dr

    import mi_npr
    from mi_npr import camera, coherence, paths
    from mi_npr.gbuffer import to_numpy
    from mi_npr.pipeline import render_layers
    from mi_npr.session import SceneSession

    w, h, frames = (160, 120, 12) if args.quick else (W, H, FRAMES)
    session = SceneSession.open(SCENE, resolution=(w, h), spp=SPP)
    scene = session.scene
    cams = paths.explore(scene, frames, "entropy", ignore=["floor"])
    beauty = scene.integrator().beauty
    sensors = [camera.sensor_for(c, session.sensor) for c in cams]

    def anchor(i: int) -> None:
        to_numpy(beauty.render(scene, sensors[i], seed=0, spp=SPP))
        dr.sync_thread()

    def ours(i: int) -> None:
        render_layers(scene, ["lines", "contours"], sensor=sensors[i], spp=SPP)

    t: dict[str, float] = {}
    for name, fn in (("anchor_path_render", anchor), ("frames", ours)):
        fn(0)  # warm-up: kernels compiled
        t0 = time.perf_counter()
        for i in range(frames):
            fn(i)
        t[name] = time.perf_counter() - t0
    with tempfile.TemporaryDirectory() as tmp:
        t0 = time.perf_counter()
        result = paths.render_frames(scene, cams, tmp, ["lines", "contours"], spp=SPP)
        t["frames_and_files"] = time.perf_counter() - t0
    ratios = {k: v / t["anchor_path_render"] for k, v in t.items()}
    for k in t:
        print(f"{k:>20}: {t[k]:8.2f} s  {t[k] / frames * 1e3:7.1f} ms/frame  {ratios[k]:5.2f} x")
    ok = ratios["frames"] <= GOAL
    print(f"lines + contours: {ratios['frames']:.2f} x the path integrator (goal <= {GOAL}): {ok}")

    orbit = paths.render_frames(scene, camera.orbit(scene, frames, 90.0), tmp_orbit(), [], spp=1)
    table: dict[str, dict[str, float]] = {}
    for label, fr in (("explore", result.gbuffers), ("orbit_90", orbit.gbuffers)):
        for radius in (1, 0):
            row = {
                name: coherence.popping(
                    [
                        mi_npr.GBuffer(
                            {
                                **{n: f[n] for n in (mi_npr.layers.Z, *mi_npr.layers.P)},
                                mi_npr.layers.LINES: coherence.variant_lines(f, name),
                            },
                            camera=f.camera,
                        )
                        for f in fr
                    ],
                    radius=radius,
                )["overall"]
                for name in coherence.VARIANTS
            }
            if label == "explore":
                row["lines layer (defaults)"] = coherence.popping(fr, radius=radius)["overall"]
            table[f"{label}_radius_{radius}"] = row
    print("popping (fraction of line ink appearing or vanishing per frame pair):")
    for r, row in table.items():
        for k, v in row.items():
            print(f"  {r:>18}  {k:>36}: {v:.4f}")
    gains = {
        r: 1 - row["gray + pre-filter + eq. 5.2"] / row["black/white"] if row["black/white"] else 0
        for r, row in table.items()
    }
    for r, g in gains.items():
        print(f"  {r}: gray + pre-filter is {100 * g:+.1f} % below black/white (goal >= 30 %)")
    report = _common.write_report(
        "bench_paths",
        args.out,
        scene="scene3.xml (npr_gbuffer over path, max_depth 8), explore entropy, floor ignored",
        size=[w, h],
        spp=SPP,
        frames=frames,
        seconds=t,
        ratio_to_anchor=ratios,
        goal_ratio=GOAL,
        goal_met=ok,
        popping=table,
        popping_reduction_vs_black_white=gains,
        goal_popping_reduction=0.3,
        quick=bool(args.quick),
    )
    print(report)


if __name__ == "__main__":
    main()

"""`mi-npr best-view` on a 400-mesh scene: wall time and peak memory of the whole command.

The scene is built procedurally in a temporary folder: 400 small PLY meshes (bricks: a uv
sphere of 24 x 16, 720 triangles, pushed towards a box, 288,000 triangles in all)
written by ``mi_npr.meshes.write_ply`` on a 20 x 20 grid of varying heights, on a ground
rectangle, lit by a constant environment and a directional light, seen by a 640 x 480
perspective sensor, ``path`` integrator (max_depth 4), 16 spp: what a user's real scene looks
like to ``best-view``. Each case runs the command as a user types it, at its default settings
(``--depth 3 --res 128``), in a fresh process; its peak RSS is
``resource.getrusage(RUSAGE_CHILDREN).ru_maxrss`` read by a wrapper process that ran only that
command.

Cases:

- ``load`` (the anchor): ``python -c "import mi_npr; mi_npr.load_scene(SCENE)"``: importing
  mi-npr and loading the scene, what any command costs before it does anything;
- ``entropy``, ``curvature``: ``mi-npr best-view SCENE --measure M -o OUT`` (sensor XML, the
  render from it, the quality-sphere picture);
- ``entropy_no_sphere``: the same with ``--no-sphere``;
- ``entropy_cold``: ``entropy`` with an empty Dr.Jit kernel cache (compilation included).

Goal: <= 10 s and <= 1 GB for ``entropy`` and ``curvature``.

    python benchmarks/bench_best_view_400.py [--out DIR]

Prints seconds, peak MB and the ratios against ``load``; writes
``benchmarks/results/bench_best_view_400.json``.
"""

from __future__ import annotations

import argparse
import sys
import tempfile
import time
from pathlib import Path

import _common
import numpy as np

HERE = Path(__file__).resolve().parent
N_MESHES = 400


def build_scene(folder: Path) -> tuple[Path, int]:
    """Write the 400 PLY meshes and the scene XML; returns the XML path and the triangles."""
    from mi_npr.meshes import uv_sphere, write_ply

    V0, F = uv_sphere(24, 16, 0.5)
    rng = np.random.default_rng(14)
    shapes, tris = [], 0
    for k in range(N_MESHES):
        i, j = divmod(k, 20)
        sx, sy, sz = rng.uniform(0.6, 1.0), rng.uniform(0.3, 1.2), rng.uniform(0.6, 1.0)
        # A brick-like blob: the sphere pushed towards a box (|x|^0.4 keeps the sign).
        V = np.sign(V0) * np.abs(V0 / 0.5) ** 0.4 * 0.5 * np.array([sx, sy, sz])
        V = V + np.array([i - 9.5, 0.5 * sy + rng.uniform(0, 0.6), j - 9.5]) * 1.05
        path = write_ply(folder / f"Brick_{i:02d}_{j:02d}.ply", V.astype(np.float32), F)
        shapes.append(f'<shape type="ply"><string name="filename" value="{path.name}"/></shape>')
        tris += len(F)
    xml = f"""<scene version="3.0.0">
    <default name="spp" value="16"/>
    <integrator type="path"><integer name="max_depth" value="4"/></integrator>
    <sensor type="perspective"><float name="fov" value="45"/>
        <transform name="to_world"><lookat origin="14, 12, 18" target="0, 0, 0" up="0, 1, 0"/>
        </transform>
        <sampler type="independent"><integer name="sample_count" value="$spp"/></sampler>
        <film type="hdrfilm"><integer name="width" value="640"/>
            <integer name="height" value="480"/></film>
    </sensor>
    <emitter type="constant"><rgb name="radiance" value="0.6"/></emitter>
    <emitter type="directional"><vector name="direction" x="-1" y="-2" z="-0.5"/>
        <rgb name="irradiance" value="2"/></emitter>
    <shape type="rectangle" id="ground"><transform name="to_world"><rotate x="1" angle="-90"/>
        <scale value="14"/></transform></shape>
    {"".join(shapes)}
</scene>"""
    scene = folder / "bricks400.xml"
    scene.write_text(xml)
    return scene, tris + 2


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", type=Path, default=HERE / "results")
    args = ap.parse_args()
    py = sys.executable
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        t0 = time.perf_counter()
        scene, tris = build_scene(tmp)
        print(f"scene: {N_MESHES} meshes, {tris} triangles ({time.perf_counter() - t0:.1f} s)")
        cli = [py, "-m", "mi_npr.cli", "best-view", str(scene), "-o", str(tmp / "out")]
        cases = {
            "load": [py, "-c", f"import mi_npr; mi_npr.load_scene({str(scene)!r})"],
            "entropy": [*cli, "--measure", "entropy"],
            "curvature": [*cli, "--measure", "curvature"],
            "entropy_no_sphere": [*cli, "--measure", "entropy", "--no-sphere"],
        }
        _common.run_measured(cases["entropy"])  # warm the kernel cache
        res = {name: _common.run_measured(cmd) for name, cmd in cases.items()}
        with tempfile.TemporaryDirectory() as cache:
            res["entropy_cold"] = _common.run_measured(cases["entropy"], {"DRJIT_CACHE_DIR": cache})
    anchor = res["load"]
    print(f"\nmi-npr best-view, {N_MESHES} meshes, defaults (depth 3, res 128), 640x480 16 spp")
    print(f"  {'case':<20}{'s':>8}{'peak MB':>10}{'s / load':>10}{'MB / load':>11}")
    for name, r in res.items():
        r["time_vs_load"] = r["s"] / anchor["s"]
        r["peak_vs_load"] = r["peak_mb"] / anchor["peak_mb"]
        print(
            f"  {name:<20}{r['s']:>8.2f}{r['peak_mb']:>10.0f}"
            f"{r['time_vs_load']:>10.2f}{r['peak_vs_load']:>11.2f}"
        )
        warn = [ln for ln in r.pop("stderr").splitlines() if "warning" in ln]
        if warn:
            print(f"    {warn[0]}")
    ok = all(res[c]["s"] <= 10 and res[c]["peak_mb"] <= 1024 for c in ("entropy", "curvature"))
    print(f"  goal <= 10 s and <= 1024 MB (entropy, curvature): {'met' if ok else 'NOT met'}")
    path = _common.write_report(
        "bench_best_view_400",
        args.out,
        scene=f"{N_MESHES} PLY bricks (uv sphere 24 x 16 each), {tris} triangles, ground, "
        "640x480, path max_depth 4, 16 spp",
        settings="mi-npr best-view defaults: depth 3, res 128, beam 3, <= 40 evaluations",
        goal_met=ok,
        results=res,
    )
    print(f"\nwrote {path}")
    return 0


if __name__ == "__main__":
    sys.exit(main())

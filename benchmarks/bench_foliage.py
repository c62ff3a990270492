"""Foliage at scale: HLPs + leaf primitives for a 100k-leaf plant, and its render with lines.

The plant is ``procedural_tree(seed=0, n_leaves=100_000)`` (leaves 0.012 long, so the crown has
about the leaf area of the 1500-leaf demo tree). Stages, each timed in this process:

- ``build_hlps``: k-means + ellipsoid fit + radius scale (default HLP radius);
- ``make_leaves``: 100k leaf primitives (``leaf`` shape, 16 triangles each, at the plant's
  leaves, orientation ``leaf``) and their one mesh (``Leaves.mesh``), as the ``npr_leaves`` shape
  builds them;
- ``load``: ``mi_npr.load_scene`` of the small_leaves-style scene (the plugin reads the plant PLY
  and the HLP JSON, builds the leaves and the ``mi.Mesh``, Mitsuba builds its BVH). Anchor: the same
  mesh written as a PLY file and loaded by Mitsuba's own ``ply`` plugin;
- ``render``: ``mi_npr.render`` at 640x480 with ``npr_lines`` (leaf outlines) over the ``direct``
  beauty with the ``npr_foliage`` BSDF (normal mixing at every hit), ``--spp`` samples per pixel.
  Anchor: Mitsuba's ``direct`` integrator alone on the same mesh with a plain ``diffuse`` BSDF, same
  spp (so the ratio is the price of the mixed normal, the G-buffer pass and the lines);
- ``lines only``: the same without a nested beauty (G-buffer pass with headlight shading + lines).

warm: median of ``--repeat`` runs after one warm-up (renders alternate with their anchor), on
``--threads`` threads, ``dr.sync_thread()`` before the timer stops. cold: the first load + render
in a fresh process with an empty Dr.Jit kernel cache. Memory: ``tracemalloc``'s peak of the
Python/numpy allocations while building HLPs + leaves, the process's peak RSS
(``resource.getrusage``) after the cold render, and Dr.Jit's allocation watermark.

    python benchmarks/bench_foliage.py [--quick] [--repeat N] [--threads N] [--spp N] [--out DIR]

Writes ``benchmarks/results/bench_foliage.json``.
"""

from __future__ import annotations

import argparse
import json
import resource
import statistics
import sys
import tempfile
import time
import tracemalloc
from pathlib import Path

import _common

HERE = Path(__file__).resolve().parent
N_LEAVES = 100_000
W, H = 640, 480


def _timed(fn):
    t0 = time.perf_counter()
    out = fn()
    return out, (time.perf_counter() - t0) * 1e3


def build(work: Path, n_leaves: int) -> dict:
    """Plant, HLPs, leaves; writes the scene and the anchor scene into ``work``."""
    import numpy as np

    from mi_npr import foliage as fo
    from mi_npr.foliage.styles import write_foliage_scene

    size = 0.09 * (1500 / n_leaves) ** 0.5
    plant, t_plant = _timed(lambda: fo.procedural_tree(seed=0, n_leaves=n_leaves, leaf_size=size))
    tracemalloc.start()
    hlps, t_hlps = _timed(lambda: fo.build_hlps(plant))
    template = fo.leaf_template("leaf")
    leaf_size = float(np.sqrt(plant.total_area / (template.area * n_leaves)))  # ~n_leaves leaves

    def leaves_and_mesh():
        leaves = fo.make_leaves(
            hlps, plant, leaf_size, shape="leaf", placement="leaves", orientation="leaf"
        )
        return leaves, leaves.mesh()

    (leaves, mesh), t_leaves = _timed(leaves_and_mesh)
    _, peak = tracemalloc.get_traced_memory()
    tracemalloc.stop()
    write_foliage_scene(
        work / "plant.xml", plant, "small_leaves", leaf_size=leaf_size, hlps=hlps, assets="plant"
    )
    text = (work / "plant.xml").read_text()
    # The scene builds the same leaves as above (small_leaves: leaf shape, at the plant's leaves).
    assert '"leaf_shape" value="leaf"' in text and '"orientation" value="leaf"' in text
    leaves.save_ply(work / "leaves.ply")
    anchor = text.split('<shape type="npr_leaves"')[0].replace(
        '<integrator type="$integrator">', '<integrator type="direct"/><!--'
    )
    anchor = anchor.replace("</integrator>\n\n    <sensor", "-->\n    <sensor", 1)
    anchor += (
        '<shape type="ply" id="leaves"><string name="filename" value="leaves.ply"/>'
        '<bsdf type="diffuse"><rgb name="reflectance" value="0.2, 0.42, 0.1"/></bsdf></shape>\n'
        + text.split("</shape>", 1)[1]
    )
    (work / "anchor.xml").write_text(anchor)
    return {
        "plant_leaves": len(plant),
        "hlps": len(hlps),
        "leaf_primitives": len(leaves),
        "triangles": len(mesh[1]),
        "leaf_size": leaf_size,
        "procedural_tree_ms": t_plant,
        "build_hlps_ms": t_hlps,
        "make_leaves_and_mesh_ms": t_leaves,
        "build_ms": t_hlps + t_leaves,
        "build_tracemalloc_peak_mb": peak / 2**20,
    }


def _render(path: Path, spp: int, integrator: str | None = None):
    import mi_npr

    defines = {"width": W, "height": H, "spp": spp}
    scene = mi_npr.load_scene(path, **defines, **({"integrator": integrator} if integrator else {}))

    def run():
        out = mi_npr.render(scene)
        mi_npr.dr.sync_thread()
        return out

    return scene, run


def _anchor_render(path: Path, spp: int):
    import mitsuba as mi

    import mi_npr

    scene = mi_npr.load_scene(path, width=W, height=H, spp=spp)

    def run():
        out = mi.render(scene, spp=spp)
        mi_npr.dr.sync_thread()
        return out

    return scene, run


def measure_warm(work: Path, spp: int, repeat: int) -> dict:
    import mi_npr

    t_load = []
    t_anchor_load = []
    for _ in range(max(3, repeat // 3)):
        _, ms = _timed(lambda: mi_npr.load_scene(work / "plant.xml", width=W, height=H))
        t_load.append(ms)
        _, ms = _timed(lambda: mi_npr.load_scene(work / "anchor.xml", width=W, height=H))
        t_anchor_load.append(ms)
    _, ours = _render(work / "plant.xml", spp)
    _, anchor = _anchor_render(work / "anchor.xml", spp)
    no_beauty = work / "lines_only.xml"
    no_beauty.write_text(
        (work / "plant.xml").read_text().replace('        <integrator type="$beauty"/>\n', "")
    )
    _, lines_only = _render(no_beauty, spp)
    fns = {"ours": ours, "anchor": anchor, "lines_only": lines_only}
    times: dict[str, list[float]] = {k: [] for k in fns}
    for fn in fns.values():
        fn()
    for _ in range(repeat):
        for k, fn in fns.items():
            time.sleep(0.02)
            _, ms = _timed(fn)
            times[k].append(ms)
    gb = ours()
    return {
        "load_ms": statistics.median(t_load),
        "anchor_ply_load_ms": statistics.median(t_anchor_load),
        "render_warm_ms": statistics.median(times["ours"]),
        "anchor_direct_warm_ms": statistics.median(times["anchor"]),
        "lines_only_warm_ms": statistics.median(times["lines_only"]),
        "line_pixels": int((gb["lines.V"] > 0.5).sum()),
        "leaf_pixels": int((gb["leaf_id.V"] > 0).sum()),
    }


def _cold_child(work: str, spp: int) -> None:
    import mi_npr

    dr = mi_npr.dr
    dr.detail.malloc_clear_statistics()
    scene, t_load = _timed(
        lambda: mi_npr.load_scene(Path(work) / "plant.xml", width=W, height=H, spp=spp)
    )

    def run():
        mi_npr.render(scene)
        dr.sync_thread()

    _, t_render = _timed(run)
    peak_kb = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    print(
        json.dumps(
            {
                "cold_load_ms": t_load,
                "cold_render_ms": t_render,
                "peak_rss_mb": peak_kb / 1024,
                "drjit_watermark_mb": dr.detail.malloc_watermark(dr.JitBackend.LLVM) / 2**20,
            }
        )
    )


def measure_cold(work: Path, spp: int, threads: int) -> dict:
    return _common.cold_run(__file__, work, "--spp", spp, "--threads", threads)


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=7)
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--spp", type=int, default=4)
    ap.add_argument("--quick", action="store_true", help="10k leaves, 3 repeats")
    ap.add_argument("--out", type=Path, default=HERE / "results")
    ap.add_argument("--cold-child", help=argparse.SUPPRESS)
    args = ap.parse_args()
    import mi_npr

    mi_npr.dr.set_thread_count(args.threads)
    if args.cold_child:
        _cold_child(args.cold_child, args.spp)
        return 0
    n = 10_000 if args.quick else N_LEAVES
    repeat = 3 if args.quick else args.repeat
    with tempfile.TemporaryDirectory() as tmp:
        work = Path(tmp)
        res = build(work, n)
        res.update(measure_warm(work, args.spp, repeat))
        res.update(measure_cold(work, args.spp, args.threads))
    res["ratio_load_vs_ply"] = res["load_ms"] / res["anchor_ply_load_ms"]
    res["ratio_render_vs_direct"] = res["render_warm_ms"] / res["anchor_direct_warm_ms"]
    print(
        f"\n{res['plant_leaves']} leaves -> {res['hlps']} HLPs, {res['leaf_primitives']} leaf "
        f"primitives ({res['triangles']} triangles); {W}x{H}, {args.spp} spp, "
        f"{args.threads} threads"
    )
    rows = [
        ("procedural_tree", res["procedural_tree_ms"], None),
        ("build_hlps", res["build_hlps_ms"], None),
        ("make_leaves + mesh", res["make_leaves_and_mesh_ms"], None),
        ("load (npr_leaves)", res["load_ms"], res["anchor_ply_load_ms"]),
        ("render, lines (warm)", res["render_warm_ms"], res["anchor_direct_warm_ms"]),
        ("lines only (warm)", res["lines_only_warm_ms"], None),
        ("cold load", res["cold_load_ms"], None),
        ("cold render", res["cold_render_ms"], None),
    ]
    print(f"  {'stage':<24}{'ms':>10}{'anchor ms':>12}{'ratio':>8}")
    for name, ms, anchor in rows:
        extra = f"{anchor:>12.1f}{ms / anchor:>8.2f}" if anchor else ""
        print(f"  {name:<24}{ms:>10.1f}{extra}")
    print(
        f"  memory: build peak (tracemalloc) {res['build_tracemalloc_peak_mb']:.0f} MB, "
        f"process peak RSS {res['peak_rss_mb']:.0f} MB, Dr.Jit watermark "
        f"{res['drjit_watermark_mb']:.0f} MB"
    )
    path = _common.write_report(
        "bench_foliage",
        args.out,
        threads=args.threads,
        repeat=repeat,
        spp=args.spp,
        size=[W, H],
        anchors={
            "load": "Mitsuba's ply plugin loading the same leaf mesh from a PLY file",
            "render": "Mitsuba's direct integrator, same mesh, plain diffuse BSDF, same spp",
        },
        results=res,
    )
    print(f"\nwrote {path}")
    return 0


if __name__ == "__main__":
    sys.exit(main())

"""Every drawing of the tutorials' Lego model: the whole `mi-npr render` command against Mitsuba's.

The scene is mitsuba-tutorials' ``scenes/lego/scene.xml`` as it comes (439 PLY meshes, 2 M
triangles, its ``path`` integrator, 64 spp), rendered at 1280x720. Each case is the command a
user types, in a fresh process; its wall time and peak RSS come from
``resource.getrusage(RUSAGE_CHILDREN)`` of a wrapper process that ran only that command:

- ``mitsuba`` (the anchor): Mitsuba's own command, ``mitsuba -m llvm_ad_rgb -D resx=1280
  -D resy=720 -D spp=64 -o OUT.exr scene.xml`` (load, render, one EXR);
- ``lines``, ``contours``, ``raytree``, ``strokes``, ``cryptomatte``: ``mi-npr render scene.xml
  --width 1280 --height 720 --spp 64 --DRAWING -o OUT`` (load, the beauty, the G-buffer, the
  drawing, the EXR with every layer, the PNGs and SVGs).

The anchor runs before every case and each case is compared with the anchor run beside it
(the shared machine's speed drifts by 10 % over minutes). Goal: every drawing within 1.3x the
anchor's time and peak memory.

The tutorials come from ``--tutorials DIR`` (a clone of mitsuba-renderer/mitsuba-tutorials;
default ``$MI_NPR_TUTORIALS``); without them, or with the model's meshes missing (Git LFS),
the benchmark is skipped with a message, exit code 0, and a JSON report saying why.

    python benchmarks/bench_public.py --tutorials DIR [--quick] [--repeat N] [--drawings A,B]
        [--out DIR]

``--quick``: ``lines`` only, at 640x360. Prints seconds, peak MB and the ratios against the
anchor; writes ``benchmarks/results/bench_public.json``.
"""

from __future__ import annotations

import argparse
import os
import sys
import tempfile
from pathlib import Path

import _common

HERE = Path(__file__).resolve().parent
SCENE = "scenes/lego/scene.xml"
DRAWINGS = ("lines", "contours", "raytree", "strokes", "cryptomatte")
SPP = 64
GOAL = 1.3


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--tutorials", type=Path, default=os.environ.get("MI_NPR_TUTORIALS") or None)
    ap.add_argument("--repeat", type=int, default=1, help="runs of each case (the median)")
    ap.add_argument("--quick", action="store_true", help="lines only, at 640x360")
    ap.add_argument("--drawings", default=",".join(DRAWINGS), help="which, comma-separated")
    ap.add_argument("--out", type=Path, default=HERE / "results")
    args = ap.parse_args()

    if args.tutorials is None or not Path(args.tutorials).is_dir():
        return _common.skipped(
            "bench_public",
            args.out,
            "no mitsuba-tutorials clone: pass --tutorials DIR or set MI_NPR_TUTORIALS",
        )
    xml = Path(args.tutorials) / SCENE
    meshes = sorted((xml.parent / "meshes").glob("*.ply"))
    if not xml.is_file() or not meshes or any(m.stat().st_size < 1024 for m in meshes[:5]):
        return _common.skipped(
            "bench_public",
            args.out,
            f"{xml}: the scene or its PLY meshes are missing (Git LFS pointers?)",
        )
    w, h = (640, 360) if args.quick else (1280, 720)
    drawings = ("lines",) if args.quick else tuple(args.drawings.split(","))
    unknown = sorted(set(drawings) - set(DRAWINGS))
    if unknown:
        raise SystemExit(f"bench_public: --drawings: unknown {', '.join(unknown)}")
    py = sys.executable
    results: dict[str, dict] = {}
    with tempfile.TemporaryDirectory() as tmp:
        out = Path(tmp)
        mitsuba = [py, "-c", "import sys; from mitsuba.cli import _main; sys.exit(_main())"]
        anchor = [*mitsuba, "-m", "llvm_ad_rgb", "-D", f"resx={w}", "-D", f"resy={h}"]
        anchor += ["-D", f"spp={SPP}", "-o", str(out / "plain.exr"), str(xml)]
        render = [py, "-m", "mi_npr.cli", "render", str(xml), "-o", str(out / "npr")]
        render += ["--width", str(w), "--height", str(h), "--spp", str(SPP), "--no-progress"]
        _common.run_measured([*render, "--lines"])  # the kernel cache and the file cache warm
        for name in drawings:
            runs = []
            for _ in range(max(1, args.repeat)):
                base = _common.run_measured(anchor)
                mine = _common.run_measured([*render, f"--{name}"])
                runs.append((mine["s"] / base["s"], mine["peak_mb"] / base["peak_mb"], base, mine))
            runs.sort(key=lambda r: r[0])
            t, m, base, mine = runs[len(runs) // 2]
            results[name] = {
                "s": mine["s"],
                "peak_mb": mine["peak_mb"],
                "mitsuba_s": base["s"],
                "mitsuba_peak_mb": base["peak_mb"],
                "time_vs_mitsuba": t,
                "peak_vs_mitsuba": m,
                "goal_met": t <= GOAL and m <= GOAL,
            }
            print(
                f"  {name:<12} {mine['s']:6.1f} s {mine['peak_mb']:6.0f} MB   mitsuba "
                f"{base['s']:6.1f} s {base['peak_mb']:6.0f} MB   {t:5.2f}x time {m:5.2f}x memory",
                flush=True,
            )
    ok = all(r["goal_met"] for r in results.values())
    print(f"  goal <= {GOAL}x mitsuba's time and peak memory, every drawing: "
          f"{'met' if ok else 'NOT met'}")  # fmt: skip
    path = _common.write_report(
        "bench_public",
        args.out,
        scene=f"mitsuba-tutorials {SCENE} (439 PLY meshes, 2 M triangles), {w}x{h}, {SPP} spp",
        anchor="mitsuba -m llvm_ad_rgb (Mitsuba's own command), run beside each case",
        goal_met=ok,
        results=results,
    )
    print(f"\nwrote {path}")
    return 0


if __name__ == "__main__":
    sys.exit(main())

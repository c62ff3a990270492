"""A cold process, as a user runs it: mi-npr's command line against Mitsuba's own, same scene.

Each case is one fresh process, timed from the shell (wall clock: interpreter start, imports,
LLVM selection, scene loading, kernel compilation or cache loading, rendering, writing files):

- ``mi-npr render``: ``mi-npr render scene1.xml --lines --width 640 --height 480 --spp 1``
  (the G-buffer, anti-aliased depth lines and creases, one EXR with every layer plus the PNGs);
- ``mitsuba aov``: Mitsuba's command line rendering the same scene with its C++ ``aov``
  integrator (depth, shape_index, sh_normal) at 640x480, 1 spp, into an EXR: the cheapest
  "G-buffer" a Mitsuba user gets from the shell (``mitsuba`` finds a good LLVM through mi-npr's
  start-up hook).

Python runs with its bytecode cache on (``PYTHONDONTWRITEBYTECODE`` removed: an installed
package has its ``.pyc`` files; compiling mi-npr's sources alone adds ~0.2 s to a start).
Both are run with Dr.Jit's kernel cache warm (the usual case from the second run on: kernels are
loaded, not compiled) and empty (the very first run on a machine: everything compiled).

    python benchmarks/bench_cold.py [--repeat N] [--out benchmarks/results]

Prints the medians and the ratio mi-npr / Mitsuba (goal: <= 1.5 warm cache), writes JSON.
"""

from __future__ import annotations

import argparse
import re
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import _common

SCENE = _common.ROOT / "scenes_xml" / "scene1.xml"
BIN = Path(sys.executable).parent
AOV = (
    '<integrator type="aov"><string name="aovs" '
    'value="dd.y:depth,id:shape_index,nn:sh_normal"/></integrator>'
)


def _aov_scene(tmp: Path) -> Path:
    """scene1.xml with Mitsuba's ``aov`` integrator in place of its own (same directory, so
    relative paths still resolve)."""
    text = SCENE.read_text()
    text = re.sub(r"<integrator type=\"\$integrator\">.*?</integrator>\s*</integrator>", AOV, text,
                  flags=re.S)  # fmt: skip
    path = SCENE.parent / f".bench_cold_{tmp.name}.xml"
    path.write_text(text)
    return path


def _time(cmd: list[str], env: dict[str, str]) -> float:
    t0 = time.perf_counter()
    subprocess.run(cmd, check=True, capture_output=True, env=env)
    return time.perf_counter() - t0


def main() -> int:
    import os

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=5)
    ap.add_argument("--out", type=Path, default=_common.HERE / "results")
    args = ap.parse_args()
    with tempfile.TemporaryDirectory() as tmp_s:
        tmp = Path(tmp_s)
        aov_xml = _aov_scene(tmp)
        try:
            cases = {
                "mi-npr render": [
                    str(BIN / "mi-npr"), "render", str(SCENE), "-o", str(tmp / "npr"),
                    "--lines", "--width", "640", "--height", "480", "--spp", "1",
                    "--no-progress",
                ],
                "mitsuba aov": [
                    str(BIN / "mitsuba"), "-m", "llvm_ad_rgb", "-D", "width=640",
                    "-D", "height=480", "-D", "spp=1", "-o", str(tmp / "aov.exr"), str(aov_xml),
                ],
            }  # fmt: skip
            res: dict = {}
            for cache in ("warm", "empty"):
                for case, cmd in cases.items():
                    times = []
                    for _ in range(args.repeat):
                        env = dict(os.environ)
                        env.pop("PYTHONDONTWRITEBYTECODE", None)
                        if cache == "empty":
                            env["DRJIT_CACHE_DIR"] = str(Path(tempfile.mkdtemp(dir=tmp)))
                        else:
                            _time(cmd, env)  # fill the cache once
                        times.append(_time(cmd, env))
                    res[f"{case} ({cache} cache)"] = statistics.median(times)
        finally:
            aov_xml.unlink(missing_ok=True)
    print("\nscene1.xml at 640x480, 1 spp, one fresh process per run (median seconds)")
    for case, s in res.items():
        print(f"  {case:<32}{s:8.2f}")
    for cache in ("warm", "empty"):
        r = res[f"mi-npr render ({cache} cache)"] / res[f"mitsuba aov ({cache} cache)"]
        res[f"ratio ({cache} cache)"] = r
        print(f"  ratio mi-npr / mitsuba ({cache} cache): {r:.2f}")
    path = _common.write_report(
        "bench_cold",
        args.out,
        scene=str(SCENE.relative_to(_common.ROOT)),
        repeat=args.repeat,
        target="mi-npr render --lines <= 1.5x mitsuba's aov command (warm cache)",
        results=[res],
    )
    print(f"\nwrote {path}")
    return 0


if __name__ == "__main__":
    sys.exit(main())

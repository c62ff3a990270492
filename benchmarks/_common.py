"""What the benchmarks share: Mitsuba's ``aov`` anchor, cold runs in a fresh process with an
empty kernel cache, and the JSON report (``import _common`` from a script in this folder)."""

from __future__ import annotations

import argparse
import json
import os
import platform
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent


def parse_args(
    doc: str, setup: Callable[[str, int, int], Callable[[], Any]], quick: str
) -> argparse.Namespace | None:
    """The benchmarks' options (``--repeat``, ``--quick``, ``--out``); ``None`` when this process
    is a cold-run child (``--cold-child case w h``), which has then timed its run."""
    ap = argparse.ArgumentParser(description=doc.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=15)
    ap.add_argument("--quick", action="store_true", help=quick)
    ap.add_argument("--out", type=Path, default=HERE / "results")
    ap.add_argument("--cold-child", nargs=3, help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.cold_child:
        cold_child(setup, args.cold_child[0], *map(int, args.cold_child[1:]))
        return None
    return args


def aov_anchor(scene: Any, w: int, h: int, box: bool) -> Callable[[], None]:
    """Mitsuba's C++ ``aov`` integrator (depth, shape_index, sh_normal) at 1 spp on ``scene``:
    with a ``box`` reconstruction filter (its cheapest setting), or with the scene's own film."""
    import mi_npr

    mi, dr = mi_npr.mi, mi_npr.dr
    aov = mi.load_dict({"type": "aov", "aovs": "dd.y:depth,id:shape_index,nn:sh_normal"})
    sensor = scene.sensors()[0]
    if box:
        import numpy as np

        m = np.asarray(sensor.world_transform().matrix, dtype=np.float64).reshape(4, 4)
        sensor = mi.load_dict(
            {
                "type": "perspective",
                "fov": float(mi.traverse(sensor)["x_fov"][0]),
                "to_world": mi.ScalarTransform4f(m),
                "film": {"type": "hdrfilm", "width": w, "height": h, "rfilter": {"type": "box"}},
                "sampler": {"type": "independent", "sample_count": 1},
            }
        )

    def run_aov():
        img = mi.render(scene, sensor=sensor, integrator=aov, spp=1)
        dr.eval(img)
        dr.sync_thread()

    return run_aov


def cold_child(setup: Callable[[str, int, int], Callable[[], Any]], case: str, w: int, h: int):
    """In the child process: time the first run of ``setup(case, w, h)``, print it as JSON."""
    fn = setup(case, w, h)
    t0 = time.perf_counter()
    fn()
    print(json.dumps({"cold_ms": (time.perf_counter() - t0) * 1e3}))


def cold_run(script: str, *args: object) -> dict[str, Any]:
    """Run ``script --cold-child ARGS`` in a fresh process with an empty Dr.Jit kernel cache
    (compilation included) and return the JSON object it printed last."""
    with tempfile.TemporaryDirectory() as cache:
        env = dict(os.environ, DRJIT_CACHE_DIR=cache)
        out = subprocess.run(
            [sys.executable, script, "--cold-child", *map(str, args)],
            capture_output=True,
            text=True,
            env=env,
            check=True,
        )
    return json.loads(out.stdout.strip().splitlines()[-1])


def measure_cold(script: str, case: str, w: int, h: int) -> float:
    """The cold time in ms of ``case`` at ``w`` x ``h`` (see :func:`cold_run`)."""
    return cold_run(script, case, w, h)["cold_ms"]


#: Runs a command (its arguments) and prints its wall time, its peak RSS and its stderr as
#: JSON: ``resource.getrusage(RUSAGE_CHILDREN)`` of a wrapper process that ran only that command.
_MEASURED = (
    "import json, resource, subprocess, sys, time\n"
    "t0 = time.perf_counter()\n"
    "r = subprocess.run(sys.argv[1:], capture_output=True, text=True)\n"
    "dt = time.perf_counter() - t0\n"
    "if r.returncode: sys.stderr.write(r.stderr); sys.exit(r.returncode)\n"
    "ru = resource.getrusage(resource.RUSAGE_CHILDREN)\n"
    "print(json.dumps({'s': dt, 'peak_mb': ru.ru_maxrss / 1024, 'stderr': r.stderr}))\n"
)


def run_measured(cmd: list[str], env: dict[str, str] | None = None) -> dict[str, Any]:
    """Run ``cmd`` in a fresh process: ``{"s": wall seconds, "peak_mb": its peak RSS,
    "stderr": ...}``; a failure ends the benchmark with the command and its stderr."""
    out = subprocess.run(
        [sys.executable, "-c", _MEASURED, *cmd],
        capture_output=True,
        text=True,
        env=dict(os.environ, **(env or {})),
    )
    if out.returncode:
        raise SystemExit(f"failed: {' '.join(cmd)}\n{out.stderr}")
    return json.loads(out.stdout.strip().splitlines()[-1])


def cpu_model() -> str:
    """The CPU's name and its widest SIMD: Dr.Jit's LLVM kernels run 16 lanes wide with AVX-512,
    8 with AVX2, so the same code differs by ~2.5x between such machines (OpenCV much less)."""
    name, flags = platform.processor() or "unknown", set()
    try:
        with open("/proc/cpuinfo") as f:
            for line in f:
                key, _, value = line.partition(":")
                if key.strip() == "model name":
                    name = value.strip()
                elif key.strip() in ("flags", "Features"):
                    flags = set(value.split())
                    break
    except OSError:
        pass
    simd = [f for f in ("avx512f", "avx2", "neon", "asimd") if f in flags]
    return f"{name} ({simd[0] if simd else 'no AVX2/AVX-512'})"


def skipped(name: str, out: Path, why: str) -> int:
    """Say why benchmark ``name`` did not run and record it in its report; exit code 0."""
    print(f"{name}: skipped: {why}")
    write_report(name, out, skipped=why)
    return 0


def write_report(name: str, out: Path, **fields: Any) -> Path:
    """``out/<name>.json``: the machine, versions and ``fields`` (scene, results, ...)."""
    import mi_npr

    report = {
        "benchmark": name,
        "date": time.strftime("%Y-%m-%dT%H:%M:%S"),
        "machine": {
            "cpu_count": os.cpu_count(),
            "cpu": cpu_model(),
            "platform": platform.platform(),
            "python": platform.python_version(),
        },
        "mi_npr": mi_npr.__version__,
        "variant": mi_npr.mi.variant(),
        "llvm": mi_npr.LLVM.chosen.describe() if mi_npr.LLVM and mi_npr.LLVM.chosen else None,
        **fields,
    }
    out.mkdir(parents=True, exist_ok=True)
    path = out / f"{name}.json"
    path.write_text(json.dumps(report, indent=2))
    return path

"""Batch at scale: ``mi_npr.batch.run`` on Dask against a plain in-process loop.

48 jobs: 2 scenes (``scene1``, ``scene2``) x ``orbit:24`` at 160 x 120, ``spp`` 16, with the
``lines`` drawing, every job written (EXR, PNG, lines PNG/SVG) and its manifest line appended.

- anchor: a plain loop in this process: each scene loaded once, each view's sensor built
  (:func:`mi_npr.camera.sensor_for`), ``render_layers`` + ``write_layered_outputs``, no Dask;
- ``1 worker``: a LocalCluster (:func:`mi_npr.batch.local_cluster`) of 1 process with 2
  Dr.Jit threads (all the cores);
- ``2 workers``: a LocalCluster of 2 processes with 1 Dr.Jit thread each.

Each cluster is started, then warmed up by a small batch (kernels compiled, scenes loaded once:
what a long batch amortises), then timed on the 48 jobs into a fresh directory. Reported:
throughput of 2 workers against 1 (goal >= 1.7x on 2 cores), per-job overhead of the batch on 1
worker against the loop (goal <= 15 ms a job), the cold time of the whole command (cluster start
included), and the projected time of 1,000 scenes x 20 views on N machines like this one from
the measured per-job cost of 2 workers (linear: jobs are independent, one task each).

    python benchmarks/bench_batch.py [--out DIR]
"""

from __future__ import annotations

import argparse
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import _common

W, H, SPP = 160, 120, 16
VIEWS = 24
SCENES = [str(_common.ROOT / "scenes_xml" / f"scene{k}.xml") for k in (1, 2)]
GOAL_SPEEDUP, GOAL_OVERHEAD_MS = 1.7, 15.0
KW = {"drawings": ["lines"], "width": W, "height": H, "spp": SPP, "progress": False}


def plain_loop(out: Path) -> float:
    """The anchor: the same renders and writes in one process, no Dask, no manifest."""
    import mi_npr
    from mi_npr.camera import sensor_for
    from mi_npr.pipeline import render_layers
    from mi_npr.session import SceneSession
    from mi_npr.views import cameras, parse_views

    spec = parse_views(f"orbit:{VIEWS}")
    t0 = time.perf_counter()
    for path in SCENES:
        s = SceneSession.open(path, spp=SPP, resolution=(W, H))
        for vid, cam in cameras(spec, s.scene, s.sensor):
            r = render_layers(s.scene, ["lines"], {}, sensor=sensor_for(cam, s.sensor), spp=SPP)
            mi_npr.io.write_layered_outputs(r, out / Path(path).stem, vid)
    return time.perf_counter() - t0


def on_cluster(workers: int, threads: int, tmp: Path) -> tuple[float, list[dict]]:
    from distributed import Client

    import mi_npr

    with mi_npr.batch.local_cluster(workers) as cluster, Client(cluster) as client:
        common = dict(KW, threads_per_worker=threads)
        warm = mi_npr.batch.run(SCENES, f"orbit:{VIEWS}", client, out=tmp / f"warm{workers}",
                                **common)  # fmt: skip
        assert all(r["status"] == "done" for r in warm)
        t0 = time.perf_counter()
        rows = mi_npr.batch.run(SCENES, f"orbit:{VIEWS}", client, out=tmp / f"w{workers}",
                                **common)  # fmt: skip
        seconds = time.perf_counter() - t0
    assert len(rows) == 2 * VIEWS and all(r["status"] == "done" for r in rows)
    return seconds, rows


def cold_command(tmp: Path) -> float:
    """``mi-npr batch`` end to end (interpreter, LocalCluster of 2 workers, 48 jobs)."""
    argv = [sys.executable, "-m", "mi_npr.cli", "batch", *SCENES, "-o", str(tmp / "cli")]
    argv += ["--views", f"orbit:{VIEWS}", "--lines", "--width", str(W), "--height", str(H)]
    argv += ["--spp", str(SPP), "--workers", "2", "--no-progress"]
    t0 = time.perf_counter()
    subprocess.run(argv, check=True, capture_output=True)
    return time.perf_counter() - t0


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", type=Path, default=_common.HERE / "results")
    args = ap.parse_args()
    jobs = 2 * VIEWS
    with tempfile.TemporaryDirectory() as d:
        tmp = Path(d)
        plain_loop(tmp / "loop_warm")  # kernels compiled, caches warm
        loop = plain_loop(tmp / "loop")
        one, _ = on_cluster(1, 2, tmp)
        two, rows = on_cluster(2, 1, tmp)
        cold = cold_command(tmp)
    speedup = one / two
    overhead_ms = (one - loop) / jobs * 1e3
    per_job = two / jobs  # seconds a job on one 2-core machine, 2 workers
    workers = sorted({r["worker"] for r in rows})
    projection = {
        f"{n} machines": round(1000 * 20 * per_job / n, 1) for n in (1, 10, 100)
    }  # seconds
    print(f"{jobs} jobs (2 scenes x orbit:{VIEWS}) at {W}x{H}, spp {SPP}, lines")
    print(f"  plain loop (anchor)     {loop:7.2f} s  {loop / jobs * 1e3:7.1f} ms/job")
    print(f"  batch, 1 worker x 2 thr {one:7.2f} s  {one / jobs * 1e3:7.1f} ms/job")
    print(f"  batch, 2 workers x 1 thr{two:7.2f} s  {two / jobs * 1e3:7.1f} ms/job")
    print(f"  2 workers / 1 worker: {speedup:.2f}x (goal >= {GOAL_SPEEDUP}x)")
    print(f"  overhead against the loop: {overhead_ms:.1f} ms/job (goal <= {GOAL_OVERHEAD_MS})")
    print(f"  mi-npr batch end to end (cold, cluster start included): {cold:.2f} s")
    for k, v in projection.items():
        print(f"  1,000 scenes x 20 views on {k}: {v:,.0f} s ({v / 3600:.2f} h)")
    path = _common.write_report(
        "bench_batch",
        args.out,
        jobs=jobs,
        size=[W, H],
        spp=SPP,
        drawings=["lines"],
        results={
            "plain_loop_s": loop,
            "one_worker_s": one,
            "two_workers_s": two,
            "speedup_2_vs_1": speedup,
            "overhead_ms_per_job": overhead_ms,
            "ms_per_job_two_workers": per_job * 1e3,
            "cold_command_s": cold,
            "workers_used": len(workers),
            "projection_1000x20_s": projection,
        },
        goals={"speedup_2_vs_1": GOAL_SPEEDUP, "overhead_ms_per_job": GOAL_OVERHEAD_MS},
    )
    print(f"wrote {path}")


if __name__ == "__main__":
    main()

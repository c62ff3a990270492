"""``mi-npr batch`` on a real Dask cluster: a ``dask scheduler`` and ``dask worker``
processes on 127.0.0.1 started here (random free ports, stopped by their PIDs). Both workers
render; a worker SIGKILLed mid-batch loses no job; a client SIGKILLed mid-batch and re-run with
``--resume`` redoes nothing finished and misses nothing; a job rendered on the cluster has the
same EXR layers, bit for bit, as in one process."""

from __future__ import annotations

import json
import os
import signal
import socket
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

import mi_npr
import mi_npr.cli
from mi_npr.io.manifest import read_rows

from .helpers import ROOT, scene_xml

SCENES = [str(ROOT / "scenes_xml" / "scene1.xml"), str(ROOT / "scenes_xml" / "scene2.xml")]
SIZE = ["--width", "32", "--height", "24", "--spp", "2"]


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def _start(args: list[str], log: Path) -> subprocess.Popen:
    return subprocess.Popen(
        [sys.executable, "-m", *args],
        stdout=subprocess.DEVNULL,
        stderr=open(log, "wb"),
        cwd=ROOT,
        start_new_session=True,
    )


def _stop(p: subprocess.Popen) -> None:
    if p.poll() is None:
        p.send_signal(signal.SIGKILL)
    p.wait(timeout=30)


class Cluster:
    def __init__(self, tmp: Path):
        self.tmp = tmp
        self.address = f"tcp://127.0.0.1:{_free_port()}"
        self.procs: dict[str, subprocess.Popen] = {}

    def start_scheduler(self) -> None:
        port = self.address.rsplit(":", 1)[1]
        self.procs["scheduler"] = _start(
            ["distributed.cli.dask_scheduler", "--host", "127.0.0.1", "--port", port,
             "--dashboard-address", ":0"],
            self.tmp / "scheduler.log",
        )  # fmt: skip

    def start_worker(self, name: str) -> None:
        self.procs[name] = _start(
            ["distributed.cli.dask_worker", self.address, "--name", name, "--nthreads", "1",
             "--no-nanny", "--no-dashboard", "--death-timeout", "60"],
            self.tmp / f"{name}.log",
        )  # fmt: skip

    def wait_for(self, n: int) -> dict[str, str]:
        """Wait until ``n`` workers are connected; {address: name}."""
        from distributed import Client

        with Client(self.address, timeout="30s") as c:
            c.wait_for_workers(n, timeout=60)
            info = c.scheduler_info(n_workers=-1)["workers"]
            return {a: w["name"] for a, w in info.items()}

    def kill(self, name: str) -> None:
        _stop(self.procs.pop(name))

    def stop(self) -> None:
        for name in [n for n in self.procs if n != "scheduler"] + ["scheduler"]:
            if name in self.procs:
                _stop(self.procs.pop(name))


@pytest.fixture(scope="module")
def cluster(tmp_path_factory):
    c = Cluster(tmp_path_factory.mktemp("cluster"))
    try:
        c.start_scheduler()
        c.start_worker("wA")
        c.start_worker("wB")
        c.wait_for(2)
        yield c
    finally:
        c.stop()


def _batch(out: Path, views: str, *more: str, popen: bool = False):
    argv = [sys.executable, "-m", "mi_npr.cli", "batch", *SCENES, "-o", str(out)]
    argv += ["--views", views, "--lines", *SIZE, "--no-progress", *more]
    if popen:
        return subprocess.Popen(argv, cwd=ROOT, stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    return subprocess.run(argv, cwd=ROOT, capture_output=True, text=True, timeout=120, check=False)


def _rows(out: Path) -> list[dict]:
    return list(read_rows(out / "manifest.jsonl"))


def _jobs(views: int) -> set[str]:
    return {f"{Path(s).stem}/orbit_{k:03d}" for s in SCENES for k in range(views)}


def test01_both_workers_render_and_the_layers_equal_one_process(cluster, tmp_path):
    out = tmp_path / "cluster"
    # One Dr.Jit thread: the film's atomic accumulation is then in one order (with more, the
    # beauty's last bits vary from run to run even in one process).
    r = _batch(out, "orbit:6", "--scheduler", cluster.address, "--threads-per-worker", "1")
    assert r.returncode == 0, r.stderr
    rows = _rows(out)
    assert {row["job"] for row in rows} == _jobs(6) and len(rows) == 12
    assert all(row["status"] == "done" for row in rows)
    names = cluster.wait_for(2)
    used = {row["worker"] for row in rows}
    assert used == set(names), (used, names)  # both workers rendered jobs
    # The same jobs in this process (no Dask): identical EXR layers.
    local = tmp_path / "local"
    here = mi_npr.batch.run(
        SCENES, "orbit:6", out=local, drawings=["lines"], width=32, height=24, spp=2,
        workers=0, threads_per_worker=1, progress=False,
    )  # fmt: skip
    assert [row["status"] for row in here] == ["done"] * 12
    for row in rows:
        a = mi_npr.io.read_exr(out / row["outputs"][0])
        b = mi_npr.io.read_exr(local / row["outputs"][0])
        assert a.names == b.names and "lines.V" in a.names
        for name in a.names:
            beauty = name in ("R", "G", "B") or name.startswith("beauty.")
            if beauty and mi_npr.mi.variant().startswith("cuda"):
                # CUDA accumulates the film's samples in no fixed order: the last bits differ.
                np.testing.assert_allclose(a.numpy(name), b.numpy(name), rtol=1e-6)
                continue
            np.testing.assert_array_equal(a.numpy(name), b.numpy(name), err_msg=name)
    local_rows = {row["job"]: row for row in here}
    for row in rows:
        assert row["camera"] == local_rows[row["job"]]["camera"]
        assert row["flags"] == local_rows[row["job"]]["flags"]
    # The G-buffer and line layers need no thread cap: exact with any thread count.
    r = _batch(tmp_path / "any", "orbit:6", "--scheduler", cluster.address)
    assert r.returncode == 0, r.stderr
    for row in rows:
        a = mi_npr.io.read_exr(tmp_path / "any" / row["outputs"][0])
        b = mi_npr.io.read_exr(local / row["outputs"][0])
        for name in ("Z", "N.X", "object_id.V", "prim_id.V", "lines.V"):
            np.testing.assert_array_equal(a.numpy(name), b.numpy(name), err_msg=name)


def _kill_when(p: subprocess.Popen, out: Path, lines: int) -> None:
    """SIGKILL ``p`` as soon as the manifest has ``lines`` lines (or it ended)."""
    deadline = time.monotonic() + 90
    manifest = out / "manifest.jsonl"
    while time.monotonic() < deadline and p.poll() is None:
        if manifest.exists() and manifest.read_bytes().count(b"\n") >= lines:
            break
        time.sleep(0.005)
    if p.poll() is None:
        p.send_signal(signal.SIGKILL)
    p.wait(timeout=30)


def test02_a_killed_client_loses_nothing_on_resume(cluster, tmp_path):
    out = tmp_path / "out"
    n = 40
    p = _batch(out, f"orbit:{n}", "--scheduler", cluster.address, popen=True)
    _kill_when(p, out, 3)
    assert p.returncode == -signal.SIGKILL, "the batch ended before it could be killed"
    before = _rows(out)
    done = {row["job"] for row in before if row["status"] == "done"}
    assert 3 <= len(done) < 2 * n
    stamps = {row["job"]: [os.stat(out / f).st_mtime_ns for f in row["outputs"]] for row in before}
    # No partial file under a final name: every EXR there reads.
    for exr in out.glob("*/*.exr"):
        mi_npr.io.read_exr(exr)
    r = _batch(out, f"orbit:{n}", "--scheduler", cluster.address, "--resume")
    assert r.returncode == 0, r.stderr
    after = _rows(out)[len(before) :]
    redone = {row["job"] for row in after}
    assert not (redone & done)  # nothing finished is redone
    assert done | redone == _jobs(n)  # nothing is missing
    assert all(row["status"] == "done" for row in after)
    for job, times in stamps.items():
        row = next(r for r in before if r["job"] == job)
        assert [os.stat(out / f).st_mtime_ns for f in row["outputs"]] == times
    # A second resume has nothing left to do.
    r = _batch(out, f"orbit:{n}", "--scheduler", cluster.address, "--resume")
    assert r.returncode == 0 and len(_rows(out)) == len(before) + len(after)


def test03_a_killed_worker_loses_no_job(cluster, tmp_path):
    cluster.start_worker("victim")
    names = cluster.wait_for(3)
    victim = next(a for a, name in names.items() if name == "victim")
    out = tmp_path / "out"
    n = 24
    p = _batch(out, f"orbit:{n}", "--scheduler", cluster.address, popen=True)
    manifest = out / "manifest.jsonl"
    deadline = time.monotonic() + 90
    while time.monotonic() < deadline and p.poll() is None:
        rows = _rows(out) if manifest.exists() else []
        if any(row["worker"] == victim for row in rows) or len(rows) >= 4:
            break
        time.sleep(0.005)
    cluster.kill("victim")
    stdout, stderr = p.communicate(timeout=120)
    assert p.returncode == 0, stderr
    rows = _rows(out)
    assert {row["job"] for row in rows} == _jobs(n)
    assert len(rows) == 2 * n and all(row["status"] == "done" for row in rows)
    assert b"2 of" not in stdout and f"{2 * n} of {2 * n} jobs done".encode() in stdout
    json.dumps(rows)


# -- nothing hangs ---------------------------------------------------------------------------


def _envmap_scene(tmp: Path) -> Path:
    """A sphere lit by an 8 x 4 EXR environment map, written by mi-npr's own EXR writer."""
    from mi_npr.gbuffer import GBuffer

    rgb = {c: np.full((4, 8), v, np.float32) for c, v in zip("RGB", (0.5, 0.6, 0.7), strict=True)}
    mi_npr.io.write_exr(tmp / "env.exr", GBuffer(rgb))
    xml = tmp / "envmap.xml"
    xml.write_text(
        scene_xml(
            '<emitter type="envmap"><string name="filename" value="env.exr"/></emitter>'
            '<shape type="sphere"><point name="center" x="0" y="0" z="3"/></shape>',
            width=16,
            height=16,
            integrator='<integrator type="path"/>',
        )
    )
    return xml


def test04_an_exr_texture_loads_on_one_thread_per_worker(tmp_path):
    """Mitsuba deadlocks loading an EXR texture under one Dr.Jit thread: two workers of one
    thread each still render the scene (the loader takes two threads, then gives one back)."""
    xml = _envmap_scene(tmp_path)
    out = tmp_path / "out"
    argv = [sys.executable, "-m", "mi_npr.cli", "batch", str(xml), "-o", str(out), "--views",
            "orbit:2", "--workers", "2", "--threads-per-worker", "1", "--no-progress"]  # fmt: skip
    r = subprocess.run(argv, cwd=ROOT, capture_output=True, text=True, timeout=90, check=False)
    assert r.returncode == 0, r.stderr
    rows = _rows(out)
    assert [row["status"] for row in rows] == ["done", "done"]
    beauty = mi_npr.io.read_exr(out / rows[0]["outputs"][0]).beauty
    # Seen around the sphere, the background is the map's constant colour.
    np.testing.assert_allclose(beauty[0, 0], (0.5, 0.6, 0.7), rtol=1e-3)


BODY = '<shape type="sphere"><point name="center" x="0" y="0" z="3"/></shape>'


def _sphere(tmp: Path) -> Path:
    xml = tmp / "sphere.xml"
    xml.write_text(scene_xml(BODY, width=16, height=12))
    return xml


def _hang_once(marker: str) -> None:
    """On a worker: the job of view ``orbit_001`` sleeps forever the first time it runs (a
    marker file says it did), as a deadlocked job would; the other jobs run as usual."""
    import mi_npr.batch as b

    original = getattr(b._scene, "original", b._scene)

    def scene(settings, job):
        if job.view == "orbit_001":
            try:
                os.close(os.open(marker, os.O_CREAT | os.O_EXCL))
            except FileExistsError:
                return original(settings, job)
            while True:
                time.sleep(1)
        return original(settings, job)

    scene.original = original
    b._scene = scene


def test05_a_job_without_progress_is_stopped_and_the_batch_ends(tmp_path):
    """The job of one view sleeps forever on its first attempt: it is stopped past its bound,
    its worker restarted, and its retry renders; the manifest row says why it was retried."""
    from distributed import Client

    xml = _sphere(tmp_path)
    out = tmp_path / "out"
    with mi_npr.batch.local_cluster(2) as cluster, Client(cluster) as client:
        client.run(_hang_once, str(tmp_path / "hung"))
        # a worker knows it is one (its jobs then share one malloc arena: its process is ours)
        assert client.submit(mi_npr.batch._on_dask_worker, pure=False).result() is True
        rows = mi_npr.batch.run([xml], "orbit:3", client, out=out, width=16, height=12, spp=1,
                                progress=False, job_timeout=10, retries=1)  # fmt: skip
    assert [r["status"] for r in rows] == ["done"] * 3
    assert [r["attempt"] for r in rows] == [1, 2, 1]
    (why,) = rows[1]["retried"]
    assert why.startswith("sphere/orbit_001: no progress in 10 s (job timeout): stopped, worker")
    assert rows[0].get("retried") is None and rows[2].get("retried") is None
    manifest = {r["job"]: r for r in _rows(out)}  # the manifest says it too
    assert manifest["sphere/orbit_001"]["retried"] == [why]


def test06_more_workers_than_jobs_start_only_what_the_jobs_need(tmp_path):
    xml = _sphere(tmp_path)
    with pytest.warns(mi_npr.errors.NprWarning, match=r"workers = 64: only 1 job to run, so 1"):
        rows = mi_npr.batch.run([xml], "scene", out=tmp_path / "o", workers=64, spp=1,
                                progress=False)  # fmt: skip
    assert [r["status"] for r in rows] == ["done"]
    assert rows[0]["worker"].startswith("tcp://")


def _peer(kind: str) -> tuple[socket.socket, str]:
    """A listening socket on localhost that never answers (``silent``) or answers bytes that
    are no Dask message (``http``, ``garbage``); served by a daemon thread."""
    import threading

    srv = socket.socket()
    srv.bind(("127.0.0.1", 0))
    srv.listen(8)
    kept = []

    def serve():
        while True:
            try:
                conn, _ = srv.accept()
            except OSError:
                return
            kept.append(conn)
            if kind == "http":
                conn.sendall(b"HTTP/1.1 400 Bad Request\r\nContent-Length: 0\r\n\r\n")
            elif kind == "garbage":
                conn.sendall(b"\xff" * 64 + b"garbage" * 50)

    threading.Thread(target=serve, daemon=True).start()
    return srv, f"tcp://127.0.0.1:{srv.getsockname()[1]}"


def test07_bad_schedulers_fail_within_the_bound_naming_the_flag(tmp_path, capsys):
    import dask

    xml = _sphere(tmp_path)
    with dask.config.set({"distributed.comm.timeouts.connect": "2s"}):
        srv, address = _peer("silent")
        with srv:
            code = mi_npr.cli.main(["batch", str(xml), "-o", str(tmp_path / "o"),
                                    "--scheduler", address, "--no-progress"])  # fmt: skip
        err = capsys.readouterr().err.strip().splitlines()
        assert code == 1 and len(err) == 1
        assert err[0] == (f"mi-npr: error: --scheduler '{address}': cannot connect "
                          "(no answer within 2 s)")  # fmt: skip
        for kind in ("http", "garbage"):
            srv, address = _peer(kind)
            with srv, pytest.raises(mi_npr.ParameterError) as e:
                mi_npr.batch.run([xml], out=tmp_path / "o", scheduler=address, progress=False)
            assert str(e.value).startswith(f"--scheduler '{address}': not a Dask scheduler")
        for bad in ("nonsense", "tcp://host:port", "tcp://[::1", "http://127.0.0.1:80",
                    "tcp://127.0.0.1:99999", ""):  # fmt: skip
            with pytest.raises(mi_npr.ParameterError) as e:
                mi_npr.batch.run([xml], out=tmp_path / "o", scheduler=bad, progress=False)
            assert f"--scheduler {bad!r}: not a scheduler address" in str(e.value)
            assert "\n" not in str(e.value)


def test08_the_dashboard_serves_on_localhost_and_its_link_is_printed(tmp_path, capsys):
    """The local cluster's dashboard (bokeh) answers at the printed link while the batch runs,
    bound to this machine only."""
    import urllib.request

    seen: list[str] = []

    def visit(link: str) -> None:  # called while the cluster is up
        with urllib.request.urlopen(link, timeout=30) as r:
            seen.append(f"{r.status} {r.read(200)[:15]!r}")
        seen.append(link)

    rows = mi_npr.batch.run([_sphere(tmp_path)], "orbit:2", out=tmp_path / "o", width=16,
                            height=12, spp=1, workers=1, progress=False,
                            on_dashboard=visit)  # fmt: skip
    assert [r["status"] for r in rows] == ["done", "done"]
    status, link = seen
    assert status.startswith("200") and link.startswith("http://127.0.0.1:")
    # the command prints it
    argv = ["batch", str(_sphere(tmp_path)), "-o", str(tmp_path / "c"), "--workers", "1",
            "--width", "16", "--height", "12", "--spp", "1", "--no-progress"]  # fmt: skip
    assert mi_npr.cli.main(argv) == 0
    err = capsys.readouterr().err
    assert "mi-npr: dashboard http://127.0.0.1:" in err

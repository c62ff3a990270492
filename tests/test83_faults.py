"""Faults leave no debris. SIGTERM is handled like SIGINT (exit 143, temporary files
removed, no partial output set); after a SIGKILL, the next run that writes to the same folder
removes the dead run's temporary files; an output set is replaced all together or not at all."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import textwrap
import time

import numpy as np
import pytest

import mi_npr
from mi_npr.io import _atomic

from .helpers import ROOT, run_cli, scene_xml

BALL = '<shape type="sphere" id="ball"><point name="center" x="0" y="0" z="4"/></shape>'

# A CLI run whose PNG writer stops half-way (its temp file open) and says so.
SLOW = textwrap.dedent("""\
    import sys, time
    import mi_npr, mi_npr.io
    from mi_npr.io._atomic import atomic_output
    from mi_npr.cli import main

    def slow_png(path, image, linear=True):
        with atomic_output(path) as tmp:
            open(tmp, "wb").write(b"partial")
            print("READY", flush=True)
            time.sleep(120)

    mi_npr.io.write_png = slow_png
    sys.exit(main(["render", sys.argv[1], "-o", sys.argv[2], "--no-progress"]))
""")


def temps(d):
    return sorted(p.name for p in d.iterdir() if p.name.endswith(".tmp"))


def _start(tmp_path):
    scene = tmp_path / "ball.xml"
    scene.write_text(scene_xml(BALL))
    out = tmp_path / "out"
    proc = subprocess.Popen(
        [sys.executable, "-c", SLOW, str(scene), str(out)],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        cwd=ROOT,
    )
    assert proc.stdout.readline().strip() == "READY"
    assert len(temps(out)) == 2  # the EXR (waiting for its set) and the PNG being written
    return scene, out, proc


def test01_sigterm_exits_cleanly_without_debris(tmp_path):
    _, out, proc = _start(tmp_path)
    proc.send_signal(signal.SIGTERM)
    _, err = proc.communicate(timeout=60)
    assert proc.returncode == 143
    assert err.strip() == "mi-npr: error: terminated"
    assert list(out.iterdir()) == []  # no temp files, and no EXR without its PNG


def test02_sigkill_debris_is_swept_by_the_next_run(tmp_path):
    scene, out, proc = _start(tmp_path)
    proc.kill()
    proc.wait(timeout=60)
    assert proc.returncode == -signal.SIGKILL
    left = temps(out)
    assert len(left) == 2 and all(f".{proc.pid}." in n for n in left)  # the PID is in the name
    assert all(f".{_atomic.OWNER}." in n for n in left)  # and this host and PID namespace
    r = run_cli("render", str(scene), "-o", str(out), "--no-progress")
    assert r.returncode == 0, r.stderr
    assert sorted(p.name for p in out.iterdir()) == ["ball.exr", "ball.png"]


def test03_stale_rules(tmp_path):
    """A temp of this host and PID namespace: removed when its PID is dead, kept while it
    lives. A temp of another host or PID namespace (shared storage, containers), or an older
    name without the owner: kept until untouched for STALE_AFTER, whatever its PID says (that
    PID may be a live writer there). Files of other tools: kept."""
    dead = subprocess.Popen([sys.executable, "-c", "pass"])
    dead.wait()
    live = subprocess.Popen([sys.executable, "-c", "import time; time.sleep(60)"])
    here, there = _atomic.OWNER, "0123456789ab"
    assert here != there and len(here) == 12
    try:
        names = {  # name: kept, touched an hour and a bit ago
            f".a.exr.{dead.pid}.{here}.abcd_123.tmp": (False, False),
            f".b.exr.{live.pid}.{here}.abcd_123.tmp": (True, False),
            f".c.exr.{dead.pid}.{there}.abcd_123.tmp": (True, False),  # a live writer there
            f".d.exr.{dead.pid}.{there}.abcd_123.tmp": (False, True),
            f".e.exr.{dead.pid}.abcd_123.tmp": (True, False),  # an older name: no owner
            f".f.exr.{dead.pid}.abcd_123.tmp": (False, True),
            ".g.png.zzzz9999.tmp": (False, True),
            ".other.txt": (True, True),
            "a.tmp": (True, True),
        }
        past = time.time() - _atomic.STALE_AFTER - 60
        for n, (_, old) in names.items():
            (tmp_path / n).write_bytes(b"x")
            if old:
                os.utime(tmp_path / n, (past, past))
        _atomic.clean_stale(tmp_path)
        kept = {n for n, (k, _) in names.items() if k}
        assert {n for n in names if (tmp_path / n).exists()} == kept
    finally:
        live.kill()
        live.wait()


def test03b_a_live_writer_in_another_pid_namespace_survives_a_sweep(tmp_path):
    """Another container writes into the same folder (shared storage): its PID, dead in this
    namespace, names a live process there. Its temp survives this process's sweep, and the
    sweep of a real run that writes beside it."""
    gone = subprocess.Popen([sys.executable, "-c", "pass"])
    gone.wait()  # in this namespace the PID is free: a dead PID, as the sweeper sees it
    theirs = tmp_path / f".x.exr.{gone.pid}.fedcba987654.k2j4h6g8.tmp"
    theirs.write_bytes(b"half an EXR")
    ball = tmp_path / "ball.xml"
    ball.write_text(scene_xml(BALL, width=16, height=12))
    assert _atomic.clean_stale(tmp_path) == []
    r = run_cli("render", str(ball), "-o", str(tmp_path), "--no-progress")
    assert r.returncode == 0, r.stderr
    assert theirs.read_bytes() == b"half an EXR"


def test04_an_output_set_is_all_or_nothing(tmp_path, monkeypatch):
    """A failure on the PNG (a full disk) must not leave the new EXR beside the old PNG."""
    rgb = {k: np.zeros((4, 5), np.float32) for k in "RGB"}
    gb = mi_npr.GBuffer({"Z": np.ones((4, 5), np.float32), **rgb})
    old = mi_npr.io.write_outputs(gb, tmp_path, "x")
    before = {p.name: p.read_bytes() for p in old}

    def full_disk(path, image, linear=True):
        with _atomic.atomic_output(path) as tmp:
            open(tmp, "wb").write(b"part")
            raise OSError(28, "No space left on device")

    monkeypatch.setattr(mi_npr.io, "write_png", full_disk)
    new = mi_npr.GBuffer({"Z": np.full((4, 5), 2.0, np.float32), **rgb})
    with pytest.raises(mi_npr.OutputError, match="No space left"):
        mi_npr.io.write_outputs(new, tmp_path, "x")
    assert {p.name: p.read_bytes() for p in tmp_path.iterdir()} == before  # no temp, no mix


def test04b_texts_made_beside_the_images_are_all_or_nothing_too(tmp_path):
    """``write_files`` makes the texts given as functions on another thread while it writes the
    images: the paths come back in order with the texts' contents; a text that fails leaves
    neither the images written meanwhile nor any temporary file."""
    import threading

    from mi_npr.io import write_files

    image = np.full((4, 5, 3), 0.5, np.float32)
    where = []

    def svg():
        where.append(threading.current_thread() is threading.main_thread())
        return "<svg/>"

    out = write_files(tmp_path, [("a.png", image), ("b.svg", svg), ("c.txt", "plain")])
    assert [p.name for p in out] == ["a.png", "b.svg", "c.txt"] and where == [False]
    assert (tmp_path / "b.svg").read_text() == "<svg/>" and (
        tmp_path / "c.txt"
    ).read_text() == "plain"
    before = {p.name: p.read_bytes() for p in tmp_path.iterdir()}

    def broken():
        raise mi_npr.OutputError("b.svg: cannot make it")

    new = np.zeros((4, 5, 3), np.float32)
    with pytest.raises(mi_npr.OutputError, match="cannot make it"):
        write_files(tmp_path, [("a.png", new), ("b.svg", broken), ("d.png", new)])
    assert {p.name: p.read_bytes() for p in tmp_path.iterdir()} == before  # no temp, no mix


def test05_fifos_are_not_regular_files_wherever_a_file_is_read_or_written(tmp_path):
    """A FIFO would block whoever opens it: as the --views file, the manifest (read on
    --resume, appended to), a scene's mesh (also through a $define) or an output, it is one
    line saying "not a regular file", and the command ends."""
    from mi_npr.io.manifest import append_row, read_rows

    fifo = tmp_path / "fifo.json"
    os.mkfifo(fifo)
    ball = tmp_path / "ball.xml"
    ball.write_text(scene_xml(BALL, width=16, height=12))
    mesh = tmp_path / "mesh.xml"
    ply = '<shape type="ply"><string name="filename" value="$m"/></shape>'
    mesh.write_text(scene_xml(f'<default name="m" value="fifo.json"/>{ply}'))
    out = tmp_path / "out"
    cases = [
        (["batch", str(ball), "-o", str(out), "--views", str(fifo)], f"{fifo}: not a regular"),
        (["batch", str(mesh), "-o", str(out)], f"{fifo}: not a regular file"),
        (["render", str(mesh), "-o", str(out)], f"{fifo}: not a regular file"),
    ]
    (tmp_path / "o2").mkdir()
    os.mkfifo(tmp_path / "o2" / "manifest.jsonl")
    for resume in ([], ["--resume"]):
        cases.append((["batch", str(ball), "-o", str(tmp_path / "o2"), *resume],
                      "manifest.jsonl: not a regular file"))  # fmt: skip
    (tmp_path / "o3").mkdir()
    os.mkfifo(tmp_path / "o3" / "ball.png")
    cases.append((["render", str(ball), "-o", str(tmp_path / "o3")], "ball.png: not a regular"))
    for argv, words in cases:
        r = subprocess.run([sys.executable, "-m", "mi_npr.cli", *argv, "--no-progress",
                            *(["--workers", "0"] if argv[0] == "batch" else [])],
                           cwd=ROOT, capture_output=True, text=True, timeout=60)  # fmt: skip
        assert r.returncode == 1, (argv, r.stderr)
        assert words in r.stderr and "Traceback" not in r.stderr, (argv, r.stderr)
    for call in (lambda: append_row(fifo, {"job": "x"}), lambda: list(read_rows(fifo))):
        with pytest.raises(mi_npr.OutputError, match="not a regular file"):
            call()
    assert sorted(p.name for p in (tmp_path / "o3").iterdir()) == ["ball.png"]  # no temp left

"""The batch manifest (whole lines under concurrent appends, bad lines skipped), the
scene's content hash, resume (what it skips and what it redoes), retries and failures, and the
``mi-npr batch`` command's errors, in one process (``--workers 0``) and on a LocalCluster."""

from __future__ import annotations

import json
import multiprocessing as mp
import os
import signal

import dask
import pytest

import mi_npr
import mi_npr.cli
from mi_npr.io.manifest import append_row, read_rows, scene_hash

from .helpers import run_cli

BODY = """<shape type="sphere"><point name="center" x="0" y="0" z="3"/>
<float name="radius" value="1"/></shape>"""


def _appender(path: str, k: int, n: int) -> None:
    for i in range(n):
        append_row(path, {"writer": k, "i": i, "pad": "x" * (37 * i % 9000)})


def test01_concurrent_appends_give_whole_lines(tmp_path):
    path = str(tmp_path / "m.jsonl")
    ctx = mp.get_context("fork")
    procs = [ctx.Process(target=_appender, args=(path, k, 60)) for k in range(4)]
    for p in procs:
        p.start()
    for p in procs:
        p.join(60)
    lines = open(path, "rb").read().split(b"\n")
    assert lines[-1] == b""
    rows = [json.loads(line) for line in lines[:-1]]  # every line parses whole
    assert len(rows) == 240
    for k in range(4):  # each writer's lines in its order
        assert [r["i"] for r in rows if r["writer"] == k] == list(range(60))


def test02_bad_lines_are_skipped(tmp_path):
    path = tmp_path / "m.jsonl"
    assert list(read_rows(path)) == []
    append_row(path, {"job": "a"})
    with open(path, "ab") as f:
        f.write(b'[1, 2]\n{"job": "b", "stat')  # not an object; a line cut short
    assert list(read_rows(path)) == [{"job": "a"}]
    with pytest.raises(ValueError):
        append_row(path, {"x": float("nan")})
    assert list(read_rows(path)) == [{"job": "a"}]


def test03_scene_hash_covers_referenced_files(tmp_path):
    mesh = tmp_path / "m.ply"
    mesh.write_bytes(b"ply 1")
    inc = tmp_path / "inc.xml"
    inc.write_text('<scene version="3.0.0"><bsdf type="diffuse" id="d"/></scene>')
    xml = tmp_path / "s.xml"
    xml.write_text(
        '<scene version="3.0.0"><include filename="inc.xml"/>'
        '<shape type="ply"><string name="filename" value="m.ply"/></shape>'
        '<shape type="ply"><string name="filename" value="$mesh"/></shape></scene>'
    )
    h0 = scene_hash(xml)
    assert h0.startswith("sha256:") and h0 == scene_hash(xml)
    (tmp_path / "other.ply").write_bytes(b"unrelated")
    assert scene_hash(xml) == h0
    mesh.write_bytes(b"ply 2")
    h1 = scene_hash(xml)
    inc.write_text('<scene version="3.0.0"><bsdf type="conductor" id="d"/></scene>')
    h2 = scene_hash(xml)
    assert len({h0, h1, h2}) == 3
    with pytest.raises(mi_npr.ParameterError, match=r"nope\.xml"):
        scene_hash(tmp_path / "nope.xml")


def _run(path, out, **kw):
    kw = {"views": "orbit:3", "out": out, "workers": 0, "progress": False, **kw}
    return mi_npr.batch.run([path], **kw)


def test04_resume_skips_done_and_redoes_the_rest(write_scene, tmp_path):
    path = write_scene(BODY, spp=1)
    out = tmp_path / "out"
    rows = _run(path, out, drawings=["lines"])
    assert [r["status"] for r in rows] == ["done"] * 3
    assert {r["job"] for r in rows} == {f"scene/orbit_{k:03d}" for k in range(3)}
    for r in rows:
        assert set(r) >= {"job", "scene", "scene_hash", "view", "camera", "flags", "outputs",
                          "status", "error", "seconds", "worker"}  # fmt: skip
        assert r["outputs"] == [f"scene/{r['view']}{s}" for s in
                                (".exr", ".png", "_lines.png", "_lines.svg")]  # fmt: skip
        assert r["scene"] == str(path.resolve()) and r["scene_hash"] == scene_hash(path)
    manifest = out / "manifest.jsonl"
    n = len(manifest.read_bytes().splitlines())
    again = _run(path, out, drawings=["lines"], resume=True)
    assert again == rows and len(manifest.read_bytes().splitlines()) == n  # nothing redone
    os.unlink(out / "scene" / "orbit_001_lines.svg")  # a missing output: that job again
    again = _run(path, out, drawings=["lines"], resume=True)
    new = list(read_rows(manifest))[n:]
    assert [r["job"] for r in new] == ["scene/orbit_001"]
    assert (out / "scene" / "orbit_001_lines.svg").is_file()
    # Other flags (spp), or another scene content: every job again.
    again = _run(path, out, drawings=["lines"], resume=True, spp=2)
    assert len(list(read_rows(manifest))) == n + 1 + 3
    path.write_text(path.read_text().replace('value="1"/></shape>', 'value="0.9"/></shape>'))
    _run(path, out, drawings=["lines"], resume=True, spp=2)
    assert len(list(read_rows(manifest))) == n + 1 + 6
    # Without --resume every job runs again.
    _run(path, out, drawings=["lines"], spp=2)
    assert len(list(read_rows(manifest))) == n + 1 + 9


def test05_failures_are_recorded_and_the_others_go_on(write_scene, tmp_path):
    good = write_scene(BODY, name="good.xml")
    bad = tmp_path / "bad.xml"
    bad.write_text('<scene version="3.0.0"><shape type="nosuchshape"/></scene>')
    out = tmp_path / "out"
    rows = mi_npr.batch.run([bad, good], "orbit:2", out=out, workers=0, retries=2,
                            progress=False)  # fmt: skip
    status = {r["job"]: (r["status"], r["attempt"]) for r in rows}
    assert status == {"bad/orbit_000": ("failed", 3), "bad/orbit_001": ("failed", 3),
                      "good/orbit_000": ("done", 1), "good/orbit_001": ("done", 1)}  # fmt: skip
    err = rows[0]["error"]
    assert "bad.xml" in err and "\n" not in err and "Traceback" not in err
    assert not (out / "bad").exists() or not any((out / "bad").iterdir())


def _main(argv: list[str], capsys) -> tuple[int, str]:
    """``mi-npr ARGV`` in this process: the exit code and what it wrote to stderr."""
    try:
        code = mi_npr.cli.main(argv)
    except SystemExit as e:  # a usage error (exit 2)
        code = int(e.code)
    return code, capsys.readouterr().err


def test06_cli_exit_codes_and_errors(write_scene, tmp_path, capsys):
    good = write_scene(BODY, name="good.xml")
    bad = tmp_path / "bad.xml"
    bad.write_text("<scene version='3.0.0'><shape type='nosuchshape'/></scene>")
    out = tmp_path / "out"
    r = run_cli("batch", str(good), str(bad), "-o", str(out), "--views", "orbit:2", "--workers",
                "0", "--no-progress")  # fmt: skip
    assert r.returncode == 1
    assert "2 of 4 jobs done" in r.stdout and r.stderr.count("bad/orbit_00") == 2
    assert "Traceback" not in r.stderr
    for argv, code, words in [
        (["--views", "orbit:0"], 1, "orbit"),
        (["--views", "best:99"], 1, "best"),
        (["--workers", "-1"], 2, "--workers"),
        (["--workers", "5000"], 2, "--workers"),
        (["--threads-per-worker", "0"], 2, "--threads-per-worker"),
        (["--retries", "1000"], 2, "--retries"),
        (["--job-timeout", "0"], 2, "--job-timeout"),
        (["--job-timeout", "nan"], 2, "--job-timeout"),
        (["--scheduler", "tcp://127.0.0.1:9", "--views", "scene"], 1, "--scheduler"),
        (
            ["--crease-angle", "30"],
            1,
            "--crease-angle: no drawing of this batch takes it (add --lines or --strokes)",
        ),
    ]:
        with dask.config.set({"distributed.comm.timeouts.connect": "1s"}):
            got, err = _main(["batch", str(good), "-o", str(tmp_path / "o2"), "--no-progress",
                              *argv], capsys)  # fmt: skip
        assert got == code, (argv, err)
        assert "Traceback" not in err
        assert words in err.strip().splitlines()[-1]  # one line says it


def test07_local_cluster_and_resume_by_cli(write_scene, tmp_path):
    """The default LocalCluster of two single-threaded workers (one thread of Dr.Jit each)."""
    a = write_scene(BODY, name="a.xml")
    b = write_scene(BODY.replace('z="3"', 'z="4"'), name="b.xml")
    out = tmp_path / "out"
    args = ["batch", str(a), str(b), "-o", str(out), "--views", "orbit:3", "--lines",
            "--workers", "2", "--threads-per-worker", "1", "--no-progress"]  # fmt: skip
    r = run_cli(*args)
    assert r.returncode == 0, r.stderr
    rows = list(read_rows(out / "manifest.jsonl"))
    assert len(rows) == 6 and all(x["status"] == "done" for x in rows)
    assert all(x["worker"].startswith("tcp://") for x in rows)
    r = run_cli(*args, "--resume")
    assert r.returncode == 0 and "6 of 6 jobs done" in r.stdout
    assert len(list(read_rows(out / "manifest.jsonl"))) == 6


# -- no file is written by two jobs ------------------------------------------------------------


def test08_job_files_are_what_a_job_writes(write_scene, tmp_path):
    """The names the clash check uses are read off the writer: equal to what a real job wrote,
    every one its stem followed by the rest."""
    from mi_npr.batch import job_files

    path = write_scene(BODY, width=16, height=12)
    for drawings in ((), ("lines",), ("lines", "contours")):
        rows = _run(path, tmp_path / "-".join(drawings or ("none",)), views="scene",
                    drawings=list(drawings))  # fmt: skip
        written = sorted(os.path.basename(p) for p in rows[0]["outputs"])
        assert sorted("scene" + s for s in job_files(tuple(sorted(drawings)))) == written
    assert set(job_files(("lines",))) >= {".exr", ".png", "_lines.png", "_lines.svg"}


def test09_two_jobs_writing_one_file_are_refused_before_rendering(write_scene, tmp_path, capsys):
    path = write_scene(BODY, width=16, height=12)
    views = tmp_path / "views.json"
    cams = [
        {"id": i, "origin": [0, 0, 0], "target": [0, 0, 1], "fov": 40} for i in ("v", "v_lines")
    ]
    views.write_text(json.dumps(cams))
    out = tmp_path / "out"
    with pytest.raises(mi_npr.ParameterError) as e:
        _run(path, out, views=str(views), drawings=["lines"])
    assert str(e.value) == (f"scene/v and scene/v_lines would both write {out / 'scene'}/"
                            "v_lines.png: rename one of them")  # fmt: skip
    assert not (out / "scene").exists()  # nothing rendered
    # Without the lines, v writes no v_lines.png: no clash.
    rows = _run(path, out, views=str(views))
    assert [r["status"] for r in rows] == ["done", "done"]
    # A scene that draws lines by itself (its integrator is npr_lines) clashes the same way.
    lines = write_scene(BODY, name="drawn.xml", integrator='<integrator type="npr_lines"/>')
    with pytest.raises(mi_npr.ParameterError, match="drawn/v and drawn/v_lines would both"):
        _run(lines, out, views=str(views))
    # render a.xml a_lines.xml --lines: one folder, the same clash between scenes.
    a = write_scene(BODY, name="a.xml")
    b = write_scene(BODY, name="a_lines.xml")
    code, err = _main(["render", str(a), str(b), "-o", str(tmp_path / "r"), "--lines"], capsys)
    assert code == 1 and "Traceback" not in err
    assert err.strip() == (f"mi-npr: error: {a} and {b} would both write "
                           f"{tmp_path / 'r' / 'a_lines.png'}: rename one of them")  # fmt: skip
    assert not list((tmp_path / "r").iterdir())
    code, err = _main(["render", str(a), str(b), "-o", str(tmp_path / "r"), "--no-progress"],
                      capsys)  # fmt: skip
    assert code == 0, err


# -- resume by content -------------------------------------------------------------------------

TRIANGLE = "v {} 0 3\nv 1 0 3\nv 0 1 3\nf 1 2 3\n"


def _redone(out, n: int) -> list[str]:
    """The jobs of the rows after the first ``n`` of the manifest."""
    return [r["job"] for r in list(read_rows(out / "manifest.jsonl"))[n:]]


def test10_resume_redoes_an_edited_camera_file_and_a_replaced_define_mesh(write_scene, tmp_path):
    (tmp_path / "a.obj").write_text(TRIANGLE.format(-1))
    body = ('<default name="mesh" value="a.obj"/>'
            '<shape type="obj"><string name="filename" value="$mesh"/></shape>')  # fmt: skip
    path = write_scene(body, width=16, height=12)
    views = tmp_path / "views.json"
    cams = [{"id": f"c{k}", "origin": [0.1 * k, 0, 0], "target": [0, 0, 3]} for k in range(3)]
    views.write_text(json.dumps(cams))
    out = tmp_path / "out"
    rows = _run(path, out, views=str(views))
    assert [r["status"] for r in rows] == ["done"] * 3
    n = 3
    _run(path, out, views=str(views), resume=True)
    assert _redone(out, n) == []
    cams[1]["origin"] = [0.5, 0, 0]  # the file edited in place: that camera only
    views.write_text(json.dumps(cams))
    _run(path, out, views=str(views), resume=True)
    assert _redone(out, n) == ["scene/c1"]
    n += 1
    (tmp_path / "a.obj").write_text(TRIANGLE.format(-2))  # the mesh named by $mesh, replaced
    _run(path, out, views=str(views), resume=True)
    assert _redone(out, n) == ["scene/c0", "scene/c1", "scene/c2"]
    n += 3
    # An output cut short (its size differs from the row's): that job again.
    exr = out / "scene" / "c2.exr"
    exr.write_bytes(exr.read_bytes()[:-1])
    _run(path, out, views=str(views), resume=True)
    assert _redone(out, n) == ["scene/c2"]


def test11_a_new_set_leaves_no_file_of_the_old_one_unnamed(write_scene, tmp_path):
    """--resume without --lines: the job's old drawing goes with its old set. A smaller
    orbit into a larger one's folder: a warning names the files it does not own."""
    path = write_scene(BODY, width=16, height=12)
    out = tmp_path / "out"
    _run(path, out, views="orbit:3", drawings=["lines"])
    assert (out / "scene" / "orbit_000_lines.svg").is_file()
    with pytest.warns(mi_npr.errors.NprWarning) as caught:
        rows = _run(path, out, views="orbit:2", resume=True)
    assert [r["status"] for r in rows] == ["done", "done"]
    assert sorted(p.name for p in (out / "scene").iterdir()) == [
        "orbit_000.exr", "orbit_000.png", "orbit_001.exr", "orbit_001.png",
        "orbit_002.exr", "orbit_002.png", "orbit_002_lines.png", "orbit_002_lines.svg",
    ]  # fmt: skip
    (warning,) = [str(w.message) for w in caught]
    assert warning == (f"{out}: 4 files of earlier jobs that this run does not have are left "
                       "beside its outputs (scene/orbit_002.exr, scene/orbit_002.png, "
                       "scene/orbit_002_lines.png, scene/orbit_002_lines.svg)")  # fmt: skip


# -- a manifest that is always readable --------------------------------------------------------


def test12_cut_lines_bad_rows_and_outputs_outside_out(write_scene, tmp_path):
    path = write_scene(BODY, width=16, height=12)
    out = tmp_path / "out"
    manifest = out / "manifest.jsonl"
    rows = _run(path, out, views="orbit:2")
    # A disk that filled mid-line, then the next run: its row starts on a line of its own.
    with open(manifest, "ab") as f:
        f.write(b'{"job": "scene/orbit_000", "sta')
    append_row(manifest, {"job": "x", "status": "failed"})
    lines = manifest.read_bytes().split(b"\n")
    assert lines[2] == b'{"job": "scene/orbit_000", "sta' and json.loads(lines[3])["job"] == "x"
    # A row with a wrong-typed field, a nesting too deep for Python's JSON reader, a row whose
    # outputs name a file outside OUT (a copy of orbit_001's EXR, size and key as recorded).
    bad = {**rows[0], "sizes": "big"}
    outside = tmp_path / "elsewhere.exr"
    outside.write_bytes((out / rows[1]["outputs"][0]).read_bytes())
    escaped = {**rows[1], "outputs": ["../elsewhere.exr"], "sizes": [outside.stat().st_size]}
    with open(manifest, "ab") as f:
        f.write(json.dumps(bad).encode() + b"\n" + b"[" * 200_000 + b"\n")
        f.write(json.dumps(escaped).encode() + b"\n")
    with pytest.warns(mi_npr.errors.NprWarning) as caught:
        again = _run(path, out, views="orbit:2", resume=True)
    said = [str(w.message) for w in caught]
    assert said == [f"{manifest}:3: row skipped: not JSON (JSONDecodeError)",
                    f"{manifest}:5: row skipped: 'sizes' is a str",
                    f"{manifest}:6: row skipped: not JSON (RecursionError)"]  # fmt: skip
    assert again[0] == rows[0]  # skipped: its last readable row is the done one
    assert again[1] != rows[1] and again[1]["status"] == "done"  # outside OUT: done again
    with pytest.warns(mi_npr.errors.NprWarning):  # the same three lines, still there
        assert [r["job"] for r in read_rows(manifest)][-1] == "scene/orbit_001"


def test13_no_bars_off_a_terminal_but_every_line(write_scene, tmp_path, capsys):
    """Without a terminal (a log file, a pipe, this test) no progress bar is drawn, even
    without --no-progress, and every failure still gets its line."""
    good = write_scene(BODY, name="good.xml")
    bad = tmp_path / "bad.xml"
    bad.write_text("<scene version='3.0.0'><shape type='nosuchshape'/></scene>")
    code, err = _main(["batch", str(good), str(bad), "-o", str(tmp_path / "o"), "--workers", "0"],
                      capsys)  # fmt: skip
    assert code == 1
    assert "|" not in err and "job/s" not in err  # no tqdm bar
    assert err.count("mi-npr: error: bad/scene") == 1
    code, err = _main(["render", str(good), str(bad), "-o", str(tmp_path / "r")], capsys)
    assert code == 1 and "|" not in err and "scene/s" not in err
    assert "bad.xml" in err


def _append_and_die(path: str, n: int) -> None:
    from mi_npr.io.manifest import Appender

    rows = Appender(path)
    for i in range(n):
        rows.append({"job": f"j{i}"})
    os.kill(os.getpid(), signal.SIGKILL)  # no close(), no fsync of the last rows


def test14_a_killed_batch_loses_no_row_it_appended(tmp_path):
    path = str(tmp_path / "m.jsonl")
    p = mp.get_context("fork").Process(target=_append_and_die, args=(path, 50))
    p.start()
    p.join(60)
    assert p.exitcode == -signal.SIGKILL
    assert [r["job"] for r in read_rows(path)] == [f"j{i}" for i in range(50)]


def test15_a_batchs_rows_are_synced_once_an_interval_and_at_its_end(
    write_scene, tmp_path, monkeypatch
):
    import mi_npr.io.manifest as manifest

    synced: list[int] = []
    real = os.fsync
    monkeypatch.setattr(os, "fsync", lambda fd: (synced.append(fd), real(fd))[1])
    monkeypatch.setattr(manifest, "SYNC_INTERVAL", 3600.0)
    path = tmp_path / "m.jsonl"
    rows = manifest.Appender(path)
    for i in range(5):
        rows.append({"job": f"j{i}"})
        assert len(list(read_rows(path))) == i + 1  # in the file at once
    assert len(synced) == 1  # the first row; the others within the interval
    rows.close()
    rows.close()
    assert len(synced) == 2  # the end of the batch, once
    monkeypatch.setattr(manifest, "SYNC_INTERVAL", 0.0)
    rows = manifest.Appender(path)
    for i in range(3):
        rows.append({"job": f"k{i}"})
    rows.close()
    assert len(synced) == 5  # every row, and nothing left for close()
    append_row(path, {"job": "alone"})
    assert len(synced) == 6  # a row appended alone is synced at once
    # A batch: its first row, then its end.
    monkeypatch.setattr(manifest, "SYNC_INTERVAL", 3600.0)
    synced.clear()
    out = tmp_path / "out"
    assert [r["status"] for r in _run(write_scene(BODY, spp=1), out)] == ["done"] * 3
    assert len(synced) == 2 and len(list(read_rows(out / "manifest.jsonl"))) == 3

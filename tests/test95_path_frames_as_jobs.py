"""the frames of a camera path as batch jobs (``render_frames(...,
cluster=...)``, ``mi-npr path --workers N``) are the frames the in-process loop writes, and a
resumed path redoes no finished frame."""

from __future__ import annotations

import json

import numpy as np

from mi_npr import camera as C
from mi_npr import layers as L
from mi_npr import paths as P
from mi_npr.io import read_exr

from .helpers import SCENES

SCENE3 = str(SCENES / "scene3.xml")
SIZE = {"resolution": (40, 30), "spp": 1}


def test01_frames_as_jobs_equal_the_in_process_frames(tmp_path):
    cams = C.orbit(SCENE3, 3, 20.0)
    here = P.render_frames(SCENE3, cams, tmp_path / "here", ["lines", "contours"], **SIZE)
    jobs = P.render_frames(
        SCENE3, cams, tmp_path / "jobs", ["lines", "contours"], cluster={"workers": 0}, **SIZE
    )
    for i in range(3):
        a = read_exr(tmp_path / "here" / f"frame_{i:04d}.exr")
        b = read_exr(tmp_path / "jobs" / f"frame_{i:04d}.exr")
        for name in (L.Z, L.LINES, L.CONTOUR, L.OBJECT_ID):
            np.testing.assert_array_equal(a.numpy(name), b.numpy(name), err_msg=name)
        assert (tmp_path / "jobs" / f"frame_{i:04d}_contours.svg").is_file()
    assert jobs.coherence["per_frame"] == here.coherence["per_frame"]
    rows = [json.loads(x) for x in (tmp_path / "jobs" / "manifest.jsonl").read_text().splitlines()]
    assert [r["view"] for r in rows] == ["frame_0000", "frame_0001", "frame_0002"]
    assert all(r["status"] == "done" for r in rows)


def test02_a_resumed_path_redoes_no_frame(tmp_path):
    cams = C.orbit(SCENE3, 2, 10.0)
    out = tmp_path / "p"
    P.render_frames(SCENE3, cams, out, ["lines"], cluster={"workers": 0}, **SIZE)
    stamp = {p.name: p.stat().st_mtime_ns for p in out.glob("frame_*.exr")}
    P.render_frames(SCENE3, cams, out, ["lines"], cluster={"workers": 0, "resume": True}, **SIZE)
    assert {p.name: p.stat().st_mtime_ns for p in out.glob("frame_*.exr")} == stamp
    assert len((out / "manifest.jsonl").read_text().splitlines()) == 2  # nothing rendered again


def test03_a_changed_path_redoes_its_changed_frames(tmp_path):
    """``mi-npr path --resume`` after ``--degrees`` changes: the frames whose camera moved are
    rendered again (the first, at the scene's camera, is not), so every frame matches the
    new ``path.json``; the batch rows record the new cameras."""
    from mi_npr.cli import main

    out = tmp_path / "p"
    argv = ["path", SCENE3, "-o", str(out), "--frames", "3", "--width", "16", "--height", "12",
            "--spp", "1", "--workers", "0", "--no-progress", "--resume"]  # fmt: skip
    assert main([*argv, "--degrees", "30"]) == 0
    assert main([*argv, "--degrees", "90"]) == 0
    rows = [json.loads(x) for x in (out / "manifest.jsonl").read_text().splitlines()]
    assert [r["view"] for r in rows] == ["frame_0000", "frame_0001", "frame_0002",
                                         "frame_0001", "frame_0002"]  # fmt: skip
    path = json.loads((out / "path.json").read_text())
    last = {r["view"]: r for r in rows}
    for i, cam in enumerate(path):
        assert last[f"frame_{i:04d}"]["camera"]["origin"] == cam["origin"]
    for cam, want in zip(path, C.orbit(SCENE3, 3, 90.0), strict=True):  # the new path
        np.testing.assert_allclose(cam["origin"], want.origin, atol=1e-5)


def test04_a_shorter_path_names_the_frames_it_leaves(tmp_path):
    import pytest

    from mi_npr.errors import NprWarning

    out = tmp_path / "p"
    P.render_frames(SCENE3, C.orbit(SCENE3, 3, 20.0), out, **SIZE)
    with pytest.warns(NprWarning) as caught:
        P.render_frames(SCENE3, C.orbit(SCENE3, 2, 20.0), out, **SIZE)
    assert [str(w.message) for w in caught] == [
        f"{out}: frame files of an earlier, longer path are left beside this path's 2 frames: "
        "frame_0002.exr, frame_0002.png"
    ]

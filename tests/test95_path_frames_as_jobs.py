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

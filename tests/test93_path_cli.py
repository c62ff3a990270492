"""``mi-npr path``: frames, drawings, path.json, coherence.json and videos."""

from __future__ import annotations

import json

import numpy as np
import pytest
from PIL import Image

from mi_npr import camera as C
from mi_npr import paths as P
from mi_npr.cli import main
from mi_npr.io import read_exr

from .helpers import SCENES

SCENE3 = str(SCENES / "scene3.xml")
SMALL = ["--width", "40", "--height", "30", "--spp", "1", "--no-progress"]


@pytest.fixture(scope="module")
def explored(tmp_path_factory):
    out = tmp_path_factory.mktemp("path")
    argv = ["path", SCENE3, "-o", str(out), "--frames", "5", "--explore", "entropy"]
    argv += ["--explore-ignore", "floor"]
    rc = main([*argv, "--lines", "--contours", "--video", "gif", "--variants", *SMALL])
    assert rc == 0
    return out


def test01_frames_drawings_and_path(explored):
    for i in range(5):
        for suffix in (".exr", ".png", "_lines.png", "_contours.png"):
            assert (explored / f"frame_{i:04d}{suffix}").is_file()
    assert not (explored / "frame_0005.exr").exists()
    cams = C.from_json((explored / "path.json").read_text())
    assert len(cams) == 5 and [c.time for c in cams] == pytest.approx(np.linspace(0, 1, 5))
    # each frame's EXR camera is the path's camera
    for i in (0, 4):
        cam = read_exr(explored / f"frame_{i:04d}.exr").camera
        np.testing.assert_allclose(cam.origin, cams[i].origin, atol=1e-4)
        np.testing.assert_allclose(cam.forward, cams[i].forward, atol=1e-4)
        assert cam.resolution == (40, 30) and cam.fov == pytest.approx(cams[i].fov, abs=1e-4)
    assert not list(explored.glob(".*.tmp"))
    assert cams == P.explore(SCENE3, 5, "entropy", ignore=["floor"])  # the flag reached explore


def test02_coherence_json_and_videos(explored):
    c = json.loads((explored / "coherence.json").read_text())
    assert c["layer"] == "lines.V" and len(c["per_frame"]) == 4 and 0 <= c["overall"] <= 1
    assert len(c["variants"]) == 4 and all(len(v["per_frame"]) == 4 for v in c["variants"].values())
    for name in ("beauty.gif", "contours.gif"):
        with Image.open(explored / name) as im:
            assert im.n_frames == 5 and im.size == (40, 30)
    first = np.asarray(Image.open(explored / "beauty.gif").convert("RGB"), np.float64)
    png = np.asarray(Image.open(explored / "frame_0000.png").convert("RGB"), np.float64)
    assert np.abs(first - png).mean() < 12  # the GIF's palette against the PNG


def test03_keys_and_mp4(tmp_path):
    keys = [
        C.Camera((4, 3, -4), (0, 0.5, 0), (0, 1, 0), 40),
        C.Camera((-4, 3, -4), (0, 0.5, 0), (0, 1, 0), 45),
    ]
    (tmp_path / "keys.json").write_text(C.to_json(keys))
    out = tmp_path / "o"
    argv = ["path", SCENE3, "-o", str(out), "--frames", "3", "--keys", str(tmp_path / "keys.json")]
    assert main([*argv, "--video", "mp4", *SMALL]) == 0
    cams = C.from_json((out / "path.json").read_text())
    np.testing.assert_allclose(cams[0].origin, keys[0].origin)
    np.testing.assert_allclose(cams[-1].origin, keys[1].origin)
    data = (out / "beauty.mp4").read_bytes()
    assert data[4:8] == b"ftyp" and len(data) > 200
    assert not (out / "contours.mp4").exists()  # no contours drawing: no contour video
    assert not (out / "coherence.json").exists()  # no line layer: nothing to measure


def test04_orbit_is_the_default(tmp_path):
    assert main(["path", SCENE3, "-o", str(tmp_path), "--frames", "2", *SMALL]) == 0
    cams = C.from_json((tmp_path / "path.json").read_text())
    assert cams == C.orbit(SCENE3, 2)
    assert not (tmp_path / "coherence.json").exists()  # nothing drawn: nothing to measure


@pytest.mark.parametrize(
    ("extra", "code", "words"),
    [
        (["--frames", "0"], 2, "--frames"),
        (["--frames", "2", "--orbit", "--explore", "pb"], 2, "not allowed with"),
        (["--frames", "2", "--video", "avi"], 2, "--video"),
        (["--frames", "2", "--max-speed", "0"], 2, "--max-speed"),
        (["--frames", "2", "--keys", "/nonexistent/k.json"], 1, "k.json"),
        (["--frames", "2", "--explore", "pb", "--explore-ignore", "nothing"], 1, "'nothing'"),
    ],
)
def test05_bad_arguments(tmp_path, capsys, extra, code, words):
    argv = ["path", SCENE3, "-o", str(tmp_path / "o"), *extra, *SMALL]
    if code == 2:
        with pytest.raises(SystemExit) as e:
            main(argv)
        assert e.value.code == 2
    else:
        assert main(argv) == 1
    err = capsys.readouterr().err
    assert words in err.strip().splitlines()[-1] and "Traceback" not in err


def test06_bad_keys_file_is_one_line(tmp_path, capsys):
    (tmp_path / "k.json").write_text('[{"origin": [0, 0, 0]}]')
    argv = ["path", SCENE3, "-o", str(tmp_path / "o"), "--frames", "2", "--keys"]
    assert main([*argv, str(tmp_path / "k.json"), *SMALL]) == 1
    err = capsys.readouterr().err
    assert "k.json: camera 0 has no 'target'" in err and len(err.strip().splitlines()) == 1

"""Corrupt, truncated, empty and non-EXR files get one line "PATH: not a valid EXR
(truncated?)" with the OpenEXR library's own messages silenced; directories and devices given as
inputs are named as such, not "no such file"."""

from __future__ import annotations

import numpy as np
import pytest

import mi_npr

from .helpers import run_cli


@pytest.fixture(scope="module")
def damaged(tmp_path_factory):
    d = tmp_path_factory.mktemp("exr")
    gb = mi_npr.GBuffer({"Z": np.ones((64, 64), np.float32), "R": np.zeros((64, 64), np.float32)})
    good = mi_npr.io.write_exr(d / "good.exr", gb).read_bytes()
    corrupt = bytearray(good)
    corrupt[300:400] = b"x" * 100
    files = {
        "truncated": good[: len(good) // 2],
        "header_only": good[:200],
        "empty": b"",
        "corrupt": bytes(corrupt),
        "text": b"hello, not an image\n",
    }
    for name, data in files.items():
        (d / f"{name}.exr").write_bytes(data)
    return d, list(files)


def test01_read_exr_names_the_file(damaged):
    d, names = damaged
    for name in names:
        with pytest.raises(mi_npr.InputError) as e:
            mi_npr.io.read_exr(d / f"{name}.exr")
        assert str(e.value) == f"{d / name}.exr: not a valid EXR (truncated?)"


@pytest.mark.parametrize("name", ["truncated", "corrupt"])
def test02_cli_info_one_line_and_no_library_noise(damaged, name):
    d, _ = damaged
    r = run_cli("info", str(d / f"{name}.exr"))
    assert r.returncode == 1
    assert r.stdout == ""  # the library printed "Warning: Exception raised ..." here
    assert r.stderr == f"mi-npr: error: {d / name}.exr: not a valid EXR (truncated?)\n"


def test03_directories_and_devices(tmp_path):
    for path, why in ((tmp_path, "is a directory"), ("/dev/null", "not a regular file")):
        with pytest.raises(mi_npr.InputError, match=why):
            mi_npr.io.read_exr(path)
        with pytest.raises(mi_npr.SceneError, match=f"{path}: {why}"):
            mi_npr.render(path)
    r = run_cli("render", str(tmp_path), "/dev/null", "-o", str(tmp_path / "out"))
    assert r.returncode == 1
    assert f"{tmp_path}: is a directory" in r.stderr
    assert "/dev/null: not a regular file" in r.stderr and "no such file" not in r.stderr
    assert not list((tmp_path / "out").iterdir())

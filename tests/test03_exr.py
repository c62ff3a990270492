"""EXR I/O: bit-exact round trips, channel types, headers, atomic writes, clear errors."""

from __future__ import annotations

import os

import numpy as np
import OpenEXR
import pytest

from mi_npr import GBuffer, InputError, OutputError, Projection
from mi_npr.io import exr as exr_module
from mi_npr.io import read_exr, write_exr


def _gbuffer(h=5, w=7, seed=0) -> GBuffer:
    rng = np.random.default_rng(seed)
    z = rng.normal(size=(h, w)).astype(np.float32) * 1e3
    special = np.array([np.inf, -np.inf, np.nan, 1e-42, -0.0], dtype=np.float32)  # denormal too
    z.flat[: min(z.size, special.size)] = special[: z.size]
    ids = rng.integers(0, 2**24, size=(h, w), dtype=np.uint64).astype(np.uint32)
    ids[0, 0] = 2**24  # the largest id a FLOAT channel holds exactly (with all below it)
    hashes = rng.integers(0, 2**32, size=(h, w), dtype=np.uint64).astype(np.uint32)
    hashes[0, 0] = 2**32 - 1
    layers = {
        "R": rng.random((h, w)),
        "G": rng.random((h, w)),
        "B": rng.random((h, w)),
        "Z": z,
        "N.X": rng.random((h, w)),
        "object_id.V": ids,
        "prim_id.V": ids // 3,
        "edges_real.V": (rng.random((h, w)) > 0.5).astype(np.float32),
        "raytree_hi.V": hashes,
        "my_ids": ids // 5,  # a user's integer layer
    }
    cam = Projection(np.diag([1.0, 1.0, 1.0, 1.0]), (w, h), 45.0, "perspective", 0.01, 1e4)
    meta = {"mi_npr/scene": "x.xml", "mi_npr/spp": "4"}
    return GBuffer(layers, {1: "floor", 2: "sphere", 3: "ünïcode name"}, cam, meta)


@pytest.mark.parametrize(("h", "w"), [(1, 1), (5, 7), (2, 33)])
def test01_round_trip_is_bit_exact(tmp_path, h, w):
    gb = _gbuffer(h, w)
    path = write_exr(tmp_path / "a.exr", gb)
    back = read_exr(path)
    assert back.names == gb.names  # order restored although EXR sorts channels
    for name in gb.names:
        assert back.numpy(name).dtype == gb.numpy(name).dtype
        np.testing.assert_array_equal(
            back.numpy(name).view(np.uint32), gb.numpy(name).view(np.uint32)
        )
    assert back.objects == gb.objects
    assert back.camera == gb.camera
    assert back.metadata["mi_npr/scene"] == "x.xml"
    assert back.metadata["mi_npr/version"] == mi_npr_version()


def mi_npr_version() -> str:
    import mi_npr

    return mi_npr.__version__


def test02_channel_types_and_names_as_stored(tmp_path):
    path = write_exr(tmp_path / "a.exr", _gbuffer())
    with OpenEXR.File(str(path), separate_channels=True) as f:
        chans = {k: v.pixels.dtype for k, v in f.channels().items()}
        header = dict(f.header())
    # ids as whole-number FLOAT (OpenImageIO reads UINT as [0, 1]); only the hash stays UINT
    assert chans["object_id.V"] == np.float32 and chans["prim_id.V"] == np.float32
    assert chans["my_ids"] == np.float32 and chans["raytree_hi.V"] == np.uint32
    assert chans["Z"] == np.float32 and chans["edges_real.V"] == np.float32
    assert {"R", "G", "B", "Z", "N.X"} <= set(chans)
    assert header["compression"] == OpenEXR.ZIP_COMPRESSION
    w2c = header["worldToCamera"]
    assert w2c.shape == (4, 4)


def test03_non_contiguous_input_is_written_right(tmp_path):
    base = np.arange(35, dtype=np.float32).reshape(5, 7)
    view = np.asfortranarray(base)  # same values, column-major memory
    gb = GBuffer({"Z": np.ones((5, 7), np.float32)})
    object.__setattr__(gb, "layers", {"Z": view})  # bypass GBuffer's own contiguity fix
    back = read_exr(write_exr(tmp_path / "nc.exr", gb))
    np.testing.assert_array_equal(back.numpy("Z"), base)


def test04_failed_write_leaves_no_file(tmp_path, monkeypatch):
    gb = _gbuffer()

    class Boom(Exception):
        pass

    def explode(*a, **k):
        raise Boom("disk full")

    target = tmp_path / "x.exr"
    write_exr(target, gb)
    before = target.read_bytes()
    monkeypatch.setattr(exr_module.OpenEXR, "File", explode)
    with pytest.raises(Boom):
        write_exr(target, gb)
    assert os.listdir(tmp_path) == ["x.exr"]  # no temporary file left behind
    assert target.read_bytes() == before  # the old file is intact


def test05_errors_name_the_file(tmp_path):
    with pytest.raises(InputError, match=r"missing\.exr: no such file"):
        read_exr(tmp_path / "missing.exr")
    bad = tmp_path / "bad.exr"
    bad.write_text("not an exr")
    with pytest.raises(InputError, match=r"bad\.exr: not a valid EXR \(truncated\?\)"):
        read_exr(bad)
    with pytest.raises(OutputError, match="does not exist"):
        write_exr(tmp_path / "nodir" / "a.exr", _gbuffer())
    blocker = tmp_path / "file"
    blocker.write_text("")
    with pytest.raises(OutputError):
        write_exr(blocker / "a.exr", _gbuffer())
    with pytest.raises(TypeError, match="GBuffer"):
        write_exr(tmp_path / "a.exr", {"Z": np.zeros((1, 1))})


def test06_written_files_are_world_readable(tmp_path):
    path = write_exr(tmp_path / "p.exr", _gbuffer())
    assert os.stat(path).st_mode & 0o044 == 0o044


def test07_foreign_exr_with_half_channels(tmp_path):
    rgb = np.random.default_rng(1).random((4, 6)).astype(np.float16)
    p = tmp_path / "foreign.exr"
    with OpenEXR.File(
        {"compression": OpenEXR.NO_COMPRESSION, "type": OpenEXR.scanlineimage},
        {"R": rgb, "G": rgb, "B": rgb},
    ) as f:
        f.write(str(p))
    gb = read_exr(p)
    assert gb.names == ("R", "G", "B") and gb.numpy("R").dtype == np.float32
    assert gb.camera is None and gb.objects == {}
    np.testing.assert_array_equal(gb.numpy("G"), rgb.astype(np.float32))


def test08_metadata_round_trip(tmp_path):
    gb = _gbuffer().with_metadata(note="hand-made", **{"mi_npr/version": "0.0.1"})
    back = read_exr(write_exr(tmp_path / "m.exr", gb))
    assert back.metadata["note"] == "hand-made"  # a key without the prefix comes back as given
    assert back.metadata["mi_npr/version"] != "0.0.1"  # the file says which mi-npr wrote it
    assert back == gb.with_metadata(**{"mi_npr/version": back.metadata["mi_npr/version"]})


def test09_foreign_exr_that_no_gbuffer_may_hold_names_the_file(tmp_path):
    path = tmp_path / "float_ids.exr"
    ids = np.full((2, 3), 1.5, np.float32)  # object ids must be whole numbers
    OpenEXR.File({"type": OpenEXR.scanlineimage}, {"object_id.V": ids}).write(str(path))
    with pytest.raises(InputError, match=r"float_ids\.exr: layer 'object_id.V'"):
        read_exr(path)


def test10_writer_runtime_error_is_an_output_error(tmp_path, monkeypatch):
    def full(*a, **k):
        raise RuntimeError("Failed to write pixel data: No space left on device")

    monkeypatch.setattr(exr_module.OpenEXR, "File", full)
    with pytest.raises(OutputError, match=r"d\.exr: cannot write \(.*No space left on device\)"):
        write_exr(tmp_path / "d.exr", _gbuffer())
    assert os.listdir(tmp_path) == []


def test11_openexr_threads_follow_drjit_and_leave_a_users_count(tmp_path):
    """OpenEXR's thread pool (off by default) gets Dr.Jit's thread count; a count set by
    somebody else stays; the files are the same with threads as without."""
    import drjit as dr

    before = OpenEXR.global_thread_count()
    gb = _gbuffer(64, 48)
    try:
        OpenEXR.set_global_thread_count(0)
        exr_module._threads_set.clear()
        write_exr(tmp_path / "a.exr", gb)
        assert OpenEXR.global_thread_count() == max(1, dr.thread_count())
        OpenEXR.set_global_thread_count(3)  # the user's
        back = read_exr(tmp_path / "a.exr")
        assert OpenEXR.global_thread_count() == 3
        write_exr(tmp_path / "b.exr", back)
        assert (tmp_path / "a.exr").read_bytes() == (tmp_path / "b.exr").read_bytes()
    finally:
        OpenEXR.set_global_thread_count(before)

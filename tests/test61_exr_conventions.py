"""EXR files as compositing apps read them: channel names Blender's multilayer reader maps
(one-letter channels, no two alike in a pass), ids as exact whole-number floats, and the
OpenEXR standard camera attributes, checked by reprojecting ``P`` onto the pixel grid."""

from __future__ import annotations

import json
from collections import defaultdict

import numpy as np
import OpenEXR
import pytest

import mi_npr
from mi_npr import GBuffer, OutputError
from mi_npr import layers as L
from mi_npr.io import read_exr, write_exr

# The channel letters Blender's reader knows (imb_exr_split_channel_name, openexr_api.cpp).
BLENDER_LETTERS = set("RGBAXYZWUV")


def blender_split(name: str) -> tuple[str, str, str] | None:
    """(layer, pass, channel letter) as Blender's multilayer reader splits a channel name, or
    ``None`` where it drops the channel (a channel token longer than one letter)."""
    if len(name) == 1:
        return (
            "",
            {"R": "Combined", "G": "Combined", "B": "Combined", "A": "Combined"}.get(
                name, "Depth" if name == "Z" else name
            ),
            name,
        )
    *rest, chan = name.split(".")
    if len(chan) != 1:
        return None
    return ".".join(rest[:-1]), rest[-1] if rest else "", chan.upper()


def _check_names(names):
    passes = defaultdict(list)
    for n in names:
        split = blender_split(n)
        assert split is not None, f"Blender drops channel {n!r}"
        layer, pas, chan = split
        assert chan in BLENDER_LETTERS, n
        passes[(layer, pas)].append(chan)
    for key, chans in passes.items():
        assert len(chans) == len(set(chans)), f"pass {key} has clashing channels {chans}"


def test01_every_known_layer_maps_in_blender():
    _check_names(L.SPECS)
    # the bare ones are the standard's: the beauty and depth
    assert [n for n in L.SPECS if "." not in n] == ["R", "G", "B", "Z"]


def test02_the_old_names_did_not():
    with pytest.raises(AssertionError):
        _check_names(L.LEGACY)  # object_id, edges.real, ...: dropped or collapsed


@pytest.fixture(scope="module")
def rendered(tmp_path_factory):
    from .helpers import scene_xml

    d = tmp_path_factory.mktemp("cam")
    body = """
        <shape type="sphere" id="ball"><point name="center" x="0.3" y="0.2" z="0"/>
            <float name="radius" value="0.8"/></shape>
        <shape type="rectangle" id="floor"><transform name="to_world">
            <scale value="4"/><rotate x="1" angle="-90"/><translate y="-0.8"/></transform></shape>
    """
    xml = d / "s.xml"
    # an odd, non-square image, a camera off every axis
    xml.write_text(
        scene_xml(body, width=37, height=23, fov=50, origin="2.5, 1.5, -3.5", target="0, 0, 0")
    )
    gb = mi_npr.render(xml)
    path = write_exr(d / "s.exr", gb)
    with OpenEXR.File(str(path), separate_channels=True) as f:
        header = dict(f.header())
        types = {k: v.pixels.dtype for k, v in f.channels().items()}
    return gb, header, types, path


def test03_rendered_file_names_and_types(rendered):
    gb, header, types, _ = rendered
    _check_names(types)
    assert types[L.OBJECT_ID] == np.float32 and types[L.PRIM_ID] == np.float32
    assert json.loads(header["mi_npr/integer_layers"]) == [L.OBJECT_ID, L.PRIM_ID]
    back = read_exr(rendered[3])
    assert back.numpy(L.OBJECT_ID).dtype == np.uint32
    np.testing.assert_array_equal(back.numpy(L.OBJECT_ID), gb.numpy(L.OBJECT_ID))


def _project(M_row: np.ndarray, P: np.ndarray) -> np.ndarray:
    """Points (N, 3) through an Imath matrix (row vectors, p * M), divided by w."""
    h = np.concatenate([P, np.ones((len(P), 1))], axis=1) @ M_row.astype(np.float64)
    return h[:, :3] / h[:, 3:4]


def test04_world_to_ndc_puts_P_on_its_pixel_centre(rendered):
    gb, header, _, _ = rendered
    hit = gb.numpy(L.OBJECT_ID) > 0
    assert hit.sum() > 100 and (~hit).sum() > 0
    ys, xs = np.nonzero(hit)
    P = gb.positions[hit].astype(np.float64)
    ndc = _project(header["worldToNDC"], P)
    px = ndc[:, 0] * gb.width
    py = ndc[:, 1] * gb.height
    err = np.hypot(px - (xs + 0.5), py - (ys + 0.5))
    assert err.max() < 0.01, err.max()
    assert np.all((ndc[:, 2] > 0) & (ndc[:, 2] < 1))  # between the clip planes


def test05_world_to_camera_is_right_up_forward(rendered):
    gb, header, _, _ = rendered
    hit = gb.numpy(L.OBJECT_ID) > 0
    ys, xs = np.nonzero(hit)
    cam = _project(header["worldToCamera"], gb.positions[hit].astype(np.float64))
    np.testing.assert_allclose(cam[:, 2], gb.numpy("Z")[hit], rtol=1e-5)  # +z: the view axis depth
    # +x right: the rightmost hit pixels have the largest x over z; +y up: top rows the largest y
    sx, sy = cam[:, 0] / cam[:, 2], cam[:, 1] / cam[:, 2]
    assert np.corrcoef(sx, xs)[0, 1] > 0.99 and np.corrcoef(sy, -ys)[0, 1] > 0.99
    # a rigid transform (the camera's frame is orthonormal, left-handed as RenderMan's)
    M = header["worldToCamera"].astype(np.float64).T
    np.testing.assert_allclose(M[:3, :3] @ M[:3, :3].T, np.eye(3), atol=1e-6)
    assert np.linalg.det(M[:3, :3]) < 0


def test06_ids_above_2_24_are_an_error_and_no_file(tmp_path):
    ids = np.array([[0, 2**24 + 1]], np.uint32)
    with pytest.raises(OutputError, match=r"big\.exr: layer 'object_id\.V' holds id 16777217"):
        write_exr(tmp_path / "big.exr", GBuffer({L.OBJECT_ID: ids}))
    assert list(tmp_path.iterdir()) == []


def test07_old_files_read_under_the_new_names(tmp_path):
    ids = np.array([[0, 3]], np.uint32)
    p = tmp_path / "old.exr"
    OpenEXR.File(
        {"type": OpenEXR.scanlineimage},
        {"object_id": ids, "edges.real": np.ones((1, 2), np.float32)},
    ).write(str(p))
    gb = read_exr(p)
    assert set(gb.names) == {L.OBJECT_ID, L.EDGES_REAL}
    np.testing.assert_array_equal(gb.numpy(L.OBJECT_ID), ids)

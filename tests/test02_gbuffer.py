"""The GBuffer type: layout checks, dtype rules, immutability of updates, camera round trip."""

from __future__ import annotations

import numpy as np
import pytest

import mi_npr
from mi_npr import GBuffer, ParameterError, Projection


def test01_layers_are_contiguous_and_typed():
    z = np.arange(12, dtype=np.float64).reshape(3, 4).T  # non-contiguous, float64
    ids = np.arange(12, dtype=np.int64).reshape(4, 3)
    gb = GBuffer({"Z": z, "object_id.V": ids, "mask": ids > 3})
    assert gb.shape == (4, 3) and gb.width == 3 and gb.height == 4
    assert gb.numpy("Z").dtype == np.float32 and gb.numpy("Z").flags["C_CONTIGUOUS"]
    assert gb.numpy("object_id.V").dtype == np.uint32
    assert gb.numpy("mask").dtype == np.uint32  # unknown integer-like layers become uint32
    np.testing.assert_array_equal(gb.numpy("Z"), z)


@pytest.mark.parametrize(
    ("layers", "message"),
    [
        ({"Z": np.zeros((2, 2)), "R": np.zeros((2, 3))}, "shape"),
        ({"Z": np.zeros(4)}, "2-D"),
        ({"object_id.V": np.array([[-1, 2]])}, "negative"),
        ({"object_id.V": np.array([[0.5, 2.0]])}, "non-integer"),
        ({}, "at least one layer"),
    ],
)
def test02_bad_layers_name_the_problem(layers, message):
    with pytest.raises(ParameterError, match=message):
        GBuffer(layers)


def test03_with_layers_returns_a_new_buffer():
    gb = GBuffer({"Z": np.ones((2, 2))}, objects={1: "a"})
    gb2 = gb.with_layers({"lines.V": np.zeros((2, 2))})
    assert "lines.V" in gb2 and "lines.V" not in gb
    assert gb2.objects == {1: "a"} and gb2.names == ("Z", "lines.V")
    assert gb2.without("lines.V") == gb
    with pytest.raises(KeyError, match=r"no layer .N.X.*Z, lines"):
        gb2.numpy("N.X")
    with pytest.raises(ParameterError, match="background"):
        GBuffer({"Z": np.ones((1, 1))}, objects={0: "bg"})


def test04_equality_is_bit_exact_with_nan():
    z = np.array([[np.nan, np.inf, -0.0]], dtype=np.float32)
    a, b = GBuffer({"Z": z}), GBuffer({"Z": z.copy()})
    assert a == b
    assert a != GBuffer({"Z": np.array([[np.nan, np.inf, 0.0]], dtype=np.float32)})


def test05_camera_dict_round_trip():
    m = np.eye(4)
    m[:3, 3] = [1, 2, 3]
    cam = Projection(m, (64, 48), 45.0, "perspective", 0.01, 100.0)
    assert Projection.from_dict(cam.to_dict()) == cam
    np.testing.assert_array_equal(cam.origin, [1, 2, 3])
    np.testing.assert_array_equal(cam.forward, [0, 0, 1])
    with pytest.raises(ParameterError, match="camera"):
        Projection.from_dict({"fov": 3})


def test06_accepts_drjit_tensors_without_copy():
    t = mi_npr.mi.TensorXf(np.arange(6, dtype=np.float32).reshape(2, 3))
    gb = GBuffer({"Z": t})
    np.testing.assert_array_equal(gb.numpy("Z"), [[0, 1, 2], [3, 4, 5]])


def test07_object_lookup():
    gb = GBuffer({"object_id.V": np.zeros((1, 1), np.uint32)}, objects={2: "b", 1: "a"})
    assert list(gb.objects) == [1, 2]
    assert gb.object_name(0) == "background" and gb.object_name(2) == "b"
    assert gb.find_object("b") == 2
    with pytest.raises(KeyError):
        gb.object_name(7)


def test08_overlays_keep_the_raw_beauty():
    from mi_npr import compose

    h, w = 3, 4
    rgb = {c: np.full((h, w), 0.5, np.float32) for c in "RGB"}
    gb = GBuffer(rgb)
    a = np.zeros((h, w), np.float32)
    a[1, 2], a[0, 0] = 1.0, np.nan
    once = compose.with_overlay(gb, a, (1, 0, 0))
    np.testing.assert_array_equal(once.beauty[1, 2], [1, 0, 0])
    np.testing.assert_array_equal(once.beauty[0, 0], [0.5, 0.5, 0.5])  # NaN coverage is none
    twice = compose.with_overlay(once, np.roll(a, 1, axis=1), (0, 0, 1))
    np.testing.assert_array_equal(compose.raw_beauty(twice), gb.beauty)  # raw kept once
    np.testing.assert_array_equal(twice.beauty[1, 3], [0, 0, 1])
    with pytest.raises(ParameterError, match="RGB triple"):
        compose.over(gb.beauty, a, (1, 0))


@pytest.mark.parametrize(
    ("layers", "message"),
    [
        ({"object_id.V": np.array([[2**32, 1]], np.int64)}, "above 2\\^32 - 1"),  # no wrap to 0
        ({"ids": np.array([[2**40]], np.uint64)}, "above 2\\^32 - 1"),
        ({"object_id.V": np.array([[2.0**33]])}, "above 2\\^32 - 1"),
        ({"Z": np.array([[None, 1.0]], dtype=object)}, "type object are not numbers"),
        ({"Z": np.array([["a"]])}, "are not numbers"),
        ({"Z": np.zeros((0, 0), np.float32)}, "empty layer of shape \\(0, 0\\)"),
        ({"Z": np.zeros((3, 0), np.float32)}, "empty layer"),
    ],
)
def test06_ids_out_of_range_objects_and_empty_layers_are_refused(layers, message):
    with pytest.raises(ParameterError, match=message):
        GBuffer(layers)
    assert GBuffer({"object_id.V": np.array([[2**32 - 1]], np.int64)}).numpy("object_id.V")[
        0, 0
    ] == np.uint32(2**32 - 1)  # the largest id still fits

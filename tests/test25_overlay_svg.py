"""The red overlay on the beauty, the contour layer, and the SVG document."""

from __future__ import annotations

import base64
import io
import xml.etree.ElementTree as ET

import numpy as np
import pytest
from PIL import Image

import mi_npr
from mi_npr import layers as L
from mi_npr.contours import Contour, overlay, trace
from mi_npr.io import svg_document, write_svg

SVG = "{http://www.w3.org/2000/svg}"


def _gb():
    ids = np.zeros((10, 12), np.uint32)
    ids[2:8, 1:6] = 1
    ids[4:6, 3:4] = 0  # a hole
    ids[3:9, 7:11] = 2
    rgb = np.full((10, 12), 0.25, np.float32)
    layers = {"R": rgb, "G": rgb, "B": rgb, L.OBJECT_ID: ids, L.PRIM_ID: np.zeros_like(ids)}
    return mi_npr.GBuffer(layers, objects={1: "a & <b>", 2: "2nd one"})


def test01_overlay_draws_red_on_contour_pixels_only():
    gb = _gb()
    out, contours = overlay(gb)
    layer = out.numpy(L.CONTOUR)
    assert layer.dtype == np.uint32
    ref = np.zeros_like(layer)
    for c in trace(gb):
        ref[c.ys, c.xs] = c.object_id
    np.testing.assert_array_equal(layer, ref)
    on = layer != 0
    assert (
        np.all(out.numpy("R")[on] == 1)
        and np.all(out.numpy("G")[on] == 0)
        and np.all(out.numpy("B")[on] == 0)
    )
    assert np.all(out.numpy("R")[~on] == 0.25) and np.all(out.numpy("G")[~on] == 0.25)
    np.testing.assert_array_equal(out.numpy("beauty.R"), gb.numpy("R"))  # the raw beauty is kept
    assert out.metadata["mi_npr/contour_method"] == "border"
    assert out.metadata["mi_npr/contour_id_mode"] == "shape"
    assert out.metadata["mi_npr/contour_objects"] == '{"1": "a & <b>", "2": "2nd one"}'
    # Again with another colour: replaces, does not stack.
    again, _ = overlay(out, color=(0, 0, 1))
    assert np.all(again.numpy("R")[on] == 0) and np.all(again.numpy("B")[on] == 1)
    assert np.all(again.numpy("R")[~on] == 0.25)
    assert len(contours) == 3


def test02_overlay_code_direction_layer_is_its_points():
    gb = _gb()
    out, contours = overlay(gb, method="code_direction")
    pts = np.zeros(gb.shape, bool)
    for c in contours:
        pts[c.ys, c.xs] = True
    np.testing.assert_array_equal(out.numpy(L.CONTOUR) != 0, pts)
    with pytest.raises(mi_npr.ParameterError, match="method"):
        overlay(gb, method="x")


def test03_svg_parses_and_groups_per_object():
    gb = _gb()
    _, contours = overlay(gb)
    text = svg_document(contours, 12, 10, beauty=gb.beauty, title="t & t")
    root = ET.fromstring(text)
    assert root.tag == SVG + "svg" and root.get("viewBox") == "0 0 12 10"
    groups = root.findall(f"{SVG}g/{SVG}g")
    assert [g.get("data-name") for g in groups] == ["a & <b>", "2nd one"]
    ids = [g.get("id") for g in groups]
    assert ids == ["a____b_", "_2nd_one"] and len(set(ids)) == 2
    paths = root.findall(f".//{SVG}path")
    assert len(paths) == len(contours) == 3
    holes = [p for p in paths if p.get("class") == "hole"]
    assert len(holes) == 1 and holes[0].get("fill-rule") == "evenodd"
    # Paths go through pixel centres, in tracing order, closed.
    d = paths[0].get("d")
    assert d.startswith("M 1.5 2.5 L 2.5 2.5") and d.endswith(" Z")
    nums = [float(v) for v in d.replace("M", "").replace("L", "").replace("Z", "").split()]
    np.testing.assert_array_equal(np.reshape(nums, (-1, 2)) - 0.5, contours[0].points)
    image = root.find(f".//{SVG}image")
    href = image.get("{http://www.w3.org/1999/xlink}href")
    png = Image.open(io.BytesIO(base64.b64decode(href.split(",", 1)[1])))
    assert png.size == (12, 10) and png.mode == "RGB"
    assert root.find(f"{SVG}g[@id='contours']").get("stroke") == "#ff0000"


def test04_svg_options_and_odd_names(tmp_path):
    cs = [
        Contour(1, "beauty", [[0, 0]]),
        Contour(2, "beauty ", [[1, 1], [2, 1]], closed=False),
        Contour(3, "", [[3, 3]]),
        Contour(4, "tab\tbell\x07 <&>", [[4, 4]]),  # XML cannot hold \x07, even escaped
    ]
    path = write_svg(
        tmp_path / "c.svg", cs, 5, 5, color=(0, 1, 0), stroke_width=2, title="a\x01 & b"
    )
    root = ET.parse(path).getroot()  # well-formed
    names = [g.get("data-name") for g in root.findall(f"{SVG}g/{SVG}g")]
    assert names[3] == "tab\tbell\ufffd <&>" and root.find(f"{SVG}title").text == "a\ufffd & b"
    assert root.find(f".//{SVG}image") is None
    ids = [g.get("id") for g in root.findall(f"{SVG}g/{SVG}g")]
    assert len(set(ids)) == 4 and "beauty" not in ids  # the image's id stays unique
    paths = root.findall(f".//{SVG}path")
    assert paths[0].get("d") == "M 0.5 0.5 Z" and not paths[1].get("d").endswith("Z")
    assert root.find(f"{SVG}g[@id='contours']").get("stroke") == "#00ff00"
    assert root.find(f"{SVG}g[@id='contours']").get("stroke-width") == "2"
    with pytest.raises(mi_npr.ParameterError, match="beauty"):
        svg_document(cs, 5, 5, beauty=np.zeros((4, 5, 3)))
    with pytest.raises(mi_npr.ParameterError, match="width"):
        svg_document(cs, 0, 5)

"""The npr_leaves shape: one mesh built when the scene loads (leaf_size as a <default>), the
leaf_id layer, npr_lines with leaf_edges, and clear errors for bad or empty plants."""

from __future__ import annotations

import numpy as np
import pytest
from PIL import Image

import mi_npr
from mi_npr import foliage as fo
from mi_npr import layers as L
from mi_npr.errors import SceneError
from mi_npr.meshes import write_ply

from .helpers import scene_xml

mi = mi_npr.mi


@pytest.fixture(scope="module")
def files(tmp_path_factory):
    d = tmp_path_factory.mktemp("plant")
    plant = fo.procedural_tree(seed=11, n_leaves=250)
    hlps = fo.build_hlps(plant, k=5)
    plant.save(d / "plant.ply")
    hlps.save(d / "hlps.json")
    return d, plant, hlps


def leaves_xml(
    params: str = "",
    bsdf: str = '<bsdf type="diffuse"/>',
    shape_id: str = "leaves",
    files: str = '<string name="plant" value="plant.ply"/><string name="hlps" value="hlps.json"/>',
) -> str:
    return f"""
        <shape type="npr_leaves" id="{shape_id}">
            {files}
            {params}
            {bsdf}
        </shape>"""


def write(d, body: str, name: str = "s.xml", **kw) -> str:
    kw = {"width": 48, "height": 48, "origin": "0, 1.4, 6", "target": "0, 1.4, 0", **kw}
    (d / name).write_text(scene_xml(body + '<emitter type="constant"/>', **kw))
    return d / name


def test01_the_mesh_is_make_leaves(files):
    d, plant, hlps = files
    path = write(
        d,
        leaves_xml(
            '<float name="leaf_size" value="$leaf_size"/><string name="leaf_shape" value="disc"/>'
        ).replace("<shape", '<default name="leaf_size" value="0.2"/><shape', 1),
    )
    for size in (0.2, 0.1):
        scene = mi_npr.load_scene(path, leaf_size=size)
        mesh = scene.shapes()[0]
        ref = fo.make_leaves(hlps, plant, leaf_size=size, shape="disc")
        V, F, UV, face_leaf = ref.mesh()
        params = mi.traverse(mesh)
        assert mesh.id() == "leaves" and mesh.face_count() == len(F)
        np.testing.assert_array_equal(np.asarray(params["vertex_positions"]).reshape(-1, 3), V)
        np.testing.assert_array_equal(np.asarray(params["faces"]).reshape(-1, 3), F)
        np.testing.assert_array_equal(np.asarray(params["vertex_texcoords"]).reshape(-1, 2), UV)
        np.testing.assert_array_equal(np.asarray(params["face_leaf"]), face_leaf)
    assert mi_npr.load_scene(path).shapes()[0].face_count() < mesh.face_count()  # 0.2 > 0.1


def test02_leaf_id_layer_and_npr_lines(files):
    d, plant, hlps = files
    lines = '<integrator type="npr_lines"><integer name="leaf_edges" value="1"/><integrator type="direct"/></integrator>'  # noqa: E501
    body = leaves_xml('<float name="leaf_size" value="0.3"/>') + leaves_xml(
        '<float name="leaf_size" value="0.25"/><string name="placement" value="volume"/>',
        shape_id="more",
    )
    path = write(d, body, "two.xml", integrator=lines)
    scene = mi_npr.load_scene(path)
    gb = mi_npr.render(scene)
    assert scene.integrator().aov_names() == [L.LINES, *L.GBUFFER_AOVS, L.LEAF_ID, *L.RAW_RGB]
    # Quads: 2 triangles per leaf, so leaf_id = prim_id // 2 + 1; shapes are numbered by name
    # ("leaves" < "more"), and the second one's ids follow the first one's.
    ids = gb.object_id
    first, more = ids == gb.find_object("leaves"), ids == gb.find_object("more")
    n_first = len(fo.make_leaves(hlps, plant, leaf_size=0.3))
    expected = np.zeros(ids.shape, np.uint32)
    expected[first] = gb.numpy("prim_id.V")[first] // 2 + 1
    expected[more] = gb.numpy("prim_id.V")[more] // 2 + 1 + n_first
    np.testing.assert_array_equal(gb.numpy(L.LEAF_ID), expected)
    assert gb.numpy(L.LEAF_ID)[first].max() <= n_first < gb.numpy(L.LEAF_ID)[more].min()
    # The lines hold every leaf outline: each boundary between two leaves has a line pixel.
    leaf = gb.numpy(L.LEAF_ID)
    ink = gb.numpy(L.LINES) > 0.5
    right = leaf[:, 1:] != leaf[:, :-1]
    assert np.all((ink[:, 1:] | ink[:, :-1])[right])
    img = np.asarray(mi.render(scene))
    names = [*L.RGB, *scene.integrator().aov_names()]
    leaf_channel = img[..., names.index(L.LEAF_ID)]
    np.testing.assert_array_equal(leaf_channel, gb.numpy(L.LEAF_ID).astype(np.float32))
    # Without leaf_edges, npr_lines' layout is unchanged.
    plain = write(d, body, "plain.xml", integrator=lines.replace('"1"', '"0"'))
    assert L.LEAF_ID not in mi_npr.render(plain)


@pytest.mark.parametrize(
    ("params", "match"),
    [
        ('<float name="leaf_size" value="0"/>', "leaf_size"),
        ('<float name="leaf_sise" value="0.1"/>', "unknown parameter 'leaf_sise'"),
        ('<string name="placement" value="air"/>', "placement"),
        ('<string name="orientation" value="leaf"/>', "orientation = 'leaf' needs placement"),
        ('<string name="leaf_shape" value="star"/>', "leaf_shape"),
        ('<string name="leaf_shape" value="none.png"/>', "none.png: no such file"),
        ('<float name="tilt" value="91"/>', "tilt"),
        (
            '<float name="leaf_size" value="0.001"/><integer name="max_leaves" value="100"/>',
            "max_leaves",
        ),
    ],
)
def test03_parameter_errors(files, params, match):
    d, _, _ = files
    with pytest.raises(SceneError, match=match):
        mi_npr.load_scene(write(d, leaves_xml(params), "bad.xml"))


def test04_empty_single_and_broken_plants(files):
    d, _, _ = files
    # No leaves: a clear error when the scene loads (there is no mesh to build).
    write_ply(d / "empty.ply", np.zeros((0, 3)), np.zeros((0, 3)))
    body = leaves_xml(files='<string name="plant" value="empty.ply"/>')
    with pytest.raises(SceneError, match="no leaves"):
        mi_npr.load_scene(write(d, body, "empty.xml"))
    # NaN positions: a clear error naming the file.
    P = np.array([[0, 1, 0], [np.nan, 1, 0]], np.float32)
    write_ply(d / "nan.ply", P, np.zeros((0, 3)), {"nx": [0, 0], "ny": [0, 0], "nz": [1, 1]})
    with pytest.raises(SceneError, match=r"nan\.ply: 1 points have non-finite"):
        mi_npr.load_scene(write(d, leaves_xml().replace("plant.ply", "nan.ply"), "nan.xml"))
    # One leaf: one primitive or more, and the scene renders.
    one = fo.Plant.from_points([[0, 1.4, 0]], [[0, 0, 1]], sizes=0.5, areas=0.125)
    one.save(d / "one.ply")
    fo.build_hlps(one).save(d / "one.json")
    body = leaves_xml('<float name="leaf_size" value="0.3"/>').replace("plant.ply", "one.ply")
    gb = mi_npr.render(write(d, body.replace("hlps.json", "one.json"), "one.xml"))
    assert (gb.object_id == 1).any()
    with pytest.raises(SceneError, match="give 'hlps'"):
        mi_npr.load_scene(write(d, leaves_xml(files=""), "none.xml"))


def test05_textured_leaf_relative_to_the_scene(files):
    d, _, _ = files
    n = 32
    yy, xx = np.mgrid[0:n, 0:n]
    alpha = (np.abs(yy - 15.5) < 8 * np.sin(np.pi * (xx + 0.5) / n)) * 255
    rgba = np.dstack([np.full((n, n), 30), np.full((n, n), 140), np.full((n, n), 20), alpha])
    (d / "tex").mkdir(exist_ok=True)
    Image.fromarray(rgba.astype(np.uint8), "RGBA").save(d / "tex" / "leaf.png")
    bsdf = (
        '<bsdf type="diffuse"><texture type="bitmap" name="reflectance">'
        '<string name="filename" value="tex/leaf.png"/></texture></bsdf>'
    )
    params = '<string name="leaf_shape" value="tex/leaf.png"/><float name="leaf_size" value="0.3"/>'
    gb = mi_npr.render(write(d, leaves_xml(params, bsdf), "tex.xml"))
    leaf = gb.object_id == 1
    assert leaf.any()
    # The texture's green shows on the leaves (UVs inside the opaque part of the image).
    rgb = gb.beauty[leaf]
    assert np.median(rgb[:, 1]) > 2 * np.median(rgb[:, 0])

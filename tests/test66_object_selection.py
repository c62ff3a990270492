"""--only/--ignore and the material/silhouette id modes, pixel-exact in the `contour`
and `edges.*` layers; file-stem names of unnamed meshes; 1-px contours between objects."""

from __future__ import annotations

import fnmatch

import numpy as np
import pytest

import mi_npr
from mi_npr import layers as L
from mi_npr.errors import ParameterError
from mi_npr.pipeline import render_layers

from .public_style import fifty, ground, room

STEP = 1.0 / 40.0  # eq. 5.1's t / c: the depth step that decides the side of an edge


def owned_reference(ids: np.ndarray, z: np.ndarray) -> np.ndarray:
    """Brute force: pixel p (id != 0) owns its edge with 4-neighbour q (other id) when q is
    farther by more than STEP (depth normalised over the finite range, background +inf), or
    neither is nearer by more than STEP and p has the larger id."""
    h, w = ids.shape
    fin = np.isfinite(z)
    lo, hi = (z[fin].min(), z[fin].max()) if fin.any() else (0.0, 1.0)
    d = np.where(fin, (z - lo) / ((hi - lo) or 1.0), np.inf)
    out = np.zeros((h, w), bool)
    for y in range(h):
        for x in range(w):
            if ids[y, x] == 0:
                continue
            for dy, dx in ((-1, 0), (1, 0), (0, -1), (0, 1)):
                v, u = y + dy, x + dx
                if not (0 <= v < h and 0 <= u < w) or ids[v, u] == ids[y, x]:
                    continue
                dp, dq = d[y, x], d[v, u]
                if dq - dp > STEP or (not dp - dq > STEP and ids[y, x] > ids[v, u]):
                    out[y, x] = True
    return out


def _select(gb, only=(), ignore=()):
    """Object ids with the unselected objects as background (fnmatch on the table's names)."""
    keep = [
        k
        for k, n in gb.objects.items()
        if (not only or any(fnmatch.fnmatchcase(n, g) for g in only))
        and not any(fnmatch.fnmatchcase(n, g) for g in ignore)
    ]
    ids = gb.object_id
    return np.where(np.isin(ids, keep), ids, 0).astype(np.uint32)


@pytest.mark.parametrize(
    ("only", "ignore"), [((), ()), (("box_*",), ()), ((), ("floor", "back")), (("*",), ("b*",))]
)
def test01_contour_layer_is_the_owned_boundary_of_the_selection(tmp_path, only, ignore):
    path = room(tmp_path)
    params = {"only": ",".join(only), "ignore": ",".join(ignore)}
    r = render_layers(path, ["contours"], params, resolution=(41, 37))
    gb = r.gbuffer
    ids = _select(gb, only, ignore)
    ref = np.where(owned_reference(ids, gb.numpy(L.Z)), ids, 0)
    np.testing.assert_array_equal(gb.numpy(L.CONTOUR), ref)
    assert ref.any()
    # the SVG's contours hold the same pixels
    pts = {(int(x), int(y)) for c in r.contours for x, y in c.points}
    assert pts == {(int(x), int(y)) for y, x in zip(*np.nonzero(ref), strict=True)}


def test02_touching_objects_share_a_one_pixel_contour(tmp_path):
    gb = render_layers(room(tmp_path), ["contours"], resolution=(64, 64)).gbuffer
    ids, layer = gb.object_id, gb.numpy(L.CONTOUR)
    a, b = gb.find_object("box_a"), gb.find_object("back")
    pairs = both = 0
    for y in range(64):
        for x in range(63):
            p, q = ids[y, x], ids[y, x + 1]
            if {int(p), int(q)} == {a, b}:
                pairs += 1
                left, right = layer[y, x] == p, layer[y, x + 1] == q
                assert left or right  # the boundary is drawn ...
                both += left and right  # ... on one side (both only at a corner)
    assert pairs > 3 and both <= 2


def _corner_objects(path, w, h):
    """Object ids seen by the corner rays of the ray-tree pass (raycast, no ray trees)."""
    from mi_npr.raycast import cast, film_grid, pixel_rays

    scene = mi_npr.load_scene(path)
    sensor = scene.sensors()[0]
    from mi_npr.session import resize_sensor

    resize_sensor(sensor, (w, h), None)
    table = mi_npr.object_table(scene)
    hits = cast(scene, pixel_rays(sensor, *film_grid(w, h, corners=True)), table)
    return np.asarray(hits.object_id.numpy()).reshape(h + 1, w + 1), table


def test03_edges_layers_keep_pixels_with_a_selected_corner(tmp_path):
    path = ground(tmp_path, '<emitter type="point" id="fill"><point name="position" x="-2" '
                  'y="2" z="2"/><rgb name="intensity" value="5"/></emitter>')  # fmt: skip
    w, h = 45, 31
    full = render_layers(path, ["raytree"], resolution=(w, h)).gbuffer
    sel = render_layers(path, ["raytree"], {"ignore": "ground"}, resolution=(w, h)).gbuffer
    corners, table = _corner_objects(path, w, h)
    keep_ids = [k for k, n in table.names.items() if n != "ground"]
    on = np.isin(corners, keep_ids)
    keep = on[:-1, :-1] | on[:-1, 1:] | on[1:, :-1] | on[1:, 1:]
    for name in L.EDGES:
        np.testing.assert_array_equal(sel.numpy(name), full.numpy(name) * keep, err_msg=name)
    assert (
        full.numpy(L.EDGES_SHADOW).sum() > sel.numpy(L.EDGES_SHADOW).sum()
    )  # the shadow on the ground
    assert sel.numpy(L.EDGES_REAL).any()


def test04_material_and_silhouette_modes(tmp_path):
    path = room(tmp_path)
    r = render_layers(path, ["contours"], {"id_mode": "material"}, resolution=(48, 48))
    gb = r.gbuffer
    names = {c.name for c in r.contours}
    assert names <= {"red", "white"} and "red" in names  # box_a and box_b: one object
    # silhouette: every object is one, so the only contour is against the background
    s = render_layers(path, ["contours"], {"id_mode": "silhouette"}, resolution=(48, 48)).gbuffer
    ids = (gb.object_id != 0).astype(np.uint32)
    np.testing.assert_array_equal(
        s.numpy(L.CONTOUR), np.where(owned_reference(ids, gb.numpy(L.Z)), 1, 0)
    )
    # the same choice in XML: the plugin parameters
    table = mi_npr.object_table(mi_npr.load_scene(path))
    assert set(table.materials.values()) == {"red", "white"}


def test05_unnamed_meshes_are_named_after_their_files(tmp_path):
    path, stems = fifty(tmp_path)
    table = mi_npr.object_table(mi_npr.load_scene(path))
    assert list(table.names.values()) == sorted(stems)
    # a glob that matches nothing is a clear error
    with pytest.raises(ParameterError, match="only 'Plate\\*': no object matches"):
        render_layers(path, ["contours"], {"only": "Plate*"}, resolution=(16, 12))
    r = render_layers(path, ["contours"], {"only": "Brick_01_02_00*"}, resolution=(48, 32))
    assert {c.name for c in r.contours} <= {f"Brick_01_02_00{k}" for k in range(10)}
    # the same file twice: unique names
    xml = path.read_text().replace("</scene>", stems_twice(stems[0]) + "</scene>")
    path.write_text(xml)
    names = list(mi_npr.object_table(mi_npr.load_scene(path)).names.values())
    assert len(set(names)) == len(names) and f"{stems[0]}_1" in names


def stems_twice(stem: str) -> str:
    return (
        f'<shape type="ply"><string name="filename" value="{stem}.ply"/>'
        '<transform name="to_world"><translate y="1"/></transform></shape>'
    )


def test06_lines_id_edges_honour_the_selection(tmp_path):
    path = room(tmp_path)
    base = {"c": 0.0, "crease_angle": 0.0, "line_aa": 1}  # ID edges alone
    full = render_layers(path, ["lines"], base, resolution=(40, 40)).gbuffer
    only = render_layers(path, ["lines"], {**base, "only": "box_a"}, resolution=(40, 40)).gbuffer
    ids = _select(full, ("box_a",))
    ref = owned_reference_any(ids, full.numpy(L.Z))
    np.testing.assert_array_equal(only.numpy(L.LINES) > 0, ref)
    assert full.numpy(L.LINES).sum() > only.numpy(L.LINES).sum() > 0


def owned_reference_any(ids: np.ndarray, z: np.ndarray) -> np.ndarray:
    """ID edges of the lines chain with c = 0 (eq. 5.1's step t / c is infinite, so no depth
    step ever decides): a pixel with a 4-neighbour of a smaller id (the background is 0)."""
    h, w = ids.shape
    out = np.zeros((h, w), bool)
    for y in range(h):
        for x in range(w):
            for dy, dx in ((-1, 0), (1, 0), (0, -1), (0, 1)):
                v, u = y + dy, x + dx
                if 0 <= v < h and 0 <= u < w and ids[v, u] < ids[y, x]:
                    out[y, x] = True
    return out


def test07_the_same_choices_as_xml_parameters(tmp_path):
    """npr_contours' only/ignore/id_mode in XML draw what the flags draw."""
    path = room(tmp_path)
    flags = render_layers(
        path, ["contours"], {"only": "box_*,floor", "ignore": "box_b"}, resolution=(40, 40)
    )
    xml = path.read_text().replace(
        '<integrator type="path"><integer name="max_depth" value="3"/></integrator>',
        '<integrator type="npr_contours"><string name="only" value="box_*, floor"/>'
        '<string name="ignore" value="box_b"/>'
        '<integrator type="path"><integer name="max_depth" value="3"/></integrator></integrator>',
    )
    path.write_text(xml)
    gb = mi_npr.render(path, res=40)
    np.testing.assert_array_equal(gb.numpy(L.CONTOUR), flags.gbuffer.numpy(L.CONTOUR))
    assert set(np.unique(gb.numpy(L.CONTOUR))) == {
        0,
        gb.find_object("box_a"),
        gb.find_object("floor"),
    }
    np.testing.assert_array_equal(gb.beauty, flags.pictures["contours"])


def test08_a_glob_that_matches_nothing_says_what_would():
    """Globs are case-sensitive like the XML's ids: a glob that matches only in another case
    says so, any other names the closest objects (not the first ones alphabetically)."""
    from mi_npr.contours.idmode import selected

    names = {1: "Apple", 2: "Brick_01", 3: "Plate_A", 4: "Plate_B", 5: "floor"}
    assert selected(names, ["Plate_*"]) == {3, 4}
    with pytest.raises(ParameterError, match="in another case it matches Plate_A, Plate_B"):
        selected(names, ["plate*"])
    with pytest.raises(ParameterError, match=r"ignore 'Flor': .*closest of the 5 objects: floor,"):
        selected(names, ignore=["Flor"])
    with pytest.raises(ParameterError, match="the scene has no objects"):
        selected({}, ["x"])

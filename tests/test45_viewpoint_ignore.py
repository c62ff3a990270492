"""best_view(..., ignore=[...]): objects whose pixels count as background (floors, backdrops)."""

from __future__ import annotations

import numpy as np
import pytest

import mi_npr
from mi_npr import viewpoint as vp

from .helpers import SCENES

BOX = (
    '<shape type="cube" id="box"><transform name="to_world"><scale value="0.5"/>'
    '<translate y="0.5"/></transform></shape>'
)
FLOOR = (
    '<shape type="rectangle" id="floor"><transform name="to_world"><rotate x="1" angle="-90"/>'
    '<scale value="3"/></transform></shape>'
)


@pytest.mark.parametrize("measure", ["pb", "curvature", "entropy"])
def test01_ignored_floor_below_equals_no_floor(write_scene, measure):
    """Seen from above, a floor under the box hides nothing: ignoring it gives the quality of
    the scene without it, for every measure (n of eq. 1 and eq. 2's vertices included)."""
    with_floor = write_scene(BOX + FLOOR, name="a.xml", origin="0, 6, -1", target="0, 0, 0")
    without = write_scene(BOX, name="b.xml", origin="0, 6, -1", target="0, 0, 0")
    origin, target = [0.3, 6.0, -1.0], [0.0, 0.4, 0.0]
    q_ign = vp.quality(with_floor, origin, target, measure, res=64, ignore=["floor"])
    q_ref = vp.quality(without, origin, target, measure, res=64)
    q_all = vp.quality(with_floor, origin, target, measure, res=64)
    assert q_ign == pytest.approx(q_ref, rel=1e-12)
    assert q_all != pytest.approx(q_ref)


def test02_ignoring_the_floor_turns_the_search_upwards():
    path = SCENES / "scene3.xml"
    plain = vp.best_view(path, "entropy", depth=2, res=48)
    ignored = vp.best_view(path, "entropy", depth=2, res=48, ignore=["floor"])
    assert ignored.origin[1] > ignored.target[1]  # from above the floor
    assert plain.evaluations == ignored.evaluations <= 40
    assert np.isfinite(ignored.quality) and ignored.quality > 0


def test03_unknown_object_is_a_clear_error():
    with pytest.raises(mi_npr.ParameterError, match="ignore = 'flor': no such object"):
        vp.best_view(SCENES / "scene3.xml", "pb", depth=0, res=16, ignore=["flor"])


def test04_cli_ignore(tmp_path, capsys):
    from mi_npr import cli

    args = ["best-view", str(SCENES / "scene3.xml"), "--measure", "entropy", "--depth", "1"]
    args += ["--res", "32", "-o", str(tmp_path), "--ignore", "floor", "--json"]
    args += ["-D", "width=32", "-D", "height=24", "-D", "spp=1"]
    assert cli.main(args) == 0
    import json

    info = json.loads(capsys.readouterr().out)
    assert info["origin"][1] > info["target"][1]


def test05_ignored_objects_leave_the_framing():
    scene = mi_npr.load_scene(SCENES / "scene3.xml", width=32, height=24)
    table = mi_npr.object_table(scene)
    lo, hi = np.full(3, np.inf), np.full(3, -np.inf)
    for k, shape in table.shapes.items():
        if table.names[k] != "floor":
            lo = np.minimum(lo, np.asarray(shape.bbox().min, np.float64).ravel())
            hi = np.maximum(hi, np.asarray(shape.bbox().max, np.float64).ravel())
    bv = vp.best_view(scene, "pb", depth=0, res=16, ignore=["floor"])
    np.testing.assert_allclose(bv.target, (lo + hi) / 2, rtol=1e-5)
    whole = vp.best_view(scene, "pb", depth=0, res=16)
    # A 12 x 12 floor is flat: not an object that matters (the framing of orbits and spheres
    # of views), so it sets neither the target nor the distance, ignored or not.
    assert whole.radius == pytest.approx(bv.radius)
    np.testing.assert_allclose(whole.target, bv.target, rtol=1e-5)

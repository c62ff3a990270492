"""Fitting a shape to a drawing (:func:`mi_npr.ad.fit.fit_shape`): an object's rotation, scale
and translation are recovered from a drawing of the scene with the object moved, the camera
held. References: the known pose change (a box rotated 8 degrees, scaled by 1.1, moved across
the view); the drawing is made by :func:`mi_npr.ad.soft_lines` of the moved scene."""

from __future__ import annotations

import numpy as np
import pytest

import mi_npr
from mi_npr.ad import soft_lines
from mi_npr.ad.fit import ShapeFit, fit_shape

mi, dr = mi_npr.mi, mi_npr.dr

W, H = 64, 48
CENTRE = [-0.5, 0.0, 0.2]

pytestmark = pytest.mark.skipif(
    not str(mi.variant()).startswith(("llvm_ad", "cuda_ad")), reason="needs an AD variant"
)


def _about_centre(m):
    T = mi.ScalarTransform4f
    return T().translate(CENTRE) @ m @ T().translate([-v for v in CENTRE])


def _scene(change=None) -> mi.Scene:
    box = mi.ScalarTransform4f().translate(CENTRE).rotate([0, 1, 0], 20).scale(0.5)
    if change is not None:
        box = change @ box
    floor = mi.ScalarTransform4f().translate([0, -1, 0]).rotate([1, 0, 0], -90).scale(2.5)
    look = mi.ScalarTransform4f().look_at([3, 2.5, -5], [0, 0, 0], [0, 1, 0])
    return mi.load_dict(
        {
            "type": "scene",
            "sensor": {
                "type": "perspective",
                "fov": 40,
                "to_world": look,
                "film": {"type": "hdrfilm", "width": W, "height": H},
            },
            "ball": {"type": "sphere", "center": [0.8, 0.0, 0.3], "radius": 0.5},
            "box": {"type": "cube", "to_world": box},
            "floor": {"type": "rectangle", "to_world": floor},
        },
        optimize=False,
    )


def _drawing(change) -> np.ndarray:
    return np.asarray(soft_lines(_scene(change), n=2, sigma=0.7))


@pytest.mark.parametrize(
    ("param", "change", "check"),
    [
        (
            "rotation",
            _about_centre(mi.ScalarTransform4f().rotate([0, 1, 0], 8.0)),
            lambda f: np.testing.assert_allclose(f.rotation, [0.0, 8.0, 0.0], atol=0.3),
        ),
        (
            "scale",
            _about_centre(mi.ScalarTransform4f().scale(1.1)),
            lambda f: np.testing.assert_allclose(f.scale, 1.1, rtol=0.005),
        ),
        (
            "translation",
            mi.ScalarTransform4f().translate([0.15, 0.1, -0.1]),
            lambda f: np.testing.assert_allclose(f.translation, [0.15, 0.1, -0.1], atol=0.02),
        ),
    ],
)
def test01_one_parameter_is_recovered(param, change, check):
    scene = _scene()
    fit = fit_shape(scene, _drawing(change), "box", params=param, iterations=80)
    assert isinstance(fit, ShapeFit) and fit.loss[-1] < 0.05 * fit.loss[0]
    check(fit)
    # the object is left at the fitted pose: its lines are the drawing's
    left = np.asarray(soft_lines(scene, n=2, sigma=0.7))
    assert np.abs(left - _drawing(change)).mean() < 0.01


def test02_the_matrix_is_the_pose_change():
    fit = ShapeFit("box", np.array(CENTRE), np.array([0.1, 0.0, 0.0]), np.array([0, 90.0, 0]), 2.0)
    m = fit.matrix
    # the centre goes to centre + translation; x about the centre turns to -z (90 deg about y)
    np.testing.assert_allclose(m @ [*CENTRE, 1.0], [-0.4, 0.0, 0.2, 1.0], atol=1e-9)
    np.testing.assert_allclose(m[:3, :3] @ [1.0, 0.0, 0.0], [0.0, 0.0, -2.0], atol=1e-9)


def test03_errors_name_the_object_and_the_parameter():
    scene = _scene()
    ink = np.zeros((H, W), np.float32)
    with pytest.raises(mi_npr.ParameterError, match="'teapot': the scene has no such object"):
        fit_shape(scene, ink, "teapot")
    with pytest.raises(mi_npr.ParameterError, match="'shear' is not a differentiable shape"):
        fit_shape(scene, ink, "box", params="translation,shear")
    with pytest.raises(mi_npr.ParameterError, match="12x10 pixels"):
        fit_shape(scene, np.zeros((10, 12)), "box")


def test04_the_command_writes_the_pose(tmp_path, capsys):
    import json

    from mi_npr import cli
    from mi_npr.ad.fit import ink_picture
    from mi_npr.io import write_png

    xml = tmp_path / "s.xml"
    xml.write_text(f"""<scene version="3.0.0">
<sensor type="perspective"><float name="fov" value="40"/>
 <transform name="to_world"><lookat origin="3, 2.5, -5" target="0, 0, 0" up="0, 1, 0"/>
 </transform><film type="hdrfilm"><integer name="width" value="{W}"/>
 <integer name="height" value="{H}"/></film></sensor>
<shape type="sphere" id="ball"><point name="center" x="0.8" y="0" z="0.3"/>
 <float name="radius" value="0.5"/></shape>
<shape type="cube" id="box"><transform name="to_world"><scale value="0.5"/>
 <rotate y="1" angle="20"/><translate x="-0.5" y="0" z="0.2"/></transform></shape>
<shape type="rectangle" id="floor"><transform name="to_world"><scale value="2.5"/>
 <rotate x="1" angle="-90"/><translate y="-1"/></transform></shape>
</scene>""")
    turned = _about_centre(mi.ScalarTransform4f().rotate([0, 1, 0], 8.0))
    write_png(tmp_path / "d.png", ink_picture(_drawing(turned)), linear=False)
    args = ["fit-shape", str(xml), str(tmp_path / "d.png"), "--object", "box"]
    assert cli.main([*args, "--fit", "rotation", "--iterations", "60", "-o", str(tmp_path)]) == 0
    assert "wrote" in capsys.readouterr().out
    pose = json.loads((tmp_path / "s_fit_shape.json").read_text())
    assert pose["object"] == "box"
    np.testing.assert_allclose(pose["rotation_degrees_xyz"], [0.0, 8.0, 0.0], atol=0.5)
    assert (tmp_path / "s_fit_shape.png").is_file()
    with pytest.raises(SystemExit):
        cli.main([*args, "-o", str(tmp_path), "--fit", "origin"])
    assert "'origin' is not a differentiable shape parameter" in capsys.readouterr().err

"""The camera from a sketch (:func:`mi_npr.ad.fit_camera`, ``mi-npr fit-camera``): a drawing
made from a known camera is matched from a start 10-20 degrees and 10% in distance away, to
within 1 degree and 1%; and the errors a user can make are one line each.

The reference is the known camera itself; the drawing is written as a PNG and read back, as a
user's would be."""

from __future__ import annotations

import numpy as np
import pytest

import mi_npr
from mi_npr import cli
from mi_npr.ad import Pinhole, soft_lines
from mi_npr.ad.fit import camera_error, fit_camera, ink_picture
from mi_npr.camera import Camera, rotate
from mi_npr.io import write_png

mi, dr = mi_npr.mi, mi_npr.dr

W, H = 64, 48
TRUE = Camera((4.0, 2.5, -5.0), (0.0, 0.0, 0.0), (0.0, 1.0, 0.0), 40.0)

pytestmark = pytest.mark.skipif(
    not str(mi.variant()).startswith(("llvm_ad", "cuda_ad")), reason="needs an AD variant"
)


def _start() -> Camera:
    """TRUE orbited 15 degrees about its target (a tilted axis) and 10% farther."""
    o, t = np.array(TRUE.origin), np.array(TRUE.target)
    axis = np.cross(o - t, [0.3, 1.0, 0.2])
    o2 = t + rotate(o - t, axis / np.linalg.norm(axis), np.radians(15.0)) * 1.1
    return Camera(tuple(o2), TRUE.target, TRUE.up, TRUE.fov)


def _scene_xml(camera: Camera, width: int = W, height: int = H) -> str:
    o, t, u = (
        ", ".join(str(float(v)) for v in x) for x in (camera.origin, camera.target, camera.up)
    )
    return f"""<scene version="3.0.0">
<sensor type="perspective"><float name="fov" value="{camera.fov}"/>
 <transform name="to_world"><lookat origin="{o}" target="{t}" up="{u}"/></transform>
 <film type="hdrfilm"><integer name="width" value="{width}"/>
  <integer name="height" value="{height}"/></film></sensor>
<shape type="sphere" id="ball"><point name="center" x="0.6" y="0.3" z="0.2"/>
 <float name="radius" value="0.6"/></shape>
<shape type="cube" id="box"><transform name="to_world"><scale value="0.6"/>
 <rotate y="1" angle="25"/><translate x="-0.6" y="-0.2" z="-0.3"/></transform></shape>
<shape type="sphere" id="small"><point name="center" x="-0.2" y="0.8" z="-0.8"/>
 <float name="radius" value="0.35"/></shape>
<shape type="rectangle" id="floor"><transform name="to_world"><scale value="2"/>
 <rotate x="1" angle="-90"/><translate y="-0.8"/></transform></shape>
</scene>"""


@pytest.fixture(scope="module")
def case(tmp_path_factory):
    d = tmp_path_factory.mktemp("fit")
    (d / "start.xml").write_text(_scene_xml(_start()))
    scene = mi_npr.load_scene(d / "start.xml")
    c = TRUE
    ink = soft_lines(
        scene, Pinhole.look_at(c.origin, c.target, c.up, c.fov), (W, H), n=2, sigma=0.7
    )
    write_png(d / "drawing.png", ink_picture(ink), linear=False)
    return d


def test01_the_command_recovers_the_camera(case, capsys):
    start = _start()
    deg, dist = camera_error(start, TRUE)
    assert 14.0 < deg < 16.0 and dist > 0.1  # the start is far
    out = case / "out"
    args = ["fit-camera", str(case / "start.xml"), str(case / "drawing.png"), "-o", str(out)]
    assert cli.main([*args, "--iterations", "100"]) == 0
    assert "wrote" in capsys.readouterr().out
    fitted = mi.load_file(str(out / "start_fit_camera.xml"))
    found = mi_npr.camera.camera_of(fitted.sensors()[0])
    deg, dist = camera_error(found, TRUE)
    assert deg < 1.0 and dist < 0.01
    assert tuple(int(v) for v in fitted.sensors()[0].film().size()) == (W, H)
    assert (out / "start_fit_camera.png").is_file()


def test02_the_loss_falls_and_held_parameters_stay(case):
    start = _start()
    fit = fit_camera(str(case / "start.xml"), str(case / "drawing.png"), iterations=6, params="up")
    assert fit.camera.origin == pytest.approx(start.origin, abs=1e-5)
    fit = fit_camera(str(case / "start.xml"), str(case / "drawing.png"), iterations=20)
    assert fit.loss[-1] < 0.5 * fit.loss[0]


def test03_errors_are_one_line(case, tmp_path, capsys):
    small = np.ones((10, 12), np.float32)
    with pytest.raises(mi_npr.ParameterError, match="12x10 pixels, the scene's film 64x48"):
        fit_camera(str(case / "start.xml"), small)
    with pytest.raises(mi_npr.ParameterError, match="'focus' is not a differentiable camera"):
        fit_camera(str(case / "start.xml"), str(case / "drawing.png"), params=["origin", "focus"])
    write_png(tmp_path / "small.png", small)
    args = ["fit-camera", str(case / "start.xml"), str(tmp_path / "small.png"), "-o", str(tmp_path)]
    assert cli.main(args) == 1
    err = capsys.readouterr().err
    assert "small.png is 12x10 pixels" in err and len(err.strip().splitlines()) == 1
    with pytest.raises(SystemExit):
        cli.main([*args, "--fit", "origin,zoom"])
    assert "'zoom' is not a differentiable camera parameter" in capsys.readouterr().err


def test04_a_variant_without_ad_is_named(case, tmp_path, monkeypatch, capsys):
    """This Mitsuba build has no ``llvm_rgb``: the variant and its lack of AD are stood in for."""
    monkeypatch.setattr(mi, "variant", lambda: "llvm_rgb")
    monkeypatch.setattr(dr, "is_diff_v", lambda _: False)
    args = ["fit-camera", str(case / "start.xml"), str(case / "drawing.png"), "-o", str(tmp_path)]
    assert cli.main(args) == 1
    err = capsys.readouterr().err
    assert "'llvm_rgb' has none: use 'llvm_ad_rgb'" in err and "Traceback" not in err
    assert not list(tmp_path.iterdir())  # nothing written


def test05_the_field_of_view_is_recovered(case):
    wide = Camera(TRUE.origin, TRUE.target, TRUE.up, 46.0)
    fit = fit_camera(str(case / "start.xml"), str(case / "drawing.png"), start=wide, params="fov")
    assert fit.camera.fov == pytest.approx(TRUE.fov, abs=0.2)
    assert fit.camera.origin == pytest.approx(TRUE.origin, abs=1e-5)  # held

"""One validation table. Generated from :func:`mi_npr.cli.tables.all_tables`: every
parameter of every plugin, of the lines chain and every numeric CLI flag, with NaN, inf,
negative, zero, huge and wrong-type values; so a new parameter cannot skip validation."""

from __future__ import annotations

import math
import subprocess
import sys

import numpy as np
import pytest

import mi_npr
from mi_npr import kernels as K
from mi_npr.cli import build_parser
from mi_npr.cli.tables import all_tables, command_tables
from mi_npr.contours import trace
from mi_npr.io import write_png, write_svg
from mi_npr.params import Param, coerce

from .helpers import scene_xml

TABLES = all_tables()
CASES = [(t, p) for t, params in TABLES.items() for p in params]
BAD = {
    "nan": math.nan,
    "inf": math.inf,
    "-inf": -math.inf,
    "negative": -1,
    "zero": 0,
    "huge": 10**40,
    "huge_float": 1e300,
    "string": "abc",
    "list": [1, 2],
}


def test01_every_plugin_and_flag_is_in_the_table():
    assert {"lines", "npr_lines", "npr_contours", "npr_raytree", "npr_leaves"} <= set(TABLES)
    assert {"mi-npr " + c for c in ("render", "best-view", "foliage", "raytree")} <= set(TABLES)
    for _, p in CASES:
        if p.type is int:
            assert p.check is not None  # a bound for every count


def test02_an_unbounded_count_cannot_be_declared():
    with pytest.raises(TypeError, match="bounded"):
        Param("n", int, 0, "a count without a rule")


@pytest.mark.parametrize(("table", "param"), CASES, ids=[f"{t}:{p.name}" for t, p in CASES])
@pytest.mark.parametrize("kind", list(BAD))
def test03_each_parameter_with_each_bad_value(table, param, kind):
    """Either a ParameterError naming the parameter, or a finite value of the right type that
    passes the parameter's rule. NaN, inf, huge and wrong types are always refused by numbers."""
    value = BAD[kind]
    try:
        out = coerce(table, param, value)
    except mi_npr.ParameterError as e:
        assert param.name in str(e) and table in str(e)
        assert "\n" not in str(e)
        return
    assert kind not in ("nan", "inf", "-inf") or param.type not in (int, float, tuple)
    if param.type in (int, float):
        assert kind not in ("huge", "string", "list")
        assert isinstance(out, param.type) and math.isfinite(out)
    if param.type is tuple:
        assert all(math.isfinite(v) for v in out)
    if param.type is str:
        assert isinstance(out, str)


CLI_CASES = [(cmd, p) for cmd, params in command_tables().items() for p in params]
_ARGS = {
    "render": ["x.xml", "-o", "out"],
    "contours": ["x.xml", "-o", "out"],
    "raytree": ["x.xml", "-o", "out"],
    "batch": ["x.xml", "-o", "out"],
    "dataset": ["x.obj", "-o", "out"],
    "best-view": ["x.xml", "--measure", "pb", "-o", "out"],
    "fit-camera": ["x.xml", "d.png", "-o", "out"],
    "fit-shape": ["x.xml", "d.png", "--object", "box", "-o", "out"],
    "foliage": ["procedural:tree", "--style", "van_gogh", "-o", "x.xml"],
    "path": ["x.xml", "-o", "out", "--frames", "2"],
}


@pytest.mark.parametrize(("cmd", "param"), CLI_CASES, ids=[f"{c}--{p.name}" for c, p in CLI_CASES])
@pytest.mark.parametrize("text", ["nan", "inf", "-1", "1e300", "99999999999999999999", "abc"])
def test04_cli_flags_refuse_bad_values_naming_the_flag(cmd, param, text, capsys):
    flag = "--" + param.name.replace("_", "-")
    if text == "-1" and flag == "--abstraction":
        text = "-0.5"
    with pytest.raises(SystemExit) as e:
        build_parser().parse_args([cmd, *_ARGS[cmd], flag, text])
    assert e.value.code == 2
    err = capsys.readouterr().err
    assert f"argument {flag}:" in err and "Traceback" not in err


@pytest.mark.parametrize(
    ("argv", "flag"),
    [
        (["render", "x.xml", "-o", "o", "--seed", "-1"], "--seed"),
        (["render", "x.xml", "-o", "o", "--seed", "4294967296"], "--seed"),
        (["render", "x.xml", "-o", "o", "--spp", "4294967295"], "--spp"),
        (["best-view", "x.xml", "--measure", "pb", "-o", "o", "--res", "100000"], "--res"),
        (["best-view", "x.xml", "--measure", "pb", "-o", "o", "--depth", "1000000"], "--depth"),
        (
            [
                "foliage",
                "procedural:tree",
                "--style",
                "van_gogh",
                "-o",
                "x.xml",
                "--hlps",
                "100000",
            ],
            "--hlps",
        ),
    ],
)
def test05_the_issues_flags(argv, flag, capsys):
    with pytest.raises(SystemExit):
        build_parser().parse_args(argv)
    assert f"argument {flag}:" in capsys.readouterr().err


def test06_seed_bounds_are_accepted():
    args = build_parser().parse_args(["render", "x.xml", "-o", "o", "--seed", "4294967295"])
    assert args.seed == 2**32 - 1


def test07_python_api_bad_inputs_are_parameter_errors(tmp_path):
    ids = np.zeros((4, 5), np.uint32)
    ids[1:3, 1:3] = 1
    calls = {
        "lines": lambda: K.lines(np.ones((4, 4))),
        "objects": lambda: trace(ids, objects=[1, 2]),
        "only": lambda: trace(ids, only="abc"),
        "width": lambda: write_svg(tmp_path / "a.svg", trace(ids), math.nan, 4),
        "color": lambda: write_svg(tmp_path / "a.svg", trace(ids), 5, 4, color=(math.inf, 0, 0)),
        "empty": lambda: write_png(tmp_path / "a.png", np.zeros((0, 0))),
        "dilation_iterations": lambda: K.lines({"Z": np.ones((3, 3))}, dilation_iterations=10**9),
    }
    for name, call in calls.items():
        with pytest.raises(mi_npr.ParameterError) as e:
            call()
        assert name in str(e.value) or "empty" in str(e.value)
    assert not list(tmp_path.iterdir())  # nothing half-written


def test08_npr_contours_color_like_line_color(tmp_path):
    for bad in ("nan, 0, 0", "1, inf, 0", "-1, 0, 0"):
        xml = scene_xml(
            '<shape type="sphere"><point name="center" x="0" y="0" z="4"/></shape>',
            integrator=f'<integrator type="npr_contours"><rgb name="color" value="{bad}"/>'
            "</integrator>",
        )
        path = tmp_path / "s.xml"
        path.write_text(xml)
        with pytest.raises(Exception, match="parameter 'color'"):
            mi_npr.render(path)


def test09_a_nested_bsdf_is_an_error_naming_it(tmp_path):
    xml = scene_xml(
        '<shape type="sphere"><point name="center" x="0" y="0" z="4"/></shape>',
        integrator='<integrator type="npr_lines"><bsdf type="diffuse" id="oops"/></integrator>',
    )
    path = tmp_path / "s.xml"
    path.write_text(xml)
    r = subprocess.run(
        [sys.executable, "-m", "mi_npr.cli", "render", str(path), "-o", str(tmp_path / "o")],
        capture_output=True,
        text=True,
        check=False,
    )
    assert r.returncode == 1
    assert "npr_lines: a nested <bsdf> (oops)" in r.stderr and "Traceback" not in r.stderr


def test10_leaf_size_has_a_lower_bound_relative_to_the_plant(tmp_path):
    """``--leaf-size 1e-6`` wrote a scene that could never render."""
    from mi_npr import foliage as fo

    plant = fo.Plant.from_points([[0, 0, 0], [1, 1, 1]], [[0, 1, 0], [0, 1, 0]], sizes=0.1)
    with pytest.raises(mi_npr.ParameterError, match="leaf_size = 1e-06: too small"):
        fo.styles.write_foliage_scene(tmp_path / "x.xml", plant, "van_gogh", leaf_size=1e-6)
    with pytest.raises(mi_npr.ParameterError, match="leaf_size"):
        fo.styles.write_foliage_scene(tmp_path / "x.xml", plant, "van_gogh", leaf_size=math.nan)
    assert not list(tmp_path.iterdir())

"""Bad values into the public Python API: every exception is an mi-npr error with one line.

The walk covers ``mi_npr.__all__`` and the public functions and classes of ``mi_npr.camera``,
``gbuffer``, ``io.*``, ``batch``, ``views``, ``paths``, ``strokes``, ``ad`` and ``dataset``. A
*value* parameter (annotated with a number, ``str``, a path, a sequence of numbers or an
array) gets each bad value below in turn, the other parameters a valid value; an *object*
parameter (a GBuffer, a scene, a camera, a callable...) is not fuzzed: passing a number where a
GBuffer belongs is a programming error, answered by Python's own ``TypeError``; nor is a flag
(``bool``), which takes any value's truth as Python does. A wrong-shape array goes only where
arrays or sequences are taken.

A call either returns, or raises :class:`mi_npr.NprError` (``ParameterError``, ``InputError``,
``OutputError``, ``SceneError``...) whose text is one line; never a ``KeyError``,
``IndexError``, ``AttributeError``, ``TypeError`` or ``ValueError`` from inside numpy, Dr.Jit or
Mitsuba.
"""

from __future__ import annotations

import importlib
import inspect
import math
import pkgutil
import re
import warnings

import numpy as np
import pytest

import mi_npr
import mi_npr.io

from .helpers import scene_xml

BAD = {
    "None": None,
    "str": "abc",
    "nan": math.nan,
    "inf": math.inf,
    "negative": -3,
    "bool": True,
    "empty_list": [],
    "wrong_shape": np.zeros((2, 3, 5, 7)),
    "no_file": "{tmp}/no_such_file.xml",
    "directory": "{tmp}/a_directory",
}

#: Annotations of value parameters, and of object parameters (which win when both match).
VALUE = re.compile(r"\b(int|float|str|bool|PathLike|ndarray|Vec3|Any|Sequence\[(float|str))")
OBJECT = re.compile(
    r"GBuffer|Scene|Sensor|Camera|Stroke|Mesh|Settings|Job|Drawing|Callable|Mapping|Param\b|"
    r"Projection|Viewing|Spec|Exploration|\bPath\b|Iterable|Integrator"
)

#: Annotations that take arrays or sequences (of which one can have the wrong shape).
ARRAY = re.compile(r"ndarray|Sequence|tuple|Vec3|Any")

MODULES = ["camera", "gbuffer", "batch", "views", "paths", "strokes", "ad", "dataset", "io"]
MODULES += ["io." + m.name for m in pkgutil.iter_modules(mi_npr.io.__path__) if m.name[0] != "_"]

#: Not walked, with the reason.
SKIP = {
    "local_cluster": "starts a Dask cluster",
    "run": "mi_npr.batch.run starts a Dask cluster for any settings it accepts",
    "quiet_library": "a context manager without value parameters",
    "output_set": "a context manager without value parameters",
    "atomic_output": "a context manager (its path is checked by the writers that use it)",
    "set_variant": "switching the variant would change the process for the other tests",
}


def _public() -> dict[str, object]:
    out = {}
    for name in mi_npr.__all__:
        obj = getattr(mi_npr, name)
        if inspect.isfunction(obj) or (inspect.isclass(obj) and not issubclass(obj, Exception)):
            out[f"{obj.__module__}.{name}"] = obj
    for short in MODULES:
        mod = importlib.import_module("mi_npr." + short)
        names = getattr(mod, "__all__", None) or [n for n in vars(mod) if n[0] != "_"]
        for name in names:
            obj = getattr(mod, name, None)
            if not (inspect.isfunction(obj) or inspect.isclass(obj)):
                continue
            if inspect.isclass(obj) and issubclass(obj, BaseException):
                continue
            if not obj.__module__.startswith(mod.__name__):
                continue  # imported from elsewhere: walked where it is defined
            out[f"{obj.__module__}.{name}"] = obj
    return {k: v for k, v in sorted(out.items()) if k.rsplit(".", 1)[1] not in SKIP}


PUBLIC = _public()

#: The parameter names that get a valid value (the ``world`` fixture builds them).
GOOD = (
    "scene scenes sensor gb gbuffer camera cameras n k frames keys width height radius fov size "
    "path out outdir text image origin target up v axis angle directions centre forward views "
    "measure sigma rendered data seed stem contours fmt lo hi samples meshes inputs to_world "
    "resolution layers"
).split()


@pytest.fixture(scope="module")
def world(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("api")
    (tmp / "a_directory").mkdir()
    path = tmp / "scene.xml"
    cube = (
        '<shape type="cube" id="cube">'
        '<transform name="to_world"><translate z="4"/></transform></shape>'
    )
    path.write_text(scene_xml(cube, width=16, height=12))
    scene = mi_npr.load_scene(path)
    gb = mi_npr.render(scene)
    cam = mi_npr.Camera((0.0, 0.0, 0.0), (0.0, 0.0, 1.0))
    good = {
        "scene": scene,
        "scenes": [str(path)],
        "sensor": scene.sensors()[0],
        "gb": gb,
        "gbuffer": gb,
        "camera": cam,
        "cameras": [cam, mi_npr.Camera((1.0, 0.0, 0.0), (0.0, 0.0, 4.0))],
        "n": 3,
        "k": 2,
        "frames": 3,
        "keys": 2,
        "width": 16,
        "height": 12,
        "radius": 1.0,
        "fov": 40.0,
        "size": (16, 12),
        "path": str(tmp / "out.png"),
        "out": str(tmp / "out"),
        "outdir": str(tmp / "out"),
        "text": "[]",
        "image": np.zeros((4, 5, 3)),
        "origin": (0.0, 0.0, 0.0),
        "target": (0.0, 0.0, 1.0),
        "up": (0.0, 1.0, 0.0),
        "v": (1.0, 0.0, 0.0),
        "axis": (0.0, 1.0, 0.0),
        "angle": 0.3,
        "directions": np.array([[0.0, 0.0, 1.0]]),
        "centre": (0.0, 0.0, 0.0),
        "forward": (0.0, 0.0, 1.0),
        "views": "orbit:2",
        "measure": "entropy",
        "sigma": 1.0,
        "rendered": np.zeros((8, 8)),
        "data": [],
        "seed": 0,
        "stem": "x",
        "contours": [],
        "fmt": "png",
        "lo": 0,
        "hi": 3,
        "samples": 4,
        "meshes": [],
        "inputs": [],
        "to_world": np.eye(4),
        "resolution": (16, 12),
        "layers": {"depth": np.zeros((2, 2), np.float32)},
    }
    assert sorted(good) == sorted(GOOD)
    return tmp, good


def _params(f) -> tuple[list[inspect.Parameter], list[inspect.Parameter]]:
    """(required parameters, value parameters) of ``f``; a scene parameter is a value one
    (a file name is a valid scene)."""
    params = [
        p
        for p in inspect.signature(f).parameters.values()
        if p.kind not in (p.VAR_POSITIONAL, p.VAR_KEYWORD)
    ]
    required = [p for p in params if p.default is p.empty]
    values = [
        p
        for p in params
        if VALUE.search(str(p.annotation))
        and str(p.annotation) != "bool"  # a flag takes any value's truth, as Python does
        and (OBJECT.search(str(p.annotation)) is None or "Scene" in str(p.annotation))
    ]
    return required, values


def _calls(f, good):
    """(parameter, bad kind, args, kwargs) for each value parameter of ``f`` and bad value."""
    required, values = _params(f)
    for t in values:
        ann = str(t.annotation)
        for kind, bad in BAD.items():
            if kind == "None" and "None" in ann:
                continue  # None is a documented value of this parameter
            if kind == "wrong_shape" and not ARRAY.search(ann):
                continue  # an array is a wrong shape only where arrays are taken
            args, kwargs = [], {}
            for p in required:
                value = bad if p is t else good[p.name]
                if p.kind == p.KEYWORD_ONLY:
                    kwargs[p.name] = value
                else:
                    args.append(value)
            if t not in required:
                kwargs[t.name] = bad
            yield t.name, kind, args, kwargs


def _walkable() -> list[str]:
    """The public callables with a value parameter whose required parameters all have a valid
    value in :data:`GOOD`."""
    out = []
    for name, f in PUBLIC.items():
        required, values = _params(f)
        if values and all(p.name in GOOD for p in required):
            out.append(name)
    return out


def test01_the_walk_covers_the_entry_points():
    for name in (
        "mi_npr.render.render",
        "mi_npr.camera.framing.orbit",
        "mi_npr.camera.files.read_cameras",
        "mi_npr.io.exr.read_exr",
        "mi_npr.io.png.write_png",
        "mi_npr.paths.key_frames",
        "mi_npr.views.random_directions",
        "mi_npr.batch.parse_define",
    ):
        assert name in WALKED
    assert len(WALKED) >= 60


WALKED = _walkable()


@pytest.mark.parametrize("name", WALKED)
def test02_bad_values_raise_one_line_mi_npr_errors(name, world, monkeypatch):
    tmp, good = world
    monkeypatch.chdir(tmp)  # a bad name that is still a valid file name ("abc") writes there
    f = PUBLIC[name]
    wrong = []
    for param, kind, args, kwargs in _calls(f, good):
        args = [a.format(tmp=tmp) if isinstance(a, str) else a for a in args]
        kwargs = {k: v.format(tmp=tmp) if isinstance(v, str) else v for k, v in kwargs.items()}
        try:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                f(*args, **kwargs)
        except mi_npr.NprError as e:
            if "\n" in str(e) or not str(e):
                wrong.append(f"{param}={kind}: message not one line: {str(e)[:80]!r}")
        except Exception as e:  # the point: any other exception is a bug
            wrong.append(f"{param}={kind}: {type(e).__name__}: {str(e)[:80]}")
    assert not wrong, "\n".join(wrong)

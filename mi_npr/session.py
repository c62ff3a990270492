"""One scene session: a loaded scene, its sensor, the render lock and the error mapping.

Every entry point that takes ``scene`` as an XML path or a loaded ``mi.Scene`` (``render``,
``trace_scene``, the ray-tree ``render``, best view, the contour overlay) opens a
:class:`SceneSession` instead of repeating the same block:

- **loading** with ``defines`` and keyword arguments filling the XML's ``<default>``\\ s
  (:func:`mi_npr.scene.load_scene`); ``spp`` (an int or a command-line string) also fills the
  XML's ``spp`` default when the file declares one, and always sets the beauty's sample count;
- **the sensor** (:func:`mi_npr.scene.sensor_of`: index or object, checked film size);
  ``resolution=(W, H)`` resizes its film and ``spp`` sets the beauty's sample count *whatever
  the XML's* ``<default>`` *names are* (``res``, ``resx``/``resy``, ``width``...): the command
  line's ``--width/--height/--spp`` (:func:`resize_sensor`);
- **the object table**, built once per session (:func:`mi_npr.scene.object_table`);
- **the render lock**: a loaded Mitsuba scene must not be rendered from two threads at once, so
  every pass over a scene runs under :data:`RENDER_LOCK`;
- **error mapping**: ``with session.step("ray casting"):`` holds the lock and turns Mitsuba's
  ``RuntimeError`` into one :class:`~mi_npr.errors.SceneError` line naming the scene file.
"""

from __future__ import annotations

import contextlib
import os
import threading
from collections.abc import Iterator, Mapping
from dataclasses import dataclass, field
from typing import Any

import mitsuba as mi

from .errors import ParameterError, SceneError, one_line
from .params import MAX_RES, MAX_SPP, Param, check_arg, entry, integer_range, seed_rule
from .raycast import require_jit
from .scene import (
    ObjectTable,
    declared_defaults,
    load_scene,
    merge_defines,
    object_table,
    sensor_of,
)

#: Mitsuba scenes must not be rendered from two threads at once.
RENDER_LOCK = threading.RLock()

#: The film and the sampler of any render, whatever the names of the XML's ``<default>``\ s:
#: the keyword arguments of the render functions and the flags of every command that renders.
RENDER_PARAMS: tuple[Param, ...] = (
    Param("width", int, None, "film width (alone: keeps the aspect)", integer_range(1, MAX_RES)),
    Param("height", int, None, "film height (alone: keeps the aspect)", integer_range(1, MAX_RES)),
    Param("spp", int, None, "samples per pixel of the beauty", integer_range(1, MAX_SPP)),
    Param("seed", int, 0, "sampler seed", seed_rule),
)


def check_spp(spp: int | str | None) -> int | None:
    """``spp`` checked against the validation table (:mod:`mi_npr.params`; a command-line string
    is parsed), or ``None``."""
    if spp is None:
        return None
    if isinstance(spp, str):
        try:
            spp = int(spp)
        except ValueError:
            raise ParameterError(f"spp = {spp!r}: must be a positive integer") from None
    return check_arg("render", entry(RENDER_PARAMS, "spp"), spp)


def check_resolution(resolution: tuple[int | None, int | None] | None) -> tuple | None:
    """``(W, H)`` with each an int >= 1 or ``None`` (keep the film's aspect), or ``None``."""
    if resolution is None:
        return None
    try:
        w, h = resolution
    except (TypeError, ValueError):
        raise ParameterError(f"resolution = {resolution!r}: expected (width, height)") from None
    for name, v in (("width", w), ("height", h)):
        if v is not None and (not isinstance(v, int) or isinstance(v, bool) or v < 1):
            raise ParameterError(f"{name} = {v!r}: must be a positive integer")
    return None if w is None and h is None else (w, h)


def resize_sensor(
    sensor: mi.Sensor, resolution: tuple[int | None, int | None] | None, spp: int | None
) -> mi.Sensor:
    """Give ``sensor``'s film the size ``resolution`` (a ``None`` side keeps the film's aspect
    ratio) and its sampler ``spp`` samples per pixel, in place; the crop window becomes the
    whole film. The horizontal field of view is kept (Mitsuba stores ``x_fov``), so a wider
    aspect shows less vertically, as resizing the XML's ``<film>`` with ``fov_axis="x"`` does.
    Rays of the resized sensor equal those of a sensor loaded at that size (tested)."""
    if spp is not None:
        sensor.sampler().set_sample_count(spp)
    res = check_resolution(resolution)
    if res is None:
        return sensor
    w0, h0 = (int(v) for v in sensor.film().size())
    w, h = res
    if w is None:
        w = max(1, round(h * w0 / h0))
    if h is None:
        h = max(1, round(w * h0 / w0))
    params = mi.traverse(sensor)
    if "film.size" not in params:
        raise ParameterError(f"{sensor.class_name()}: its film cannot be resized")
    params["film.size"] = mi.ScalarVector2u(w, h)
    params["film.crop_size"] = mi.ScalarVector2u(w, h)
    if "film.crop_offset" in params:
        params["film.crop_offset"] = mi.ScalarPoint2u(0, 0)
    params.update()
    return sensor


@dataclass
class SceneSession:
    """A loaded scene with the sensor it is seen from (see the module docstring)."""

    scene: mi.Scene
    sensor: mi.Sensor
    source: str | None = None  # the XML path, when loaded from a file
    spp: int | None = None  # the beauty's sample count asked for (None: the sampler's)
    _table: ObjectTable | None = field(default=None, repr=False)

    @classmethod
    def open(
        cls,
        scene: str | os.PathLike[str] | mi.Scene,
        *,
        sensor: int | mi.Sensor = 0,
        spp: int | str | None = None,
        defines: Mapping[str, Any] | None = None,
        resolution: tuple[int | None, int | None] | None = None,
        **more: Any,
    ) -> SceneSession:
        """Load ``scene`` (or take it as it is) and pick ``sensor``; ``resolution`` resizes
        its film (:func:`resize_sensor`: a loaded ``mi.Scene``'s sensor is changed in place);
        ``spp`` is kept as :attr:`spp`, the sample count every beauty render is given."""
        require_jit()
        defines = merge_defines(defines, more)
        source = os.fspath(scene) if isinstance(scene, (str, os.PathLike)) else None
        spp = check_spp(spp)
        if spp is not None and source is not None and "spp" in declared_defaults(source):
            defines["spp"] = spp
        resolution = check_resolution(resolution)
        loaded = load_scene(scene, defines)
        picked = sensor_of(loaded, sensor)
        if resolution is not None:  # spp is the beauty's render argument (session.spp)
            resize_sensor(picked, resolution, None)
        return cls(loaded, picked, source, spp)

    @property
    def name(self) -> str:
        """How messages name the scene: its file, or ``scene``."""
        return self.source or "scene"

    @property
    def objects(self) -> ObjectTable:
        """The scene's object table (built once)."""
        if self._table is None:
            self._table = object_table(self.scene)
        return self._table

    @contextlib.contextmanager
    def step(self, what: str) -> Iterator[None]:
        """Run a pass over the scene under the render lock; Mitsuba's errors become one
        :class:`~mi_npr.errors.SceneError` line: ``<scene>: <what> failed: <message>``."""
        with RENDER_LOCK:
            try:
                yield
            except (ParameterError, SceneError):
                raise
            except RuntimeError as e:
                raise SceneError(f"{self.name}: {what} failed: {one_line(e)}") from None

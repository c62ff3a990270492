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
from .params import check_arg, entry
from .raycast import require_jit
from .scene import (  # RENDER_PARAMS, check_resolution, resize_sensor: also this module's API
    RENDER_PARAMS,
    ObjectTable,
    check_resolution,
    declared_defaults,
    load_scene,
    merge_defines,
    object_table,
    resize_sensor,
    sensor_of,
)

#: Mitsuba scenes must not be rendered from two threads at once.
RENDER_LOCK = threading.RLock()


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


@dataclass
class SceneSession:
    """A loaded scene with the sensor it is seen from (see the module docstring)."""

    scene: mi.Scene
    sensor: mi.Sensor
    source: str | None = None  # the XML path, when loaded from a file
    spp: int | None = None  # the beauty's sample count asked for (None: the sampler's)
    #: Whether a stroke extraction keeps the meshes' topology for later views of this scene
    #: (:func:`mi_npr.strokes.extract_strokes`); a render sets it off for its last extraction
    #: from a scene it loaded itself, which no other view can be drawn from.
    keep_topology: bool = True
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

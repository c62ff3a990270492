"""One camera model: the :class:`Camera` type, camera files, sensors, orbits and framing.

Every camera mi-npr places or reads is a :class:`Camera` (:mod:`~mi_npr.camera.model`):
``lookat(origin, target, up)``, a horizontal ``fov`` in degrees, a ``time`` in [0, 1] and an
optional ``id``; ``up``/``fov`` ``None`` mean the scene sensor's. The batch's views
(:mod:`mi_npr.views`), camera paths (:mod:`mi_npr.paths`) and best view (:mod:`mi_npr.viewpoint`)
build it, read it and render it through the same functions:

- :mod:`~mi_npr.camera.model`: :class:`Camera`, :func:`check_lookat` (the one check of a
  ``lookat``), :func:`nearest_axis`, :func:`view_frame`;
- :mod:`~mi_npr.camera.files`: the camera file format, :func:`read_cameras`,
  :func:`from_json`, :func:`to_json`;
- :mod:`~mi_npr.camera.sensor`: :func:`camera_of` (a sensor's pose), :func:`projection_of`
  (the G-buffer's record of it), :func:`up_axis`, :func:`resolve` (missing ``up``/``fov`` from
  a sensor), :func:`sensor_for` (a camera as a Mitsuba sensor), :func:`sensor_xml` (as a file);
- :mod:`~mi_npr.camera.framing`: :func:`bounding_sphere`, :func:`fit_distance`,
  :func:`orbit`, :func:`fibonacci_sphere`, :func:`sphere_directions`, :func:`on_sphere`.

This package reads scenes (:mod:`mi_npr.scene`) and knows no renderer, drawing, batch or CLI.

>>> from mi_npr.camera import Camera, to_json, from_json
>>> keys = [Camera((4, 3, -4), (0, 0.5, 0), (0, 1, 0), 40)]
>>> from_json(to_json(keys)) == keys
True
"""

from __future__ import annotations

from .files import from_data, from_json, read_cameras, to_json
from .framing import (
    across_from,
    bounding_sphere,
    fibonacci_sphere,
    fit_distance,
    framed_shapes,
    objects_that_matter,
    on_sphere,
    orbit,
    rotation_y_to,
    sphere_directions,
)
from .model import Camera, check_lookat, nearest_axis, orthogonal_up, rotate, view_frame
from .sensor import (
    DEFAULT_FOV,
    camera_of,
    projection_of,
    resolve,
    sensor_for,
    sensor_xml,
    up_axis,
)

__all__ = [
    "DEFAULT_FOV",
    "Camera",
    "across_from",
    "bounding_sphere",
    "camera_of",
    "check_lookat",
    "fibonacci_sphere",
    "fit_distance",
    "framed_shapes",
    "from_data",
    "from_json",
    "nearest_axis",
    "objects_that_matter",
    "on_sphere",
    "orbit",
    "orthogonal_up",
    "projection_of",
    "read_cameras",
    "resolve",
    "rotate",
    "rotation_y_to",
    "sensor_for",
    "sensor_xml",
    "sphere_directions",
    "to_json",
    "up_axis",
    "view_frame",
]

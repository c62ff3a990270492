"""The one camera type of mi-npr, checked once, and the frame of a ``lookat``.

A :class:`Camera` is Mitsuba's ``lookat(origin, target, up)`` with a horizontal field of view
``fov`` in degrees (Mitsuba's ``x_fov``: ``fov_axis="x"``), the ``time`` in [0, 1] of the frame
it belongs to (a camera path's; 0 elsewhere) and an optional ``id``, the stem of the files it is
rendered to. ``up`` and ``fov`` may be ``None``: *the scene sensor's*, filled in when the camera
meets a sensor (:func:`mi_npr.camera.resolve`).

Frame (Mitsuba's ``look_at``): with ``f = (target - origin) / |target - origin|``,
``left = (up x f) / |up x f|`` and ``up' = f x left``, camera space has +z along ``f``, +y along
``up'`` and +x along ``left``. ``up`` need not be orthogonal to ``f``, only not parallel to it:
``|f x up| > 1e-9 |f| |up|``.

>>> cam = Camera((0, 1, -4), (0, 0, 0), (0, 1, 0), 40)
>>> cam.origin, cam.fov, cam.time
((0.0, 1.0, -4.0), 40.0, 0.0)
>>> Camera((0, 0, 0), (0, 0, 0))
Traceback (most recent call last):
    ...
mi_npr.errors.ParameterError: camera: origin and target are the same point [0.0, 0.0, 0.0]
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass
from typing import Any

import numpy as np

from ..errors import ParameterError, shown

Vec3 = tuple[float, float, float]

#: A camera id is a file stem: letters, digits, ``_``, ``-`` and ``.`` (not first).
CAMERA_ID = re.compile(r"^[A-Za-z0-9_-][A-Za-z0-9_.-]{0,99}$")


#: The largest coordinate a camera takes: Mitsuba computes in float32, where a larger one is
#: infinite (and the camera NaN).
MAX_COORDINATE = float(np.finfo(np.float32).max)


def _number(x: Any) -> bool:
    return isinstance(x, (int, float, np.integer, np.floating)) and not isinstance(
        x, (bool, np.bool_)
    )


def _vec3(where: str, name: str, value: Any) -> Vec3:
    try:  # a string of three digits is not three numbers, nor are booleans
        items = [] if isinstance(value, (str, bytes)) else list(value)
        v = [float(x) for x in items] if all(_number(x) for x in items) else []
    except (TypeError, ValueError, OverflowError):
        v = []
    if len(v) != 3 or not all(math.isfinite(x) and abs(x) <= MAX_COORDINATE for x in v):
        raise ParameterError(
            f"{where}: {name} = {shown(value)}: expected 3 finite numbers (float32: |x| <= 3.4e38)"
        )
    return (v[0] + 0.0, v[1] + 0.0, v[2] + 0.0)  # + 0.0: no -0.0


def vectors(name: str, value: Any, nonzero: bool = False) -> np.ndarray:
    """``value`` as a float64 array of 3-vectors, shape ``(..., 3)``, or :class:`ParameterError`
    naming ``name``: the vector helpers below take points and directions from users, and a
    string, NaN, a wrong shape or (with ``nonzero``) a zero vector is no direction."""
    try:
        if isinstance(value, (str, bytes)) or value is None:
            raise ValueError
        v = np.asarray(value, np.float64)
    except (TypeError, ValueError, OverflowError):
        v = np.zeros((0,))
    if v.ndim == 0 or v.shape[-1] != 3 or v.size == 0 or not np.all(np.isfinite(v)):
        raise ParameterError(f"{name} = {shown(value)}: expected 3 finite numbers (or rows of 3)")
    if nonzero and np.any(np.linalg.norm(v, axis=-1) == 0):
        raise ParameterError(f"{name} = {shown(value)}: a direction must not be zero")
    return v


def vector(name: str, value: Any, nonzero: bool = False) -> np.ndarray:
    """One 3-vector (shape ``(3,)``) of :func:`vectors`."""
    v = vectors(name, value, nonzero)
    if v.shape != (3,):
        raise ParameterError(f"{name} = {shown(value)}: expected one vector of 3 numbers")
    return v


def angle_of(name: str, value: Any) -> float:
    """``value`` as a finite float, or :class:`ParameterError` naming ``name``."""
    if not _number(value) or not math.isfinite(value):
        raise ParameterError(f"{name} = {shown(value)}: expected a finite number")
    return float(value)


def parallel(direction: Any, up: Any) -> bool:
    """Whether ``up`` lies along ``direction`` (``|d x up| <= 1e-9 |d| |up|``): no frame."""
    d, u = np.asarray(direction, np.float64), np.asarray(up, np.float64)
    return bool(
        np.linalg.norm(np.cross(d, u)) <= 1e-9 * np.linalg.norm(d) * max(np.linalg.norm(u), 1e-30)
    )


def check_lookat(
    where: str, origin: Any, target: Any, up: Any, fov: Any
) -> tuple[Vec3, Vec3, Vec3 | None, float | None]:
    """A pinhole camera's ``lookat(origin, target, up)`` and horizontal ``fov`` (degrees),
    checked and as floats; ``up`` and ``fov`` may be ``None`` (the sensor's). Errors are one
    :class:`~mi_npr.errors.ParameterError` line starting with ``where``."""
    o, t = _vec3(where, "origin", origin), _vec3(where, "target", target)
    d = np.subtract(t, o)
    with np.errstate(over="ignore", invalid="ignore"):  # as Mitsuba sees them, in float32
        d32 = np.subtract(np.float32(t), np.float32(o))
        n32 = float(np.linalg.norm(d32.astype(np.float64)))
    if np.linalg.norm(d) == 0 or n32 == 0:
        raise ParameterError(f"{where}: origin and target are the same point {list(o)}")
    if not (np.all(np.isfinite(d32)) and math.isfinite(n32)):
        raise ParameterError(f"{where}: origin and target are too far apart (float32)")
    u = None if up is None else _vec3(where, "up", up)
    if u is not None and parallel(d, u):
        raise ParameterError(f"{where}: up = {list(u)} lies along the view direction (parallel)")
    if fov is not None:
        if isinstance(fov, bool) or not isinstance(fov, (int, float)) or not 0 < fov < 180:
            raise ParameterError(f"{where}: fov = {fov!r}: must be in (0, 180) degrees")
        fov = float(fov)
    return o, t, u, fov


def _check(
    where: str, origin: Any, target: Any, up: Any, fov: Any, time: Any, id: Any
) -> tuple[Vec3, Vec3, Vec3 | None, float | None, float, str | None]:
    o, t, u, f = check_lookat(where, origin, target, up, fov)
    if (
        isinstance(time, bool)
        or not isinstance(time, (int, float, np.integer, np.floating))
        or not 0.0 <= time <= 1.0
    ):
        raise ParameterError(f"{where}: time = {time!r}: must be in [0, 1]")
    if id is not None and (not isinstance(id, str) or not CAMERA_ID.match(id)):
        raise ParameterError(f"{where}: id {id!r} is not a valid file stem")
    return o, t, u, f, float(time), id


_FIELDS = ("origin", "target", "up", "fov", "time", "id")


@dataclass(frozen=True)
class Camera:
    """A pinhole camera (module docstring): ``lookat(origin, target, up)``, horizontal ``fov``
    in degrees, ``time`` in [0, 1] and an optional ``id``; ``up``/``fov`` ``None``: the
    sensor's. Checked on construction (:func:`check_lookat`)."""

    origin: Vec3
    target: Vec3
    up: Vec3 | None = None
    fov: float | None = None
    time: float = 0.0
    id: str | None = None

    def __post_init__(self) -> None:
        values = _check("camera", self.origin, self.target, self.up, self.fov, self.time, self.id)
        for name, value in zip(_FIELDS, values, strict=True):
            object.__setattr__(self, name, value)

    @classmethod
    def checked(cls, where: str, **fields: Any) -> Camera:
        """A camera from ``fields`` (the constructor's), its errors starting with ``where``."""
        defaults = {"up": None, "fov": None, "time": 0.0, "id": None}
        values = [fields.get(n, defaults.get(n)) for n in _FIELDS]
        return cls(*_check(where, *values))

    @property
    def forward(self) -> np.ndarray:
        """The unit view direction ``(target - origin) / |target - origin|``."""
        d = np.subtract(self.target, self.origin)
        return d / np.linalg.norm(d)

    @property
    def resolved(self) -> bool:
        """Whether ``up`` and ``fov`` are given (nothing left to take from a sensor)."""
        return self.up is not None and self.fov is not None

    def to_dict(self) -> dict[str, Any]:
        """The camera file's fields (:mod:`mi_npr.camera.files`); ``id`` only when set."""
        d: dict[str, Any] = {
            "origin": list(self.origin),
            "target": list(self.target),
            "up": None if self.up is None else list(self.up),
            "fov": self.fov,
            "time": self.time,
        }
        if self.id is not None:
            d["id"] = self.id
        return d


# -- frames -------------------------------------------------------------------------------


def nearest_axis(v: Any) -> np.ndarray:
    """The signed world axis closest to ``v``: a tilted camera's up vector (0, 0.95, 0.3) means
    the world's +y is up.

    >>> nearest_axis([0.1, -0.2, -0.9])
    array([ 0.,  0., -1.])
    """
    v = vectors("v", v, nonzero=True).reshape(-1)
    if v.shape != (3,):
        raise ParameterError(f"v = {shown(v)}: expected one vector of 3 numbers")
    i = int(np.argmax(np.abs(v)))
    axis = np.zeros(3)
    axis[i] = 1.0 if v[i] >= 0 else -1.0
    return axis


def view_frame(
    origin: Any, target: Any, up: Any = None
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(forward, left, up)`` unit vectors of cameras at ``origin`` (..., 3) looking at ``target``.

    Mitsuba's ``lookat`` convention (camera +z forward, +y up, +x left). ``up`` is the preferred
    up direction (default +y); where the view direction is within ~8 degrees of it
    (``|f . up| > 0.99``), the world axis least aligned with the view direction is used
    instead, so the frame never degenerates. The returned ``up`` is orthogonal to ``forward``.
    """
    o = vectors("origin", origin)
    t = vectors("target", target)
    if np.broadcast_shapes(o.shape, t.shape) != o.shape:
        raise ParameterError(f"target = {shown(target)}: one per origin {o.shape} or one for all")
    t = np.broadcast_to(t, o.shape)
    f = t - o
    norm = np.linalg.norm(f, axis=-1, keepdims=True)
    if np.any(norm <= 0):
        raise ParameterError("origin and target coincide: no view direction")
    f = f / norm
    u0 = np.array([0.0, 1.0, 0.0]) if up is None else vectors("up", up, nonzero=True)
    if np.broadcast_shapes(u0.shape, f.shape) != f.shape:
        raise ParameterError(f"up = {shown(up)}: one per origin {o.shape} or one for all")
    u0 = np.broadcast_to(u0 / np.linalg.norm(u0, axis=-1, keepdims=True), f.shape)
    bad = np.abs((f * u0).sum(-1)) > 0.99
    axis = np.eye(3)[np.argmin(np.abs(f), axis=-1)]
    u = np.where(bad[..., None], axis, u0)
    left = np.cross(u, f)
    left /= np.linalg.norm(left, axis=-1, keepdims=True)
    return f, left, np.cross(f, left)


def rotate(v: Any, axis: Any, angle: float) -> np.ndarray:
    """Rodrigues' rotation of ``v`` about the unit ``axis`` by ``angle`` radians:
    ``v cos a + (axis x v) sin a + axis (axis . v)(1 - cos a)``."""
    v, axis = vectors("v", v), vectors("axis", axis, nonzero=True)
    if axis.shape != (3,):
        raise ParameterError(f"axis = {shown(axis)}: expected one vector of 3 numbers")
    angle = angle_of("angle", angle)
    c, s = math.cos(angle), math.sin(angle)
    return v * c + np.cross(axis, v) * s + axis * np.dot(axis, v) * (1 - c)


def orthogonal_up(forward: Any, up: Any) -> np.ndarray:
    """``up`` made orthogonal to the unit ``forward`` and unit length (Gram-Schmidt): the image's
    up direction of ``lookat(o, o + forward, up)``; ``up`` must not be parallel to ``forward``."""
    f, u = vectors("forward", forward, nonzero=True), vectors("up", up, nonzero=True)
    if f.shape != (3,) or u.shape != (3,):
        raise ParameterError("forward and up: expected one vector of 3 numbers each")
    u = u - np.dot(u, f) * f
    n = np.linalg.norm(u)
    if n <= 1e-12 * np.linalg.norm(f):
        raise ParameterError(f"up = {u.tolist()} lies along forward = {f.tolist()} (parallel)")
    return u / n

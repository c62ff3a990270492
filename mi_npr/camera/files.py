"""Camera files: the one JSON format of every camera a user writes or mi-npr writes back.

A camera file holds a non-empty list of cameras, or an object ``{"cameras": [...]}``. Each
camera is an object with the fields of :class:`~mi_npr.camera.Camera`:

==========  ============================================================================
``origin``  3 numbers (required)
``target``  3 numbers (required)
``up``      3 numbers, not along ``target - origin``; absent or ``null``: the scene's up
            axis (:func:`mi_npr.camera.resolve`)
``fov``     horizontal field of view in degrees, in (0, 180); absent or ``null``: the
            scene sensor's
``time``    in [0, 1]; absent or ``null``: camera ``k`` of ``K`` gets ``k / (K - 1)`` (0
            for one)
``id``      a file stem (letters, digits, ``_``, ``-``, ``.``), unique in the file; absent:
            the reader's caller names the camera (the batch: ``cam_000`` ...)
==========  ============================================================================

Any other key is an error. Every error is one :class:`~mi_npr.errors.ParameterError` line
naming the file, the camera's index and the field: ``keys.json: camera 2: unknown key 'zoom'``.
:func:`to_json` writes the same format (``id`` only where set), so what mi-npr writes
(``path.json``) reads back equal.

>>> cams = from_json('[{"origin": [0, 1, -4], "target": [0, 0, 0]}]', "keys.json")
>>> cams[0].up is None and cams[0].fov is None
True
>>> try:
...     from_json('[{"origin": [0, 1, -4], "target": [0, 0, 0], "zoom": 2}]', "k.json")
... except ParameterError as e:
...     print(e)
k.json: camera 0: unknown key 'zoom' (keys: origin, target, up, fov, time, id)
"""

from __future__ import annotations

import json
import os
from collections.abc import Sequence
from typing import Any

import numpy as np

from ..errors import ParameterError, as_path, check_input_file, shown
from .model import Camera

#: The fields of a camera in a file, in the order :func:`to_json` writes them.
KEYS = ("origin", "target", "up", "fov", "time", "id")


def from_data(data: Any, source: str = "cameras") -> list[Camera]:
    """The cameras of parsed JSON ``data`` (module docstring); errors name ``source``."""
    if isinstance(data, dict) and "cameras" in data:
        other = sorted(set(data) - {"cameras"}, key=str)
        if other:
            raise ParameterError(f"{source}: unknown key {other[0]!r} (beside 'cameras')")
        data = data["cameras"]
    if not isinstance(data, list) or not data:
        raise ParameterError(f"{source}: expected a non-empty list of cameras")
    times = np.linspace(0.0, 1.0, len(data)) if len(data) > 1 else np.zeros(1)
    out: list[Camera] = []
    seen: set[str] = set()
    for k, item in enumerate(data):
        where = f"{source}: camera {k}"
        if not isinstance(item, dict):
            raise ParameterError(f"{where}: expected an object with origin and target")
        unknown = sorted(set(item) - set(KEYS), key=str)
        if unknown:
            raise ParameterError(f"{where}: unknown key {unknown[0]!r} (keys: {', '.join(KEYS)})")
        for key in ("origin", "target"):
            if key not in item:
                raise ParameterError(f"{where} has no {key!r}")
        fields = dict(item)
        if fields.get("time") is None:
            fields["time"] = float(times[k])
        cam = Camera.checked(where, **fields)
        if cam.id is not None:
            if cam.id in seen:
                raise ParameterError(f"{where}: id {cam.id!r} is used twice")
            seen.add(cam.id)
        out.append(cam)
    return out


def from_json(text: str, source: str = "cameras") -> list[Camera]:
    """The cameras of a camera file's text (module docstring); errors name ``source``."""
    if not isinstance(text, (str, bytes, bytearray)):
        raise ParameterError(f"{source}: expected the text of a camera file, got {shown(text)}")
    try:
        data = json.loads(text)
    except ValueError as e:
        raise ParameterError(f"{source}: not a JSON file of cameras ({e})") from None
    except RecursionError:  # Python's reader recurses once per nesting level
        raise ParameterError(f"{source}: not a JSON file of cameras (nested too deeply)") from None
    return from_data(data, source)


def read_cameras(path: str | os.PathLike[str]) -> list[Camera]:
    """The cameras of the camera file ``path`` (module docstring)."""
    name = os.fspath(as_path(path, "camera file"))
    check_input_file(name, ParameterError)
    try:
        with open(name, encoding="utf-8") as f:
            text = f.read()
    except OSError as e:
        raise ParameterError(f"{name}: cannot read the cameras ({e.strerror})") from None
    except UnicodeDecodeError as e:
        raise ParameterError(f"{name}: not a JSON file of cameras ({e})") from None
    return from_json(text, name)


def to_json(cameras: Sequence[Camera]) -> str:
    """``cameras`` as a camera file (module docstring): what :func:`from_json` reads back."""
    return json.dumps([c.to_dict() for c in cameras], indent=1)

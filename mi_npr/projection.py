"""World -> image for a Mitsuba perspective (or thin-lens) camera, written once.

The EXR writer's standard attributes (``worldToCamera``, ``worldToNDC``) and the reprojection of
:mod:`mi_npr.coherence` use the same matrices. A :class:`~mi_npr.gbuffer.Projection` holds Mitsuba's
``to_world`` (camera space: +z forward, +y up, +x to the *left*) and its horizontal ``fov``.

- :func:`world_to_camera`: OpenEXR/RenderMan camera space (+x right, +y up, +z forward);
- :func:`world_to_ndc`: RenderMan NDC after the divide by w (x = 0 at the left edge, 1 at the
  right; y = 0 at the top, 1 at the bottom; z = 0 on the near, 1 on the far clip plane);
- :func:`project`: points -> continuous pixel coordinates (pixel ``(i, j)`` covers
  ``[i, i + 1) x [j, j + 1)``, its centre at ``i + 0.5``) and the camera-space depth that the
  ``Z`` layer holds (distance along the view axis).
"""

from __future__ import annotations

import numpy as np

from .gbuffer import Projection

#: OpenEXR/RenderMan camera space against Mitsuba's: x is mirrored (Mitsuba's +x is left).
_MIRROR_X = np.diag([-1.0, 1.0, 1.0, 1.0])


def world_to_camera(camera: Projection) -> np.ndarray:
    """World -> OpenEXR camera space (+x right, +y up, +z forward), 4x4 for column vectors."""
    return _MIRROR_X @ np.linalg.inv(camera.to_world)


#: The camera kinds that project through one point (:func:`world_to_ndc`): a thin lens through
#: the centre of its lens, where the G-buffer's pixel rays pass (:mod:`mi_npr.render`).
PINHOLE = ("perspective", "thinlens")


def world_to_ndc(camera: Projection) -> np.ndarray | None:
    """World -> OpenEXR NDC (homogeneous, column vectors; ``None`` unless the camera's kind is
    one of :data:`PINHOLE`).

    After the divide by w: x = 0 at the image's left edge and 1 at its right, y = 0 at the top
    and 1 at the bottom (RenderMan's NDC, which OpenEXR's standard attributes use), z = 0 on the
    near and 1 on the far clip plane. ``camera.fov`` is Mitsuba's horizontal field of view.
    """
    if camera.fov is None or camera.kind not in PINHOLE:
        return None
    w, h = camera.resolution
    tan_x = np.tan(np.radians(camera.fov) / 2.0)
    tan_y = tan_x * h / w
    n, f = camera.near_clip, camera.far_clip
    proj = np.array(
        [
            [0.5 / tan_x, 0.0, 0.5, 0.0],
            [0.0, -0.5 / tan_y, 0.5, 0.0],
            [0.0, 0.0, f / (f - n), -f * n / (f - n)],
            [0.0, 0.0, 1.0, 0.0],
        ]
    )
    return proj @ world_to_camera(camera)


def project(camera: Projection, points: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """World ``points`` (..., 3) seen by a perspective ``camera``: ``(x, y, depth)`` with
    ``x``, ``y`` continuous pixel coordinates (centre of pixel ``(i, j)`` at
    ``(i + 0.5, j + 0.5)``) and ``depth`` the camera-space distance along the view axis (the
    ``Z`` layer's). Points behind the camera (``depth <= 0``) get ``x = y = nan``."""
    ndc = world_to_ndc(camera)
    if ndc is None:
        raise ValueError(f"project: a {camera.kind} camera is not perspective")
    p = np.asarray(points, np.float64)
    flat = p.reshape(-1, 3)
    hom = np.concatenate([flat, np.ones((len(flat), 1))], axis=1)
    clip = hom @ ndc.T
    depth = clip[:, 3]  # w = camera-space z
    with np.errstate(divide="ignore", invalid="ignore"):
        ok = depth > 0
        x = np.where(ok, clip[:, 0] / depth, np.nan) * camera.resolution[0]
        y = np.where(ok, clip[:, 1] / depth, np.nan) * camera.resolution[1]
    shape = p.shape[:-1]
    return x.reshape(shape), y.reshape(shape), depth.reshape(shape)

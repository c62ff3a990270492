"""Temporal coherence of line drawings along a camera path: how much line intensity pops.

Popping (section 5.1 of the thesis) is line ink that appears or vanishes from one frame to the
next although the surface under it stays in view. :func:`popping` measures it between
consecutive frames ``a`` and ``b`` of a path:

1. every pixel of ``a`` that saw a surface (finite ``Z``) is *reprojected* into ``b``: its
   world position ``P`` through ``b``'s camera (:func:`mi_npr.projection.project`, the one
   world -> pixel mapping) gives a pixel of ``b`` and a depth;
2. pixels that leave ``b``'s image, or whose reprojected depth lies behind ``b``'s ``Z`` there
   (more than ``depth_tolerance`` relative, against the farthest ``Z`` of the ``(2 radius + 1)``
   window, so a pixel on a silhouette is not dropped for landing one pixel off) are *occluded*
   and dropped: their ink may legitimately disappear;
3. the ink of ``a`` that ``b`` does not have there is what *vanishes*:
   ``sum max(ink_a - max_window(ink_b), 0)`` over the kept pixels; the window (``radius``
   pixels, default 1) forgives the sub-pixel shift of nearest-pixel reprojection;
4. what *appears* is the same from ``b`` back to ``a``.

Per frame pair, ``popping = (vanished + appeared) / (kept ink of a + kept ink of b)``, in
[0, 1] (0 when neither frame has ink where the other sees); ``overall`` is the ratio of the
sums over the whole path. A static camera gives exactly 0.

``frames`` are :class:`~mi_npr.gbuffer.GBuffer` objects (anything with ``P.X P.Y P.Z``,
``Z``, the line layer and a perspective ``.camera``), e.g. :attr:`mi_npr.paths.Frames.gbuffers`.
"""

from __future__ import annotations

import itertools
from collections.abc import Iterable, Mapping, Sequence
from typing import Any

import numpy as np

from . import layers as L
from .errors import ParameterError
from .gbuffer import GBuffer, Projection
from .kernels import lines
from .projection import project


def _numpy(frame: Any, name: str) -> np.ndarray:
    try:
        v = frame[name]
    except KeyError:
        raise ParameterError(f"popping: a frame has no {name!r} layer") from None
    return np.asarray(v, np.float64)


def _camera(frame: Any) -> Projection:
    cam = getattr(frame, "camera", None)
    if cam is None or cam.fov is None:
        raise ParameterError("popping: every frame needs a perspective camera")
    return cam


def reproject(
    frame: Any,
    camera: Projection,
    Z: np.ndarray | None = None,
    *,
    radius: int = 1,
    depth_tolerance: float = 0.02,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Each pixel of ``frame`` (its ``P`` and ``Z`` layers) seen by ``camera``: ``(col, row, depth,
    kept)``, integer pixel indices (-1 where not kept), the camera-space depth, and whether the
    pixel is kept (a surface, inside the image, in front, and not behind ``Z`` of the other
    frame when given; module docstring)."""
    P = np.stack([_numpy(frame, n) for n in L.P], axis=-1)
    x, y, depth = project(camera, P)
    w, h = camera.resolution
    with np.errstate(invalid="ignore"):
        # a surface: finite Z (the background's P holds zeros, its Z is +inf)
        kept = np.isfinite(_numpy(frame, L.Z)) & np.all(np.isfinite(P), axis=-1)
        kept &= np.isfinite(x) & np.isfinite(y)
        kept &= (x >= 0) & (x < w) & (y >= 0) & (y < h) & (depth > 0)
    col = np.where(kept, np.floor(np.nan_to_num(x)), -1).astype(np.int64)
    row = np.where(kept, np.floor(np.nan_to_num(y)), -1).astype(np.int64)
    col, row = np.minimum(col, w - 1), np.minimum(row, h - 1)
    if Z is not None:
        z = np.asarray(Z, np.float64)
        if z.shape != (h, w):
            raise ParameterError(f"popping: Z is {z.shape}, the camera's image is {(h, w)}")
        far = _maximum_filter(np.where(np.isnan(z), np.inf, z), radius)
        behind = depth[kept] > far[row[kept], col[kept]] * (1 + depth_tolerance)
        idx = np.flatnonzero(kept.ravel())[behind]
        kept.ravel()[idx] = False
        col[~kept], row[~kept] = -1, -1
    return col, row, depth, kept


def _maximum_filter(a: np.ndarray, radius: int) -> np.ndarray:
    """The maximum over a (2 radius + 1)^2 window, the border repeated."""
    from scipy.ndimage import maximum_filter  # lazy: keeps scipy's import out of start-up

    return maximum_filter(a, size=2 * radius + 1, mode="nearest")


def _vanished(a: Any, b: Any, layer: str, radius: int, tol: float) -> tuple[float, float]:
    """(ink of ``a`` that ``b`` lacks, kept ink of ``a``) for ``a`` reprojected into ``b``."""
    ink_a = np.clip(np.nan_to_num(_numpy(a, layer)), 0, 1)
    ink_b = np.clip(np.nan_to_num(_numpy(b, layer)), 0, 1)
    col, row, _, kept = reproject(a, _camera(b), _numpy(b, L.Z), radius=radius, depth_tolerance=tol)
    near = _maximum_filter(ink_b, radius) if radius else ink_b
    ia = ink_a[kept]
    there = near[row[kept], col[kept]]
    return float(np.maximum(ia - there, 0).sum()), float(ia.sum())


def popping(
    frames: Iterable[Any], layer: str = L.LINES, *, radius: int = 1, depth_tolerance: float = 0.02
) -> dict:
    """The popping of ``layer`` along ``frames`` (module docstring): a dict with ``layer``,
    ``per_frame`` (one value per consecutive pair), ``appeared`` and ``vanished`` (fractions of
    each pair's kept ink), ``ink`` (kept ink per pair) and ``overall``."""
    if isinstance(radius, bool) or not isinstance(radius, int) or not 0 <= radius <= 8:
        raise ParameterError(f"radius = {radius!r}: must be an integer in [0, 8]")
    if not (isinstance(depth_tolerance, (int, float)) and 0 <= depth_tolerance < 1):
        raise ParameterError(f"depth_tolerance = {depth_tolerance!r}: must be in [0, 1)")
    per, app, van, inks = [], [], [], []
    total_pop = total_ink = 0.0
    seen = [0]

    def each() -> Any:  # one pass, two frames held at a time: frames may be read from disk
        for f in frames:
            seen[0] += 1
            yield f

    for a, b in itertools.pairwise(each()):
        v, ink_a = _vanished(a, b, layer, radius, depth_tolerance)
        u, ink_b = _vanished(b, a, layer, radius, depth_tolerance)
        ink = ink_a + ink_b
        per.append((v + u) / ink if ink > 0 else 0.0)
        van.append(v / ink if ink > 0 else 0.0)
        app.append(u / ink if ink > 0 else 0.0)
        inks.append(ink)
        total_pop += v + u
        total_ink += ink
    return {
        "layer": layer,
        "radius": radius,
        "depth_tolerance": depth_tolerance,
        "frames": seen[0],
        "per_frame": per,
        "appeared": app,
        "vanished": van,
        "ink": inks,
        "overall": total_pop / total_ink if total_ink > 0 else 0.0,
    }


def figure(curves: Mapping[str, Mapping[str, Any]]) -> Any:
    """A matplotlib figure of the per-frame popping of each named result of :func:`popping`,
    or ``None`` without matplotlib (the ``plots`` extra)."""
    try:  # imported here: matplotlib is optional (the plots extra) and slow to import
        import matplotlib

        if "matplotlib.pyplot" not in __import__("sys").modules:
            matplotlib.use("Agg")
        import matplotlib.pyplot as plt  # after the backend is chosen
    except ImportError:
        return None
    fig, ax = plt.subplots(figsize=(6.4, 3.2))
    for name, c in curves.items():
        per = c.get("per_frame", [])
        ax.plot(range(1, len(per) + 1), per, label=f"{name} ({c.get('overall', 0):.3f})")
    ax.set_xlabel("frame")
    ax.set_ylabel("popping (fraction of line ink)")
    ax.set_ylim(bottom=0)
    ax.legend(fontsize=8)
    fig.tight_layout()
    return fig


#: The line variants of the thesis's claim (section 5.1), as :func:`mi_npr.kernels.lines`
#: parameters on depth contours alone (no ID edges, no creases: those are drawn at full strength
#: in every variant and would only dilute the difference) and whether the result is
#: thresholded to black/white at ``t0``.
VARIANTS: dict[str, tuple[dict[str, Any], bool]] = {
    "gray": ({"dilation_iterations": 0, "remove_isolated": False}, False),
    "black/white": ({"dilation_iterations": 0, "remove_isolated": False}, True),
    "gray + pre-filter + eq. 5.2": ({"dilation_iterations": 1, "remove_isolated": True}, False),
    "black/white + pre-filter + eq. 5.2": (
        {"dilation_iterations": 1, "remove_isolated": True},
        True,
    ),
}


def variant_lines(frame: Any, name: str, **params: Any) -> np.ndarray:
    """The ink of line variant ``name`` (:data:`VARIANTS`) of one frame's G-buffer (``Z``):
    eq. 5.1 gray levels as they are, or thresholded at ``t0`` (black/white), with or without
    the selective-dilation pre-filter (eqs. 5.3-5.4) and eq. 5.2. ``params`` are further
    :func:`mi_npr.kernels.lines` parameters (``c``, ``t``, ``t0``...)."""

    if name not in VARIANTS:
        raise ParameterError(f"line variant {name!r}: expected one of {', '.join(VARIANTS)}")
    chain, bw = VARIANTS[name]
    p = {"id_edges": False, "crease_angle": 0.0, **chain, **params}
    ink = np.asarray(lines({L.Z: frame[L.Z]}, **p), np.float32)
    if bw:
        ink = (ink > p.get("t0", 0.5)).astype(np.float32)
    return ink


def line_variants(frames: Sequence[Any], **params: Any) -> dict[str, dict]:
    """:func:`popping` of every line variant of :data:`VARIANTS` along ``frames`` (each with
    ``Z``, ``P`` and a camera): the thesis's claim that gray levels and the pre-filter reduce
    popping, measured. ``params`` go to :func:`variant_lines`."""

    out = {}
    for name in VARIANTS:
        fr = (
            GBuffer(
                {**{n: f[n] for n in (L.Z, *L.P)}, L.LINES: variant_lines(f, name, **params)},
                camera=_camera(f),
            )
            for f in frames
        )
        out[name] = popping(fr, L.LINES)
    return out

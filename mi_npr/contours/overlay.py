"""Contours of a rendered G-buffer drawn over its beauty image: the paper's Fig. 10.

The one function the ``npr_contours`` plugin, the ``mi-npr contours`` command and the notebooks
share: ids of the chosen ``id_mode`` from the G-buffer, every contour traced on them, the
``contour`` layer, and the contour pixels painted in ``color`` (red by default) over the raw
beauty (kept in ``beauty.R/G/B``, see :mod:`mi_npr.compose`).
"""

from __future__ import annotations

import json
from collections.abc import Sequence

import mitsuba as mi
import numpy as np

from .. import layers as L
from ..compose import raw_beauty_layers, with_overlay
from ..errors import ParameterError
from ..gbuffer import GBuffer
from ..kernels import id_edges, widen_lines
from .contour import Contour
from .idmode import check_id_mode, id_map, split_globs
from .trace import check_method, contour_layer, trace

RED = (1.0, 0.0, 0.0)


#: Depth step (normalised over the frame's finite depth range) above which the nearer object
#: owns the contour between two objects: eq. 5.1's default ``t / c`` = 1 / 40, the step the
#: ``npr_lines`` chain uses for its 1-px ID edges (:mod:`mi_npr.kernels.edges`).
CONTACT_STEP = 1.0 / 40.0


def mode_ids(
    gb: GBuffer,
    scene: mi.Scene | None = None,
    id_mode: str = "shape",
    only: Sequence[str] | str = (),
    ignore: Sequence[str] | str = (),
) -> tuple[np.ndarray, dict[int, str]]:
    """``gb``'s ids in ``id_mode`` (:mod:`mi_npr.contours.idmode`) and their names, the
    objects not selected by ``only``/``ignore`` as background. ``"shape"`` with every object
    is the ``object_id`` layer and the object table; anything else needs the ``scene``."""
    check_id_mode(id_mode)
    if id_mode == "shape" and not only and not ignore:
        return gb.object_id, dict(gb.objects)
    if scene is None:
        raise ParameterError(f"id_mode = {id_mode!r} needs the scene (its meshes)")
    ids = id_map(scene, id_mode, only=split_globs(only), ignore=split_globs(ignore))
    return ids.apply(gb.numpy(L.OBJECT_ID), gb.numpy(L.PRIM_ID)), ids.names


def owned(ids: np.ndarray, depth: np.ndarray) -> np.ndarray:
    """Pixels of an object (id != 0) that own an edge with a 4-neighbour of another id, by
    the side rule of :mod:`mi_npr.kernels.edges`: the nearer pixel where the depth,
    normalised over the frame's finite range, steps by more than :data:`CONTACT_STEP`, else
    the larger id. So the contour between two touching objects is 1 px, and an object's
    contour against the background (or an object far behind) lies on the object."""

    z = np.asarray(depth, np.float32)
    fin = np.isfinite(z)
    if fin.any():
        lo, hi = float(z[fin].min()), float(z[fin].max())
        z = np.where(fin, (z - lo) / (hi - lo if hi > lo else 1.0), np.inf).astype(np.float32)
    edge = np.asarray(id_edges(ids, 1, z, CONTACT_STEP)) > 0
    return edge & (np.asarray(ids) != 0)


def one_sided(contours: list[Contour], keep: np.ndarray) -> list[Contour]:
    """The pieces of ``contours`` on the pixels ``keep`` (a contour leaving them is cut into
    open pieces; a contour kept whole stays as it was)."""
    out: list[Contour] = []
    for c in contours:
        p = c.points
        if len(p) == 0:
            continue
        k = keep[p[:, 1], p[:, 0]]
        if k.all():
            out.append(c)
            continue
        if c.closed and k[0] and k[-1] and not k.all():  # a run wraps around the start
            start = int(np.argmin(k))
            p, k = np.roll(p, -start, axis=0), np.roll(k, -start)
        edges = np.flatnonzero(np.diff(np.r_[0, k.astype(np.int8), 0]))
        for a, b in zip(edges[::2], edges[1::2], strict=True):
            out.append(Contour(c.object_id, c.name, p[a:b], closed=False, is_hole=c.is_hole))
    return out


def overlay(
    gb: GBuffer,
    scene: mi.Scene | None = None,
    *,
    method: str = "border",
    id_mode: str = "shape",
    color: Sequence[float] = RED,
    only: Sequence[str] | str = (),
    ignore: Sequence[str] | str = (),
    line_width: float = 1.0,
) -> tuple[GBuffer, list[Contour]]:
    """``gb`` with its contours: the ``contour`` layer added and drawn in ``color`` on R G B.

    Returns the new GBuffer and the contours (:func:`mi_npr.contours.trace` on the ids of
    ``id_mode``). The overlay always starts from the raw beauty (``beauty.R/G/B`` when an earlier
    overlay left it, else ``R G B``), so calling it again replaces the contours rather than
    stacking them. ``only``/``ignore`` select the objects drawn (the others count as
    background); a contour shared by two objects is drawn on one side only (:func:`owned`), in
    the layer and in the returned contours (cut into open pieces). ``line_width`` widens the
    drawing (not the layer). Metadata: ``mi_npr/contour_method``, ``mi_npr/contour_id_mode``,
    ``mi_npr/contour_color`` and ``mi_npr/contour_objects`` (JSON id -> name of the ``contour``
    layer's ids; with ``id_mode="shape"`` the object table itself).
    """
    check_method(method)
    mapped, names = mode_ids(gb, scene, id_mode, only, ignore)
    contours = trace(mapped, objects=names, method=method)
    depth = gb.get(L.Z)  # without depth, the larger id owns every edge
    contours = one_sided(contours, owned(mapped, np.zeros(gb.shape) if depth is None else depth))
    layer = contour_layer(contours, gb.shape)
    base = gb.with_layers(raw_beauty_layers(gb))
    ink = (layer != 0).astype(np.float32)
    if line_width != 1.0:
        ink = np.asarray(widen_lines(ink, float(line_width)))
    out = with_overlay(base, ink, color).with_layers({L.CONTOUR: layer})
    out = out.with_metadata(
        **{
            "mi_npr/contour_method": method,
            "mi_npr/contour_id_mode": id_mode,
            "mi_npr/contour_objects": json.dumps({str(k): v for k, v in names.items()}),
            "mi_npr/contour_color": ",".join(f"{float(v):g}" for v in color),
            "mi_npr/contour_line_width": f"{float(line_width):g}",
            "mi_npr/contour_only": ",".join(split_globs(only)),
            "mi_npr/contour_ignore": ",".join(split_globs(ignore)),
        }
    )
    return out, contours

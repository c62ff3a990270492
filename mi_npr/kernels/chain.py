"""The thesis's line chain as one call: ``lines(gbuffer, **params)``.

Section 5.1 of the thesis: normalised depth -> optional pre-filter (selective dilation, eqs.
5.3-5.4) -> signed depth contours (eq. 5.1) -> optional isolated-pixel removal (eq. 5.2); mi-npr
adds optional object-ID and normal (crease) edges from the exact G-buffer, drawn at full
strength (``lines = max(p, edges)``). The result is the gray-level line image of the ``lines``
layer, in [0, 1].

The stages are fused into few Dr.Jit kernels: one pass finds the frame's depth range, the depth
normalisation happens inside the first stencil that reads ``Z``, each dilation iteration is one
kernel, eq. 5.1 is one, and eq. 5.2 with the edges is the last one.

Parameters (:data:`LINES_PARAMS`, shared with the ``npr_lines`` plugin):

=====================  =======  ========  ======================================================
name                   type     default   meaning
=====================  =======  ========  ======================================================
``c``                  float    40        eq. 5.1 gain on the normalised depth difference (>= 0)
``t``                  float    1         eq. 5.1 threshold (>= 0): a step lights up above
                                          ``t / c`` and is black from ``(1 + t) / c``
``t0``                 float    0.5       eq. 5.2 threshold in [0, 1]
``dilation_size``      int      3         selective-dilation window, odd, 3..15
``dilation_iterations`` int     1         selective-dilation passes (0 = no pre-filter)
``remove_isolated``    bool     true      apply eq. 5.2
``id_edges``           bool     false     add object-ID edges (2 px thick)
``normal_edges``       float    0         add creases sharper than this angle, in degrees, on one
                                          object (2 px thick); 0 = off
``near``, ``far``      float    unset     depth range mapped to [0, 1]; unset = the frame's
                                          finite ``Z`` range
=====================  =======  ========  ======================================================

Why these defaults: with ``Z`` normalised over the frame's depth range, a depth step lights up
when it exceeds ``t / c`` = 2.5 % of that range and is fully black from 5 %; on the paper's
scenes at 640x480 this draws every silhouette as a clean 1-px line, while the steepest in-surface
steps (the floor near the horizon, sphere rims) stay below it. ID and normal edges are off because
they are 2 px thick (see :mod:`mi_npr.kernels.edges`); turn them on for touching or intersecting
objects (scene 4) and for creases.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import drjit as dr
from drjit.llvm.ad import TensorXf

from .. import layers as L
from ..errors import ParameterError
from ..params import Param, check_values
from ._stencil import (
    Field,
    Grid,
    finite,
    float_image,
    id_image,
    nonnegative,
    same_shape,
    tensor,
    unit_interval,
)
from .depth_lines import check_range, contours, depth_normalizer, isolated_removed
from .edges import angle, id_edge, normal_edge
from .morphology import dilated, iteration_count, window_size

LINES_PARAMS: tuple[Param, ...] = (
    Param("c", float, 40.0, "eq. 5.1 gain on the normalised depth difference", nonnegative),
    Param("t", float, 1.0, "eq. 5.1 threshold: steps above t / c light up", nonnegative),
    Param("t0", float, 0.5, "eq. 5.2 threshold: line pixels lie above it", unit_interval),
    Param("dilation_size", int, 3, "selective dilation window (odd, 3..15)", window_size),
    Param("dilation_iterations", int, 1, "selective dilation passes (0 = off)", iteration_count),
    Param("remove_isolated", bool, True, "remove isolated line pixels (eq. 5.2)"),
    Param("id_edges", bool, False, "add object-ID edges"),
    Param("normal_edges", float, 0.0, "add creases sharper than this (degrees; 0 = off)", angle),
    Param("near", float, None, "depth mapped to 0 (unset: nearest finite Z)", finite),
    Param("far", float, None, "depth mapped to 1 (unset: farthest finite Z)", finite),
)


def _layer(gbuffer: Mapping[str, Any], name: str, why: str) -> Any:
    try:
        return gbuffer[name]
    except KeyError:
        raise ParameterError(f"lines: the G-buffer has no {name!r} layer ({why})") from None


def lines(gbuffer: Mapping[str, Any], **params: Any) -> TensorXf:
    """The gray-level line image of a G-buffer (the ``lines`` layer), see the module docstring.

    ``gbuffer`` is a :class:`~mi_npr.gbuffer.GBuffer` (or any mapping of layer names to (H, W)
    arrays) with ``Z``, plus ``object_id`` for ID edges and ``N.X N.Y N.Z`` for normal edges.
    ``params`` are those of :data:`LINES_PARAMS`; unknown names and bad values raise
    :class:`~mi_npr.errors.ParameterError` naming the parameter.

    >>> gb = mi_npr.render("scenes_xml/scene2.xml", width=160, height=120)  # doctest: +SKIP
    >>> ink = mi_npr.kernels.lines(gb, t=0.5, id_edges=True)                 # doctest: +SKIP
    >>> np.asarray(ink).shape                                                # doctest: +SKIP
    (120, 160)
    """
    p = check_values("lines", LINES_PARAMS, params)
    check_range(p["near"], p["far"], "lines")
    z, shape = float_image(_layer(gbuffer, L.Z, "depth"), L.Z)
    grid = Grid(shape)

    depth = Field(z, grid, depth_normalizer(z, p["near"], p["far"]))
    for _ in range(p["dilation_iterations"]):
        d = dilated(depth, p["dilation_size"])
        dr.eval(d)
        depth = Field(d, grid)

    ink = contours(depth, p["c"], p["t"])
    if p["remove_isolated"]:
        dr.eval(ink)
        ink = isolated_removed(Field(ink, grid), p["t0"])

    edge = None
    if p["id_edges"] or p["normal_edges"] > 0:
        why = "needed by id_edges and normal_edges"
        ids, shape_i = id_image(_layer(gbuffer, L.OBJECT_ID, why), L.OBJECT_ID)
        same_shape({L.Z: shape, L.OBJECT_ID: shape_i})
        id_field = Field(ids, grid)
        if p["id_edges"]:
            edge = id_edge(id_field)
        if p["normal_edges"] > 0:
            normals = [float_image(_layer(gbuffer, n, "needed by normal_edges"), n) for n in L.N]
            same_shape({L.Z: shape, **{n: s for n, (_, s) in zip(L.N, normals, strict=True)}})
            planes = [q for q, _ in normals]
            crease = normal_edge([Field(q, grid) for q in planes], id_field, p["normal_edges"])
            edge = crease if edge is None else edge | crease
    if edge is not None:
        ink = dr.select(edge, 1.0, ink)
    return tensor(ink, shape)

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

=========================  =======  ========  ======================================================
name                       type     default   meaning
=========================  =======  ========  ======================================================
``c``                      float    40        eq. 5.1 gain on the normalised depth difference (>= 0)
``t``                      float    1         eq. 5.1 threshold (>= 0): a step lights up above
                                              ``t / c`` and is black from ``(1 + t) / c``
``t0``                     float    0.5       eq. 5.2 threshold in [0, 1]
``dilation_size``          int      3         selective-dilation window, odd, 3..15
``dilation_iterations``    int      1         selective-dilation passes, 0..64 (0 = none)
``remove_isolated``        bool     true      apply eq. 5.2
``id_edges``               bool     true      object boundaries (ID edges), 1 px
``crease_angle``           float    134       creases: 4-neighbours on one object whose dihedral
                                              angle is below this, in degrees (Freestyle's crease
                                              angle; 0 = off), 1 px
``leaf_edges``             int      0         add the outline of every leaf from the ``leaf_id``
                                              layer: 0 = off, 1 = 1 px on the nearer leaf, 2 = 2 px
``max_density``            float    1         thin lines where the ink of a 9x9 region exceeds this
                                              share: creases go first, then ID/leaf edges; depth
                                              contours stay (1 = off)
``line_width``             float    1         width of every line in pixels, (0, 15]
``bright_fade``            float    0         fade lines out where the beauty's luminance exceeds
                                              this: full below it, none from twice it; 0 = off
``near``, ``far``          float    unset     depth range mapped to [0, 1]; unset = the frame's
                                              nearest finite ``Z`` and the larger of its farthest
                                              and 4x its nearest; background reads 2 (see below)
=========================  =======  ========  ======================================================

Why these defaults: a line drawing holds silhouettes, object boundaries and creases,
which is what Blender Freestyle draws (silhouette + border + crease at 134 degrees); depth alone
misses boundaries at equal depth (touching objects, a box on the floor) and every crease (room
corners, hole rims). With ``Z`` normalised over the frame's depth range, a depth step lights up
when it exceeds ``t / c`` = 2.5 % of that range and is fully black from 5 %.

**The width rule**: every kind of line is 1 px wide before ``line_width``: one side of every
edge. Eq. 5.1 is signed and inks the near side of a depth step; ID and crease edges ink one
pixel of each pair of 4-neighbours they separate, the near one where the pair's depth (the same
normalised, pre-filtered depth eq. 5.1 reads) steps by more than eq. 5.1's ``t / c``, else the
larger id (ID edges) or the surface facing the camera more (creases; the camera's axis is the
G-buffer's ``camera.forward``, +z for a plain mapping); see :mod:`mi_npr.kernels.edges`. So
edges of several kinds on one boundary land on the same pixels and never double the width.
Then ``max_density`` thins (:func:`~mi_npr.kernels.ink.ink_density`), ``line_width`` widens
every line alike (:func:`~mi_npr.kernels.ink.widen_lines`) and ``bright_fade`` fades.

**Anti-aliasing** (the ``npr_lines`` plugin's ``line_aa``, :mod:`mi_npr.antialias`) runs this
chain unchanged on an ``n``-times supersampled G-buffer with ``line_width * n``, box-filters the
result and scales each line by its own peak across it, so that its darkest pixel keeps the
sub-pixels' ink (:func:`mi_npr.antialias.full_ink_filter`): eq. 5.1's gray levels then also
carry *sub-pixel position* (the pixels beside a line's darkest one get the share it covers); eq.
5.2 removes fragments shorter than 3 sub-pixels, not 3 pixels; the selective dilation (eqs.
5.3-5.4) fills holes of ``dilation_size`` sub-pixels; ``max_density``'s window is 9 sub-pixels
wide.

A G-buffer without ``object_id`` (or ``N.X N.Y N.Z``) gets no ID edges (creases) unless they
were asked for explicitly, which is then an error naming the missing layer: depth alone is
enough for the defaults.

Depth at any scale (a departure from eq. 5.1's plain normalisation): the background reads as
``D = 2``, a full step beyond every finite pixel (the thesis's OpenGL depth buffer had its far
plane behind the scene; with the frame's own range the farthest object pixel got the background's
1 and its outline vanished), and with ``far`` unset the far bound is at least ``4 * near``, so a
step counts against at least the depth where it happens: a lone sphere's whole outline, and
nothing inside it from 50 radii on, at camera distances of 2 to 500 radii and scene scales of
1e-3 to 1e3, with ``far`` given or not (``tests/test80_depth_lines_scale.py``).

Foliage (thesis section 4.3): ``leaf_edges`` outlines every leaf primitive, which depth
contours alone miss where leaves overlap at nearly equal depth (see
:func:`~mi_npr.kernels.leaf_edges`); ``bright_fade`` gives the thesis's "lack of detail in bright
areas" (Fig. 4.8 b): the line strength is multiplied by ``clip(2 - Y / bright_fade, 0, 1)``, with
``Y`` the Rec. 709 luminance of the raw beauty (``beauty.R/G/B`` if present, else ``R G B``).
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from typing import Any

import drjit as dr

from .. import layers as L
from ..errors import ParameterError
from ..params import Param, check_values
from ._stencil import (
    Field,
    Grid,
    Tensor,
    exact,
    finite,
    float_image,
    id_image,
    nonnegative,
    same_shape,
    tensor,
    unit_interval,
)
from .depth_lines import check_range, contours, depth_normalizer, isolated_removed
from .edges import crease_edge, dihedral, edge_width, id_edge_sided, leaf_edge
from .ink import DENSITY_WINDOW, box_mean, density_bound, line_width, widened
from .morphology import dilated, iteration_count, window_size


def _leaf_width(v: Any) -> str | None:
    return None if v == 0 else edge_width(v)


LINES_PARAMS: tuple[Param, ...] = (
    Param("c", float, 40.0, "eq. 5.1 gain on the normalised depth difference", nonnegative),
    Param("t", float, 1.0, "eq. 5.1 threshold: steps above t / c light up", nonnegative),
    Param("t0", float, 0.5, "eq. 5.2 threshold: line pixels lie above it", unit_interval),
    Param("dilation_size", int, 3, "selective dilation window (odd, 3..15)", window_size),
    Param("dilation_iterations", int, 1, "selective dilation passes (0 = off)", iteration_count),
    Param("remove_isolated", bool, True, "remove isolated line pixels (eq. 5.2)"),
    Param("id_edges", bool, True, "draw object boundaries (ID edges, 1 px)"),
    Param(
        "crease_angle", float, 134.0, "draw creases below this dihedral angle (0 = off)", dihedral
    ),
    Param("leaf_edges", int, 0, "outline every leaf: 0 off, 1 or 2 px", _leaf_width),
    Param("max_density", float, 1.0, "thin lines denser than this (1 = off)", density_bound),
    Param("line_width", float, 1.0, "width of every line, in pixels", line_width),
    Param("bright_fade", float, 0.0, "fade lines above this luminance (0 = off)", nonnegative),
    Param("near", float, None, "depth mapped to 0 (unset: nearest finite Z)", finite),
    Param("far", float, None, "depth mapped to 1 (unset: farthest finite Z)", finite),
)


_DEFAULT = {p.name: p.default for p in LINES_PARAMS}


def depth_field(
    z: Any,
    near: float | None = None,
    far: float | None = None,
    frame: tuple[Any, Any] | None = None,
) -> Callable[[Any], Any]:
    """The chain's map ``Z -> D`` for the frame ``z`` (flat): eq. 5.1's normalised depth with
    the background at 2 and, with ``far`` unset, ``far >= 4 near`` (module docstring, "Depth at
    any scale"); ``frame`` as in :func:`~mi_npr.kernels.depth_lines.depth_normalizer`."""
    return depth_normalizer(z, near, far, relative=True, background=2.0, frame=frame)


def depth_step(c: float = _DEFAULT["c"], t: float = _DEFAULT["t"]) -> float:
    """The step of :func:`depth_field`'s ``D`` that the chain draws: eq. 5.1 lights a pixel up
    above ``t / c`` (``inf`` for ``c = 0``); ID edges and creases at such a step take its near
    side (:func:`~mi_npr.kernels.edges.owns`)."""
    return t / c if c > 0 else float("inf")


def _layer(gbuffer: Mapping[str, Any], name: str, why: str) -> Any:
    try:
        return gbuffer[name]
    except KeyError:
        raise ParameterError(f"lines: the G-buffer has no {name!r} layer ({why})") from None


@exact
def lines(
    gbuffer: Mapping[str, Any], *, depth_range: tuple[Any, Any] | None = None, **params: Any
) -> Tensor:
    """The gray-level line image of a G-buffer (the ``lines`` layer), see the module docstring.

    ``gbuffer`` is a :class:`~mi_npr.gbuffer.GBuffer` (or any mapping of layer names to (H, W)
    arrays) with ``Z``, plus ``object_id`` for ID edges, ``N.X N.Y N.Z`` (and ``object_id``) for
    creases, ``leaf_id`` for leaf edges and ``R G B`` (or ``beauty.R/G/B``) for ``bright_fade``.
    ``params`` are those of :data:`LINES_PARAMS`; unknown names and bad values raise
    :class:`~mi_npr.errors.ParameterError` naming the parameter. ``depth_range``: where
    ``gbuffer`` is a part of a frame (a strip of :func:`mi_npr.antialias.antialiased_lines`),
    the whole frame's smallest and largest finite ``Z`` (1-lane ``Float`` arrays,
    :func:`~mi_npr.kernels.depth_lines.finite_range`), which ``near`` and ``far`` default to.

    >>> gb = mi_npr.render("scenes_xml/scene2.xml", width=64, height=48, spp=1)
    >>> ink = mi_npr.kernels.lines(gb, t=0.5, crease_angle=0)
    >>> np.asarray(ink).shape
    (48, 64)
    """
    if not isinstance(gbuffer, Mapping) and not hasattr(gbuffer, "names"):
        raise ParameterError(
            f"lines: expected a GBuffer (or a mapping of layer names to (H, W) arrays), got "
            f"{type(gbuffer).__name__}; for a depth image alone use lines({{'Z': Z}})"
        )
    p = check_values("lines", LINES_PARAMS, params)
    check_range(p["near"], p["far"], "lines")
    z, shape = float_image(_layer(gbuffer, L.Z, "depth"), L.Z)
    grid = Grid(shape, z)

    depth = Field(z, grid, depth_field(z, p["near"], p["far"], depth_range))
    for _ in range(p["dilation_iterations"]):
        d = dilated(depth, p["dilation_size"])
        dr.eval(d)
        depth = Field(d, grid)

    ink = contours(depth, p["c"], p["t"])
    if p["remove_isolated"]:
        dr.eval(ink)
        ink = isolated_removed(Field(ink, grid), p["t0"])

    # The step eq. 5.1 draws: ID and crease edges at such a step take eq. 5.1's (near) side.
    step = grid.opaque(depth_step(p["c"], p["t"]))
    boundary, crease = _edges(gbuffer, params, p, depth, grid, step)
    if p["leaf_edges"]:
        leaf, shape_l = id_image(
            _layer(gbuffer, L.LEAF_ID, "needed by leaf_edges"), L.LEAF_ID, grid.B
        )
        same_shape({L.Z: shape, L.LEAF_ID: shape_l})
        z_raw = Field(z, grid, lambda v: dr.select(dr.isnan(v), dr.inf, v))
        outline = leaf_edge(Field(leaf, grid), z_raw, p["leaf_edges"])
        boundary = outline if boundary is None else boundary | outline
    ink = _thinned(ink, boundary, crease, grid, p["max_density"])
    if p["line_width"] != 1.0:
        dr.eval(ink)
        ink = widened(Field(ink, grid), p["line_width"])
    if p["bright_fade"] > 0:
        ink = ink * fade(gbuffer, grid, p["bright_fade"])
    return tensor(ink, shape)


def _edges(
    gbuffer: Mapping[str, Any],
    given: Mapping[str, Any],
    p: Mapping[str, Any],
    depth: Field,
    grid: Grid,
    step: Any,
) -> tuple[Any, Any]:
    """The lazy 1-px ID and crease edge masks (``None`` where off). A kind left at its default
    is skipped on a G-buffer without its layers; asked for explicitly, it needs them."""
    shape = grid.shape
    has_n = all(n in gbuffer for n in L.N)
    want_id = p["id_edges"] and ("id_edges" in given or L.OBJECT_ID in gbuffer)
    want_crease = p["crease_angle"] > 0 and (
        "crease_angle" in given or (has_n and L.OBJECT_ID in gbuffer)
    )
    if not (want_id or want_crease):
        return None, None
    why = "needed by id_edges and crease_angle"
    ids, shape_i = id_image(_layer(gbuffer, L.OBJECT_ID, why), L.OBJECT_ID, grid.B)
    same_shape({L.Z: shape, L.OBJECT_ID: shape_i})
    id_field = Field(ids, grid)
    boundary = id_edge_sided(id_field, depth, step) if want_id else None
    crease = None
    if want_crease:
        normals = [
            float_image(_layer(gbuffer, n, "needed by crease_angle"), n, grid.B) for n in L.N
        ]
        same_shape({L.Z: shape, **{n: s for n, (_, s) in zip(L.N, normals, strict=True)}})
        fields = [Field(q, grid) for q, _ in normals]
        crease = crease_edge(fields, id_field, p["crease_angle"], depth, step, view_axis(gbuffer))
    return boundary, crease


def view_axis(gbuffer: Any) -> tuple[float, float, float]:
    """The camera's viewing axis in world space: ``gbuffer.camera.forward`` when the G-buffer
    has a camera, else +z (Mitsuba's camera space)."""
    camera = getattr(gbuffer, "camera", None)
    if camera is None:
        return (0.0, 0.0, 1.0)
    f = [float(v) for v in camera.forward]
    return (f[0], f[1], f[2])


def _thinned(ink: Any, boundary: Any, crease: Any, grid: Grid, bound: float) -> Any:
    """Contours, boundaries and creases combined at full strength (``max``), thinned where the
    ink density over :data:`DENSITY_WINDOW` exceeds ``bound``: first without creases, then,
    where still too dense, without ID (and leaf) edges; depth contours always stay."""
    edge = boundary if crease is None else crease if boundary is None else boundary | crease
    full = ink if edge is None else dr.select(edge, 1.0, ink)
    if bound >= 1.0 or edge is None:
        return full
    levels = [full]
    if crease is not None and boundary is not None:
        levels.append(dr.select(boundary, 1.0, ink))
    levels.append(ink)
    dr.eval(*levels)
    out = levels[0]
    for sparser in levels[1:]:
        dr.eval(out)
        dense = box_mean(Field(out, grid), DENSITY_WINDOW) > grid.opaque(bound)
        out = dr.select(dense, sparser, out)
    return out


def fade(gbuffer: Mapping[str, Any], grid: Grid, level: float) -> Any:
    """``clip(2 - Y / level, 0, 1)`` of the raw beauty's luminance ``Y`` (lazy)."""
    names = L.RAW_RGB if L.RAW_RGB[0] in gbuffer else L.RGB
    planes = []
    for n in names:
        q, s = float_image(_layer(gbuffer, n, "needed by bright_fade"), n, grid.B)
        same_shape({L.Z: grid.shape, n: s})
        planes.append(dr.select(dr.isfinite(q), q, 0.0))
    Y = dr.fma(0.2126, planes[0], dr.fma(0.7152, planes[1], 0.0722 * planes[2]))
    return dr.clip(2.0 - Y / grid.opaque(level), 0.0, 1.0)

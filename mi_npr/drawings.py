"""The drawings: what mi-npr draws from an exact G-buffer, each registered once.

A :class:`Drawing` is a name users type (``lines``: ``mi-npr render --lines``,
``render_layers(scene, ["lines"])``), the plugin that draws it alone (``npr_lines``), **one
parameter table** (the plugin's XML parameters, the command line's flags ``--crease-angle``
and the keyword names of :func:`mi_npr.pipeline.render_layers`, checked by the same rules), the
layers it adds, and **one function that adds them** to a :class:`~mi_npr.gbuffer.GBuffer`.
:data:`DRAWINGS` holds them in the order they are computed; the pipeline, the plugins, the
batch, camera paths and the command line loop over it, and no algorithm package imports it.

How a drawing meets the beauty (:attr:`Drawing.overlay`):

- ``beauty``: composited onto ``R G B`` (the lines: ink over the render);
- ``picture``: drawn over the raw beauty as a picture of its own (contours in red, ray-tree
  edges in their class colours), ``R G B`` untouched;
- ``none``: layers only (Cryptomatte).
"""

from __future__ import annotations

import json
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

from . import cryptomatte
from . import layers as L
from .ad.fit import require_ad
from .ad.visibility import soft_lines
from .antialias import aa_factor, antialiased_lines, check_aa_width
from .compose import over_raw, raw_beauty_layers, with_overlay
from .contours.idmode import ID_MODES, OBJECT_MODES, IdMap, id_map
from .contours.overlay import overlay as contour_overlay
from .contours.trace import METHODS
from .contours.vector import RayIds, vectorize
from .errors import ParameterError
from .foliage.leaves import leaf_id_layer
from .gbuffer import GBuffer
from .kernels import LINES_PARAMS
from .kernels.depth_lines import check_range
from .kernels.ink import line_width
from .params import Param, coerce, integer_range, one_of, rgb_color
from .raytree.lights import HARD, check_shadow_lights
from .raytree.render import add_raytree
from .raytree.tracer import MAX_DEPTH
from .session import SceneSession
from .strokes.drawing import STROKES_PARAMS, depth_range_of, draw_strokes

#: How a drawing meets the beauty (module docstring).
OVERLAYS = ("beauty", "picture", "none")


@dataclass
class Drawn:
    """What one drawing adds: ``gbuffer`` is the input G-buffer with the drawing's layers and
    metadata (its ``R G B`` the drawing over the beauty, unless the overlay is ``none``), and
    ``extras`` what the drawing computed on the way (the traced ``contours``, their vector
    ``paths``)."""

    gbuffer: GBuffer
    extras: dict[str, Any] = field(default_factory=dict)


#: ``draw(session, gb, params, *, seed=0, spp=None, vector=False) -> Drawn``: ``params`` all of
#: the drawing's parameters (checked), ``seed`` and ``spp`` those of the render, ``vector`` also
#: the drawing's vector form where it has one.
DrawFn = Callable[..., Drawn]


@dataclass(frozen=True)
class Drawing:
    """One drawing of the registry (module docstring)."""

    #: The name users type: ``--lines``, ``render_layers(..., ["lines"])``.
    name: str
    #: The Mitsuba plugin that draws it alone (``None``: a switch of every mi-npr integrator).
    plugin: str | None
    #: One line of what it draws (the command line's help).
    summary: str
    #: Its parameter table, in the order the manual lists them.
    params: tuple[Param, ...]
    #: Adds its layers to a G-buffer (see :data:`DrawFn`).
    draw: DrawFn
    #: How it meets the beauty: one of :data:`OVERLAYS`.
    overlay: str = "picture"
    #: The rules between parameters (``near < far``), checked after each one's own rule.
    check: Callable[[Mapping[str, Any], str], None] = lambda values, who: None
    #: What it refuses about a scene, checked before the render starts (a render the drawing
    #: could not finish is refused before its beauty is paid for).
    preflight: Callable[[SceneSession], None] = lambda session: None

    def __post_init__(self) -> None:
        if self.overlay not in OVERLAYS:
            raise ValueError(f"drawing {self.name}: overlay {self.overlay!r} not in {OVERLAYS}")

    def param(self, name: str) -> Param:
        """The table's entry ``name``."""
        for p in self.params:
            if p.name == name:
                return p
        raise ParameterError(f"{self.name}: unknown parameter {name!r}")

    def defaults(self) -> dict[str, Any]:
        """Every parameter at its default."""
        return {p.name: p.default for p in self.params}

    def values(self, given: Mapping[str, Any], who: str | None = None) -> dict[str, Any]:
        """Every parameter: ``given`` (checked, by name) over the defaults; the rules between
        parameters checked too. An unknown name is a :class:`ParameterError` naming ``who``
        (default: the plugin)."""
        who = who or self.plugin or self.name
        out = self.defaults()
        for name, value in given.items():
            p = next((q for q in self.params if q.name == name), None)
            if p is None:
                raise ParameterError(f"{who}: unknown parameter {name!r}")
            out[name] = coerce(who, p, value)
        self.check(out, who)
        return out


# ------------------------------------------------------------------------- object selection


def selection_params(modes: Sequence[str] | None = None) -> tuple[Param, ...]:
    """The ``id_mode``, ``only`` and ``ignore`` parameters of every per-object drawing: what
    one object is and which objects are drawn (:mod:`mi_npr.contours.idmode`); ``modes``: the
    id modes allowed (default all)."""
    allowed = tuple(modes or ID_MODES)
    return (
        Param(
            "id_mode", str, "shape", "what one object is: " + ", ".join(allowed), one_of(allowed)
        ),
        Param("only", str, "", "draw only objects matching these globs (comma-separated)"),
        Param("ignore", str, "", "objects matching these globs count as background"),
    )


def object_ids(scene: Any, table: Any, params: Mapping[str, Any]) -> IdMap:
    """The :class:`~mi_npr.contours.idmode.IdMap` of a drawing's ``id_mode``, ``only`` and
    ``ignore`` parameters (strings of comma-separated globs, or lists)."""
    return id_map(
        scene,
        params.get("id_mode") or "shape",
        table,
        only=params.get("only") or (),
        ignore=params.get("ignore") or (),
    )


# ------------------------------------------------------------------------------ soft models


@dataclass(frozen=True)
class SoftModel:
    """A drawing's differentiable form: its layer is :func:`mi_npr.ad.soft_lines` of the
    sensor at its film's size, on when the parameter :attr:`switch` is ``'soft'``, so that
    ``dr.backward`` through ``mi.render(scene, params=params)`` carries the interior and
    boundary terms of silhouettes and occlusion boundaries that move."""

    #: The parameter that picks the model (``line_model``); ``'soft'`` turns this one on.
    switch: str
    #: The layer it draws (an (H, W) float image in [0, 1]).
    layer: str
    #: The parameters it takes besides :attr:`switch`; the drawing's others are refused.
    takes: tuple[str, ...]
    #: The parameter holding the colour it is composited in.
    color: str
    #: Samples a pixel side: the parameter holding it, or the number itself.
    aa: str | int
    #: Its metadata key (``mi_npr/lines``): the parameters it was drawn with, as JSON.
    meta: str
    #: Keywords of :func:`~mi_npr.ad.soft_lines` that pick its features (``depth_weight``).
    features: tuple[tuple[str, float], ...] = ()


def soft_model(params: Mapping[str, Any]) -> SoftModel | None:
    """The soft model that ``params`` (one drawing's) turn on, or ``None``."""
    return next((m for m in SOFT_MODELS if params.get(m.switch) == "soft"), None)


def _check_soft(model: SoftModel, table: Sequence[Param], values: Mapping[str, Any], who: str):
    """A soft model needs an AD variant and takes none of the exact model's parameters: one
    set away from its default would be ignored, so it is refused."""
    require_ad(f"{who}: {model.switch} = 'soft'")
    exact = next(p.default for p in table if p.name == model.switch)
    for p in table:
        if (
            p.name not in (model.switch, *model.takes)
            and values.get(p.name, p.default) != p.default
        ):
            raise ParameterError(
                f"{who}: parameter {p.name!r} belongs to {model.switch} = {exact!r}; "
                f"{model.switch} = 'soft' takes {', '.join(model.takes)}"
            )


def soft_image(
    model: SoftModel,
    scene: Any,
    sensor: Any,
    params: Mapping[str, Any],
    depth_scale: float | None = None,
) -> Any:
    """The layer of the soft ``model``, an (H, W) ``TensorXf`` with its gradients:
    :func:`mi_npr.ad.soft_lines` of ``sensor`` at its film's size with the model's features,
    ``aa`` samples a pixel side and a filter of ``sigma = line_width / 2`` pixels (its band is
    about ``2 sigma`` wide). ``depth_scale``: the length that makes depths unitless (``None``:
    the scene's bounding-box diagonal now). The film must have no crop window (the soft lines
    are drawn over the whole film)."""
    film = sensor.film()
    size, crop = (tuple(int(v) for v in f) for f in (film.size(), film.crop_size()))
    if size != crop or any(int(v) for v in film.crop_offset()):
        raise ParameterError(
            f"{model.switch} = 'soft' draws the whole film: its crop window "
            f"{crop[0]}x{crop[1]} of {size[0]}x{size[1]} is not supported"
        )
    return soft_lines(
        scene,
        sensor,
        size,
        n=params[model.aa] if isinstance(model.aa, str) else model.aa,
        sigma=0.5 * params["line_width"],
        depth_scale=depth_scale,
        **dict(model.features),
    )


def _draw_soft(
    model: SoftModel,
    session: SceneSession,
    gb: GBuffer,
    params: Mapping[str, Any],
    depth_scale: float | None,
) -> Drawn:
    """:func:`soft_image` composited in the model's colour onto ``R G B``, as the exact
    model's drawing is."""
    ink = soft_image(model, session.scene, session.sensor, params, depth_scale)
    names = (model.switch, *model.takes)
    meta = json.dumps({k: params[k] for k in names if k != model.color})
    gb = gb.with_layers({model.layer: ink}).with_metadata(**{model.meta: meta})
    return Drawn(with_overlay(gb, ink, params[model.color]))


# ----------------------------------------------------------------------------------- lines

#: Rays per pixel side of the anti-aliased lines: 3 x 3 leaves about a fifth of the error of
#: one ray against 8 x 8 (:mod:`mi_npr.antialias`).
LINE_AA_DEFAULT = 3

#: What draws the ``lines`` layer: ``thesis``, eqs. 5.1-5.4 on the exact G-buffer
#: (:func:`mi_npr.antialias.antialiased_lines`), or ``soft``, the differentiable line image of
#: :func:`mi_npr.ad.soft_lines` whose gradients include silhouettes that move.
LINE_MODELS = ("thesis", "soft")

#: The ``soft`` line model: every feature of :func:`mi_npr.ad.soft_lines` (ids, depth, normal).
SOFT_LINES = SoftModel(
    "line_model",
    L.LINES,
    ("line_width", "line_aa", "line_color"),
    "line_color",
    "line_aa",
    "mi_npr/lines",
)

#: The parameters that the ``soft`` line model takes; the others are the thesis model's.
SOFT_PARAMS = (SOFT_LINES.switch, *SOFT_LINES.takes)

LINES_TABLE: tuple[Param, ...] = (
    Param(
        "line_model",
        str,
        "thesis",
        "thesis (eqs. 5.1-5.4) or soft (differentiable: silhouettes that move have gradients)",
        one_of(LINE_MODELS),
    ),
    *LINES_PARAMS[:-2],
    Param("line_color", tuple, (0.0, 0.0, 0.0), "colour of the lines (linear RGB)", rgb_color),
    Param("line_aa", int, LINE_AA_DEFAULT, "rays per pixel side for anti-aliased lines", aa_factor),
    *LINES_PARAMS[-2:],
    *selection_params(),
)


def _check_lines(values: Mapping[str, Any], who: str) -> None:
    if values.get("line_model", "thesis") == "soft":
        _check_soft(SOFT_LINES, LINES_TABLE, values, who)
        return
    check_range(values["near"], values["far"], who)
    check_aa_width(values["line_width"], values["line_aa"], who)


def _draw_lines(
    session: SceneSession,
    gb: GBuffer,
    params: Mapping[str, Any],
    *,
    depth_scale: float | None = None,
    **_: Any,
) -> Drawn:
    """The ``lines`` layer of the ``npr_lines`` parameters (all of them, checked), composited
    in ``line_color`` onto ``R G B`` (the raw beauty kept). ``depth_scale``: that of the soft
    model (:func:`soft_image`)."""
    scene, sensor = session.scene, session.sensor
    if params.get("line_model") == "soft":
        return _draw_soft(SOFT_LINES, session, gb, params, depth_scale)
    chain = {p.name: params[p.name] for p in LINES_PARAMS}
    if chain["leaf_edges"] and L.LEAF_ID not in gb:
        gb = gb.with_layers({L.LEAF_ID: leaf_id_layer(scene, gb)})
    ids = object_ids(scene, session.objects, params)
    n = params["line_aa"]
    ink = antialiased_lines(scene, sensor, gb, n, ids=ids, **chain)
    sel = {k: params[k] for k in ("id_mode", "only", "ignore") if params.get(k)}
    meta = json.dumps({**chain, "line_aa": n, **sel})
    gb = gb.with_layers({L.LINES: ink}).with_metadata(**{"mi_npr/lines": meta})
    return Drawn(with_overlay(gb, ink, params["line_color"]))


# -------------------------------------------------------------------------------- contours

#: What draws the contours: ``exact``, every contour traced on the pixel-centre ids
#: (:func:`mi_npr.contours.overlay.overlay`), or ``soft``, the object outlines of
#: :func:`mi_npr.ad.soft_lines` (its id feature alone) whose gradients include outlines that move.
CONTOUR_MODELS = ("exact", "soft")

#: Samples a pixel side of the soft contours (:func:`mi_npr.ad.soft_lines`' default).
SOFT_CONTOUR_AA = 4

#: The ``soft`` contour model: the id feature alone, i.e. every object's outline against the
#: background and the other objects (apparent contours and occlusion boundaries between objects).
SOFT_CONTOURS = SoftModel(
    "contour_model",
    L.CONTOUR_INK,
    ("line_width", "color"),
    "color",
    SOFT_CONTOUR_AA,
    "mi_npr/contours",
    (("depth_weight", 0.0), ("normal_weight", 0.0)),
)

CONTOURS_TABLE: tuple[Param, ...] = (
    Param(
        "contour_model",
        str,
        "exact",
        "exact (traced on the pixel ids) or soft (differentiable: outlines that move have "
        "gradients)",
        one_of(CONTOUR_MODELS),
    ),
    Param("method", str, "border", "border or code_direction", one_of(METHODS)),
    *selection_params(ID_MODES),
    Param("color", tuple, (1.0, 0.0, 0.0), "linear RGB of the contours", rgb_color),
    Param("line_width", float, 1.0, "width of the drawn contours, in pixels", line_width),
)


def _check_contours(values: Mapping[str, Any], who: str) -> None:
    if values.get("contour_model", "exact") == "soft":
        _check_soft(SOFT_CONTOURS, CONTOURS_TABLE, values, who)


def _draw_contours(
    session: SceneSession,
    gb: GBuffer,
    p: Mapping[str, Any],
    *,
    vector: bool = False,
    depth_scale: float | None = None,
    **_: Any,
) -> Drawn:
    """Every contour of every selected object traced and drawn over the raw beauty; with
    ``vector`` also their vector paths on the true outline (rays cast into the scene). With
    ``contour_model = 'soft'``: the ``contour_ink.V`` layer of :data:`SOFT_CONTOURS` drawn over
    the raw beauty instead (no traced or vector contours)."""
    s, sensor = session.scene, session.sensor
    if p.get("contour_model") == "soft":
        raw = gb.with_layers(raw_beauty_layers(gb))
        return _draw_soft(SOFT_CONTOURS, session, raw, p, depth_scale)
    drawn, contours = contour_overlay(
        gb,
        s,
        method=p["method"],
        id_mode=p["id_mode"],
        color=p["color"],
        only=p["only"],
        ignore=p["ignore"],
        line_width=p["line_width"],
    )
    extras: dict[str, Any] = {"contours": contours}
    if vector:
        with session.step("vector contours"):
            idm = object_ids(s, session.objects, p)
            ids = idm.apply(gb.numpy(L.OBJECT_ID), gb.numpy(L.PRIM_ID))
            extras["paths"] = vectorize(
                ids, objects=idm.names, ids_at=RayIds(s, sensor, id_map=idm)
            )
    return Drawn(drawn, extras)


#: The soft models, one a drawing (:func:`soft_model`).
SOFT_MODELS = (SOFT_LINES, SOFT_CONTOURS)


# --------------------------------------------------------------------------------- raytree

RAYTREE_TABLE: tuple[Param, ...] = (
    Param("max_depth", int, 3, "levels of the ray trees", integer_range(1, MAX_DEPTH)),
    Param(
        "shadow_lights",
        str,
        HARD,
        "lights of shadow edges: hard, all or names",
        check_shadow_lights,
    ),
    *selection_params(OBJECT_MODES),
    Param("line_width", float, 1.0, "width of the drawn edges, in pixels", line_width),
)


def _draw_raytree(session: SceneSession, gb: GBuffer, p: Mapping[str, Any], **_: Any) -> Drawn:
    """The ray-tree signatures and classified edges, drawn over the raw beauty."""
    drawn = add_raytree(
        session,
        session.sensor,
        gb,
        p["max_depth"],
        ids=object_ids(session.scene, session.objects, p),
        shadow_lights=p["shadow_lights"],
        line_width=p["line_width"],
    )
    return Drawn(drawn)


# --------------------------------------------------------------------------------- strokes


def _draw_strokes(session: SceneSession, gb: GBuffer, p: Mapping[str, Any], **_: Any) -> Drawn:
    """Chained, typed vector strokes with exact visibility (:mod:`mi_npr.strokes`), styled:
    the ``strokes.V`` coverage, the strokes over the raw beauty as the picture, and the
    strokes themselves (``vector_strokes``) for the SVG and JSON writers."""
    z = gb.numpy(L.Z) if L.Z in gb else None
    done = draw_strokes(
        session.scene,
        session.sensor,
        session.objects,
        p,
        depth_range=depth_range_of(z) if z is not None else None,
        keep_topology=session.keep_topology,
    )
    out = over_raw(gb, done.alpha, done.ink).with_layers({L.STROKES: done.alpha})
    meta = json.dumps({k: v for k, v in p.items() if v is not None})
    out = out.with_metadata(**{"mi_npr/strokes": meta})
    return Drawn(out, {"vector_strokes": done})


# ----------------------------------------------------------------------------- cryptomatte


def _cryptomatte_preflight(session: SceneSession) -> None:
    w = int(session.sensor.film().crop_size()[0])
    cryptomatte.check_cells(w, 1, len(session.objects.names))  # one row a band at least


def _draw_cryptomatte(
    session: SceneSession,
    gb: GBuffer,
    p: Mapping[str, Any],
    *,
    seed: int = 0,
    spp: int | None = None,
    **_: Any,
) -> Drawn:
    """The Cryptomatte 1.2 layers, rendered as ``gb`` was: same sensor and seed, ``spp``
    samples per pixel (default the session's)."""
    if cryptomatte.has_cryptomatte(gb):
        return Drawn(gb)
    spp = session.spp if spp is None else spp
    return Drawn(cryptomatte.add_cryptomatte(gb, session.scene, session.sensor, spp, seed))


# -------------------------------------------------------------------------------- registry

DRAWINGS: dict[str, Drawing] = {
    d.name: d
    for d in (
        Drawing(
            "lines",
            "npr_lines",
            "the thesis's depth lines, ID edges and creases over the beauty",
            LINES_TABLE,
            _draw_lines,
            overlay="beauty",
            check=_check_lines,
        ),
        Drawing(
            "contours",
            "npr_contours",
            "the apparent contours of the real objects, in red over the beauty",
            CONTOURS_TABLE,
            _draw_contours,
            check=_check_contours,
        ),
        Drawing(
            "raytree",
            "npr_raytree",
            "ray-tree edges: real contour, reflection, refraction, shadow",
            RAYTREE_TABLE,
            _draw_raytree,
        ),
        Drawing(
            "strokes",
            "npr_strokes",
            "chained, typed vector strokes with exact hidden lines, styled (SVG, JSON)",
            STROKES_PARAMS,
            _draw_strokes,
        ),
        Drawing(
            "cryptomatte",
            None,
            "Cryptomatte 1.2 layers (CryptoObject, CryptoMaterial)",
            (),
            _draw_cryptomatte,
            overlay="none",
            preflight=_cryptomatte_preflight,
        ),
    )
}


def drawing(name: str) -> Drawing:
    """The registered drawing ``name``; a :class:`ParameterError` listing them otherwise."""
    if name not in DRAWINGS:
        raise ParameterError(f"drawing {name!r}: expected one of {', '.join(DRAWINGS)}")
    return DRAWINGS[name]


def of_plugin(plugin: str | None) -> Drawing | None:
    """The drawing that the plugin ``plugin`` draws (``None``: not a drawing's plugin)."""
    return next((d for d in DRAWINGS.values() if plugin and d.plugin == plugin), None)


def split_params(
    drawings: Sequence[str], params: Mapping[str, Any], what: str = "render"
) -> dict[str, dict[str, Any]]:
    """The values in ``params`` (parameter name -> value, the command line's flags) that each of
    ``drawings`` takes, checked by its table: ``{drawing: {name: value}}``, drawings in
    :data:`DRAWINGS` order. A name that none of them takes is a :class:`ParameterError` naming
    the flag and the drawings that would take it (``what``: "render", "batch")."""
    for d in drawings:
        drawing(d)
    out: dict[str, dict[str, Any]] = {}
    for name, d in DRAWINGS.items():
        if name in drawings:
            who = d.plugin or name
            known = {p.name: p for p in d.params}
            out[name] = {n: coerce(who, known[n], v) for n, v in params.items() if n in known}
    unused = [n for n in params if not any(n in taken for taken in out.values())]
    if unused:
        flags = ", ".join("--" + n.replace("_", "-") for n in unused)
        takers = sorted(
            {name for name, d in DRAWINGS.items() for p in d.params if p.name in unused}
        )
        hint = " or ".join("--" + t for t in takers) or "a drawing"
        raise ParameterError(f"{flags}: no drawing of this {what} takes it (add {hint})")
    return out


def shared_params(names: Sequence[str] | None = None) -> dict[str, list[tuple[str, Param]]]:
    """The parameters of the drawings ``names`` (default all) by parameter name, each with the
    drawings that take it: a name several drawings share (``line_width``, ``id_mode``) is one
    command-line flag that sets it in each."""
    out: dict[str, list[tuple[str, Param]]] = {}
    for name, d in DRAWINGS.items():
        if names is None or name in names:
            for p in d.params:
                out.setdefault(p.name, []).append((name, p))
    return out

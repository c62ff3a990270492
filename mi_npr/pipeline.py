"""Every drawing on any scene in one render: the scene's own integrator as the beauty, plus the
drawings asked for (:data:`mi_npr.drawings.DRAWINGS`: ``mi-npr render --lines --contours
--raytree --cryptomatte``).

The beauty is the scene's own integrator with all its parameters (a ``path`` with its
``max_depth``); when the scene's integrator is one of mi-npr's (``npr_lines``, ...), its nested
integrator makes the beauty and its drawing is on, with the XML's parameters as defaults (and
Cryptomatte when the XML turns it on). Each drawing takes the parameters of its table, by the
same names, checked the same way; every drawing is computed from the same exact G-buffer and
the same raw beauty, so the drawings never stack on each other:

- ``R G B`` is the beauty with the lines (or the beauty alone), ``beauty.R/G/B`` the raw
  beauty, and the layers of every drawing are added (``lines``, ``contour``, ``raytree.*``,
  ``edges.*``, Cryptomatte): one G-buffer, one EXR;
- :attr:`LayeredRender.pictures` holds each drawing over the raw beauty (``contours``,
  ``raytree``), the images of ``<stem>_contours.png`` and ``<stem>_raytree.png``;
- :attr:`LayeredRender.strokes` holds the vector form of the line drawings for the SVG files:
  the ray-tree edge classes traced from their masks, and the ``lines`` drawing as object-space
  strokes (:func:`lines_as_strokes`), extracted from the pixel-centre G-buffer before the
  drawings, while the meshes' topology built beside the beauty is fresh (or the ``strokes``
  drawing's, when they are the same).

The shorthands :func:`render_contours`, :func:`render_vector_contours` and
:func:`render_raytree` are one drawing each (``mi-npr contours``, ``mi-npr raytree`` from
Python).
"""

from __future__ import annotations

import os
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import drjit as dr
import mitsuba as mi
import numpy as np

from . import layers as L
from .contours.contour import Contour
from .contours.idmode import SILHOUETTE, selected, split_globs
from .contours.vector import VectorPath, near_polylines, stroke_layers, trace_strokes, vectorize
from .drawings import DRAWINGS, drawing, of_plugin, split_params
from .errors import ParameterError
from .gbuffer import GBuffer
from .io.svg import StrokeLayer
from .params import names
from .render import render_gbuffer
from .scene import merge_defines
from .session import SceneSession
from .strokes import Strokes, extract_strokes
from .strokes.drawing import StrokeDrawing, depth_range_of
from .strokes.edges import Projector, prefetch_topology, wait_for_topology
from .strokes.intersect import touching_pairs
from .strokes.style import make_style


def settings(
    integrator: mi.Integrator,
    drawings: Sequence[str] = (),
    params: Mapping[str, Any] | None = None,
    scene_drawings: bool = True,
) -> dict[str, dict[str, Any]]:
    """Every drawing that is on and its full, checked parameters.

    On: the ``drawings`` asked for, and (with ``scene_drawings``) the one whose plugin is the
    scene's integrator, and Cryptomatte when that integrator has ``cryptomatte`` on. Each takes
    from ``params`` (:func:`~mi_npr.drawings.split_params`) the names its table has, over the
    scene integrator's XML values (when it is that plugin), over the table's defaults."""
    for d in names("drawings", drawings):
        drawing(d)
    own = of_plugin(getattr(integrator, "PLUGIN", None))
    xml = dict(getattr(integrator, "params", {}) or {})
    on = [
        name
        for name in DRAWINGS
        if name in drawings
        or (scene_drawings and own is not None and own.name == name)
        or (scene_drawings and name == "cryptomatte" and xml.get("cryptomatte"))
    ]
    taken = split_params(on, dict(params or {}))
    out: dict[str, dict[str, Any]] = {}
    for name in on:
        d = DRAWINGS[name]
        values = {k: v for k, v in xml.items() if own is d and any(p.name == k for p in d.params)}
        values.update(taken[name])
        out[name] = d.values(values)
    return out


@dataclass
class LayeredRender:
    """What :func:`render_layers` makes: the G-buffer with every layer, the traced contours
    (``contours`` drawing) and each drawing over the raw beauty (linear (H, W, 3))."""

    gbuffer: GBuffer
    contours: list[Contour] = field(default_factory=list)
    pictures: dict[str, np.ndarray] = field(default_factory=dict)
    drawings: tuple[str, ...] = ()
    #: The contours as vector paths on the true outline (:func:`mi_npr.contours.vectorize`).
    paths: list[VectorPath] = field(default_factory=list)
    #: The line drawings as SVG stroke layers: the ray-tree edge classes traced from their
    #: masks (:func:`mi_npr.contours.stroke_layers`), the ``lines`` drawing as strokes
    #: (:func:`lines_as_strokes`).
    strokes: dict = field(default_factory=dict)
    #: The ``strokes`` drawing: its vector strokes, style and raster
    #: (:class:`mi_npr.strokes.drawing.StrokeDrawing`), written as ``<stem>_strokes.*``.
    vector_strokes: Any = None

    def drawing(self, name: str) -> GBuffer:
        """The G-buffer with ``R G B`` = the picture of drawing ``name`` (``contours``,
        ``raytree``): what the shorthands :func:`render_contours`, :func:`render_raytree` and
        the ``contours``/``raytree`` commands return and write."""
        if name not in self.pictures:
            raise ParameterError(f"no {name!r} drawing in this render ({', '.join(self.pictures)})")
        p = self.pictures[name]
        rgb = {c: np.ascontiguousarray(p[..., i]) for i, c in enumerate(("R", "G", "B"))}
        plugin = DRAWINGS[name].plugin or name
        return self.gbuffer.with_layers(rgb).with_metadata(**{"mi_npr/integrator": plugin})


def render_layers(
    scene: str | os.PathLike[str] | mi.Scene,
    drawings: Sequence[str] = (),
    params: Mapping[str, Any] | None = None,
    *,
    scene_drawings: bool = True,
    sensor: int | mi.Sensor = 0,
    spp: int | str | None = None,
    seed: int = 0,
    resolution: tuple[int | None, int | None] | None = None,
    defines: Mapping[str, Any] | None = None,
    progress: bool = False,
    cryptomatte: bool = False,
    vector: bool = True,
    gbuffer: GBuffer | None = None,
    **more: Any,
) -> LayeredRender:
    """Render ``scene`` with its own integrator as the beauty and the ``drawings`` (names of
    :data:`~mi_npr.drawings.DRAWINGS`) with the parameters ``params`` (see :func:`settings` and
    the module docstring).

    ``sensor``: the scene's sensor index, or a sensor object (a batch's camera,
    :func:`mi_npr.camera.sensor_for`). ``resolution=(W, H)`` and ``spp`` size the film and the
    sampler whatever the XML's ``<default>`` names (:class:`~mi_npr.session.SceneSession`);
    ``defines`` and the other keyword arguments fill the XML's ``<default>``\\ s; ``progress``
    shows a bar on a long beauty.
    ``cryptomatte`` is the same as naming the ``cryptomatte`` drawing; ``vector`` traces
    the drawings as vector paths for the SVG writers (:attr:`LayeredRender.paths`,
    :attr:`LayeredRender.strokes`). ``gbuffer``: the G-buffer of this sensor already rendered
    (many views in one launch, :func:`mi_npr.render.render_views`), drawn on as it is.

    >>> r = render_layers("scenes_xml/scene1.xml", ["contours"], {"only": "sphere*"},
    ...                   resolution=(64, 48), spp=4)
    >>> r.gbuffer["contour.V"].shape, sorted(r.pictures)
    ((48, 64), ['contours'])
    """
    session = SceneSession.open(
        scene,
        sensor=sensor,
        spp=spp,
        defines=merge_defines(defines, more),
        resolution=resolution,
    )
    integ = session.scene.integrator()
    asked = [*names("drawings", drawings), *(["cryptomatte"] if cryptomatte else [])]
    with session.step("reading the drawings' parameters"):
        on = settings(integ, asked, params, scene_drawings)
        for name in on:
            DRAWINGS[name].preflight(session)
    beauty = integ.beauty if hasattr(integ, "npr_gbuffer") else integ
    if gbuffer is None:
        gbuffer = render_gbuffer(
            session,
            beauty=beauty,
            spp=session.spp,
            seed=seed,
            progress=progress,
            before_beauty=_topology_ahead(session, on, vector),
        )
        wait_for_topology()  # beside the beauty only: the drawings' memory does not add to it
    gb = gbuffer
    if session.source is not None:
        gb = gb.with_metadata(**{"mi_npr/scene": session.source})
    out = LayeredRender(gb, drawings=tuple(on))
    # A scene loaded here is drawn once: its last stroke extraction drops the meshes' topology.
    # The lines' SVG extracts its own strokes (unless it takes the strokes drawing's) first,
    # from the pixel-centre G-buffer, while the topology built beside the beauty is fresh: it
    # is then dropped before the anti-aliased lines (or kept for the strokes drawing).
    once = session.source is not None
    svg_strokes = None
    if _lines_extract_own(on, vector):
        with session.step("lines as strokes"):
            # what Dr.Jit keeps for reuse from the render (the beauty's samples, the film) is
            # freed first: the strokes' visibility rays take its place, not memory beside it
            dr.flush_malloc_cache()
            session.keep_topology = not once or "strokes" in on
            svg_strokes = line_strokes(session, gb, on["lines"])
    session.keep_topology = not once
    new: dict[str, Any] = {}
    meta: dict[str, str] = {}
    for name, p in on.items():
        d = DRAWINGS[name]
        with session.step(name):
            drawn = d.draw(session, gb, p, seed=seed, vector=vector)
        g = drawn.gbuffer
        new.update({k: g[k] for k in g.names if k not in gb and k not in new})
        if d.overlay == "beauty":
            new.update({k: g[k] for k in ("R", "G", "B")})
        elif d.overlay == "picture":
            out.pictures[name] = g.beauty
        meta.update(g.metadata)
        out.contours = drawn.extras.get("contours", out.contours)
        out.paths = drawn.extras.get("paths", out.paths)
        out.vector_strokes = drawn.extras.get("vector_strokes", out.vector_strokes)
    plugins = [DRAWINGS[name].plugin for name in on if DRAWINGS[name].plugin]
    if plugins:
        meta["mi_npr/integrator"] = "+".join(plugins)
    if new:
        out.gbuffer = gb.with_layers(new).with_metadata(**meta)
    if vector:
        # The lines drawing's layer is made of the scene's strokes below: no trace of its mask.
        out.strokes = stroke_layers(out.gbuffer, lines="lines" not in on)
        if "lines" in on:
            with session.step("lines as strokes"):
                out.strokes[LINES_SVG] = lines_as_strokes(
                    session, out.gbuffer, on["lines"], out.vector_strokes, svg_strokes
                )
    return out


def _topology_ahead(
    session: SceneSession, on: Mapping[str, Any], vector: bool
) -> Callable[[dict[str, Any]], None] | None:
    """What starts the meshes' topology (:func:`mi_npr.strokes.edges.prefetch_topology`)
    while the beauty renders, for the drawings of ``on`` that extract strokes: the ``strokes``
    drawing (every pair of meshes searched for intersection lines) and the ``lines`` drawing's
    SVG (:func:`line_strokes`: the pairs whose pixels touch in the pixel-centre ids); ``None``
    when none does, or the camera is one the strokes refuse. The whole build, except where
    the lines' SVG takes the strokes drawing's strokes: the anti-aliased lines may then be
    drawn before the strokes, and the first stage alone (the intersection search and the
    weld) is built ahead, so that the rest is not alive through them; a whole build classifies
    the edges too (their kinds at the crease angle of the strokes extracted first). The beauty
    keeps both cores busy, so this work is not free, but it takes half the time there that it
    takes alone on one core after the beauty."""
    if "strokes" not in on and not ("lines" in on and vector):
        return None
    try:
        Projector(session.sensor)
    except ParameterError:
        return None

    whole = not ("lines" in on and vector and _lines_reuse_strokes(on))
    first = "lines" if _lines_extract_own(on, vector) else "strokes"

    def start(layers: dict[str, Any]) -> None:
        ids = None if "strokes" in on else np.asarray(layers[L.OBJECT_ID])
        dr.flush_malloc_cache()  # the pixel-centre pass's temporaries: the search takes their place
        pairs = None if ids is None else touching_pairs(ids)
        # the edges' kinds too, at the crease angle of the strokes extracted first
        crease = on[first]["crease_angle"]
        prefetch_topology(session.objects, pairs, whole=whole, crease_angle=crease)

    return start


def _reuses(crease: float, strokes_crease: Any) -> bool:
    """Whether the lines' SVG at ``crease`` degrees takes the strokes drawing's strokes,
    extracted at ``strokes_crease`` (``None``: not known): the lines draw no creases, or the
    same ones."""
    return float(crease) in (0.0, strokes_crease)


def _lines_reuse_strokes(on: Mapping[str, Mapping[str, Any]]) -> bool:
    """Whether :func:`lines_as_strokes` takes the strokes of the ``strokes`` drawing of a render
    of the drawings ``on`` (their parameters) instead of extracting its own."""
    if "strokes" not in on or "lines" not in on:
        return False
    return _reuses(on["lines"]["crease_angle"], on["strokes"]["crease_angle"])


def _lines_extract_own(on: Mapping[str, Mapping[str, Any]], vector: bool) -> bool:
    """Whether a render of the drawings ``on`` extracts strokes for ``<stem>_lines.svg`` of its
    own (:func:`line_strokes`, right after the beauty): the ``lines`` drawing with its vector
    form, not taking the ``strokes`` drawing's."""
    return "lines" in on and vector and not _lines_reuse_strokes(on)


#: The layer of ``<stem>_lines.svg`` that holds the ``lines`` drawing.
LINES_SVG = L.LINES.split(".")[0]


def line_kinds(params: Mapping[str, Any]) -> tuple[str, ...]:
    """The stroke kinds (:data:`mi_npr.strokes.KINDS`) the ``lines`` drawing draws with
    ``params``: ``silhouette`` and ``border`` (its depth contours, and its ID edges against
    another object), ``crease`` when ``crease_angle > 0``, ``material`` and ``intersection``
    (object boundaries) when ``id_edges`` is on and ``id_mode`` is not ``silhouette``.

    >>> line_kinds({"crease_angle": 0, "id_edges": True, "id_mode": "shape"})
    ('silhouette', 'border', 'material', 'intersection')
    """
    kinds = ["silhouette", "border"]
    if params.get("crease_angle", 0) > 0:
        kinds.append("crease")
    if params.get("id_edges") and params.get("id_mode", "shape") != SILHOUETTE:
        kinds += ["material", "intersection"]
    return tuple(kinds)


def line_strokes(session: SceneSession, gb: GBuffer, params: Mapping[str, Any]) -> Strokes:
    """The strokes :func:`lines_as_strokes` extracts for the ``lines`` drawing (``params``) of
    the pixel-centre G-buffer ``gb``: visible ones alone, with no ``depth_behind``, the
    intersection lines of the meshes whose pixels touch (its docstring); none for a camera the
    strokes refuse."""
    z = gb.numpy(L.Z) if L.Z in gb else None
    try:
        return extract_strokes(
            session.scene,
            session.sensor,
            session.objects,
            crease_angle=float(params["crease_angle"]),
            max_qi=0,  # the visible strokes alone: no ray past the first surface
            depth_range=depth_range_of(z) if z is not None else None,
            depth_behind=False,  # the layer's style has no gray: never read
            keep_topology=session.keep_topology,
            # the intersection lines of the meshes whose pixels touch: the visible ones
            intersect=touching_pairs(gb.numpy(L.OBJECT_ID)) if L.OBJECT_ID in gb else None,
        )
    except ParameterError:  # a camera the strokes refuse: every line pixel is traced
        return Strokes([], gb.width, gb.height, dict(session.objects.names))


def lines_as_strokes(
    session: SceneSession,
    gb: GBuffer,
    params: Mapping[str, Any],
    drawn: StrokeDrawing | None = None,
    extracted: Strokes | None = None,
) -> StrokeLayer:
    """The ``lines`` drawing of ``gb`` (its ``lines.V`` layer, drawn with ``params``, all of the
    drawing's, checked) as object-space strokes: the layer of ``<stem>_lines.svg``.

    **Which strokes** (:func:`mi_npr.strokes.extract_strokes`, with the drawing's
    ``crease_angle``): the visible ones (``qi == 0``, those seen through glass too) of
    :func:`line_kinds`, of the objects that ``only`` and ``ignore`` select (a stroke's object:
    that of its first vertex). The strokes of ``drawn`` (the ``strokes`` drawing of the same
    render) are reused when they were extracted at the same crease angle, or creases are off;
    extracted here (or given as ``extracted``, :func:`line_strokes`), they carry no
    ``depth_behind`` (the layer's style never reads it), and the intersection lines are looked
    for only between meshes whose pixels touch in the G-buffer's object ids
    (:func:`~mi_npr.strokes.intersect.touching_pairs`; a visible line runs between them).
    **How**: ``line_width`` px wide, in ``line_color``, opaque: the ID edges and creases of the
    lines are drawn at full strength, and an outline always has a depth step or an ID change, so
    an opaque stroke is what the PNG shows, except where eq. 5.1 fades a depth step too small for
    ``t / c`` (an object occluding itself) and no ID edge inks it.
    **Nothing asked for is dropped**: the pixels of ``lines.V > 0.5`` farther than
    ``line_width / 2 + 2`` px from every stroke are traced (:func:`mi_npr.contours.trace_strokes`)
    into the layer's ``traced`` sub-layer: leaf edges, depth lines where a surface recedes
    steeply, ID edges of an ``id_mode`` finer than a shape, and, for a camera the strokes refuse
    (a sensor that is not a perspective, thin-lens or orthographic camera), every line pixel."""
    crease = float(params["crease_angle"])
    strokes = extracted
    if strokes is None and drawn is not None:
        if _reuses(crease, drawn.strokes.params.get("crease_angle")):
            strokes = drawn.strokes
    if strokes is None:
        strokes = line_strokes(session, gb, params)
    kinds = line_kinds(params)
    names = session.objects.names
    chosen = selected(names, split_globs(params.get("only")), split_globs(params.get("ignore")))
    keep = [s for s in strokes if s.qi == 0 and s.kind in kinds and int(s.object_id[0]) in chosen]
    style = make_style(
        "lines", width=params["line_width"], color=params["line_color"], hidden=False
    )
    mask = gb.numpy(L.LINES) > 0.5
    lines = [np.concatenate([s.points, s.points[:1]]) if s.closed else s.points for s in keep]
    near = near_polylines(mask.shape, lines, params["line_width"] / 2.0 + 2.0)
    subset = Strokes(
        keep,
        strokes.width,
        strokes.height,
        objects=strokes.objects,
        depth_range=strokes.depth_range,
        camera=strokes.camera,
        params={"crease_angle": crease},
    )
    return StrokeLayer(subset, style, tuple(trace_strokes(mask & ~near)))


def render_contours(
    scene: str | os.PathLike[str] | mi.Scene,
    *,
    sensor: int = 0,
    spp: int | None = None,
    seed: int = 0,
    method: str | None = None,
    id_mode: str | None = None,
    color: Sequence[float] | None = None,
    defines: Mapping[str, Any] | None = None,
    **more: Any,
) -> tuple[GBuffer, list[Contour]]:
    """Render ``scene`` and draw its contours: ``mi-npr contours`` from Python (the
    ``contours`` drawing of :func:`render_layers`, ``R G B`` its picture).

    ``method``, ``id_mode`` and ``color`` left at ``None`` take the values of the scene's
    ``npr_contours`` integrator when it has one, else the defaults (``border``, ``shape``, red).
    ``spp`` sets the beauty's samples per pixel (and the XML's ``spp`` default when it declares
    one, like :func:`mi_npr.render`); ``defines`` and the other keyword arguments fill the XML's
    ``<default>``\\ s.
    """
    given = {"method": method, "id_mode": id_mode, "color": color}
    r = render_layers(
        scene,
        ["contours"],
        {k: v for k, v in given.items() if v is not None},
        scene_drawings=False,
        sensor=sensor,
        spp=spp,
        seed=seed,
        defines=merge_defines(defines, more),
    )
    return r.drawing("contours"), r.contours


def render_vector_contours(
    scene: str | os.PathLike[str] | mi.Scene,
    *,
    sensor: int = 0,
    spp: int | None = None,
    seed: int = 0,
    method: str | None = None,
    id_mode: str | None = None,
    color: Sequence[float] | None = None,
    tolerance: float = 0.25,
    defines: Mapping[str, Any] | None = None,
    **more: Any,
) -> tuple[GBuffer, list[Contour], list[VectorPath], dict]:
    """:func:`render_contours` plus the vector paths of its contours (rays cast into the same
    scene) and the stroke layers: ``(gb, contours, paths, strokes)``, what ``mi-npr
    contours`` writes."""
    session = SceneSession.open(scene, sensor=sensor, spp=spp, defines=merge_defines(defines, more))
    loaded = session.scene
    gb, contours = render_contours(
        loaded,
        sensor=sensor,
        spp=session.spp,
        seed=seed,
        method=method,
        id_mode=id_mode,
        color=color,
    )
    if session.source is not None:
        gb = gb.with_metadata(**{"mi_npr/scene": session.source})
    mode = gb.metadata.get("mi_npr/contour_id_mode", "shape")
    paths = vectorize(gb, loaded, sensor=sensor, id_mode=mode, tolerance=tolerance)
    return gb, contours, paths, stroke_layers(gb, tolerance)


def render_raytree(
    scene: str | os.PathLike[str] | mi.Scene,
    *,
    max_depth: int | None = None,
    sensor: int = 0,
    spp: int | str | None = None,
    seed: int = 0,
    defines: Mapping[str, Any] | None = None,
    **more: Any,
) -> GBuffer:
    """Render ``scene`` with the ray-tree layers and overlay, whatever its integrator:
    ``mi-npr raytree`` from Python (the ``raytree`` drawing of :func:`render_layers`,
    ``R G B`` its picture).

    The beauty comes from the scene's integrator (the nested one of an mi-npr integrator).
    ``max_depth`` (and ``shadow_lights``, ``id_mode``, ``only``, ``ignore``) default to the
    scene's ``npr_raytree`` integrator's, else 3 (``hard``, every object). ``defines`` and the
    other keyword arguments fill the XML's ``<default>``\\ s, as in :func:`mi_npr.render`.
    """
    r = render_layers(
        scene,
        ["raytree"],
        {} if max_depth is None else {"max_depth": max_depth},
        scene_drawings=False,
        sensor=sensor,
        spp=spp,
        seed=seed,
        defines=merge_defines(defines, more),
    )
    return r.drawing("raytree")

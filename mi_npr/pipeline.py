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
  ``raytree``), the images of ``<stem>_contours.png`` and ``<stem>_raytree.png``.

The shorthands :func:`render_contours`, :func:`render_vector_contours` and
:func:`render_raytree` are one drawing each (``mi-npr contours``, ``mi-npr raytree`` from
Python).
"""

from __future__ import annotations

import os
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import mitsuba as mi
import numpy as np

from .contours.contour import Contour
from .contours.vector import VectorPath, stroke_layers, vectorize
from .drawings import DRAWINGS, drawing, of_plugin, split_params
from .errors import ParameterError
from .gbuffer import GBuffer
from .render import render_gbuffer
from .scene import merge_defines
from .session import SceneSession


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
    for d in drawings:
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
    #: The line drawings as SVG stroke layers (:func:`mi_npr.contours.stroke_layers`).
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
    asked = [*drawings, *(["cryptomatte"] if cryptomatte else [])]
    with session.step("reading the drawings' parameters"):
        on = settings(integ, asked, params, scene_drawings)
        for name in on:
            DRAWINGS[name].preflight(session)
    beauty = integ.beauty if hasattr(integ, "npr_gbuffer") else integ
    if gbuffer is None:
        gbuffer = render_gbuffer(
            session, beauty=beauty, spp=session.spp, seed=seed, progress=progress
        )
    gb = gbuffer
    if session.source is not None:
        gb = gb.with_metadata(**{"mi_npr/scene": session.source})
    out = LayeredRender(gb, drawings=tuple(on))
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
        out.strokes = stroke_layers(out.gbuffer)
    return out


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

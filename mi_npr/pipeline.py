"""Every drawing on any scene in one render: the scene's own integrator as the beauty, plus the
``lines``, ``contours`` and ``raytree`` layers asked for (``mi-npr render --lines --contours
--raytree``).

The beauty is the scene's own integrator with all its parameters (a ``path`` with its
``max_depth``); when the scene's integrator is one of mi-npr's (``npr_lines``, ...), its nested
integrator makes the beauty and its drawing is on, with the XML's parameters as defaults. Each
drawing takes the parameters of its plugin (:data:`LAYERS`: ``npr_lines``, ``npr_contours``,
``npr_raytree``), by the same names, checked the same way; every drawing is computed from the
same exact G-buffer and the same raw beauty, so the drawings never stack on each other:

- ``R G B`` is the beauty with the lines (or the beauty alone), ``beauty.R/G/B`` the raw
  beauty, and the layers of every drawing are added (``lines``, ``contour``, ``raytree.*``,
  ``edges.*``): one G-buffer, one EXR;
- :attr:`LayeredRender.pictures` holds each drawing over the raw beauty (``contours``,
  ``raytree``), the images of ``<stem>_contours.png`` and ``<stem>_raytree.png``.
"""

from __future__ import annotations

import os
import sys
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import mitsuba as mi
import numpy as np

from . import layers as L
from .errors import ParameterError
from .gbuffer import GBuffer
from .params import Param, coerce
from .render import render_gbuffer
from .scene import merge_defines
from .session import SceneSession

#: The drawings and their plugins, in the order they are computed.
LAYERS = {"lines": "npr_lines", "contours": "npr_contours", "raytree": "npr_raytree"}


def plugin_class(plugin: str) -> type:
    """The integrator class of an mi-npr plugin for the active variant."""
    module = sys.modules.get(f"mi_npr.plugins.{plugin}")
    for obj in vars(module).values() if module else ():
        if isinstance(obj, type) and getattr(obj, "PLUGIN", None) == plugin:
            return obj
    raise ParameterError(f"{plugin}: plugin not registered")


def layer_params(layer: str) -> tuple[Param, ...]:
    """The parameters of a drawing (those of its plugin, :data:`LAYERS`)."""
    if layer not in LAYERS:
        raise ParameterError(f"layer {layer!r}: expected one of {', '.join(LAYERS)}")
    return plugin_class(LAYERS[layer]).PARAMS


def drawing_params(
    drawings: Sequence[str], params: Mapping[str, Any], what: str = "render"
) -> dict[str, dict[str, Any]]:
    """The values in ``params`` (parameter name -> value, the command line's flags) that each of
    ``drawings`` takes, checked by its plugin's table: ``{drawing: {name: value}}``, drawings in
    :data:`LAYERS` order. A name that none of them takes is a :class:`ParameterError` naming the
    flag and the drawings that would take it (``what``: "render", "batch")."""
    for d in drawings:
        if d not in LAYERS:
            raise ParameterError(f"drawing {d!r}: expected one of {', '.join(LAYERS)}")
    out: dict[str, dict[str, Any]] = {}
    for layer, plugin in LAYERS.items():
        if layer in drawings:
            known = {p.name: p for p in layer_params(layer)}
            out[layer] = {n: coerce(plugin, known[n], v) for n, v in params.items() if n in known}
    unused = [n for n in params if not any(n in taken for taken in out.values())]
    if unused:
        flags = ", ".join("--" + n.replace("_", "-") for n in unused)
        takers = sorted(
            {layer for layer in LAYERS for p in layer_params(layer) if p.name in unused}
        )
        hint = " or ".join("--" + t for t in takers) or "a drawing"
        raise ParameterError(f"{flags}: no drawing of this {what} takes it (add {hint})")
    return out


def settings(
    integrator: mi.Integrator,
    drawings: Sequence[str] = (),
    params: Mapping[str, Any] | None = None,
    scene_drawings: bool = True,
) -> dict[str, dict[str, Any]]:
    """Every drawing that is on and its full, checked parameters.

    On: the ``drawings`` asked for, and (with ``scene_drawings``) the one whose plugin is the
    scene's integrator. Each takes from ``params`` (:func:`drawing_params`) the names its plugin
    has, over the scene integrator's XML values (when it is that plugin), over the plugin's
    defaults."""
    own = getattr(integrator, "PLUGIN", None)
    for d in drawings:
        if d not in LAYERS:
            raise ParameterError(f"drawing {d!r}: expected one of {', '.join(LAYERS)}")
    on = [k for k, plugin in LAYERS.items() if k in drawings or (scene_drawings and own == plugin)]
    taken = drawing_params(on, dict(params or {}))
    out: dict[str, dict[str, Any]] = {}
    for layer in on:
        values = dict(integrator.params) if own == LAYERS[layer] else {}
        values.update(taken[layer])
        out[layer] = {p.name: values.get(p.name, p.default) for p in layer_params(layer)}
    return out


@dataclass
class LayeredRender:
    """What :func:`render_layers` makes: the G-buffer with every layer, the traced contours
    (``contours`` drawing) and each drawing over the raw beauty (linear (H, W, 3))."""

    gbuffer: GBuffer
    contours: list = field(default_factory=list)
    pictures: dict[str, np.ndarray] = field(default_factory=dict)
    drawings: tuple[str, ...] = ()
    #: The contours as vector paths on the true outline (:func:`mi_npr.contours.vectorize`).
    paths: list = field(default_factory=list)
    #: The line drawings as SVG stroke layers (:func:`mi_npr.contours.stroke_layers`).
    strokes: dict = field(default_factory=dict)

    def drawing(self, name: str) -> GBuffer:
        """The G-buffer with ``R G B`` = the picture of drawing ``name`` (``contours``,
        ``raytree``): what the shorthands ``mi_npr.contours.render_contours``,
        ``mi_npr.raytree.render`` and the ``contours``/``raytree`` commands return and write."""
        if name not in self.pictures:
            raise ParameterError(f"no {name!r} drawing in this render ({', '.join(self.pictures)})")
        p = self.pictures[name]
        rgb = {c: np.ascontiguousarray(p[..., i]) for i, c in enumerate(("R", "G", "B"))}
        return self.gbuffer.with_layers(rgb).with_metadata(**{"mi_npr/integrator": LAYERS[name]})


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
    **more: Any,
) -> LayeredRender:
    """Render ``scene`` with its own integrator as the beauty and the ``drawings`` (names of
    :data:`LAYERS`) with the plugin parameters ``params`` (see :func:`settings` and the module
    docstring).

    ``sensor``: the scene's sensor index, or a sensor object (a batch's camera,
    :func:`mi_npr.camera.sensor_for`). ``resolution=(W, H)`` and ``spp`` size the film and the
    sampler whatever the XML's ``<default>`` names (:class:`~mi_npr.session.SceneSession`);
    ``defines`` and the other keyword arguments fill the XML's ``<default>``\\ s; ``progress``
    shows a bar on a long beauty.
    ``cryptomatte`` adds the Cryptomatte layers (:mod:`mi_npr.cryptomatte`); ``vector`` traces
    the drawings as vector paths for the SVG writers (:attr:`LayeredRender.paths`,
    :attr:`LayeredRender.strokes`).

    >>> r = render_layers("scenes_xml/scene1.xml", ["contours"], {"only": "sphere*"},
    ...                   resolution=(64, 48), spp=4)                        # doctest: +SKIP
    >>> r.gbuffer["contour"].shape, sorted(r.pictures)                      # doctest: +SKIP
    """
    from .contours import overlay as contour_overlay
    from .drawing import add_lines, object_ids
    from .raytree.render import add_raytree

    session = SceneSession.open(
        scene,
        sensor=sensor,
        spp=spp,
        defines=merge_defines(defines, more),
        resolution=resolution,
    )
    integ = session.scene.integrator()
    with session.step("reading the drawings' parameters"):
        on = settings(integ, drawings, params, scene_drawings)
    beauty = integ.beauty if hasattr(integ, "npr_gbuffer") else integ
    gb = render_gbuffer(session, beauty=beauty, spp=session.spp, seed=seed, progress=progress)
    if session.source is not None:
        gb = gb.with_metadata(**{"mi_npr/scene": session.source})
    s, sensor_obj = session.scene, session.sensor
    out = LayeredRender(gb, drawings=tuple(on))
    new: dict[str, np.ndarray] = {}
    meta: dict[str, str] = {}
    if "lines" in on:
        with session.step("lines"):
            lined = add_lines(s, sensor_obj, gb, on["lines"])
        new.update({k: lined[k] for k in lined.names if k not in gb})
        new.update({k: lined[k] for k in ("R", "G", "B")})
        meta.update(lined.metadata)
    if "contours" in on:
        p = on["contours"]
        with session.step("contours"):
            drawn, out.contours = contour_overlay(
                gb,
                s,
                method=p["method"],
                id_mode=p["id_mode"],
                color=p["color"],
                only=p["only"],
                ignore=p["ignore"],
                line_width=p["line_width"],
            )
        out.pictures["contours"] = drawn.beauty
        if vector:
            from .contours.vector import RayIds, vectorize

            with session.step("vector contours"):
                idm = object_ids(s, session.objects, p)
                ids = idm.apply(gb.numpy(L.OBJECT_ID), gb.numpy(L.PRIM_ID))
                out.paths = vectorize(
                    ids, objects=idm.names, ids_at=RayIds(s, sensor_obj, id_map=idm)
                )
        new.update({k: drawn[k] for k in drawn.names if k not in gb and k not in new})
        meta.update(drawn.metadata)
    if "raytree" in on:
        p = on["raytree"]
        drawn = add_raytree(
            session,
            sensor_obj,
            gb,
            p["max_depth"],
            ids=object_ids(s, session.objects, p),
            shadow_lights=p["shadow_lights"],
            line_width=p["line_width"],
        )
        out.pictures["raytree"] = drawn.beauty
        new.update({k: drawn[k] for k in drawn.names if k not in gb and k not in new})
        meta.update(drawn.metadata)
    if new:
        meta["mi_npr/integrator"] = "+".join(LAYERS[d] for d in on)
        out.gbuffer = gb.with_layers(new).with_metadata(**meta)
    if cryptomatte:
        from .cryptomatte import add_cryptomatte, has_cryptomatte

        if not has_cryptomatte(out.gbuffer):
            with session.step("cryptomatte"):
                out.gbuffer = add_cryptomatte(out.gbuffer, s, sensor_obj, session.spp, seed)
    if vector:
        from .contours.vector import stroke_layers

        out.strokes = stroke_layers(out.gbuffer)
    return out

"""Contours of a rendered G-buffer drawn over its beauty image: the paper's Fig. 10.

The one function the ``npr_contours`` plugin, the ``mi-npr contours`` command and the notebooks
share: ids of the chosen ``id_mode`` from the G-buffer, every contour traced on them, the
``contour`` layer, and the contour pixels painted in ``color`` (red by default) over the raw
beauty (kept in ``beauty.R/G/B``, see :mod:`mi_npr.compose`).
"""

from __future__ import annotations

import json
import os
from collections.abc import Mapping, Sequence
from typing import Any

import mitsuba as mi
import numpy as np

from .. import layers as L
from ..compose import raw_beauty, with_overlay
from ..errors import ParameterError
from ..gbuffer import GBuffer
from .contour import Contour
from .idmode import check_id_mode, id_map
from .trace import check_method, contour_layer, trace

RED = (1.0, 0.0, 0.0)


def mode_ids(
    gb: GBuffer, scene: mi.Scene | None = None, id_mode: str = "shape"
) -> tuple[np.ndarray, dict[int, str]]:
    """``gb``'s ids in ``id_mode`` (:mod:`mi_npr.contours.idmode`) and their names. ``"shape"``
    is the ``object_id`` layer and the object table; the other modes need the ``scene``."""
    check_id_mode(id_mode)
    if id_mode == "shape":
        return gb.object_id, dict(gb.objects)
    if scene is None:
        raise ParameterError(f"id_mode = {id_mode!r} needs the scene (its meshes)")
    ids = id_map(scene, id_mode)
    return ids.apply(gb.numpy(L.OBJECT_ID), gb.numpy(L.PRIM_ID)), ids.names


def overlay(
    gb: GBuffer,
    scene: mi.Scene | None = None,
    *,
    method: str = "border",
    id_mode: str = "shape",
    color: Sequence[float] = RED,
) -> tuple[GBuffer, list[Contour]]:
    """``gb`` with its contours: the ``contour`` layer added and drawn in ``color`` on R G B.

    Returns the new GBuffer and the contours (:func:`mi_npr.contours.trace` on the ids of
    ``id_mode``). The overlay always starts from the raw beauty (``beauty.R/G/B`` when an earlier
    overlay left it, else ``R G B``), so calling it again replaces the contours rather than
    stacking them. Metadata: ``mi_npr/contour_method``, ``mi_npr/contour_id_mode``,
    ``mi_npr/contour_color`` and ``mi_npr/contour_objects`` (JSON id -> name of the ``contour``
    layer's ids; with ``id_mode="shape"`` the object table itself).
    """
    check_method(method)
    mapped, names = mode_ids(gb, scene, id_mode)
    contours = trace(mapped, objects=names, method=method)
    layer = contour_layer(contours, gb.shape)
    raw = raw_beauty(gb)
    base = gb.with_layers({c: raw[..., i] for i, c in enumerate(L.RGB)})
    out = with_overlay(base, (layer != 0).astype(np.float32), color).with_layers({L.CONTOUR: layer})
    out = out.with_metadata(
        **{
            "mi_npr/contour_method": method,
            "mi_npr/contour_id_mode": id_mode,
            "mi_npr/contour_objects": json.dumps({str(k): v for k, v in names.items()}),
            "mi_npr/contour_color": ",".join(f"{float(v):g}" for v in color),
        }
    )
    return out, contours


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
    """Render ``scene`` (:func:`mi_npr.render`) and :func:`overlay` its contours.

    ``method``, ``id_mode`` and ``color`` left at ``None`` take the values of the scene's
    ``npr_contours`` integrator when it has one, else the defaults (``border``, ``shape``, red).
    ``spp`` sets the beauty's samples per pixel (and the XML's ``spp`` default when it declares
    one, like :func:`mi_npr.render`); ``defines`` and the other keyword arguments fill the XML's
    ``<default>``s.
    """
    from ..render import render
    from ..scene import merge_defines
    from ..session import SceneSession

    session = SceneSession.open(scene, sensor=sensor, spp=spp, defines=merge_defines(defines, more))
    integrator = session.scene.integrator()
    xml = getattr(integrator, "params", {}) if _plugin(integrator) == "npr_contours" else {}
    gb = render(session.scene, sensor=sensor, spp=session.spp, seed=seed)
    if session.source is not None:
        gb = gb.with_metadata(**{"mi_npr/scene": session.source})
    return overlay(
        gb,
        session.scene,
        method=method or xml.get("method", "border"),
        id_mode=id_mode or xml.get("id_mode", "shape"),
        color=color if color is not None else xml.get("color", RED),
    )


def _plugin(integrator: Any) -> str | None:
    return getattr(integrator, "PLUGIN", None)

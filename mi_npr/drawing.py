"""The line drawing alone (issue 19): ``<stem>_lines.png``, ink on paper, and the render that
takes the command line's line options (``--line-width``, ``--line-aa``, ``--line-color``).

The ``lines`` layer is coverage in [0, 1]; the drawing is ``paper * (1 - lines) + line_color *
lines`` in linear RGB (black ink on white by default), written sRGB-encoded like every PNG.
"""

from __future__ import annotations

import os
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from . import layers as L
from .compose import over
from .errors import ParameterError
from .gbuffer import GBuffer
from .params import Param
from .render import render as render_gbuffer
from .scene import merge_defines
from .session import SceneSession

#: Black ink on white paper (linear RGB).
INK, PAPER = (0.0, 0.0, 0.0), (1.0, 1.0, 1.0)


def drawing(
    gb: GBuffer, line_color: Sequence[float] = INK, paper: Sequence[float] = PAPER
) -> np.ndarray:
    """The ``lines`` layer of ``gb`` as ``line_color`` on ``paper``: (H, W, 3) linear RGB."""
    if L.LINES not in gb:
        raise ParameterError(f"the G-buffer has no {L.LINES!r} layer (render with npr_lines)")
    h, w = gb.shape
    sheet = np.broadcast_to(np.asarray(paper, np.float32).reshape(1, 1, 3), (h, w, 3))
    return over(sheet, gb[L.LINES], line_color)


#: Parameters every per-object drawing takes (npr_lines, npr_contours, npr_raytree): what one
#: object is and which objects are drawn (:mod:`mi_npr.contours.idmode`).
def selection_params(modes: Sequence[str] | None = None) -> tuple[Param, ...]:
    """The ``id_mode``, ``only`` and ``ignore`` plugin parameters (``modes``: the id modes
    allowed, default all)."""
    from .contours.idmode import ID_MODES

    allowed = tuple(modes or ID_MODES)

    def one_of(v: str) -> str | None:
        return None if v in allowed else f"expected one of {', '.join(allowed)}"

    return (
        Param("id_mode", str, "shape", "what one object is: " + ", ".join(allowed), one_of),
        Param("only", str, "", "draw only objects matching these globs (comma-separated)"),
        Param("ignore", str, "", "objects matching these globs count as background"),
    )


def object_ids(scene: Any, table: Any, params: Mapping[str, Any]) -> Any:
    """The :class:`~mi_npr.contours.idmode.IdMap` of a drawing's ``id_mode``, ``only`` and
    ``ignore`` parameters (strings of comma-separated globs, or lists)."""
    from .contours.idmode import id_map

    return id_map(
        scene,
        params.get("id_mode") or "shape",
        table,
        only=params.get("only") or (),
        ignore=params.get("ignore") or (),
    )


def add_lines(scene: Any, sensor: Any, gb: GBuffer, params: Mapping[str, Any]) -> GBuffer:
    """``gb`` with the ``lines`` layer of the ``npr_lines`` parameters ``params`` (all of them,
    checked), composited in ``line_color`` onto ``R G B`` (the raw beauty kept)."""
    import json

    from .antialias import antialiased_lines
    from .compose import with_overlay
    from .foliage.leaves import leaf_id_layer
    from .kernels import LINES_PARAMS
    from .scene import object_table

    chain = {p.name: params[p.name] for p in LINES_PARAMS}
    if chain["leaf_edges"] and L.LEAF_ID not in gb:
        gb = gb.with_layers({L.LEAF_ID: leaf_id_layer(scene, gb)})
    ids = object_ids(scene, object_table(scene), params)
    n = params["line_aa"]
    ink = antialiased_lines(scene, sensor, gb, n, ids=ids, **chain)
    sel = {k: params[k] for k in ("id_mode", "only", "ignore") if params.get(k)}
    meta = json.dumps({**chain, "line_aa": n, **sel})
    gb = gb.with_layers({L.LINES: ink}).with_metadata(**{"mi_npr/lines": meta})
    return with_overlay(gb, ink, params["line_color"])


def render_lines(
    scene: str | os.PathLike[str],
    *,
    line_width: float | None = None,
    line_aa: int | None = None,
    line_color: Sequence[float] | None = None,
    spp: int | str | None = None,
    seed: int = 0,
    defines: Mapping[str, Any] | None = None,
) -> GBuffer:
    """:func:`mi_npr.render` with the scene's ``npr_lines`` parameters ``line_width``,
    ``line_aa`` and ``line_color`` overridden where given (not ``None``); giving one for a
    scene whose integrator is not ``npr_lines`` is an error naming the scene."""
    given = {"line_width": line_width, "line_aa": line_aa, "line_color": line_color}
    given = {k: v for k, v in given.items() if v is not None}
    if not given:
        return render_gbuffer(scene, spp=spp, seed=seed, defines=defines)
    session = SceneSession.open(scene, spp=spp, defines=merge_defines(defines, {}))
    integrator = session.scene.integrator()
    if getattr(integrator, "PLUGIN", None) != "npr_lines":
        flags = ", ".join("--" + k.replace("_", "-") for k in given)
        used = getattr(integrator, "PLUGIN", None) or integrator.class_name()
        raise ParameterError(
            f"{session.name}: {flags}: only for the npr_lines integrator "
            f"(the scene uses {used}; try -D integrator=npr_lines)"
        )
    integrator.set_params(**given)
    return integrator.npr_gbuffer(session, spp=session.spp, seed=seed)

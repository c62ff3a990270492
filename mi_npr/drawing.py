"""The line drawing alone (issue 19): ``<stem>_lines.png``, ink on paper; the ``lines`` layer
added to a G-buffer (:func:`add_lines`, the ``npr_lines`` plugin's pass and ``mi-npr render
--lines``); the object-selection parameters every per-object drawing takes (issue 14).

The ``lines`` layer is coverage in [0, 1]; the drawing is ``paper * (1 - lines) + line_color *
lines`` in linear RGB (black ink on white by default), written sRGB-encoded like every PNG.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from . import layers as L
from .compose import over
from .errors import ParameterError
from .gbuffer import GBuffer
from .params import Param, one_of

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
    return over(sheet, gb.numpy(L.LINES), line_color)


def selection_params(modes: Sequence[str] | None = None) -> tuple[Param, ...]:
    """The ``id_mode``, ``only`` and ``ignore`` parameters of every per-object drawing
    (``npr_lines``, ``npr_contours``, ``npr_raytree``): what one object is and which objects are
    drawn (:mod:`mi_npr.contours.idmode`); ``modes``: the id modes allowed (default all)."""
    from .contours.idmode import ID_MODES

    allowed = tuple(modes or ID_MODES)
    return (
        Param(
            "id_mode", str, "shape", "what one object is: " + ", ".join(allowed), one_of(allowed)
        ),
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

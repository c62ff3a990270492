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
    return over(sheet, gb.numpy(L.LINES), line_color)


def render_lines(
    scene: str | os.PathLike[str],
    *,
    line_width: float | None = None,
    line_aa: int | None = None,
    line_color: Sequence[float] | None = None,
    cryptomatte: bool = False,
    spp: int | str | None = None,
    seed: int = 0,
    defines: Mapping[str, Any] | None = None,
) -> GBuffer:
    """:func:`mi_npr.render` with the scene's ``npr_lines`` parameters ``line_width``,
    ``line_aa`` and ``line_color`` overridden where given (not ``None``); giving one for a
    scene whose integrator is not ``npr_lines`` is an error naming the scene. ``cryptomatte``
    adds the Cryptomatte layers (:mod:`mi_npr.cryptomatte`) whatever the integrator."""
    from .cryptomatte import add_cryptomatte, has_cryptomatte
    from .render import render_gbuffer

    given = {"line_width": line_width, "line_aa": line_aa, "line_color": line_color}
    given = {k: v for k, v in given.items() if v is not None}
    session = SceneSession.open(scene, spp=spp, defines=merge_defines(defines, {}))
    integrator = session.scene.integrator()
    if given and getattr(integrator, "PLUGIN", None) != "npr_lines":
        flags = ", ".join("--" + k.replace("_", "-") for k in given)
        used = getattr(integrator, "PLUGIN", None) or integrator.class_name()
        raise ParameterError(
            f"{session.name}: {flags}: only for the npr_lines integrator "
            f"(the scene uses {used}; try -D integrator=npr_lines)"
        )
    if given:
        integrator.set_params(**given)
    if hasattr(integrator, "npr_gbuffer"):
        gb = integrator.npr_gbuffer(session, spp=session.spp, seed=seed)
    else:
        gb = render_gbuffer(session, beauty=integrator, spp=session.spp, seed=seed)
    if cryptomatte and not has_cryptomatte(gb):
        gb = add_cryptomatte(gb, session.scene, session.sensor, session.spp, seed)
    return gb

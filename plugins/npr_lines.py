"""``npr_lines``: the thesis's depth lines (section 5.1) drawn over a beauty render.

The exact pixel-centre G-buffer of ``npr_gbuffer`` goes through :func:`mi_npr.kernels.lines`:
normalised depth -> selective dilation (eqs. 5.3-5.4) -> signed depth contours (eq. 5.1) ->
isolated-pixel removal (eq. 5.2), plus optional object-ID and crease edges. The gray-level result
is the ``lines.V`` layer, and it is composited onto the nested integrator's beauty in ``line_color``
(``R G B``); the untouched beauty stays in ``beauty.R beauty.G beauty.B``.

.. list-table::
   :header-rows: 1

   * - Parameter
     - Type
     - Default
     - Meaning
   * - ``c``
     - float
     - 40
     - Eq. 5.1 gain on the normalised depth difference (>= 0).
   * - ``t``
     - float
     - 1
     - Eq. 5.1 threshold (>= 0): depth steps above ``t / c`` of the depth range light up, steps
       above ``(1 + t) / c`` are drawn at full strength; gray levels in between.
   * - ``t0``
     - float
     - 0.5
     - Eq. 5.2 threshold in [0, 1]: a line pixel needs 2 neighbours above it.
   * - ``dilation_size``
     - integer
     - 3
     - Window of the selective dilation (odd, 3 to 15).
   * - ``dilation_iterations``
     - integer
     - 1
     - Selective-dilation passes; 0 turns the pre-filter off.
   * - ``remove_isolated``
     - boolean
     - true
     - Apply eq. 5.2.
   * - ``id_edges``
     - boolean
     - false
     - Also draw object-ID edges (where a 4-neighbour is another object; 2 px thick).
   * - ``normal_edges``
     - float
     - 0
     - Also draw creases: a 4-neighbour on the same object whose normal turns by more than this
       angle, in degrees (0 = off; 2 px thick).
   * - ``leaf_edges``
     - integer
     - 0
     - Also outline every leaf primitive (``npr_leaves`` shapes) from the ``leaf_id.V`` layer:
       0 = off, 1 = 1 px on the nearer leaf, 2 = 2 px. Adds the ``leaf_id.V`` layer to the output.
   * - ``bright_fade``
     - float
     - 0
     - Fade the lines out where the beauty's luminance exceeds this value (none from twice it):
       no detail in bright areas. 0 = off.
   * - ``line_color``
     - rgb
     - 0, 0, 0
     - Colour of the lines composited onto the beauty (linear RGB, finite, >= 0).
   * - ``near``, ``far``
     - float
     - unset
     - Camera depths mapped to 0 and 1. Unset: the frame's nearest and farthest finite depth.
       The background is always 1, so the farthest object's contour against the background
       needs a ``far`` beyond the scene.
   * - (nested integrator)
     - integrator
     - none
     - Renders the beauty (``path``, ``direct``, ...); without one, a headlight shading.

The defaults draw clean 1-pixel contours on the paper's scenes at 640x480 (see
:mod:`mi_npr.kernels.chain` for why).

``mi.render(scene)`` returns (H, W, 16): ``R G B`` (beauty with the lines), ``lines.V``, the
G-buffer channels ``Z P.X P.Y P.Z N.X N.Y N.Z object_id.V prim_id.V`` (then ``leaf_id.V`` when
``leaf_edges`` is on), and last the untouched beauty ``beauty.R beauty.G beauty.B``: the layout
of every mi-npr integrator that draws on the beauty (its own layers, the G-buffer, the raw
beauty). The sensor's film holds the same channels afterwards. ``mi-npr render`` writes every
layer to the EXR and the composited beauty to the PNG.

XML::

    <integrator type="npr_lines">
        <float name="t" value="0.5"/>
        <boolean name="id_edges" value="true"/>
        <rgb name="line_color" value="0.1, 0.05, 0.0"/>
        <integrator type="path"/>
    </integrator>

Every scene of ``scenes_xml/`` takes it: ``mi-npr render scenes_xml/scene1.xml -o out
-D integrator=npr_lines``.
"""

from __future__ import annotations

import json
import math

import mitsuba as mi

from mi_npr import layers as L
from mi_npr.compose import with_overlay
from mi_npr.foliage.leaves import leaf_id_layer
from mi_npr.gbuffer import GBuffer, to_numpy
from mi_npr.integrator import NprIntegrator
from mi_npr.kernels import LINES_PARAMS, lines
from mi_npr.kernels.depth_lines import check_range
from mi_npr.params import Param


def _color(rgb: tuple[float, ...]) -> str | None:
    ok = all(math.isfinite(v) and v >= 0 for v in rgb)
    return None if ok else "must be finite and >= 0 (linear RGB)"


_LINE_COLOR = Param(
    "line_color", tuple, (0.0, 0.0, 0.0), "colour of the lines (linear RGB)", _color
)
_CHAIN = tuple(p.name for p in LINES_PARAMS)


class NprLinesIntegrator(NprIntegrator):
    """Depth lines over the beauty (see the module docstring for the manual)."""

    PLUGIN = "npr_lines"
    # The chain's parameters with line_color before near and far, as the manual lists them.
    PARAMS = (*LINES_PARAMS[:-2], _LINE_COLOR, *LINES_PARAMS[-2:])

    def __init__(self, props: mi.Properties) -> None:
        super().__init__(props)
        # near < far is a rule between two parameters: check it when the scene loads.
        check_range(self.params["near"], self.params["far"], self.PLUGIN)

    def aov_names(self) -> list[str]:
        extra = [L.LEAF_ID] if self.params["leaf_edges"] else []
        return [L.LINES, *L.GBUFFER_AOVS, *extra, *L.RAW_RGB, *self.crypto_aovs()]

    def post(self, scene: mi.Scene, sensor: mi.Sensor, gb: GBuffer) -> GBuffer:
        params = {k: self.params[k] for k in _CHAIN}
        if params["leaf_edges"] and L.LEAF_ID not in gb:
            gb = gb.with_layers({L.LEAF_ID: leaf_id_layer(scene, gb)})
        ink = to_numpy(lines(gb, **params))
        gb = gb.with_layers({L.LINES: ink}).with_metadata(**{"mi_npr/lines": json.dumps(params)})
        return with_overlay(gb, ink, self.params["line_color"])


mi.register_integrator("npr_lines", lambda props: NprLinesIntegrator(props))

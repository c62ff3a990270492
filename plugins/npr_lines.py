"""``npr_lines``: the thesis's depth lines (section 5.1) drawn over a beauty render.

The exact pixel-centre G-buffer of ``npr_gbuffer`` goes through :func:`mi_npr.kernels.lines`:
normalised depth -> selective dilation (eqs. 5.3-5.4) -> signed depth contours (eq. 5.1) ->
isolated-pixel removal (eq. 5.2), plus object boundaries (ID edges) and creases, every kind 1 px
wide on one side of its edge (see :mod:`mi_npr.kernels.chain` for the width rule), computed from
``line_aa`` x ``line_aa`` rays per pixel and box-filtered. The gray-level result is the ``lines.V``
layer, and it is composited onto the nested integrator's beauty in ``line_color``
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
     - Selective-dilation passes, 0..64; 0 turns the pre-filter off.
   * - ``remove_isolated``
     - boolean
     - true
     - Apply eq. 5.2.
   * - ``id_edges``
     - boolean
     - true
     - Draw object boundaries (a 4-neighbour is another object), 1 px.
   * - ``crease_angle``
     - float
     - 134
     - Draw creases: a 4-neighbour on the same object at a dihedral angle below this, in
       degrees (Blender Freestyle's crease angle; 0 = off), 1 px.
   * - ``leaf_edges``
     - integer
     - 0
     - Also outline every leaf primitive (``npr_leaves`` shapes) from the ``leaf_id.V`` layer:
       0 = off, 1 = 1 px on the nearer leaf, 2 = 2 px. Adds the ``leaf_id.V`` layer to the output.
   * - ``max_density``
     - float
     - 1
     - Thin lines where the ink of a 9x9 region exceeds this share (dense geometry): creases go
       first, then object boundaries; depth contours stay. 1 = off.
   * - ``line_width``
     - float
     - 1
     - Width of every line, in pixels of the film, (0, 15].
   * - ``bright_fade``
     - float
     - 0
     - Fade the lines out where the beauty's luminance exceeds this value (none from twice it):
       no detail in bright areas. 0 = off.
   * - ``line_color``
     - rgb
     - 0, 0, 0
     - Colour of the lines composited onto the beauty (linear RGB, finite, >= 0).
   * - ``line_aa``
     - integer
     - 3
     - Anti-aliasing: the lines are computed from ``line_aa`` x ``line_aa`` rays per pixel and
       box-filtered to gray levels (1 = the pixel-centre G-buffer, aliased). 3 by measurement:
       against 8 x 8 it leaves a fifth of the error of 1 ray at ~2x the time of 2 x 2 (see
       :mod:`mi_npr.antialias`, which also tells how this meets eqs. 5.1-5.4).
   * - ``near``, ``far``
     - float
     - unset
     - Camera depths mapped to 0 and 1. Unset: the frame's nearest finite depth and the larger
       of its farthest and 4x its nearest. The background is a full step beyond every object
       pixel whatever ``far`` is (see :mod:`mi_npr.kernels.chain`).
   * - (nested integrator)
     - integrator
     - none
     - Renders the beauty (``path``, ``direct``, ...); without one, a headlight shading.

The defaults draw what a line drawing holds, as Blender Freestyle's silhouette + border + crease
(134 degrees) do: depth contours, object boundaries and creases, each 1 px wide (see
:mod:`mi_npr.kernels.chain` for why).

``mi.render(scene)`` returns (H, W, 16): ``R G B`` (beauty with the lines), ``lines.V``, the
G-buffer channels ``Z P.X P.Y P.Z N.X N.Y N.Z object_id.V prim_id.V`` (then ``leaf_id.V`` when
``leaf_edges`` is on), and last the untouched beauty ``beauty.R beauty.G beauty.B``: the layout
of every mi-npr integrator that draws on the beauty (its own layers, the G-buffer, the raw
beauty). The sensor's film holds the same channels afterwards. ``mi-npr render`` writes every
layer to the EXR, the composited beauty to the PNG and the drawing alone (black ink on white, or
``--line-color`` on ``--paper``) to ``<stem>_lines.png``; ``--line-width``, ``--line-aa`` and
``--line-color`` override this plugin's parameters (:meth:`NprLinesIntegrator.set_params`).

XML::

    <integrator type="npr_lines">
        <float name="t" value="0.5"/>
        <float name="crease_angle" value="120"/>
        <rgb name="line_color" value="0.1, 0.05, 0.0"/>
        <integrator type="path"/>
    </integrator>

Every scene of ``scenes_xml/`` takes it: ``mi-npr render scenes_xml/scene1.xml -o out
-D integrator=npr_lines``.
"""

from __future__ import annotations

import json

import mitsuba as mi

from mi_npr import layers as L
from mi_npr.antialias import aa_factor, antialiased_lines, check_aa_width
from mi_npr.compose import with_overlay
from mi_npr.errors import ParameterError
from mi_npr.foliage.leaves import leaf_id_layer
from mi_npr.gbuffer import GBuffer
from mi_npr.integrator import NprIntegrator
from mi_npr.kernels import LINES_PARAMS
from mi_npr.kernels.depth_lines import check_range
from mi_npr.params import Param, coerce, rgb_color

_LINE_COLOR = Param(
    "line_color", tuple, (0.0, 0.0, 0.0), "colour of the lines (linear RGB)", rgb_color
)
#: Measured (issue 19, cornell_box and scene4 at 320x240): the mean |error| of the lines layer
#: against 8 x 8 rays per pixel, relative to its mean ink, is 0.86-1.5 with 1 ray, 0.25-0.33
#: with 2 x 2, 0.19 with 3 x 3 and 0.16-0.23 with 4 x 4, at 17-20, 36-56 and 69-128 ms.
LINE_AA_DEFAULT = 3
_LINE_AA = Param(
    "line_aa", int, LINE_AA_DEFAULT, "rays per pixel side for anti-aliased lines", aa_factor
)
_CHAIN = tuple(p.name for p in LINES_PARAMS)


class NprLinesIntegrator(NprIntegrator):
    """Depth lines over the beauty (see the module docstring for the manual)."""

    PLUGIN = "npr_lines"
    # The chain's parameters with line_color before near and far, as the manual lists them.
    PARAMS = (*LINES_PARAMS[:-2], _LINE_COLOR, _LINE_AA, *LINES_PARAMS[-2:])

    def __init__(self, props: mi.Properties) -> None:
        super().__init__(props)
        # near < far is a rule between two parameters: check it when the scene loads.
        check_range(self.params["near"], self.params["far"], self.PLUGIN)
        check_aa_width(self.params["line_width"], self.params["line_aa"], self.PLUGIN)

    def aov_names(self) -> list[str]:
        extra = [L.LEAF_ID] if self.params["leaf_edges"] else []
        return [L.LINES, *L.GBUFFER_AOVS, *extra, *L.RAW_RGB, *self.crypto_aovs()]

    def post(self, scene: mi.Scene, sensor: mi.Sensor, gb: GBuffer) -> GBuffer:
        params = {k: self.params[k] for k in _CHAIN}
        if params["leaf_edges"] and L.LEAF_ID not in gb:
            gb = gb.with_layers({L.LEAF_ID: leaf_id_layer(scene, gb)})
        n = self.params["line_aa"]
        ink = antialiased_lines(scene, sensor, gb, n, **params)
        meta = json.dumps({**params, "line_aa": n})
        gb = gb.with_layers({L.LINES: ink}).with_metadata(**{"mi_npr/lines": meta})
        return with_overlay(gb, ink, self.params["line_color"])

    def set_params(self, **values: object) -> None:
        """Override parameters after loading (the command line's ``--line-width`` and friends),
        checked like the XML's."""
        by_name = {p.name: p for p in self.PARAMS}
        for name, value in values.items():
            if name not in by_name:
                raise ParameterError(f"{self.PLUGIN}: unknown parameter {name!r}")
            self.params[name] = coerce(self.PLUGIN, by_name[name], value)
        check_range(self.params["near"], self.params["far"], self.PLUGIN)
        check_aa_width(self.params["line_width"], self.params["line_aa"], self.PLUGIN)


mi.register_integrator("npr_lines", lambda props: NprLinesIntegrator(props))

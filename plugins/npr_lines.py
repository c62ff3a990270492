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
   * - ``line_model``
     - string
     - ``thesis``
     - What draws ``lines.V``: ``thesis``, eqs. 5.1-5.4 on the exact G-buffer (this page), or
       ``soft``, the differentiable line image of :func:`mi_npr.ad.soft_lines` (below), whose
       gradients under ``mi.render(scene, params=params)`` include silhouettes and occlusion
       boundaries that move. ``soft`` takes ``line_width``, ``line_aa`` and ``line_color``
       only (any other parameter set is an error) and needs an AD variant.
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
       box-filtered to gray levels (1 = the pixel-centre G-buffer, aliased), normalised so that
       every line keeps a pixel of full ink. 3: against 8 x 8
       it leaves a fifth of the error of 1 ray (see :mod:`mi_npr.antialias`, which also tells
       how this meets eqs. 5.1-5.4).
   * - ``near``, ``far``
     - float
     - unset
     - Camera depths mapped to 0 and 1. Unset: the frame's nearest finite depth and the larger
       of its farthest and 4x its nearest. The background is a full step beyond every object
       pixel whatever ``far`` is (see :mod:`mi_npr.kernels.chain`).
   * - ``id_mode``
     - string
     - ``shape``
     - What one object is for the ID edges: ``shape``, ``component``, ``primitive``,
       ``material`` (one object per BSDF) or ``silhouette`` (all objects one: ID edges only
       against the background); see :mod:`mi_npr.contours.idmode`.
   * - ``only``, ``ignore``
     - string
     - ``""``
     - Comma-separated shell globs on object names: ID edges and creases only on the objects
       ``only`` matches (all if empty) and not ``ignore``; the others count as background.
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
``--line-color`` on ``--paper``) to ``<stem>_lines.png``; every parameter is also a flag
(``--line-width``, ``--line-aa``, ``--line-color``, ...) over the XML's value; the table is the
``lines`` drawing's (:data:`mi_npr.drawings.DRAWINGS`).

**The soft line model** (``line_model = 'soft'``): ``lines.V`` is
:func:`mi_npr.ad.soft_lines` of the sensor at its film's size (no crop window), with
``line_aa`` samples a pixel side and a Gaussian filter of ``sigma = line_width / 2`` pixels (a
band about ``line_width`` wide): silhouettes, ID edges, occlusion boundaries and creases drawn
by one rule, composited in ``line_color`` as above. Its depths are made unitless by the
scene's bounding-box diagonal when this integrator first draws the scene, kept afterwards (so
that moving a shape does not change what the lines measure). ``dr.backward`` through
``mi.render(scene, params=params)`` gives its interior terms (the samples' rays follow the
camera and the shapes) and boundary terms (the flux of each moving discontinuity, from the
front surface's image velocity); topology changes (a line born at a cusp or a T-junction,
features thinner than a sample) and the image frame beyond the filter's margin are not
covered (:mod:`mi_npr.ad.visibility`). When only ``lines.V`` receives gradients, the backward
pass differentiates the soft lines alone; a gradient on any other channel differentiates the
whole render: the soft lines in it (``R G B`` composites them) with both terms, the G-buffer
and the beauty with the interior term only (their pixel-centre silhouettes jump). The
forward-mode derivative (``dr.forward``) is that of the whole render too.

XML::

    <integrator type="npr_lines">
        <float name="t" value="0.5"/>
        <float name="crease_angle" value="120"/>
        <rgb name="line_color" value="0.1, 0.05, 0.0"/>
        <integrator type="path"/>
    </integrator>

Differentiable lines, for ``mi.render(scene, params=params)`` and ``dr.backward``::

    <integrator type="npr_lines">
        <string name="line_model" value="soft"/>
        <integer name="line_aa" value="4"/>
    </integrator>

Every scene of ``scenes_xml/`` takes it: ``mi-npr render scenes_xml/scene1.xml -o out
-D integrator=npr_lines``.
"""

from __future__ import annotations

import mitsuba as mi

from mi_npr import layers as L
from mi_npr.drawings import DRAWINGS
from mi_npr.integrator import NprIntegrator


class NprLinesIntegrator(NprIntegrator):
    """Depth lines over the beauty (see the module docstring for the manual)."""

    PLUGIN = "npr_lines"
    DRAWING = DRAWINGS["lines"]
    PARAMS = DRAWING.params

    def aov_names(self) -> list[str]:
        extra = [L.LEAF_ID] if self.params["leaf_edges"] else []
        return [L.LINES, *L.GBUFFER_AOVS, *extra, *L.RAW_RGB, *self.crypto_aovs()]


mi.register_integrator("npr_lines", lambda props: NprLinesIntegrator(props))

"""``npr_strokes``: chained, typed vector strokes with exact hidden lines, over a beauty render.

The thesis pairs image-space contours with object-space information for stylization; here the
strokes themselves come from object space where the scene has it (:mod:`mi_npr.strokes`): the
meshes' silhouette, border, crease, material and intersection edges, the exact outlines of the
other shapes (spheres, cylinders..., glass ones too), each visible or hidden by ray casting
against the scene (quantitative invisibility; glass does not hide), and, with
``raytree_depth``, the ray trees' reflection, refraction and shadow lines; chained into
polylines and styled. The styled strokes are
rasterised with anti-aliasing into the ``strokes.V`` layer and drawn over the nested
integrator's beauty (``R G B``; the untouched beauty stays in ``beauty.R beauty.G beauty.B``).
``mi-npr render --strokes`` also writes them as ``<stem>_strokes.svg`` (one Inkscape layer per
edge kind, a group per object), ``<stem>_strokes.json`` (every stroke with per-vertex
attributes) and ``<stem>_strokes.png`` (ink on paper).

.. list-table::
   :header-rows: 1

   * - Parameter
     - Type
     - Default
     - Meaning
   * - (nested integrator)
     - integrator
     - none
     - Renders the beauty (``path``, ...). Without one, a headlight diffuse shading.
   * - ``style``
     - string
     - ``technical``
     - ``technical`` (1 px, hidden lines dashed), ``illustration`` (depth-tapered widths,
       tapered ends, no hidden lines) or ``thesis`` (opacity = the gray level of the thesis's
       eq. 5.1 at the stroke).
   * - ``hidden``
     - boolean
     - the style's
     - Draw hidden lines (quantitative invisibility 1 to ``max_qi``), dashed.
   * - ``line_width``
     - float
     - the style's
     - Base stroke width in pixels, in (0, 15].
   * - ``dash``
     - string
     - the style's
     - Dash pattern of hidden lines: on, off, ... lengths in pixels (``"4,3"``); not all 0.
   * - ``crease_angle``
     - float
     - 134
     - Mesh edges whose dihedral angle is below it (degrees, [0, 180]) are creases; 0 = none.
       The same definition as ``npr_lines``'s (Freestyle's).
   * - ``chain_angle``
     - float
     - 60
     - A stroke continues through a joint only where it turns by less than this, degrees.
   * - ``max_qi``
     - integer
     - 1
     - Hidden lines behind more surfaces than this are left out (0..64; 0: the visible
       strokes alone; 1: each object's own back edges and what lies behind one sheet).
   * - ``raytree_depth``
     - integer
     - 0
     - Levels of ray trees whose reflection, refraction and shadow lines are added as strokes
       (traced in image space, within half a pixel diagonal); 0: none.

Channels (``aov_names()``, after ``R G B``): ``strokes.V`` (coverage of the styled strokes in
[0, 1]), the G-buffer's ``Z P.X P.Y P.Z N.X N.Y N.Z object_id.V prim_id.V``, then the untouched
beauty ``beauty.R beauty.G beauty.B``. ``R G B`` hold the beauty with the strokes drawn.

XML::

    <integrator type="npr_strokes">
        <string name="style" value="illustration"/>
        <float name="crease_angle" value="120"/>
        <integrator type="path"/>
    </integrator>

Every scene of ``scenes_xml/`` takes it: ``mi-npr render scenes_xml/cornell_box.xml -o out
-D integrator=npr_strokes``.
"""

from __future__ import annotations

import mitsuba as mi

from mi_npr import layers as L
from mi_npr.drawings import DRAWINGS
from mi_npr.integrator import NprIntegrator


class NprStrokesIntegrator(NprIntegrator):
    """Vector strokes over the beauty (see the module docstring for the manual)."""

    PLUGIN = "npr_strokes"
    DRAWING = DRAWINGS["strokes"]
    PARAMS = DRAWING.params

    def aov_names(self) -> list[str]:
        return [L.STROKES, *L.GBUFFER_AOVS, *L.RAW_RGB, *self.crypto_aovs()]


mi.register_integrator("npr_strokes", lambda props: NprStrokesIntegrator(props))

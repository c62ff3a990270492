"""``npr_contours``: the apparent contours of the real objects, in red over a beauty render.

The paper's Fig. 10 from XML: the nested integrator renders the realistic image (reflections,
refractions, shadows), the exact pixel-centre G-buffer gives every object's id, every contour of
every object is traced (:func:`mi_npr.contours.trace`) and drawn over the beauty, so a viewer tells
real objects from their reflections and refractions.

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
   * - ``method``
     - string
     - ``border``
     - ``border`` (exact border follower) or ``code_direction`` (the paper's walk, can leave
       contours open).
   * - ``id_mode``
     - string
     - ``shape``
     - What one object is: ``shape``, ``primitive`` (every triangle, the paper's Fig. 9 b/c) or
       ``component`` (connected parts of a mesh, the fix for Fig. 9 a).
   * - ``color``
     - rgb
     - ``1, 0, 0``
     - Linear RGB of the contour pixels (finite, >= 0, like ``npr_lines``'s ``line_color``).
   * - ``only``, ``ignore``
     - string
     - ``""``
     - Comma-separated shell globs on object names: contours of the objects ``only`` matches
       (all if empty) and not ``ignore``; the others count as background.
   * - ``line_width``
     - float
     - 1
     - Width of the drawn contours in pixels (the ``contour`` layer stays 1 px).

``id_mode`` also takes ``material`` (one object per BSDF) and ``silhouette`` (all objects one:
contours only against the background). A contour between two touching objects is drawn once,
1 px, on the nearer object's side (the larger id's when they touch at equal depth).

Channels (``aov_names()``, after ``R G B``): ``contour.V`` (object id on contour pixels, 0
elsewhere, in the ids of ``id_mode``; their names are in the GBuffer's metadata
``mi_npr/contour_objects``), the G-buffer's ``Z P.X P.Y P.Z N.X N.Y N.Z object_id.V prim_id.V``,
then the untouched beauty ``beauty.R beauty.G beauty.B``. ``R G B`` hold the beauty with the
contours drawn.

XML::

    <integrator type="npr_contours">
        <string name="id_mode" value="component"/>
        <rgb name="color" value="1, 0, 0"/>
        <integrator type="path">
            <integer name="max_depth" value="8"/>
        </integrator>
    </integrator>
"""

from __future__ import annotations

import mitsuba as mi

from mi_npr import layers as L
from mi_npr.drawings import DRAWINGS
from mi_npr.integrator import NprIntegrator


class NprContoursIntegrator(NprIntegrator):
    """Apparent contours over a beauty render (see the module docstring for the manual)."""

    PLUGIN = "npr_contours"
    DRAWING = DRAWINGS["contours"]
    PARAMS = DRAWING.params

    def aov_names(self) -> list[str]:
        return [L.CONTOUR, *L.GBUFFER_AOVS, *L.RAW_RGB, *self.crypto_aovs()]


mi.register_integrator("npr_contours", lambda props: NprContoursIntegrator(props))

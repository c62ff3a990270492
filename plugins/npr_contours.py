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
   * - ``contour_model``
     - string
     - ``exact``
     - What draws the contours: ``exact``, traced on the pixel-centre ids (this page), or
       ``soft``, the object outlines of :func:`mi_npr.ad.soft_lines` (below), whose gradients
       under ``mi.render(scene, params=params)`` include outlines that move. ``soft`` takes
       ``line_width`` and ``color`` only (any other parameter set is an error) and needs an AD
       variant.
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

**The soft contour model** (``contour_model = 'soft'``): the first channel is
``contour_ink.V`` instead of ``contour.V``, the ink in [0, 1] of :func:`mi_npr.ad.soft_lines`
of the sensor at its film's size (no crop window) with its id feature alone
(``depth_weight = 0, normal_weight = 0``): every object's outline against the background and
against the other objects (apparent contours and occlusion boundaries between objects), 4 x 4
samples a pixel, a Gaussian filter of ``sigma = line_width / 2`` pixels, composited in
``color`` onto the raw beauty; nothing is traced (no ``contour.V``, no vector contours: the
``contours`` command writes no ``<stem>_contours.svg``), the object table's shapes are the
objects. ``dr.backward`` through ``mi.render(scene,
params=params)`` gives its interior terms (the samples' rays follow the camera and the shapes)
and boundary terms (the flux of each moving outline, from the front surface's image
velocity); topology changes and the image frame beyond the filter's margin are not covered
(:mod:`mi_npr.ad.visibility`). When only ``contour_ink.V`` receives gradients, the backward
pass differentiates the soft contours alone; a gradient on any other channel differentiates
the whole render (the G-buffer and beauty with the interior term only), as ``npr_lines``'s
soft model does.

XML::

    <integrator type="npr_contours">
        <string name="id_mode" value="component"/>
        <rgb name="color" value="1, 0, 0"/>
        <integrator type="path">
            <integer name="max_depth" value="8"/>
        </integrator>
    </integrator>

Differentiable contours, for ``mi.render(scene, params=params)`` and ``dr.backward``::

    <integrator type="npr_contours">
        <string name="contour_model" value="soft"/>
        <float name="line_width" value="2"/>
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
        first = L.CONTOUR_INK if self.params["contour_model"] == "soft" else L.CONTOUR
        return [first, *L.GBUFFER_AOVS, *L.RAW_RGB, *self.crypto_aovs()]


mi.register_integrator("npr_contours", lambda props: NprContoursIntegrator(props))

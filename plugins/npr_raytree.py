"""``npr_raytree``: Nehab-Gattass ray-tree signatures and classified ray-tree edges.

Every pixel's ray tree (paper, section 2.2.3) is traced deterministically: the object hit, the
lights visible from it (one shadow ray per emitter), and, below mirror-like surfaces (delta
reflection) a reflection child, below glass (delta transmission) also a refraction child, down to
``max_depth`` levels; rough and diffuse surfaces end a branch. The tree's 64-bit hash is written
as ``raytree_hi.V``/``raytree_lo.V``; trees at pixel corners are compared and each edge pixel is
classified as a real contour, a shadow, a reflection or a refraction edge. The classes are drawn
over the beauty: real red, reflection blue, refraction green, shadow gray.

.. list-table::
   :header-rows: 1

   * - Parameter
     - Type
     - Default
     - Meaning
   * - ``max_depth``
     - integer
     - 3
     - levels of the ray trees (1: primary hits only; 3: primary hits, their reflections and
       refractions, and those rays' own reflections and refractions)
   * - ``shadow_lights``
     - string
     - ``hard``
     - the lights whose shadows make ``edges.shadow``: ``hard`` (point, spot, directional),
       ``all``, or comma-separated light names / shell globs (see :mod:`mi_npr.raytree.lights`
       for the approximation of area and environment lights)
   * - ``id_mode``
     - string
     - ``shape``
     - what one object is for ``edges.real``: ``shape``, ``material`` or ``silhouette``
   * - ``only``, ``ignore``
     - string
     - ``""``
     - comma-separated shell globs on object names: edges only where a corner ray sees an
       object ``only`` matches (all if empty) and not ``ignore``
   * - ``line_width``
     - float
     - 1
     - width of the drawn edges in pixels (the ``edges.*`` layers stay 1 px)
   * - (nested integrator)
     - integrator
     - none
     - renders the beauty ``R G B`` under the overlay (``path``, ``direct``, ...); without one,
       a headlight diffuse shading

Lights (see :mod:`mi_npr.raytree.lights`): point and spot lights are tested at their position,
directional lights along their direction; with ``shadow_lights`` asking for them, area lights
at their shape's centre and an environment (``envmap``, ``constant``) as one light shining from
its zenith (+y).
Lights are numbered 1..K by name (their XML ``id``), objects by the stable object ids.

Channels after ``R G B`` (``aov_names()``):

========================  =======  ==========================================================
channel                   type     meaning
========================  =======  ==========================================================
``raytree_hi/lo.V``       uint32   64-bit hash of the pixel-centre tree (0: nothing hit)
``edges_real.V``          float32  1 where the corner trees' primary objects differ
``edges_reflection.V``    float32  1 where they first differ in reflection children
``edges_refraction.V``    float32  1 where they first differ in refraction children
``edges_shadow.V``        float32  1 where the objects agree but the visible lights differ
(G-buffer)                ...      ``Z P.X P.Y P.Z N.X N.Y N.Z object_id.V prim_id.V``
``beauty.R/G/B``          float32  the beauty before the overlay
========================  =======  ==========================================================

``R G B`` hold the beauty with the edge classes drawn over it. ``mi_npr.raytree.signature(scene,
x, y)`` returns the readable tree of one pixel (``"4A2BL1C"``).

XML::

    <integrator type="npr_raytree">
        <integer name="max_depth" value="3"/>
        <integrator type="path"/>
    </integrator>
"""

from __future__ import annotations

import mitsuba as mi

from mi_npr import layers as L
from mi_npr.drawings import DRAWINGS
from mi_npr.integrator import NprIntegrator
from mi_npr.raytree import LAYERS


class NprRayTreeIntegrator(NprIntegrator):
    """Ray-tree signatures and classified edges (see the module docstring for the manual)."""

    PLUGIN = "npr_raytree"
    DRAWING = DRAWINGS["raytree"]
    PARAMS = DRAWING.params

    def aov_names(self) -> list[str]:
        return [*LAYERS, *L.GBUFFER_AOVS, *L.RAW_RGB, *self.crypto_aovs()]


mi.register_integrator("npr_raytree", lambda props: NprRayTreeIntegrator(props))

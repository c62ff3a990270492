"""``npr_gbuffer``: exact per-pixel G-buffer AOVs beside a beauty render.

.. list-table::
   :header-rows: 1

   * - Parameter
     - Type
     - Default
     - Meaning
   * - (nested integrator)
     - integrator
     - none
     - Renders ``R G B`` at the film's filter and spp (``path``, ``direct``, ...). Without one,
       a headlight diffuse shading is shown so there is something to look at.

Every AOV comes from one ray through the exact centre of each pixel, never filtered or averaged,
whatever the film's ``rfilter`` and the sampler's spp:

===============  =======  =============================================================
channel          type     meaning
===============  =======  =============================================================
``Z``            float32  camera-space depth along the view axis, ``+inf`` on a miss
``P.X/Y/Z``      float32  world position of the hit (0 on a miss)
``N.X/Y/Z``      float32  world shading normal (0 on a miss)
``object_id.V``  uint32   0 = background, 1..N = shapes sorted by name (stable ids)
``prim_id.V``    uint32   triangle / primitive index within the shape
===============  =======  =============================================================

``mi.render(scene)`` returns (H, W, 12): ``R G B`` then the channels above in this order (ids as
float32). ``mi_npr.render(scene)`` returns a :class:`mi_npr.GBuffer` with the object table.

XML::

    <integrator type="npr_gbuffer">
        <integrator type="path">
            <integer name="max_depth" value="8"/>
        </integrator>
    </integrator>

Python::

    import mi_npr, mitsuba as mi
    scene = mi.load_dict({"type": "scene", "integrator": {"type": "npr_gbuffer",
                          "beauty": {"type": "path"}}, "ball": {"type": "sphere"}, ...})
    img = mi.render(scene)                 # (H, W, 12) tensor
    gb = mi_npr.render(scene)              # GBuffer: gb["Z"], gb["object_id.V"], gb.objects
"""

from __future__ import annotations

import mitsuba as mi

from mi_npr.integrator import NprIntegrator


class NprGBufferIntegrator(NprIntegrator):
    """Exact G-buffer AOVs (see the module docstring for the manual)."""

    PLUGIN = "npr_gbuffer"
    PARAMS = ()


mi.register_integrator("npr_gbuffer", lambda props: NprGBufferIntegrator(props))

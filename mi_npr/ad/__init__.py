"""Losses between line drawings for optimisation with Mitsuba's AD variants.

A rendered line image (the ``lines.V`` layer, coverage in [0, 1], a Dr.Jit tensor that keeps its
AD graph) is compared with a target drawing (:func:`read_drawing`: a PNG of dark ink on light
paper, or an SVG of paths). A plain L2 between two thin-line images has no gradient where the
lines do not overlap, so an optimiser far from the target sees nothing; the losses here give a
gradient everywhere:

- :func:`blurred_l2` (multi-scale): ``sum_s mean((G_s * r - G_s * t)^2) / len(scales)``, ``G_s``
  a Gaussian of standard deviation ``s`` pixels (separable, the border repeated), computed in
  Dr.Jit so gradients flow to ``r``. Wide scales pull from afar, narrow ones place the lines.
- :func:`chamfer` (one-sided): ``sum(r D_t) / sum(r)``, ``D_t`` the Euclidean distance (pixels)
  from each pixel to the target's nearest line pixel (ink above one half): the mean distance of
  the rendered ink to the target's lines, 0 when every inked pixel lies on them.

The rendered image with gradients from silhouettes and occlusion boundaries that move is
:func:`soft_lines` (:mod:`mi_npr.ad.visibility`: prefiltered multi-sample lines, interior and
boundary terms). :func:`fit_camera` finds the camera a drawing was made from and
:func:`fit_shape` an object's pose (:mod:`mi_npr.ad.fit`; commands ``mi-npr fit-camera`` and
``mi-npr fit-shape``).

Both losses take ``r`` as an (H, W) Dr.Jit tensor or array and ``t`` as an (H, W) array of the same
size; a drawing of another size is a :class:`~mi_npr.errors.ParameterError` naming both sizes.
"""

from __future__ import annotations

from .fit import CameraFit, ShapeFit, fit_camera, fit_shape, write_fit_camera, write_fit_shape
from .losses import blur, blurred_l2, chamfer, read_drawing
from .visibility import Pinhole, soft_lines

__all__ = [
    "CameraFit",
    "Pinhole",
    "ShapeFit",
    "blur",
    "blurred_l2",
    "chamfer",
    "fit_camera",
    "fit_shape",
    "read_drawing",
    "soft_lines",
    "write_fit_camera",
    "write_fit_shape",
]

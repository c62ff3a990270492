"""Scene understanding: viewpoint quality (eqs. 1-3 of the paper) and best-view search.

- :mod:`~mi_npr.viewpoint.measures`: eqs. 1-3 as pure functions of per-polygon projected areas,
  and the angle defects of a mesh (eq. 2);
- :mod:`~mi_npr.viewpoint.idbuffer`: the scene's polygons and the ID buffers of many viewpoints,
  rendered in one Dr.Jit launch and counted sparsely (one-sided back faces are background);
- :mod:`~mi_npr.viewpoint.search`: :func:`quality`, :func:`best_view` (the 8 spherical
  triangles, the allowed side of the up axis, the beam search), :func:`quality_map`;
- :mod:`~mi_npr.viewpoint.camera`: the best view as a Mitsuba ``<sensor>`` and the picture of
  the viewing sphere coloured by quality (matplotlib, the ``plots`` extra);
- :mod:`~mi_npr.viewpoint.outputs`: the files ``mi-npr best-view`` writes, and the warning for
  an empty or black best view.

>>> scene = mi_npr.load_scene("scenes_xml/scene4.xml")
>>> bv = mi_npr.viewpoint.best_view(scene, "entropy", depth=1, res=32)
>>> xml = mi_npr.viewpoint.sensor_xml(bv, scene)   # the file ``mi-npr best-view`` writes
>>> print(xml.splitlines()[4].strip())
<sensor type="perspective" id="best_view">
"""

from __future__ import annotations

from .camera import plots_missing, sensor_xml, sphere_image
from .idbuffer import areas, polygons, sparse_areas
from .measures import MEASURES, SparseAreas, curvature, entropy, pb, vertex_curvature
from .outputs import view_warning, write_best_view
from .search import BestView, best_view, qualities, quality, quality_map

__all__ = [
    "MEASURES",
    "BestView",
    "SparseAreas",
    "areas",
    "best_view",
    "curvature",
    "entropy",
    "pb",
    "plots_missing",
    "polygons",
    "qualities",
    "quality",
    "quality_map",
    "sensor_xml",
    "sparse_areas",
    "sphere_image",
    "vertex_curvature",
    "view_warning",
    "write_best_view",
]

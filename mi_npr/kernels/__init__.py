"""Image-space line kernels in Dr.Jit (LLVM backend): pure functions on (H, W) images.

Section 5.1 of the thesis, plus edges from the exact G-buffer:

- :func:`normalize_depth` -- camera depth ``Z`` to ``D`` in [0, 1] (0 near, 1 far/background);
- :func:`depth_contours` -- signed depth-difference contours, eq. 5.1;
- :func:`remove_isolated` -- isolated-pixel removal, eq. 5.2;
- :func:`selective_dilation` -- the depth pre-filter, eqs. 5.3-5.4;
- :func:`id_edges`, :func:`normal_edges` -- object-ID and normal edges (1 or 2 px);
- :func:`crease_edges` -- creases by dihedral angle (Freestyle's crease angle), 1 px;
- :func:`widen_lines`, :func:`ink_density` -- line width and ink density;
- :func:`leaf_edges` -- the outline of every leaf primitive (foliage, ``leaf_id`` layer);
- :func:`lines` -- the whole chain on a :class:`~mi_npr.gbuffer.GBuffer` (the ``lines`` layer).

Inputs are numpy arrays or Dr.Jit tensors, checked on entry (a
:class:`~mi_npr.errors.ParameterError` names the argument); results are evaluated
``TensorXf`` of the input's shape, on the backend of the first Dr.Jit input, else on the active
variant's (``drjit.cuda.ad`` for ``cuda_*``, else ``drjit.llvm.ad``); ``np.asarray`` gives numpy.
Kernels never read or write files and never see a scene.
"""

from __future__ import annotations

from .chain import LINES_PARAMS, lines
from .depth_lines import depth_contours, normalize_depth, remove_isolated
from .edges import crease_edges, id_edges, leaf_edges, normal_edges
from .ink import ink_density, widen_lines
from .morphology import selective_dilation

__all__ = [
    "LINES_PARAMS",
    "crease_edges",
    "depth_contours",
    "id_edges",
    "ink_density",
    "leaf_edges",
    "lines",
    "normal_edges",
    "normalize_depth",
    "remove_isolated",
    "selective_dilation",
    "widen_lines",
]

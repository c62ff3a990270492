"""Edges between ray trees, classified by where the trees differ (paper, section 2.2.3).

Nehab and Gattass cast one ray per pixel corner and compare trees; a pixel whose trees differ is
an edge pixel. Here pixel ``(x, y)`` of a W x H image is an edge pixel when the trees of its
four corners ``(x, y), (x + 1, y), (x, y + 1), (x + 1, y + 1)`` of the (W + 1) x (H + 1) corner
grid are not all equal (the paper's variant compares a pixel's lower-left-corner ray with its
three 4-neighbours'; four corners make the test symmetric and centred on the pixel).

Each edge pixel gets exactly one class, from the *shallowest* tree depth at which the four
corner trees do not all agree:

- depth 0, the primary hit's object differs: ``edges.real`` (a real contour);
- depth 0, same object, different visible lights: ``edges.shadow``;
- depth ``d >= 1`` (the trees agree above it): ``edges.reflection`` if the differing nodes at that
  depth are reflection children (even positions), ``edges.refraction`` if refraction children
  (odd positions). The class names the kind of the ray that reaches the differing node, so a
  refracted image seen in a mirror is ``refraction``, and a shadow seen in a mirror is
  ``reflection``: only a difference at the root is a shadow. A node present in some trees and
  absent from others (a reflection ray that misses) differs like any other.
- Tie: when reflection and refraction children differ at the same depth, ``edges.refraction``
  wins. Both children exist only under glass-like surfaces, whose transmitted image dominates
  at all but grazing angles (Fresnel), so the refracted difference is the one a viewer sees.

Nodes at one depth and of one kind are compared through the sum of their 64-bit keys
(:class:`~mi_npr.raytree.tracer.Trees`): equal node sets give equal sums, different ones differ
with probability 1 - 2**-64. The root's object and lights are compared exactly.
"""

from __future__ import annotations

from typing import Any

import drjit as dr
import mitsuba as mi

from .. import layers as L
from ..errors import ParameterError
from .tracer import Trees


def _differs(a: Any, tp: type, c: tuple[Any, Any, Any, Any]) -> Any:
    v0, v1, v2, v3 = (dr.gather(tp, a, i) for i in c)
    return (v0 != v1) | (v0 != v2) | (v0 != v3)


def classify_edges(corners: Trees, width: int, height: int) -> dict[str, Any]:
    """The four edge layers of a ``width`` x ``height`` image from the trees of its corner grid.

    ``corners`` holds (width + 1) * (height + 1) trees in row-major order (row 0 at the top).
    Returns ``{edges.real, edges.reflection, edges.refraction, edges.shadow}``: ``Float`` arrays
    of ``width * height`` values, 1 on the pixels of that class and 0 elsewhere (row-major).
    """
    if width < 1 or height < 1:
        raise ParameterError(f"image size {width} x {height}: must be at least 1 x 1")
    if corners.width != (width + 1) * (height + 1):
        raise ParameterError(
            f"{corners.width} corner trees for a {width} x {height} image: "
            f"expected {(width + 1) * (height + 1)}"
        )
    i = dr.arange(mi.UInt32, width * height)
    x, y = i % width, i // width
    c00 = y * (width + 1) + x
    c = (c00, c00 + 1, c00 + width + 1, c00 + width + 2)
    real = _differs(corners.root_obj, mi.UInt32, c)
    lights = dr.zeros(mi.Bool, width * height)
    for w in corners.root_lights:
        lights |= _differs(w, mi.UInt32, c)
    shadow = ~real & lights
    done = real | lights
    refl = dr.zeros(mi.Bool, width * height)
    refr = dr.zeros(mi.Bool, width * height)
    for sum_r, sum_t in corners.levels:
        dt = _differs(sum_t, mi.UInt64, c)
        dr_ = _differs(sum_r, mi.UInt64, c)
        refr |= ~done & dt
        refl |= ~done & ~dt & dr_
        done |= dt | dr_
    return {
        L.EDGES_REAL: mi.Float(real),
        L.EDGES_REFLECTION: mi.Float(refl),
        L.EDGES_REFRACTION: mi.Float(refr),
        L.EDGES_SHADOW: mi.Float(shadow),
    }


def any_corner(flags: Any, width: int, height: int) -> Any:
    """``Bool`` per pixel of a ``width`` x ``height`` image: one of its four corners (in the
    (width + 1) x (height + 1) corner grid ``flags``) is set."""
    i = dr.arange(mi.UInt32, width * height)
    c00 = (i // width) * (width + 1) + i % width
    out = dr.zeros(mi.Bool, width * height)
    for c in (c00, c00 + 1, c00 + width + 1, c00 + width + 2):
        out |= dr.gather(mi.Bool, flags, c)
    return out


def as_image(values: Any, width: int, height: int) -> Any:
    """A flat Dr.Jit array of ``width * height`` values as an (H, W) tensor (``TensorXu`` for
    integers, ``TensorXf`` otherwise; no copy, no host round trip)."""
    tensor = mi.TensorXu if dr.type_v(values) == dr.VarType.UInt32 else mi.TensorXf
    return tensor(values, shape=(height, width))

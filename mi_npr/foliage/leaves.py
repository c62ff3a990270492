"""Leaf primitives: the flat leaves drawn instead of a plant's own (thesis section 4.3).

"Rendering of leaf primitives instead of the original geometry ensures a controlled density of
geometric features and thus of silhouette edges, determined by the chosen leaf size." So
:func:`make_leaves` takes a ``leaf_size`` (the primitive's length, in scene units) and derives the
*number* of leaves from it, keeping the covered area constant:

    count = round(coverage * A / (a_shape * leaf_size^2)),

where ``A`` is the plant's total leaf area (placement ``"leaves"``) or the area of the HLP surface
(placements ``"surface"`` and ``"volume"``), and ``a_shape`` the area of the shape at length 1.

**Placement** (where the leaf centres are):

- ``"leaves"`` -- at the original leaves: a sample of them weighted by area (without replacement
  while there are fewer primitives than leaves; beyond that every leaf is used and the extra
  primitives are spread uniformly in a ball of the original leaf's half-length around it, not in
  its plane, where overlapping coplanar primitives would z-fight);
- ``"surface"`` -- about uniformly on the HLP implicit surface (points on the blobs' ellipsoids
  that no other blob buries, projected onto ``F = iso`` by Newton steps);
- ``"volume"`` -- uniformly inside the implicit surface.

**Orientation** (which way each leaf faces and points):

- ``"hlp"`` -- facing along the HLP normal at its centre, tilted at random by up to ``tilt``
  degrees, turned at random about it;
- ``"leaf"`` -- as the original leaf it sits on (placement ``"leaves"`` only);
- ``"van_gogh"`` -- the Van Gogh style: the long axis is perpendicular to ``d``, the direction from
  the leaf's HLP centre (the blob contributing most to the field at the leaf), and runs along the
  circles of latitude about the HLP's longest axis (``axis = a_long x d``, normalised), turned about
  ``d`` by up to ``tilt`` / 2 degrees (which keeps it perpendicular to ``d``); the leaf faces
  ``d`` tilted about its own axis by up to ``tilt`` degrees. Ambiguity resolved: the thesis only
  says "re-oriented around their HLP"; strokes circling the centre like latitude lines give the
  swirling look of Van Gogh's foliage and keep the long axis exactly perpendicular to ``d``;
- ``"random"`` -- uniformly random.

Every leaf is then turned so its front faces the outside of the HLP surface (``n . n_hlp >= 0``).

**Shapes** (:func:`leaf_template`, length 1 along +x, the leaf plane is xy, front = +z):
``"quad"`` (a unit square, 2 triangles), ``"disc"`` (12-gon, 12 triangles), ``"ellipse"``
(12-gon of width 0.4, 12 triangles), ``"leaf"`` (a built-in pointed leaf outline, 16 triangles),
or the path of an RGBA PNG: a *textured alpha leaf*. Its outline is traced from the alpha
channel (16 rays from the alpha's centroid, the farthest pixel with alpha >= 0.5 on each, so the
outline is the star-shaped hull of the leaf) and its UVs map the image onto the leaf, so a
``bitmap`` texture in the nested BSDF colours it. Ambiguity resolved: Mitsuba's ``mask`` BSDF
makes alpha a random null-scattering event that neither the exact pixel-centre G-buffer nor shadow
rays see, so lines would outline quads; baking the alpha into the outline keeps the beauty, the
G-buffer, the shadows and the lines in agreement.

**The mesh** (:meth:`Leaves.mesh`): ONE triangle mesh for all leaves (Mitsuba loads it as one
shape, fast), with UVs and the per-face leaf index (the ``face_leaf`` mesh attribute of the
``npr_leaves`` shape, which :func:`leaf_id_layer` turns into the ``leaf_id`` layer so the line
kernels can outline every leaf). Every leaf has the same number of triangles, in leaf order.
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass
from pathlib import Path

import mitsuba as mi
import numpy as np
from PIL import Image, UnidentifiedImageError

from .. import layers as L
from ..errors import InputError, ParameterError, check_input_file
from ..meshes import write_ply
from ..scene import object_table
from .hlp import HLPSet
from .plant import Plant, any_perpendicular, unit_rows

SHAPES = ("quad", "disc", "ellipse", "leaf")
PLACEMENTS = ("leaves", "surface", "volume")
ORIENTATIONS = ("hlp", "leaf", "van_gogh", "random")
#: Largest number of leaves make_leaves emits (float32 face attributes are exact to 2**24).
MAX_LEAVES = 4_000_000


@dataclass(frozen=True)
class LeafTemplate:
    """A leaf shape at length 1: ``xy`` (v, 2) outline (+x = long axis), ``faces`` (t, 3)
    counter-clockwise seen from +z (the leaf's front), ``uv`` (v, 2) texture coordinates."""

    name: str
    xy: np.ndarray
    faces: np.ndarray
    uv: np.ndarray

    @property
    def area(self) -> float:
        """Area at length 1."""
        a, b, c = (self.xy[self.faces[:, j]] for j in range(3))
        e1, e2 = b - a, c - a
        return float(0.5 * np.sum(e1[:, 0] * e2[:, 1] - e1[:, 1] * e2[:, 0]))

    @property
    def triangles(self) -> int:
        return len(self.faces)


def _fan(rim: np.ndarray, name: str) -> LeafTemplate:
    """A centre vertex plus a counter-clockwise ``rim``, triangulated as a fan."""
    n = len(rim)
    xy = np.concatenate([np.zeros((1, 2)), rim])
    faces = np.array([(0, 1 + i, 1 + (i + 1) % n) for i in range(n)], np.int64)
    return LeafTemplate(name, xy, faces, xy + 0.5)


def _leaf_outline(n_side: int = 7) -> np.ndarray:
    """A pointed leaf: base at x = -0.5, tip at x = +0.5, widest (0.44) before the middle."""
    t = (np.arange(1, n_side + 1) / (n_side + 1))[::-1]
    half = 0.22 * np.sin(np.pi * t) ** 0.8 * (1.25 - 0.5 * t)
    x = t - 0.5
    top = np.stack([x, half], axis=1)  # tip to base along the upper edge
    bottom = np.stack([x[::-1], -half[::-1]], axis=1)
    return np.concatenate([[[0.5, 0.0]], top, [[-0.5, 0.0]], bottom])


def _alpha_outline(path: Path, rays: int = 16) -> np.ndarray:
    """The star-shaped outline of an RGBA image's alpha (>= 0.5), in [-0.5, 0.5]^2 (+x = u)."""

    try:
        with Image.open(path) as im:
            if "A" not in im.getbands():
                raise InputError(f"{path}: a textured leaf needs an alpha channel (RGBA PNG)")
            alpha = np.asarray(im.getchannel("A"), np.float64) / 255.0
    except (OSError, UnidentifiedImageError) as e:
        raise InputError(f"{path}: cannot read the leaf image ({e})") from None
    h, w = alpha.shape
    ys, xs = np.nonzero(alpha >= 0.5)
    if len(xs) < 3:
        raise InputError(f"{path}: the alpha channel holds no leaf (no pixel with alpha >= 0.5)")
    # Pixel centres in uv: u = (x + 0.5) / w, v = 1 - (y + 0.5) / h (image rows go down).
    u, v = (xs + 0.5) / w, 1.0 - (ys + 0.5) / h
    cu, cv = u.mean(), v.mean()
    ang = np.arctan2(v - cv, u - cu)
    dist = np.hypot(u - cu, v - cv) + 0.5 / max(w, h)  # to the pixel's far edge
    sector = np.floor((ang + np.pi) / (2 * np.pi) * rays).astype(np.int64) % rays
    radius = np.zeros(rays)
    np.maximum.at(radius, sector, dist)
    theta = -np.pi + (np.arange(rays) + 0.5) * 2 * np.pi / rays
    radius = np.where(radius > 0, radius, np.median(radius[radius > 0]))
    rim = np.stack([cu + radius * np.cos(theta), cv + radius * np.sin(theta)], axis=1)
    return rim - 0.5


def leaf_template(shape: str | os.PathLike[str]) -> LeafTemplate:
    """The template of a shape name (:data:`SHAPES`) or of an RGBA PNG file (textured leaf)."""
    if shape == "quad":
        xy = np.array([[-0.5, -0.5], [0.5, -0.5], [0.5, 0.5], [-0.5, 0.5]])
        return LeafTemplate("quad", xy, np.array([[0, 1, 2], [0, 2, 3]]), xy + 0.5)
    phi = 2 * np.pi * np.arange(12) / 12
    if shape == "disc":
        return _fan(0.5 * np.stack([np.cos(phi), np.sin(phi)], axis=1), "disc")
    if shape == "ellipse":
        return _fan(np.stack([0.5 * np.cos(phi), 0.2 * np.sin(phi)], axis=1), "ellipse")
    if shape == "leaf":
        return _fan(_leaf_outline(), "leaf")
    p = Path(shape)
    if p.suffix.lower() == ".png":
        check_input_file(p)
        t = _fan(_alpha_outline(p), str(p))
        # Centre vertex at the outline's centre, uv = the image position of each vertex.
        rim = t.xy[1:]
        xy = np.concatenate([rim.mean(axis=0, keepdims=True), rim])
        return LeafTemplate(str(p), xy, t.faces, xy + 0.5)
    raise ParameterError(
        f"leaf_shape = {shape!r}: expected one of {', '.join(SHAPES)} or an RGBA .png file"
    )


@dataclass(frozen=True)
class Leaves:
    """Leaf primitives, one row each: ``centers``, ``normals`` (front), ``axes`` (long axis, unit,
    perpendicular to the normal), ``sizes`` (lengths), ``hlp`` (index of the leaf's HLP, -1 if
    none), and the shared ``template``."""

    centers: np.ndarray
    normals: np.ndarray
    axes: np.ndarray
    sizes: np.ndarray
    hlp: np.ndarray
    template: LeafTemplate

    def __len__(self) -> int:
        return len(self.centers)

    def mesh(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """``(V, F, UV, face_leaf)``: float32 (m*v, 3) positions, uint32 (m*t, 3) triangles,
        float32 (m*v, 2) texture coordinates, uint32 (m*t,) leaf index of every triangle."""
        t = self.template
        m, nv = len(self), len(t.xy)
        bitangent = np.cross(self.normals, self.axes)
        s = self.sizes[:, None, None]
        V = self.centers[:, None, :] + s * (
            t.xy[None, :, 0, None] * self.axes[:, None, :]
            + t.xy[None, :, 1, None] * bitangent[:, None, :]
        )
        F = t.faces[None] + (np.arange(m) * nv)[:, None, None]
        UV = np.broadcast_to(t.uv[None], (m, nv, 2))
        face_leaf = np.repeat(np.arange(m, dtype=np.uint32), t.triangles)
        return (
            V.reshape(-1, 3).astype(np.float32),
            F.reshape(-1, 3).astype(np.uint32),
            UV.reshape(-1, 2).astype(np.float32),
            face_leaf,
        )

    def save_ply(self, path: str | os.PathLike[str]) -> Path:
        """Write the leaf mesh as binary PLY with ``u v`` per vertex (atomic)."""
        V, F, UV, _ = self.mesh()
        return write_ply(path, V, F, {"u": UV[:, 0], "v": UV[:, 1]})


def _rotate(v: np.ndarray, k: np.ndarray, angle: np.ndarray) -> np.ndarray:
    """Rodrigues: rows of ``v`` rotated about unit rows ``k`` by ``angle`` (radians)."""
    c, s = np.cos(angle)[:, None], np.sin(angle)[:, None]
    return v * c + np.cross(k, v) * s + k * np.sum(k * v, axis=1, keepdims=True) * (1 - c)


def _random_unit(rng: np.random.Generator, n: int) -> np.ndarray:
    v, length = unit_rows(rng.normal(size=(n, 3)))
    v[length == 0] = [0.0, 1.0, 0.0]
    return v


def _spin(normals: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """A random unit axis in the plane of each normal."""
    t = any_perpendicular(normals)
    return _rotate(t, normals, rng.uniform(0, 2 * np.pi, len(normals)))


def _tilted(normals: np.ndarray, tilt_deg: float, rng: np.random.Generator) -> np.ndarray:
    """Each normal tilted by a random angle in [0, tilt] towards a random side."""
    side = _spin(normals, rng)
    angle = np.radians(tilt_deg) * np.sqrt(rng.random(len(normals)))
    return normals * np.cos(angle)[:, None] + side * np.sin(angle)[:, None]


def leaf_count(area: float, leaf_size: float, template: LeafTemplate, coverage: float) -> int:
    """How many leaves of length ``leaf_size`` cover ``coverage * area``."""
    if area <= 0:
        return 0
    return max(1, round(coverage * area / (template.area * leaf_size**2)))


def _check(name: str, value: float, ok: bool, rule: str) -> None:
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not ok:
        raise ParameterError(f"{name} = {value!r}: {rule}")


def make_leaves(
    hlps: HLPSet | None,
    plant: Plant | None = None,
    leaf_size: float = 0.1,
    shape: str = "quad",
    placement: str = "surface",
    orientation: str = "hlp",
    coverage: float = 1.0,
    tilt: float = 25.0,
    seed: int = 0,
    max_leaves: int = 1_000_000,
) -> Leaves:
    """Leaf primitives for a plant and/or its HLPs (see the module docstring for every rule).

    An empty plant or empty HLPs give an empty :class:`Leaves` (no error); a leaf size so small
    that more than ``max_leaves`` would be needed is a :class:`ParameterError` naming both.

    >>> from mi_npr.foliage import procedural_tree, build_hlps
    >>> plant = procedural_tree(seed=0, n_leaves=300)
    >>> leaves = make_leaves(build_hlps(plant, k=6), plant, leaf_size=0.2)
    >>> len(leaves) > 0
    True
    """
    _check("leaf_size", leaf_size, math.isfinite(leaf_size) and leaf_size > 0, "must be > 0")
    _check("coverage", coverage, math.isfinite(coverage) and coverage > 0, "must be > 0")
    _check("tilt", tilt, 0 <= tilt <= 90, "must lie in [0, 90] degrees")
    if placement not in PLACEMENTS:
        raise ParameterError(f"placement = {placement!r}: expected one of {', '.join(PLACEMENTS)}")
    if orientation not in ORIENTATIONS:
        raise ParameterError(
            f"orientation = {orientation!r}: expected one of {', '.join(ORIENTATIONS)}"
        )
    if placement == "leaves" and plant is None:
        raise ParameterError("placement = 'leaves' needs the plant")
    if orientation == "leaf" and placement != "leaves":
        raise ParameterError("orientation = 'leaf' needs placement = 'leaves'")
    template = leaf_template(shape)
    rng = np.random.default_rng(seed)
    empty_hlps = hlps is None or not len(hlps)
    if placement == "leaves":
        area = plant.total_area if plant is not None else 0.0
    else:
        area = 0.0 if empty_hlps else hlps.surface_area(seed)  # type: ignore[union-attr]
    m = leaf_count(area, leaf_size, template, coverage)
    if m > min(max_leaves, MAX_LEAVES):
        raise ParameterError(
            f"leaf_size = {leaf_size!r} needs {m} leaves to cover the foliage "
            f"(max_leaves = {min(max_leaves, MAX_LEAVES)}): choose larger leaves"
        )
    needs_hlps = placement != "leaves" or orientation in ("hlp", "van_gogh")
    if m == 0 or (needs_hlps and empty_hlps):
        z = np.zeros((0, 3))
        return Leaves(z, z, z, np.zeros(0), np.zeros(0, np.int64), template)

    src = None
    if placement == "leaves":
        assert plant is not None
        n = len(plant)
        p = plant.areas / plant.areas.sum()
        if m <= n:
            src = rng.choice(n, m, replace=False, p=p)
            P = plant.centers[src].copy()
        else:  # every leaf, plus extra primitives in a small cloud around their leaf
            src = np.concatenate([np.arange(n), rng.choice(n, m - n, p=p)])
            radius = 0.5 * plant.sizes[src] * rng.random(m) ** (1 / 3)  # uniform in the ball
            off = _random_unit(rng, m) * radius[:, None]
            off[:n] = 0.0
            P = plant.centers[src] + off
    elif placement == "surface":
        P = hlps.sample_surface(m, rng)  # type: ignore[union-attr]
    else:
        P = hlps.sample_volume(m, rng)  # type: ignore[union-attr]
    m = len(P)

    n_hlp = hlps.normal(P) if not empty_hlps else np.zeros((m, 3))  # type: ignore[union-attr]
    which = hlps.dominant(P) if not empty_hlps else np.full(m, -1)  # type: ignore[union-attr]
    undefined = np.linalg.norm(n_hlp, axis=1) < 0.5
    if orientation == "leaf":
        assert plant is not None and src is not None
        N, A = plant.normals[src].copy(), plant.axes[src].copy()
    elif orientation == "random":
        N = _random_unit(rng, m)
        A = _spin(N, rng)
    elif orientation == "hlp":
        base = np.where(undefined[:, None], _random_unit(rng, m), n_hlp)
        N = _tilted(base, tilt, rng)
        A = _spin(N, rng)
    else:  # van_gogh
        assert hlps is not None
        d, dl = unit_rows(P - hlps.centers[which])
        d = np.where(dl[:, None] > 1e-9, d, np.where(undefined[:, None], [[0.0, 1.0, 0.0]], n_hlp))
        order = np.argsort(-hlps.radii[which], axis=1)
        longest = hlps.axes[which, order[:, 0]]
        A, al = unit_rows(np.cross(longest, d))
        alt, _ = unit_rows(np.cross(hlps.axes[which, order[:, 1]], d))
        A = np.where(al[:, None] > 1e-3, A, alt)
        A = _rotate(A, d, np.radians(tilt / 2) * rng.uniform(-1, 1, m))
        N = _rotate(d, A, np.radians(tilt) * rng.uniform(-1, 1, m))
    # Leaves face the outside of the HLP surface.
    flip = np.sum(N * n_hlp, axis=1) < 0
    N[flip] = -N[flip]
    # Exact frames: axis in the leaf plane, unit.
    N, _ = unit_rows(N)
    A = A - np.sum(A * N, axis=1, keepdims=True) * N
    A, al = unit_rows(A)
    A[al < 1e-9] = any_perpendicular(N[al < 1e-9])
    sizes = np.full(m, float(leaf_size))
    return Leaves(P, N, A, sizes, which.astype(np.int64), template)


def leaf_id_layer(scene: object, gbuffer: object) -> np.ndarray:
    """The ``leaf_id`` layer: for pixels of a mesh with a ``face_leaf`` attribute (the
    ``npr_leaves`` shape), ``1 +`` the leaf index, offset per shape so ids are unique across the
    scene's leaf meshes (shapes in object-id order); 0 on every other pixel.

    Derived from the G-buffer's exact ``object_id`` and ``prim_id`` (no second render).
    """

    ids = np.asarray(gbuffer[L.OBJECT_ID])  # type: ignore[index]
    prim = np.asarray(gbuffer[L.PRIM_ID])  # type: ignore[index]
    out = np.zeros(ids.shape, np.uint32)
    offset = 0
    table = object_table(scene)  # type: ignore[arg-type]
    for oid in sorted(table.shapes):
        shape = table.shapes[oid]
        if not (isinstance(shape, mi.Mesh) and bool(np.all(shape.has_attribute("face_leaf")))):
            continue
        lut = np.asarray(mi.traverse(shape)["face_leaf"], np.float64).astype(np.uint32)
        if not len(lut):
            continue
        mask = ids == oid
        out[mask] = lut[np.minimum(prim[mask], len(lut) - 1)] + np.uint32(offset + 1)
        offset += int(lut.max()) + 1
    return out

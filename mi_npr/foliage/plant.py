"""Input foliage: a plant as a list of leaves (centre, normal, long axis, length, area).

Thesis section 4.3 replaces the original leaves by *leaf primitives* and abstracts them by
*higher-level primitives*; both only need to know where each original leaf is, which way it faces,
how long it is and how much area it covers. A :class:`Plant` holds exactly that, one row per leaf,
plus an optional ``wood`` mesh (trunk and branches, drawn as it is).

Where plants come from:

- a triangle mesh (PLY or OBJ) whose leaves are its connected components (``leaves="components"``,
  the default: leaves that share no vertex with each other) or its single triangles
  (``leaves="triangles"``), see :meth:`Plant.from_mesh`;
- a point set with normals (a PLY with ``nx ny nz`` and no faces), one leaf per point, optionally
  with ``size`` (leaf length), ``area`` and ``ax ay az`` (long axis); this is also the format
  :meth:`Plant.save` writes, so a plant round-trips exactly (to float32);
- :func:`mi_npr.foliage.procedural_tree` (seeded, nothing to download).

Per leaf, from a mesh component: ``area`` = sum of its triangle areas; ``center`` = area-weighted
centroid; ``normal`` = the normalised area-weighted sum of its triangle normals (the mean plane of
a folded leaf); ``axis`` = the principal direction of its vertices projected into that plane;
``size`` = the extent of its vertices along ``axis`` (the leaf's length). Components whose area is
zero are dropped (they have no normal). Ambiguity resolved: a leaf's "size" could be its length,
its width or its area; mi-npr uses the *length* along the long axis everywhere (``leaf_size`` of
the leaf primitives means the same), and ``area`` separately, so covered area can be kept
constant.

Validation: non-finite coordinates are an :class:`~mi_npr.errors.InputError` naming the file and
how many values are bad; a plant with no leaves is valid and empty (``len(plant) == 0``); the
functions that need leaves say so with a clear error.
"""

from __future__ import annotations

import os
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..errors import InputError, ParameterError, check_input_file
from ..meshes import face_components, read_ply, write_ply

LEAF_MODES = ("components", "triangles")

#: Per-vertex properties of the point-set PLY that :meth:`Plant.save` writes.
_POINT_PROPS = ("nx", "ny", "nz", "ax", "ay", "az", "size", "area")


def unit_rows(v: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Rows of ``v`` normalised, and their original lengths (0 rows stay 0)."""
    n = np.linalg.norm(v, axis=-1)
    safe = np.where(n > 0, n, 1.0)
    return v / safe[..., None], n


def any_perpendicular(n: np.ndarray) -> np.ndarray:
    """A unit vector perpendicular to each unit row of ``n`` (deterministic)."""
    helper = np.where(np.abs(n[:, 1:2]) < 0.9, [[0.0, 1.0, 0.0]], [[1.0, 0.0, 0.0]])
    t, _ = unit_rows(np.cross(n, helper))
    return t


def _check_finite(name: str, what: str, a: np.ndarray) -> None:
    bad = ~np.isfinite(a)
    if bad.any():
        rows = int(np.count_nonzero(bad.reshape(len(a), -1).any(axis=1)))
        raise InputError(f"{name}: {rows} {what} have non-finite (NaN or inf) values")


@dataclass(frozen=True)
class Plant:
    """A plant's leaves, one row each (float64 arrays), and an optional wood mesh.

    ``centers`` (n, 3), ``normals`` (n, 3) unit, ``axes`` (n, 3) unit and perpendicular to the
    normals, ``sizes`` (n,) leaf lengths > 0, ``areas`` (n,) leaf areas > 0. ``wood`` is ``(V, F)``
    or ``None``. Build one with :meth:`from_mesh`, :meth:`from_points`, :func:`read_plant` or
    :func:`~mi_npr.foliage.procedural_tree`; all arrays are checked on construction.
    """

    centers: np.ndarray
    normals: np.ndarray
    axes: np.ndarray
    sizes: np.ndarray
    areas: np.ndarray
    wood: tuple[np.ndarray, np.ndarray] | None = field(default=None, repr=False)
    name: str = "plant"

    def __post_init__(self) -> None:
        n = len(np.asarray(self.centers).reshape(-1, 3))
        for attr, cols in (("centers", 3), ("normals", 3), ("axes", 3), ("sizes", 0), ("areas", 0)):
            a = np.asarray(getattr(self, attr), dtype=np.float64)
            a = a.reshape(-1, cols) if cols else a.reshape(-1)
            if len(a) != n:
                raise ParameterError(f"{self.name}: {attr} has {len(a)} rows, centers has {n}")
            _check_finite(self.name, f"leaf {attr}", a)
            a.setflags(write=False)
            object.__setattr__(self, attr, a)
        if n and (np.any(self.sizes <= 0) or np.any(self.areas <= 0)):
            raise ParameterError(f"{self.name}: leaf sizes and areas must be > 0")
        if n and np.any(np.abs(np.linalg.norm(self.normals, axis=1) - 1) > 1e-3):
            raise ParameterError(f"{self.name}: leaf normals must be unit vectors")
        if self.wood is not None:
            V = np.asarray(self.wood[0], np.float32).reshape(-1, 3)
            F = np.asarray(self.wood[1], np.uint32).reshape(-1, 3)
            _check_finite(self.name, "wood vertices", V)
            object.__setattr__(self, "wood", (V, F) if len(F) else None)

    def __len__(self) -> int:
        return len(self.centers)

    @property
    def total_area(self) -> float:
        return float(self.areas.sum())

    def bbox(self) -> tuple[np.ndarray, np.ndarray]:
        """Axis-aligned bounds of the leaves (each leaf counted as a ball of its size), and wood."""
        if not len(self) and self.wood is None:
            return np.zeros(3), np.zeros(3)
        lo, hi = [], []
        if len(self):
            r = self.sizes[:, None] / 2
            lo.append((self.centers - r).min(axis=0))
            hi.append((self.centers + r).max(axis=0))
        if self.wood is not None:
            lo.append(self.wood[0].min(axis=0))
            hi.append(self.wood[0].max(axis=0))
        return np.min(lo, axis=0), np.max(hi, axis=0)

    # ------------------------------------------------------------------ constructors
    @classmethod
    def from_points(
        cls,
        points: np.ndarray,
        normals: np.ndarray,
        sizes: np.ndarray | float | None = None,
        axes: np.ndarray | None = None,
        areas: np.ndarray | None = None,
        name: str = "plant",
    ) -> Plant:
        """One leaf per point. ``sizes`` default: ``(bounding-box volume / n) ** (1/3)`` (a rough
        spacing); ``axes`` default: any direction in the leaf plane; ``areas`` default:
        ``0.5 * size**2`` (a leaf about half as wide as long)."""
        P = np.asarray(points, dtype=np.float64).reshape(-1, 3)
        _check_finite(name, "points", P)
        N = np.asarray(normals, dtype=np.float64).reshape(-1, 3)
        if len(N) != len(P):
            raise InputError(f"{name}: {len(P)} points but {len(N)} normals")
        _check_finite(name, "normals", N)
        N, length = unit_rows(N)
        if np.any(length == 0):
            raise InputError(f"{name}: {int(np.sum(length == 0))} points have a zero normal")
        if sizes is None:
            ext = np.ptp(P, axis=0) if len(P) else np.zeros(3)
            vol = float(np.prod(np.maximum(ext, 1e-3 * max(float(ext.max()), 1e-9))))
            sizes = (vol / max(len(P), 1)) ** (1 / 3) if len(P) else 1.0
        S = np.broadcast_to(np.asarray(sizes, dtype=np.float64), (len(P),)).copy()
        if axes is None:
            A = any_perpendicular(N)
        else:
            A = np.asarray(axes, dtype=np.float64).reshape(-1, 3)
            _check_finite(name, "leaf axes", A)
            A = A - np.sum(A * N, axis=1, keepdims=True) * N  # into the leaf plane
            A, alen = unit_rows(A)
            A[alen < 1e-9] = any_perpendicular(N[alen < 1e-9])
        ar = 0.5 * S**2 if areas is None else np.asarray(areas, np.float64).reshape(-1)
        return cls(P, N, A, S, ar, None, name)

    @classmethod
    def from_mesh(
        cls,
        V: np.ndarray,
        F: np.ndarray,
        leaves: str = "components",
        name: str = "plant",
    ) -> Plant:
        """Leaves from a triangle mesh: its connected components or its single triangles."""
        if leaves not in LEAF_MODES:
            raise ParameterError(f"leaves = {leaves!r}: expected one of {', '.join(LEAF_MODES)}")
        V = np.asarray(V, dtype=np.float64).reshape(-1, 3)
        F = np.asarray(F, dtype=np.int64).reshape(-1, 3)
        _check_finite(name, "vertices", V)
        if F.size and (F.min() < 0 or F.max() >= len(V)):
            raise InputError(f"{name}: a face refers to a vertex that does not exist")
        if not len(F):
            z = np.zeros((0, 3))
            return cls(z, z, z, np.zeros(0), np.zeros(0), None, name)
        if leaves == "components":
            label = face_components(F)  # leaves share vertices by index: no welding
        else:
            label = np.arange(len(F))
        return _leaves_from_faces(V, F, label, name)

    def save(self, path: str | os.PathLike[str]) -> Path:
        """Write the leaves as a point-set PLY (x y z nx ny nz ax ay az size area, float32), atomic.

        The wood mesh is not included (save it with :func:`mi_npr.meshes.write_ply`).
        """
        attrs = dict(zip(_POINT_PROPS[:3], self.normals.T, strict=True))
        attrs.update(zip(_POINT_PROPS[3:6], self.axes.T, strict=True))
        attrs.update(size=self.sizes, area=self.areas)
        return write_ply(path, self.centers, np.zeros((0, 3), np.uint32), attrs)


def _leaves_from_faces(V: np.ndarray, F: np.ndarray, label: np.ndarray, name: str) -> Plant:
    """Per-label leaf records (see the module docstring for the formulas)."""
    p0, p1, p2 = V[F[:, 0]], V[F[:, 1]], V[F[:, 2]]
    cross = np.cross(p1 - p0, p2 - p0)
    tri_area = 0.5 * np.linalg.norm(cross, axis=1)
    c = label.max() + 1
    area = np.bincount(label, tri_area, minlength=c)
    cen = (p0 + p1 + p2) / 3
    center = np.stack([np.bincount(label, tri_area * cen[:, i], c) for i in range(3)], axis=1)
    keep = area > 0
    center[keep] /= area[keep, None]
    nsum = np.stack([np.bincount(label, cross[:, i], c) for i in range(3)], axis=1)
    normal, nlen = unit_rows(nsum)
    keep &= nlen > 0
    # Principal in-plane direction of each leaf's vertices (per-face vertex triples, so a vertex
    # shared by several faces counts several times: harmless for the direction).
    vl = np.repeat(label, 3)
    pts = np.stack([p0, p1, p2], axis=1).reshape(-1, 3) - center[vl]
    pts -= np.sum(pts * normal[vl], axis=1, keepdims=True) * normal[vl]
    cov = np.zeros((c, 3, 3))
    np.add.at(cov, vl, pts[:, :, None] * pts[:, None, :])
    _, vecs = np.linalg.eigh(cov)
    axis = vecs[:, :, 2]
    bad = np.linalg.norm(axis, axis=1) < 0.5
    axis[bad] = any_perpendicular(normal[bad])
    along = np.sum(pts * axis[vl], axis=1)
    hi = np.full(c, -np.inf)
    lo = np.full(c, np.inf)
    np.maximum.at(hi, vl, along)
    np.minimum.at(lo, vl, along)
    size = hi - lo
    keep &= size > 0
    return Plant(center[keep], normal[keep], axis[keep], size[keep], area[keep], None, name)


def read_obj(path: str | os.PathLike[str]) -> tuple[np.ndarray, np.ndarray, np.ndarray | None]:
    """``(V, F, N)`` of a Wavefront OBJ: ``v`` positions, ``f`` polygons (fanned into triangles,
    negative indices allowed, ``v/vt/vn`` forms read by their first index), and the ``vn``
    normals of the vertices when the file has one ``vn`` per ``v`` and no faces (a point set).

    Not Mitsuba's ``obj`` loader: (3.9.1) it rejects negative indices, loads a point set as an
    empty mesh, and splits a vertex that faces use with different ``vt``/``vn``, which would cut
    a leaf into separate components."""
    p = Path(path)
    check_input_file(p)
    verts: list[list[float]] = []
    normals: list[list[float]] = []
    tris: list[tuple[int, int, int]] = []
    try:
        text = p.read_text(encoding="utf-8", errors="replace")
        for lineno, line in enumerate(text.splitlines(), 1):
            t = line.split()
            if not t or t[0].startswith("#"):
                continue
            if t[0] in ("v", "vn"):
                if len(t) < 4:
                    raise ValueError(f"line {lineno}: {t[0]!r} needs 3 coordinates")
                (verts if t[0] == "v" else normals).append([float(x) for x in t[1:4]])
            elif t[0] == "f":
                idx = []
                for tok in t[1:]:
                    k = int(tok.split("/")[0])
                    idx.append(k - 1 if k > 0 else len(verts) + k)
                    if not 0 <= idx[-1] < len(verts):
                        raise ValueError(f"line {lineno}: vertex {k} does not exist")
                if len(idx) < 3:
                    raise ValueError(f"line {lineno}: a face needs 3 vertices")
                tris += [(idx[0], idx[j], idx[j + 1]) for j in range(1, len(idx) - 1)]
    except ValueError as e:
        raise InputError(f"{p}: malformed OBJ ({e})") from None
    V = np.asarray(verts, dtype=np.float64).reshape(-1, 3)
    F = np.asarray(tris, dtype=np.int64).reshape(-1, 3)
    N = None
    if not len(F) and normals and len(normals) == len(verts):
        N = np.asarray(normals, dtype=np.float64).reshape(-1, 3)
    return V, F, N


def read_plant(path: str | os.PathLike[str], leaves: str = "components") -> Plant:
    """A :class:`Plant` from a PLY or OBJ file (mesh of leaves, or point set with normals).

    Errors (missing file, unknown format, NaN coordinates, a point set without normals) are one-line
    :class:`~mi_npr.errors.InputError` naming the file. A file without leaves gives an empty plant.
    """
    p = Path(path)
    name = str(p)
    suffix = p.suffix.lower()
    if suffix == ".ply":
        V, F, extra = read_ply(p)
        N = None
        if all(k in extra for k in ("nx", "ny", "nz")):
            N = np.stack([extra["nx"], extra["ny"], extra["nz"]], axis=1)
        if len(F):
            return Plant.from_mesh(V, F, leaves, name)
        if N is None:
            if not len(V):
                return Plant.from_mesh(V, F, leaves, name)
            raise InputError(f"{p}: a point set needs normals (nx ny nz) to make leaves")
        axes = None
        if all(k in extra for k in ("ax", "ay", "az")):
            axes = np.stack([extra["ax"], extra["ay"], extra["az"]], axis=1)
        return Plant.from_points(V, N, extra.get("size"), axes, extra.get("area"), name)
    if suffix == ".obj":
        V, F, N = read_obj(p)
        if len(F) or not len(V):
            return Plant.from_mesh(V, F, leaves, name)
        if N is None:
            raise InputError(f"{p}: a point set needs normals (one vn per v) to make leaves")
        return Plant.from_points(V, N, name=name)
    raise InputError(f"{p}: unknown plant format {p.suffix!r} (expected .ply or .obj)")

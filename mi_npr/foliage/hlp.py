"""Higher-level primitives (HLPs): ellipsoid blobs whose summed field is a smooth implicit surface.

Thesis section 4.3: the foliage is abstracted by a few HLPs; the normal of the implicit surface
they generate replaces (or is mixed into) the normals of the leaf primitives, so the lighting
loses its leaf-level detail (Fig. 4.8, 4.9), and the HLP centres organise the "Van Gogh" leaves.

**The field.** HLP ``i`` has a centre ``c_i``, three orthonormal axes ``a_i1..a_i3`` (the rows of
``axes[i]``), radii ``r_i1..r_i3`` along them, and a weight ``w_i``. With the ellipsoidal distance

    q_i(p) = sum_j ((p - c_i) . a_ij / r_ij)^2  =  (p - c_i)^T M_i (p - c_i),
    M_i = A_i^T diag(1 / r_i^2) A_i,

the field is a sum of Gaussian blobs (Blinn's "blobby" model):

    F(p) = sum_i w_i exp(-q_i(p) / 2),

and the surface is the iso-surface ``F(p) = T`` with ``T = exp(-1/2)`` (:data:`ISO`): a lone blob
of weight 1 has exactly its ellipsoid (``q = 1``) as surface, and nearby blobs melt into one smooth
surface. ``F`` grows towards the centres, so the *outward* normal is the normalised negative
gradient, in closed form::

    grad F(p) = -sum_i w_i exp(-q_i(p) / 2) M_i (p - c_i),    n_hlp(p) = -grad F / |grad F|.

:meth:`HLPSet.normal` (numpy) and :func:`field_normal` (Dr.Jit, used by the ``npr_foliage`` BSDF
at every hit point) evaluate ``n_hlp`` with the blobs' exponents shifted by their maximum (the
direction does not change when every term is scaled by the same factor), so it stays defined far
from every blob where ``F`` itself underflows; it is undefined (returned as 0) only where the
gradient truly vanishes, such as the centre of a lone blob.

**Building HLPs** (:func:`build_hlps`): k-means on the leaf centres (scipy's ``kmeans2``, k-means++
seeding from ``seed``; ``k`` given, or chosen from a target HLP radius as the number of occupied
grid cells of side ``2 * radius``); each cluster becomes a blob with its mean as centre and the
eigenvectors of its covariance as axes; radii ``r_j = sqrt(5 * lambda_j)`` (a solid ellipsoid of
radius ``R`` has variance ``R^2 / 5`` along each axis), floored at the mean leaf length and at
``0.35 *`` the cluster's largest radius so flat clusters do not become pancakes; weights 1.
Overlapping Gaussian blobs inflate the union (where ``n`` equal blobs overlap, the surface lies at
``q = 1 + 2 ln n``), so finally all radii are scaled by one common factor, found by bisection, such
that the fraction ``inside`` (default 0.9) of the leaf centres lies inside the surface: the surface
is the crown's envelope. Ambiguity resolved: the thesis builds HLPs by hand or from the plant's
structure; here they come from clustering the leaves, and k-means on leaf positions is the
simplest deterministic choice. Empty clusters are dropped, so ``len(hlps)`` can be below ``k``
when leaves coincide.

**Data.** An :class:`HLPSet` is plain numpy data: inspect it, edit it (``dataclasses.replace``),
save/load it as JSON (:meth:`HLPSet.save`, :meth:`HLPSet.load`)::

    {"format": "mi-npr/hlps", "version": 1, "iso": 0.6065306597126334,
     "hlps": [{"center": [x, y, z], "radii": [r1, r2, r3],
               "axes": [[...], [...], [...]], "weight": 1.0}, ...]}
"""

from __future__ import annotations

import hashlib
import json
import math
import os
import warnings
from dataclasses import dataclass, replace
from functools import cached_property
from pathlib import Path
from typing import Any

import drjit as dr
import mitsuba as mi
import numpy as np

from ..errors import InputError, ParameterError, check_input_file
from ..io._atomic import atomic_output
from ..params import MAX_HLPS, Param, check_arg, integer_range
from .plant import Plant

#: The number of HLPs asked for (at most MAX_HLPS; k-means keeps at most one per leaf).
HLPS = Param(
    "hlps",
    int,
    None,
    "number of HLPs (default: one per cell of leaves)",
    integer_range(1, MAX_HLPS),
)

#: The iso-value of the surface: a lone blob of weight 1 has its ellipsoid as surface.
ISO = math.exp(-0.5)
FORMAT = "mi-npr/hlps"
#: Floats per blob in :meth:`HLPSet.packed`: centre (3), M (xx xy xz yy yz zz), log weight.
PACKED = 10
_CHUNK = 1 << 16  # points per block in the numpy evaluations (bounds memory at (chunk, k))
_GRID_VERTICES = 1_000_000  # most vertices of the grid that finds the surface's cells


def _orthonormal(name: str, axes: np.ndarray) -> np.ndarray:
    """The nearest orthonormal rows (polar decomposition); error if singular. Rows that are
    already orthonormal are kept bit for bit (so JSON round trips are exact)."""
    if np.all(np.abs(axes @ np.swapaxes(axes, 1, 2) - np.eye(3)) < 1e-12):
        return axes
    u, s, vt = np.linalg.svd(axes)
    if np.any(s < 1e-6 * np.maximum(s.max(axis=-1, keepdims=True), 1e-300)):
        raise ParameterError(f"{name}: HLP axes must be 3 independent directions")
    return u @ vt


#: Surface areas already estimated, by (geometry digest, seed, samples).
_AREAS: dict[tuple[str, int, int], float] = {}
#: The estimate's default seed and sample count (the one a saved file records).
AREA_SEED, AREA_SAMPLES = 0, 100_000


@dataclass(frozen=True)
class HLPSet:
    """``k`` ellipsoid blobs and the iso-value of their summed field (see the module docstring).

    ``centers`` (k, 3), ``radii`` (k, 3) > 0, ``axes`` (k, 3, 3) with the blob's unit axes as rows
    (re-orthonormalised on construction), ``weights`` (k,) > 0, ``iso`` > 0.
    """

    centers: np.ndarray
    radii: np.ndarray
    axes: np.ndarray
    weights: np.ndarray
    iso: float = ISO
    name: str = "hlps"

    def __post_init__(self) -> None:
        c = np.asarray(self.centers, np.float64).reshape(-1, 3)
        k = len(c)
        r = np.asarray(self.radii, np.float64).reshape(k, 3) if k else np.zeros((0, 3))
        a = np.asarray(self.axes, np.float64).reshape(k, 3, 3) if k else np.zeros((0, 3, 3))
        w = np.asarray(self.weights, np.float64).reshape(k) if k else np.zeros(0)
        for what, arr in (("centers", c), ("radii", r), ("axes", a), ("weights", w)):
            if not np.all(np.isfinite(arr)):
                raise ParameterError(f"{self.name}: HLP {what} hold NaN or inf")
        if np.any(r <= 0) or np.any(w <= 0):
            raise ParameterError(f"{self.name}: HLP radii and weights must be > 0")
        if not (math.isfinite(self.iso) and self.iso > 0):
            raise ParameterError(f"{self.name}: iso = {self.iso!r} must be > 0")
        if k:
            a = _orthonormal(self.name, a)
        for attr, arr in (("centers", c), ("radii", r), ("axes", a), ("weights", w)):
            arr.setflags(write=False)
            object.__setattr__(self, attr, arr)
        object.__setattr__(self, "iso", float(self.iso))

    def __len__(self) -> int:
        return len(self.centers)

    # ------------------------------------------------------------------ the field
    def metrics(self) -> np.ndarray:
        """``M_i = A_i^T diag(1 / r_i^2) A_i`` (k, 3, 3)."""
        return np.einsum("kji,kj,kjl->kil", self.axes, 1.0 / self.radii**2, self.axes)

    def _terms(self, P: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Per point and blob: ``log(w_i) - q_i / 2`` (n, k) and ``M_i (p - c_i)`` (n, k, 3)."""
        d = P[:, None, :] - self.centers[None]
        md = np.einsum("kij,nkj->nki", self.metrics(), d)
        q = np.sum(d * md, axis=-1)
        return np.log(self.weights)[None] - 0.5 * q, md

    def _blocks(self, P: np.ndarray, fn: Any, width: int) -> np.ndarray:
        P = np.asarray(P, np.float64).reshape(-1, 3)
        out = np.zeros((len(P), width) if width else len(P))
        if not len(self):
            return out
        for s in range(0, len(P), _CHUNK):
            out[s : s + _CHUNK] = fn(P[s : s + _CHUNK])
        return out

    def field(self, P: np.ndarray) -> np.ndarray:
        """``F(p)`` for each row of ``P`` (n, 3) -> (n,)."""
        return self._blocks(P, lambda p: np.exp(self._terms(p)[0]).sum(axis=1), 0)

    def gradient(self, P: np.ndarray) -> np.ndarray:
        """``grad F(p)`` in closed form, (n, 3)."""

        def g(p: np.ndarray) -> np.ndarray:
            lw, md = self._terms(p)
            return -np.einsum("nk,nki->ni", np.exp(lw), md)

        return self._blocks(P, g, 3)

    def normal(self, P: np.ndarray) -> np.ndarray:
        """Outward unit normal ``-grad F / |grad F|`` (n, 3); 0 where the gradient vanishes."""

        def n(p: np.ndarray) -> np.ndarray:
            lw, md = self._terms(p)
            s = np.einsum("nk,nki->ni", np.exp(lw - lw.max(axis=1, keepdims=True)), md)
            length = np.linalg.norm(s, axis=1, keepdims=True)
            return np.where(length > 1e-12, s / np.where(length > 0, length, 1.0), 0.0)

        return self._blocks(P, n, 3)

    def dominant(self, P: np.ndarray) -> np.ndarray:
        """Index of the blob contributing most to ``F`` at each point ("its HLP"), (n,) int."""
        P = np.asarray(P, np.float64).reshape(-1, 3)
        if not len(self):
            return np.full(len(P), -1, np.int64)
        out = np.empty(len(P), np.int64)
        for s in range(0, len(P), _CHUNK):
            out[s : s + _CHUNK] = np.argmax(self._terms(P[s : s + _CHUNK])[0], axis=1)
        return out

    def packed(self) -> np.ndarray:
        """Float32 (k * PACKED,) array for :func:`field_normal`: per blob c, M (6), log w."""
        M = self.metrics()
        cols = [
            self.centers,
            M[:, 0, 0:3],
            M[:, 1, 1:3],
            M[:, 2, 2:3],
            np.log(self.weights)[:, None],
        ]
        return np.concatenate(cols, axis=1).astype(np.float32).reshape(-1)

    # ------------------------------------------------------------------ geometry
    def bounds(self) -> tuple[np.ndarray, np.ndarray]:
        """A box that holds the whole implicit surface. ``F >= iso`` needs some blob with
        ``q_i <= 2 ln(sum w / iso)``, so the ellipsoids scaled by ``sqrt`` of that hold it."""
        scale = math.sqrt(max(1.0, 2.0 * math.log(float(self.weights.sum()) / self.iso)))
        ext = np.abs(self.axes * self.radii[:, :, None]).sum(axis=1) * scale
        return (self.centers - ext).min(axis=0), (self.centers + ext).max(axis=0)

    @cached_property
    def _cells(self) -> tuple[np.ndarray, float, np.ndarray]:
        """``(origin, cell size, cells)``: the cells of a grid over :meth:`bounds` that the
        surface crosses (a corner inside, a corner outside, as marching cubes finds them), with
        their 26 neighbours, as integer (c, 3) coordinates. The surface's thin sampling shell
        (half-thickness = half a cell) lies in them."""
        lo, hi = self.bounds()
        # A fifth of the typical radius, coarser only beyond ~1M grid vertices.
        volume = float(np.prod(hi - lo + 0.4 * np.median(self.radii)))
        h = max(0.2 * float(np.median(self.radii)), (volume / _GRID_VERTICES) ** (1 / 3))
        lo, hi = lo - h, hi + h  # the shell reaches half a cell beyond the surface's box
        ext = hi - lo
        n = np.maximum(np.ceil(ext / h).astype(np.int64), 1)
        axes = [lo[i] + h * np.arange(n[i] + 1) for i in range(3)]
        grid = np.stack(np.meshgrid(*axes, indexing="ij"), axis=-1).reshape(-1, 3)
        inside = (self.field(grid) >= self.iso).reshape(*(n + 1))
        offsets = [(i, j, k) for i in (0, 1) for j in (0, 1) for k in (0, 1)]
        corners = [inside[i : i + n[0], j : j + n[1], k : k + n[2]] for i, j, k in offsets]
        cross = np.any(corners, axis=0) & ~np.all(corners, axis=0)
        pad = np.pad(cross, 1)
        near = np.zeros_like(cross)
        for i in range(3):
            for j in range(3):
                for k in range(3):
                    near |= pad[i : i + n[0], j : j + n[1], k : k + n[2]]
        return lo, h, np.argwhere(near)

    def _shell(self) -> float:
        """Half-thickness of the sampling shell around the surface (half a grid cell)."""
        return 0.5 * self._cells[1]

    def _in_shell(self, p: np.ndarray) -> np.ndarray:
        """Points whose first-order distance ``|F - iso| / |grad F|`` to the surface is below
        the shell's half-thickness."""

        def test(q: np.ndarray) -> np.ndarray:
            lw, md = self._terms(q)
            e = np.exp(lw)
            g = np.linalg.norm(np.einsum("nk,nki->ni", e, md), axis=1)
            return np.abs(e.sum(axis=1) - self.iso) < self._shell() * g

        return self._blocks(p, test, 0).astype(bool)

    def _shell_candidates(self, n: int, rng: np.random.Generator) -> np.ndarray:
        """``n`` points uniform in the union of the cells of :attr:`_cells`."""
        lo, h, cells = self._cells
        pick = cells[rng.integers(0, len(cells), n)]
        return lo + h * (pick + rng.random((n, 3)))

    def digest(self) -> str:
        """A key of the blobs' geometry (to 9 decimals, so a JSON round trip keeps it)."""
        h = hashlib.sha1()
        for arr in (self.centers, self.radii, self.axes, self.weights, np.array([self.iso])):
            h.update(np.ascontiguousarray(np.round(arr, 9) + 0.0).tobytes())
        return h.hexdigest()

    def surface_area(self, seed: int = AREA_SEED, samples: int = AREA_SAMPLES) -> float:
        """Area of the implicit surface: the volume of a thin shell around it over its thickness,
        the volume measured by uniform samples in the grid cells that hold the shell.

        The cost grows with the number of blobs (a grid of up to ~1M points evaluates every
        blob), so results are remembered per geometry, and :meth:`save` writes the default one
        into the JSON file (``surface_area``), where :meth:`load` finds it again.
        """
        key = (self.digest(), seed, samples)
        if key in _AREAS:
            return _AREAS[key]
        area = 0.0
        cells = self._cells[2] if len(self) else ()
        if len(cells):
            h = self._cells[1]
            p = self._shell_candidates(samples, np.random.default_rng(seed))
            volume = float(np.mean(self._in_shell(p))) * len(cells) * h**3
            area = volume / (2 * self._shell())
        _AREAS[key] = area
        return area

    def project(self, P: np.ndarray, steps: int = 6) -> np.ndarray:
        """Newton steps along the gradient onto ``F = iso`` (each step at most 1/2 the smallest
        radius long, so a point never jumps across the surface)."""
        P = np.asarray(P, np.float64).reshape(-1, 3).copy()
        if not len(self) or not len(P):
            return P
        limit = 0.5 * float(self.radii.min())
        for _ in range(steps):
            f, g = self.field(P), self.gradient(P)
            g2 = np.sum(g * g, axis=1)
            step = np.where(g2 > 0, (f - self.iso) / np.where(g2 > 0, g2, 1.0), 0.0)[:, None] * g
            length = np.linalg.norm(step, axis=1, keepdims=True)
            P -= step * np.minimum(1.0, limit / np.maximum(length, 1e-300))
        return P

    def _rejection(self, n: int, rng: np.random.Generator, draw: Any, keep: Any) -> np.ndarray:
        """``n`` of the points ``draw(count, rng)`` for which ``keep(points)`` holds."""
        if not len(self) or n <= 0:
            return np.zeros((0, 3))
        out: list[np.ndarray] = []
        have, batch = 0, 2 * n + 256
        for _ in range(1000):
            if have >= n:
                break
            p = draw(batch, rng)
            p = p[keep(p)]
            out.append(p)
            have += len(p)
            if len(p) < batch // 100:  # a rare event: take bigger batches
                batch = min(batch * 4, 1 << 22)
        return np.concatenate(out)[:n] if out else np.zeros((0, 3))

    def sample_surface(self, n: int, rng: np.random.Generator) -> np.ndarray:
        """``n`` points uniform on the implicit surface (n, 3): uniform points of a thin shell
        around it (uniform in volume = uniform in area), projected onto it."""
        if not len(self) or not len(self._cells[2]):
            return np.zeros((0, 3))
        return self.project(self._rejection(n, rng, self._shell_candidates, self._in_shell))

    def sample_volume(self, n: int, rng: np.random.Generator) -> np.ndarray:
        """``n`` points uniform inside the implicit surface (``F >= iso``), (n, 3)."""
        lo, hi = self.bounds() if len(self) else (np.zeros(3), np.zeros(3))

        def draw(count: int, r: np.random.Generator) -> np.ndarray:
            return r.uniform(lo, hi, size=(count, 3))

        return self._rejection(n, rng, draw, lambda p: self.field(p) >= self.iso)

    # ------------------------------------------------------------------ data
    def to_dict(self) -> dict[str, Any]:
        return {
            "format": FORMAT,
            "version": 1,
            "iso": self.iso,
            "hlps": [
                {
                    "center": self.centers[i].tolist(),
                    "radii": self.radii[i].tolist(),
                    "axes": self.axes[i].tolist(),
                    "weight": float(self.weights[i]),
                }
                for i in range(len(self))
            ],
        }

    @classmethod
    def from_dict(cls, d: Any, name: str = "hlps") -> HLPSet:
        """Inverse of :meth:`to_dict`; a malformed description is a one-line ``InputError``."""
        try:
            if d.get("format") != FORMAT:
                raise ValueError(f"not an HLP file (format {d.get('format')!r})")
            items = d["hlps"]
            c = np.array([h["center"] for h in items], np.float64).reshape(-1, 3)
            r = np.array([h["radii"] for h in items], np.float64).reshape(-1, 3)
            a = np.array([h["axes"] for h in items], np.float64).reshape(-1, 3, 3)
            w = np.array([h.get("weight", 1.0) for h in items], np.float64).reshape(-1)
            hlps = cls(c, r, a, w, float(d.get("iso", ISO)), name)
            area = d.get("surface_area")
            if area is not None:  # written by save(): the default estimate, and for which blobs
                value = area.get("value") if isinstance(area, dict) else None
                if not (isinstance(value, (int, float)) and math.isfinite(value) and value >= 0):
                    raise ValueError(f"surface_area = {area!r}")
                if area.get("geometry") == hlps.digest():  # blobs edited by hand: recomputed
                    _AREAS.setdefault((area["geometry"], AREA_SEED, AREA_SAMPLES), float(value))
            return hlps
        except ParameterError as e:
            raise InputError(str(e)) from None
        except (AttributeError, KeyError, TypeError, ValueError) as e:
            raise InputError(f"{name}: malformed HLP description ({e})") from None

    def save(self, path: str | os.PathLike[str]) -> Path:
        """Write the JSON description (atomic), with the surface area of these blobs (so loading
        the file does not estimate it again; ignored once the blobs are edited)."""
        d = self.to_dict()
        d["surface_area"] = {"value": self.surface_area(), "geometry": self.digest()}
        items = ",\n  ".join(json.dumps(h) for h in d.pop("hlps"))
        head = json.dumps(d)[:-1]  # one HLP per line: readable, diffable, small
        target = Path(path)
        with atomic_output(target) as tmp, open(tmp, "w", encoding="utf-8") as f:
            f.write(f'{head}, "hlps": [\n  {items}\n]}}\n')
        return target

    @classmethod
    def load(cls, path: str | os.PathLike[str]) -> HLPSet:
        p = Path(path)
        check_input_file(p)
        try:
            d = json.loads(p.read_text(encoding="utf-8"))
        except (UnicodeDecodeError, json.JSONDecodeError) as e:
            raise InputError(f"{p}: not JSON ({e})") from None
        return cls.from_dict(d, str(p))


# ---------------------------------------------------------------------- building
def kmeans(
    X: np.ndarray, k: int, seed: int = 0, iterations: int = 30
) -> tuple[np.ndarray, np.ndarray]:
    """k-means with k-means++ seeding (scipy's ``kmeans2``): ``(centres (k', 3), labels (n,))``,
    each point labelled with its nearest centre; empty clusters are dropped, so ``k' <= k``
    (``k`` is also capped at the number of distinct points). Deterministic for a given ``seed``."""
    from scipy.cluster.vq import kmeans2, vq  # lazy: keeps scipy's import out of start-up

    X = np.asarray(X, np.float64)
    k = max(1, min(int(k), len(np.unique(X, axis=0))))
    with warnings.catch_warnings():  # an emptied cluster keeps its centre; dropped below
        warnings.filterwarnings("ignore", "One of the clusters is empty", UserWarning)
        C, _ = kmeans2(X, k, iter=iterations, minit="++", rng=np.random.default_rng(seed))
    labels, _ = vq(X, C)
    used = np.unique(labels)
    remap = np.full(len(C), -1, np.int64)
    remap[used] = np.arange(len(used))
    return C[used], remap[labels]


def clusters_for_radius(points: np.ndarray, radius: float) -> int:
    """Number of grid cells of side ``2 * radius`` that hold a point: the ``k`` for a target
    HLP radius (each HLP covers about one cell)."""
    if not (math.isfinite(radius) and radius > 0):
        raise ParameterError(f"radius = {radius!r}: must be > 0")
    P = np.asarray(points, np.float64).reshape(-1, 3)
    if not len(P):
        return 0
    cells = np.floor((P - P.min(axis=0)) / (2 * radius)).astype(np.int64)
    return len(np.unique(cells, axis=0))


def default_radius(plant: Plant) -> float:
    """The HLP radius used when neither ``k`` nor ``radius`` is given: 1/5 of the bounding
    box's diagonal (a few HLPs per crown: the thesis's HLPs are "much less detailed" than the
    foliage, and many small blobs make a lumpy surface whose normals vary between leaves)."""
    lo, hi = plant.bbox()
    return max(0.2 * float(np.linalg.norm(hi - lo)), 1e-6)


def build_hlps(
    plant: Plant,
    k: int | None = None,
    radius: float | None = None,
    seed: int = 0,
    inside: float = 0.9,
) -> HLPSet:
    """HLPs for ``plant``: ``k`` blobs, or as many as cells of side ``2 * radius`` hold leaves
    (default radius: :func:`default_radius`), scaled so that the fraction ``inside`` of the leaf
    centres lies inside the surface. An empty plant gives an empty :class:`HLPSet`."""
    if not (isinstance(inside, (int, float)) and 0 < inside <= 1):
        raise ParameterError(f"inside = {inside!r}: must lie in (0, 1]")
    if k is not None:
        # At most MAX_HLPS; k-means keeps at most one per leaf.
        k = check_arg("build_hlps", replace(HLPS, name="k"), k)
    if not len(plant):
        z = np.zeros((0, 3))
        return HLPSet(z, z, np.zeros((0, 3, 3)), np.zeros(0), ISO, f"{plant.name} HLPs")
    if k is None:
        k = clusters_for_radius(plant.centers, radius or default_radius(plant))
    C, labels = kmeans(plant.centers, k, seed)
    kk = len(C)
    d = plant.centers - C[labels]
    cov = np.zeros((kk, 3, 3))
    np.add.at(cov, labels, d[:, :, None] * d[:, None, :])
    counts = np.bincount(labels, minlength=kk)
    cov /= counts[:, None, None]
    lam, vec = np.linalg.eigh(cov)  # ascending eigenvalues, eigenvectors as columns
    radii = np.sqrt(5 * np.maximum(lam, 0.0))
    floor = np.maximum(0.35 * radii.max(axis=1), float(np.mean(plant.sizes)))
    radii = np.maximum(radii, floor[:, None])
    axes = np.transpose(vec, (0, 2, 1))  # eigenvectors as rows
    hlps = HLPSet(C, radii, axes, np.ones(kk), ISO, f"{plant.name} HLPs")
    hlps = _fit_scale(hlps, plant.centers, inside, seed)
    # No blob smaller than a leaf: a cluster of one leaf (k close to the number of leaves) is
    # inside its own blob at any scale, and the bisection would shrink it towards nothing.
    lo, hi = plant.bbox()
    smallest = max(float(np.mean(plant.sizes)), 1e-6 * float(np.linalg.norm(hi - lo)), 1e-9)
    return replace(hlps, radii=np.maximum(hlps.radii, smallest))


def _fit_scale(hlps: HLPSet, points: np.ndarray, inside: float, seed: int) -> HLPSet:
    """``hlps`` with every radius scaled by one factor, so that the fraction ``inside`` of
    ``points`` lies inside the surface (the smallest such factor, by bisection: ``F`` grows
    with it)."""
    rng = np.random.default_rng(seed)
    if len(points) > 20000:  # a sample fixes the factor well enough
        points = points[rng.choice(len(points), 20000, replace=False)]
    lo, hi = 1e-3, 16.0
    for _ in range(40):
        mid = math.sqrt(lo * hi)
        f = replace(hlps, radii=hlps.radii * mid).field(points)
        if np.mean(f >= hlps.iso) >= inside:
            hi = mid
        else:
            lo = mid
    return replace(hlps, radii=hlps.radii * hi)


# ---------------------------------------------------------------------- Dr.Jit evaluation
def field_normal(packed: Any, k: int, p: Any) -> Any:
    """``n_hlp(p)`` for a Dr.Jit ``mi.Point3f`` (any width): the outward unit normal of the
    implicit surface at ``p`` from :meth:`HLPSet.packed` data (``mi.Float``, ``k`` blobs), or 0
    where it is undefined. One symbolic loop over the blobs (so ``k`` does not grow the kernel);
    the running maximum of the exponents keeps the sum finite, see the module docstring."""

    def g(base: Any, j: int) -> Any:
        return dr.gather(mi.Float, packed, base + j)

    def body(i: Any, m: Any, s: Any) -> tuple[Any, Any, Any]:
        base = i * PACKED
        d = p - mi.Point3f(g(base, 0), g(base, 1), g(base, 2))
        mxx, mxy, mxz, myy, myz, mzz = (g(base, j) for j in range(3, 9))
        md = mi.Vector3f(
            dr.fma(mxx, d.x, dr.fma(mxy, d.y, mxz * d.z)),
            dr.fma(mxy, d.x, dr.fma(myy, d.y, myz * d.z)),
            dr.fma(mxz, d.x, dr.fma(myz, d.y, mzz * d.z)),
        )
        lw = g(base, 9) - 0.5 * dr.dot(d, md)
        m_new = dr.maximum(m, lw)
        s = s * dr.exp(m - m_new) + md * dr.exp(lw - m_new)
        return i + 1, m_new, s

    i0 = dr.zeros(mi.UInt32, dr.width(p))
    m0 = dr.full(mi.Float, -dr.inf, dr.width(p))
    s0 = dr.zeros(mi.Vector3f, dr.width(p))
    _, _, s = dr.while_loop((i0, m0, s0), lambda i, m, s: i < k, body)
    length = dr.norm(s)
    return dr.select(length > 1e-12, s / dr.maximum(length, 1e-30), mi.Vector3f(0.0))

"""A small seeded tree/bush generator, so demos and tests need no downloaded plant.

``procedural_tree(seed, n_leaves, kind)`` grows a branching skeleton (a trunk, then branches that
split 2-3 ways at each level, like a very small L-system), builds the wood as 6-sided tapered
tubes, and puts the leaves in clumps at the branch tips: every leaf is a point in a Gaussian cloud
around its tip, facing mostly away from the tip (plus noise), with a random in-plane axis and a
length drawn around ``leaf_size``. The clumps are what the HLPs of :mod:`mi_npr.foliage.hlp`
abstract. Everything comes from ``numpy.random.default_rng(seed)``: the same arguments give the
same plant, bit for bit, on every machine.

Units: y is up, the trunk starts at the origin; a ``"tree"`` is about 2.4 tall with a crown about
2 wide, a ``"bush"`` about 1.2 tall and 1.8 wide.
"""

from __future__ import annotations

import numpy as np

from ..errors import ParameterError
from .plant import Plant, any_perpendicular, unit_rows

KINDS = ("tree", "bush")


def _rotate_towards(d: np.ndarray, angle: float, azimuth: float) -> np.ndarray:
    """``d`` tilted by ``angle`` (radians) towards the direction at ``azimuth`` around it."""
    t = any_perpendicular(d[None])[0]
    b = np.cross(d, t)
    side = np.cos(azimuth) * t + np.sin(azimuth) * b
    out = np.cos(angle) * d + np.sin(angle) * side
    return out / np.linalg.norm(out)


def _tube(
    p0: np.ndarray, p1: np.ndarray, r0: float, r1: float, sides: int = 6
) -> tuple[np.ndarray, np.ndarray]:
    """An open tapered tube from ``p0`` (radius ``r0``) to ``p1`` (``r1``), outward winding."""
    d = (p1 - p0) / np.linalg.norm(p1 - p0)
    t = any_perpendicular(d[None])[0]
    b = np.cross(d, t)
    phi = 2 * np.pi * np.arange(sides) / sides
    ring = np.cos(phi)[:, None] * t + np.sin(phi)[:, None] * b
    V = np.concatenate([p0 + r0 * ring, p1 + r1 * ring])
    F = []
    for i in range(sides):
        j = (i + 1) % sides
        F += [(i, j, sides + j), (i, sides + j, sides + i)]
    return V, np.asarray(F, dtype=np.int64)


def procedural_tree(
    seed: int = 0,
    n_leaves: int = 1500,
    kind: str = "tree",
    leaf_size: float = 0.09,
) -> Plant:
    """A deterministic plant: ``n_leaves`` leaves in clumps at the tips of a branching skeleton.

    >>> plant = procedural_tree(seed=1, n_leaves=200)
    >>> len(plant), plant.wood is not None
    (200, True)
    """
    if kind not in KINDS:
        raise ParameterError(f"kind = {kind!r}: expected one of {', '.join(KINDS)}")
    if not isinstance(n_leaves, (int, np.integer)) or n_leaves < 0:
        raise ParameterError(f"n_leaves = {n_leaves!r}: must be an integer >= 0")
    if not np.isfinite(leaf_size) or leaf_size <= 0:
        raise ParameterError(f"leaf_size = {leaf_size!r}: must be > 0")
    rng = np.random.default_rng(seed)
    up = np.array([0.0, 1.0, 0.0])

    # Skeleton: (start, end, radius at start, radius at end, level); clumps sit at the ends of the
    # last two levels' branches.
    segments: list[tuple[np.ndarray, np.ndarray, float, float, int]] = []
    tips: list[tuple[np.ndarray, np.ndarray]] = []  # (tip position, branch direction)
    if kind == "tree":
        trunk_top = np.array([0.0, 0.8, 0.0])
        segments.append((np.zeros(3), trunk_top, 0.08, 0.06, 0))
        stack = [(trunk_top, up, 0.45, 0.06, 1)]
        levels, spread, shrink = 4, (0.6, 1.1), (0.7, 0.85)
    else:
        stack = []
        for _ in range(5):
            d = _rotate_towards(up, rng.uniform(0.4, 1.0), rng.uniform(0, 2 * np.pi))
            stack.append((np.zeros(3), d, 0.4, 0.04, 1))
        levels, spread, shrink = 3, (0.35, 0.7), (0.6, 0.75)
    while stack:
        start, d, length, radius, level = stack.pop(0)
        end = start + length * d
        segments.append((start, end, radius, radius * 0.7, level))
        if level >= levels - 1:  # clumps on the last two levels fill the crown's volume
            tips.append((end, d))
        if level >= levels:
            continue
        for _ in range(int(rng.integers(2, 4))):
            nd = _rotate_towards(d, rng.uniform(*spread), rng.uniform(0, 2 * np.pi))
            nd = nd + 0.15 * up  # branches bend upwards, like phototropism
            nd /= np.linalg.norm(nd)
            stack.append((end, nd, length * rng.uniform(*shrink), radius * 0.7, level + 1))

    Vs, Fs, off = [], [], 0
    for p0, p1, r0, r1, _ in segments:
        V, F = _tube(p0, p1, r0, r1)
        Vs.append(V)
        Fs.append(F + off)
        off += len(V)
    wood = (np.concatenate(Vs).astype(np.float32), np.concatenate(Fs).astype(np.uint32))

    # Leaves: clumps at the tips, each a Gaussian cloud pushed out along the branch direction.
    tip_pos = np.array([t[0] for t in tips])
    tip_dir = np.array([t[1] for t in tips])
    clump = rng.integers(0, len(tips), n_leaves)
    sigma = 0.13 if kind == "tree" else 0.11
    centre = tip_pos[clump] + 0.12 * tip_dir[clump]
    P = centre + rng.normal(0.0, sigma, (n_leaves, 3)) * [1.0, 0.8, 1.0]
    outward, _ = unit_rows(P - centre + 0.05 * tip_dir[clump])
    N, _ = unit_rows(outward + 0.6 * rng.normal(0.0, 1.0, (n_leaves, 3)) + 0.3 * up)
    N[np.linalg.norm(N, axis=1) == 0] = up
    A, _ = unit_rows(np.cross(N, rng.normal(0.0, 1.0, (n_leaves, 3))))
    zero = np.linalg.norm(A, axis=1) < 0.5
    A[zero] = any_perpendicular(N[zero])
    S = leaf_size * np.exp(rng.normal(0.0, 0.15, n_leaves))
    areas = 0.5 * S**2  # leaves about half as wide as long
    return Plant(P, N, A, S, areas, wood, f"procedural_{kind}_{seed}")

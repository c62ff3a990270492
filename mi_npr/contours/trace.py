"""Contour following on an ID buffer: the robust border follower and the paper's code direction.

A *contour pixel* of object ``k`` is a pixel of ``k`` with a 4-neighbour that is not ``k``, the
outside of the image counting as "not k"; the background (id 0) has no contours. Pixels are
``(x, y)`` = (column, row), row 0 at the top.

**Border follower** (``method="border"``, the default). Every pair of 4-adjacent pixels ``p`` of
object ``k`` and ``q`` not ``k`` is a *crack* ``(p, d)``, ``d`` the direction from ``p`` to ``q``
(0 = +x, 1 = +y, 2 = -x, 3 = -y). A contour pixel is exactly a pixel with at least one crack.
Cracks are followed with ``k`` on one side and "not k" on the other, objects taken 8-connected and
what surrounds them 4-connected (the convention of Suzuki & Abe's border following, which OpenCV's
``findContours`` implements). From crack ``(p, d)``, moving along ``t = d + 1`` (mod 4), with
``a = p + t`` and ``b = p + d + t``::

    b is k          -> (b, d - 1)   the object turns towards the crack side (8-connected step)
    else a is k     -> (a, d)       straight on
    else            -> (p, d + 1)   turn around p

This successor is a permutation of the cracks; its cycles are the contours, one per border between
an 8-connected piece of an object and a 4-connected region around or inside it (outer borders and
holes). Because every crack lies on exactly one cycle, the union of an object's contours is its
contour-pixel set *exactly*, every piece (split by an occluder, touching the image border, seen
through a gap, a single pixel) and every hole has its own contour, and each contour is an
8-connected chain. The cycles are found without a per-pixel Python loop: the successor graph's
connected components (scipy) label each cycle by its first crack in raster order, a depth-first
walk from a root joined to those first cracks lists every cycle in order (linear time for ``n``
cracks), then consecutive cracks on the same pixel collapse into one point. A contour
starts at its first pixel in raster order (like OpenCV's) and runs clockwise on screen for outer
borders, counter-clockwise around holes; ``is_hole`` comes from the sign of the area it encloses.

**Code direction** (``method="code_direction"``): section 3.2 of the paper, as written. The 8
neighbours are numbered as in its Fig. 8: 0 = (x, y+1), 1 = (x-1, y+1), 2 = (x-1, y), then on
around the pixel in the same sense (3 = (x-1, y-1), 4 = (x, y-1), 5 = (x+1, y-1), 6 = (x+1, y),
7 = (x+1, y+1)); with y = row, 0 is the pixel below. From the current pixel the neighbours are
tested in the order 0..7, skipping the ones already coloured (visited); the first that has the
object's id and passes the contour test becomes the next pixel and is coloured. Ambiguities
resolved: "its previous and following pixels don't have the same ID" is read as *not both* of
neighbours ``i - 1`` and ``i + 1`` (mod 8) have the object's id (both lie in the current pixel's
ring and are 4-neighbours of candidate ``i``); the departure pixel is coloured from the start, and
the walk stops when no neighbour qualifies; it is *closed* when it stopped next to its departure
pixel (or is a single pixel) *and* holds every pixel of its piece's border (the border follower's
cycle), else *open* (stopping next to the start after skipping pixels is not closing).
Colouring is per contour, so contours do not depend on the order they are traced in. Each contour
piece gets its own departure pixel (the first pixel of its border-follower contour) instead of one
per object. Where it goes wrong, by construction:

- the ring test sees only two of the candidate's four 4-neighbours, so a true contour pixel whose
  "not k" neighbour is the other two is skipped;
- the fixed scan order and the colouring make it a greedy walk: it enters 1-pixel-wide spurs and
  bridges and cannot come back through coloured pixels, so it dead-ends (open contour) and the rest
  of the piece is not traced;
- it never adds a pixel that is not a contour pixel (the test is a subset of the definition), but
  its union can miss contour pixels and two contours may share pixels (outer border and hole of a
  1-pixel-thick ring);
- since colouring is per contour, a hole's walk may wander on along the object's other border
  pixels, so on inputs with very many holes its cost grows much faster than the image and far
  beyond the border follower's (a one-pixel checkerboard is the worst case); rendered scenes
  have few holes.

The tests show each case; the border follower has none of them.
"""

from __future__ import annotations

from collections.abc import Callable, Generator, Iterable, Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from ..errors import ParameterError
from ..gbuffer import GBuffer, to_numpy
from .contour import Contour

METHODS = ("border", "code_direction")

#: Pixel id of the one-pixel ring around the image (never an object id: ids are < 2**32 - 1).
OUTSIDE = np.uint32(0xFFFFFFFF)

# Corner coordinates (pixel (x, y) spans [x, x+1] x [y, y+1]) of each crack's edge, start -> end,
# in the direction of travel: they give the signed area that tells outer borders from holes.
_EDGE = np.array(
    [[1, 0, 1, 1], [1, 1, 0, 1], [0, 1, 0, 0], [0, 0, 1, 0]], dtype=np.int64
)  # x1, y1, x2, y2 offsets per side
# Fig. 8 of the paper: neighbour i of (x, y), as (dx, dy).
FIG8 = ((0, 1), (-1, 1), (-1, 0), (-1, -1), (0, -1), (1, -1), (1, 0), (1, 1))


# --------------------------------------------------------------------------- the padded grid
@dataclass
class Grid:
    """An ID map padded with one ring of :data:`OUTSIDE`, flattened (row-major).

    ``known`` (same layout) marks the pixels whose id has been computed; ``None`` means all of
    them (buffer mode). Ray-cast mode fills ``ids`` and ``known`` as it casts.
    """

    height: int
    width: int
    ids: np.ndarray  # uint32, (height + 2) * (width + 2)
    known: np.ndarray | None = None

    @property
    def stride(self) -> int:
        return self.width + 2

    @classmethod
    def from_ids(cls, ids: np.ndarray) -> Grid:
        h, w = ids.shape
        p = np.full((h + 2, w + 2), OUTSIDE, dtype=np.uint32)
        p[1:-1, 1:-1] = ids
        return cls(h, w, p.reshape(-1))

    @classmethod
    def empty(cls, height: int, width: int) -> Grid:
        """Nothing known yet but the outside ring."""
        p = np.full((height + 2, width + 2), OUTSIDE, dtype=np.uint32)
        known = np.ones((height + 2, width + 2), dtype=bool)
        known[1:-1, 1:-1] = False
        return cls(height, width, p.reshape(-1), known.reshape(-1))

    def offsets4(self) -> np.ndarray:
        """Flat offsets of the crack sides d = 0..3: +x, +y, -x, -y."""
        s = self.stride
        return np.array([1, s, -1, -s], dtype=np.int64)

    def offsets8(self) -> list[int]:
        """Flat offsets of the paper's Fig. 8 neighbours 0..7."""
        s = self.stride
        return [dx + dy * s for dx, dy in FIG8]

    def index(self, x: np.ndarray, y: np.ndarray) -> np.ndarray:
        """Flat padded index of pixels (x, y)."""
        return (np.asarray(y, np.int64) + 1) * self.stride + np.asarray(x, np.int64) + 1

    def xy(self, idx: np.ndarray) -> np.ndarray:
        """(N, 2) int32 pixel positions (x, y) of flat padded indices."""
        idx = np.asarray(idx, np.int64)
        return np.stack([idx % self.stride - 1, idx // self.stride - 1], axis=-1).astype(np.int32)


def distinct(a: np.ndarray) -> np.ndarray:
    """The sorted distinct values of an integer array (by sorting: ``np.unique``'s hash-based
    implementation in numpy 2.x is slower on the sizes used here)."""
    s = np.sort(np.asarray(a).reshape(-1))
    if len(s) < 2:
        return s
    keep = np.empty(len(s), dtype=bool)
    keep[0] = True
    np.not_equal(s[1:], s[:-1], out=keep[1:])
    return s[keep]


# --------------------------------------------------------------------------- cracks
def _dense_contour_mask(grid: Grid) -> np.ndarray:
    """(H, W) bool: object pixels with a 4-neighbour of another id (complete grids)."""
    p = grid.ids.reshape(grid.height + 2, grid.stride)
    c = p[1:-1, 1:-1]
    dh = p[1:-1, 1:] != p[1:-1, :-1]  # (H, W + 1): pixel pairs along x
    dv = p[1:, 1:-1] != p[:-1, 1:-1]  # (H + 1, W): pixel pairs along y
    m = dh[:, 1:] | dh[:, :-1]
    m |= dv[1:]
    m |= dv[:-1]
    m &= c != 0  # the background has no contours
    return m


def contour_mask(object_id: np.ndarray) -> np.ndarray:
    """(H, W) bool: the contour pixels of every object (see the module docstring)."""
    return _dense_contour_mask(Grid.from_ids(_check_ids(object_id)))


def _cracks(grid: Grid) -> tuple[np.ndarray, np.ndarray]:
    """Padded pixel index and side of every crack, sorted by (pixel, side).

    Complete grids: the contour pixels come from whole-image comparisons. Partial grids: only
    known pixels are candidates, and a side counts only where its neighbour is known too.
    """
    if grid.known is None:
        flat = np.flatnonzero(_dense_contour_mask(grid))
        pix = flat + grid.stride + 1 + 2 * (flat // grid.width)  # inner -> padded index
    else:
        pix = np.flatnonzero(grid.known)
        k = grid.ids[pix]
        pix = pix[(k != OUTSIDE) & (k != 0)]
    k = grid.ids[pix]
    nb = pix[:, None] + grid.offsets4()[None, :]
    has = grid.ids[nb] != k[:, None]
    if grid.known is not None:
        has &= grid.known[nb]
    sel = has.reshape(-1)
    return np.repeat(pix, 4)[sel], np.tile(np.arange(4, dtype=np.int64), len(pix))[sel]


@dataclass
class Cycles:
    """The contours of a grid as crack cycles, ordered and collapsed to pixels."""

    object_id: np.ndarray  # per contour
    start: np.ndarray  # per contour: flat padded index of its first pixel
    is_hole: np.ndarray  # per contour
    offsets: np.ndarray  # per contour: first point in ``points`` (len = contours + 1)
    points: np.ndarray  # (N, 2) int32, all contours' points back to back


def _successor(grid: Grid, pix: np.ndarray, side: np.ndarray) -> np.ndarray:
    """Flat key (pixel * 4 + side) of each crack's successor (module docstring's rule)."""
    off = grid.offsets4()
    k = grid.ids[pix]
    t = (side + 1) & 3
    a = pix + off[t]
    b = a + off[side]
    return np.where(
        grid.ids[b] == k,
        b * 4 + ((side + 3) & 3),
        np.where(grid.ids[a] == k, a * 4 + side, pix * 4 + t),
    )


def _cycle_min(val: np.ndarray, succ: np.ndarray) -> np.ndarray:
    """The minimum of ``val`` over each cycle of the permutation ``succ``: the cycles are the
    connected components of the graph ``i -> succ[i]`` (scipy, linear time)."""
    n = len(succ)
    # imported here: scipy.sparse slows the start of every command, most of which never trace
    from scipy.sparse import csr_matrix
    from scipy.sparse.csgraph import connected_components

    graph = csr_matrix((np.ones(n, np.int8), succ, np.arange(n + 1)), shape=(n, n))
    count, label = connected_components(graph, directed=True, connection="weak")
    low = np.full(count, np.iinfo(np.int64).max)
    np.minimum.at(low, label, val)
    return low[label]


def _cycle_order(succ: np.ndarray, is_rep: np.ndarray, reps: np.ndarray) -> np.ndarray:
    """All elements, cycle after cycle in the order of ``reps`` (each cycle's representative,
    ascending), each cycle from its representative along ``succ``: the depth-first order from a
    root joined to every representative, in the graph ``i -> succ[i]`` cut before each
    representative (every chain is then walked whole before the next one starts)."""
    n = len(succ)
    keep = ~is_rep[succ]
    indptr = np.concatenate([[0], np.cumsum(keep), [keep.sum() + len(reps)]])
    cols = np.concatenate([succ[keep], reps])  # one edge per row, then the root's (ascending)
    from scipy.sparse import csr_matrix  # imported here: see _components
    from scipy.sparse.csgraph import depth_first_order

    graph = csr_matrix((np.ones(len(cols), np.int8), cols, indptr), shape=(n + 1, n + 1))
    return depth_first_order(graph, n, directed=True, return_predecessors=False)[1:]


@dataclass
class CrackCycles:
    """The contours of a grid as ordered crack cycles (before collapsing cracks to pixels)."""

    pix: np.ndarray  # flat padded index of each crack's pixel, cycle after cycle, in order
    side: np.ndarray  # each crack's side d (0 = +x, 1 = +y, 2 = -x, 3 = -y)
    offsets: np.ndarray  # per cycle: first crack in ``pix`` (len = cycles + 1)
    object_id: np.ndarray  # per cycle
    start: np.ndarray  # per cycle: flat padded index of its first pixel
    is_hole: np.ndarray  # per cycle


def crack_cycles(grid: Grid, cracks: tuple[np.ndarray, np.ndarray] | None = None) -> CrackCycles:
    """Every contour of ``grid`` (all objects) as an ordered cycle of cracks (module docstring).

    With a partial grid (``known`` set), only cracks whose two pixels are known take part: the
    caller guarantees that the successors of those cracks are known too (ray-cast mode's closure).
    ``cracks``: the grid's cracks ``(pixel, side)`` sorted by ``pixel * 4 + side``, when the
    caller has them already (ray-cast mode finds them in Dr.Jit); else they are found here.
    """
    pix, side = _cracks(grid) if cracks is None else cracks
    n = len(pix)
    if n == 0:
        z = np.zeros(0, np.int64)
        return CrackCycles(z, z, np.zeros(1, np.int64), z, z, z.astype(bool))
    keys = pix * 4 + side  # sorted
    # Successor keys -> crack indices through a table over all keys (only the cracks' entries
    # are written and read: np.empty touches no other page), faster than searchsorted.
    slot = np.empty(len(grid.ids) * 4, np.int64)
    slot[keys] = np.arange(n)
    succ = slot[_successor(grid, pix, side)]
    pred = np.empty(n, np.int64)
    pred[succ] = np.arange(n)
    # A contour starts at its first crack in raster order that begins a run of cracks on one
    # pixel, so that no pixel's run is split between the end and the start of the chain.
    idx = np.arange(n, dtype=np.int64)
    run_start = pix[pred] != pix
    rep = _cycle_min(np.where(run_start, idx, idx + n), succ)
    rep = np.where(rep >= n, rep - n, rep)
    is_rep = rep == idx
    reps = np.flatnonzero(is_rep)
    cyc_of = np.empty(n, np.int64)
    cyc_of[reps] = np.arange(len(reps))
    cyc = cyc_of[rep]
    length = np.bincount(cyc, minlength=len(reps))
    seq = _cycle_order(succ, is_rep, reps)
    # Twice the signed area enclosed by each cycle's crack edges: > 0 outer border, < 0 hole.
    x = pix % grid.stride - 1
    y = pix // grid.stride - 1
    e = _EDGE[side]
    cross = (x + e[:, 0]) * (y + e[:, 3]) - (x + e[:, 2]) * (y + e[:, 1])
    area = np.bincount(cyc, weights=cross.astype(np.float64), minlength=len(reps))
    return CrackCycles(
        pix=pix[seq],
        side=side[seq],
        offsets=np.concatenate([[0], np.cumsum(length)]),
        object_id=grid.ids[pix[reps]].astype(np.int64),
        start=pix[reps],
        is_hole=area < 0,
    )


def cycles(grid: Grid, cracks: tuple[np.ndarray, np.ndarray] | None = None) -> Cycles:
    """Every closed contour of ``grid`` (all objects): :func:`crack_cycles` (``cracks`` as it
    takes them) with consecutive cracks on one pixel collapsed into one point."""
    cc = crack_cycles(grid, cracks)
    n_cyc = len(cc.object_id)
    cyc_seq = np.repeat(np.arange(n_cyc, dtype=np.int64), np.diff(cc.offsets))
    keep = np.ones(len(cc.pix), dtype=bool)
    keep[1:] = (cc.pix[1:] != cc.pix[:-1]) | (cyc_seq[1:] != cyc_seq[:-1])
    counts = np.bincount(cyc_seq[keep], minlength=n_cyc)
    return Cycles(
        object_id=cc.object_id,
        start=cc.start,
        is_hole=cc.is_hole,
        offsets=np.concatenate([[0], np.cumsum(counts)]).astype(np.int64),
        points=grid.xy(cc.pix[keep]),
    )


# --------------------------------------------------------------------------- code direction
Walk = Generator[list[int], None, tuple[list[int], bool]]


def code_direction_walk(
    ids: Sequence[int], known: Sequence[bool] | None, start: int, stride: int
) -> Walk:
    """The paper's code-direction walk from flat padded index ``start`` (module docstring).

    A generator: it yields the list of flat indices whose ids it needs and that ``known`` does not
    have yet (the caller computes them, updates ``ids``/``known`` in place and resumes it); it
    returns ``(chain of flat indices, closed)``. With ``known=None`` it never yields.
    """
    ring = [dx + dy * stride for dx, dy in FIG8]  # Grid.offsets8
    k = ids[start]
    chain = [start]
    colored = {start}
    cur = start
    while True:
        if known is not None:
            need = [cur + o for o in ring if not known[cur + o]]
            if need:
                yield need
        nxt = -1
        for i in range(8):
            n = cur + ring[i]
            if n in colored or ids[n] != k:
                continue
            if ids[cur + ring[i - 1]] == k and ids[cur + ring[(i + 1) & 7]] == k:
                continue  # both ring neighbours are the object: not a contour point
            nxt = n
            break
        if nxt < 0:
            break
        chain.append(nxt)
        colored.add(nxt)
        cur = nxt
    closed = len(chain) == 1 or (cur - start) in ring
    return chain, closed


def run_walks(
    walks: list[Walk], fetch: Callable[[list[int]], None] | None = None
) -> list[tuple[list[int], bool]]:
    """Run walks to completion; the ids they ask for are computed by ``fetch`` in one batch per
    round (all blocked walks together). Results are in the order of ``walks``."""
    results: list[Any] = [None] * len(walks)
    active: dict[int, list[int] | None] = dict.fromkeys(range(len(walks)))
    while active:
        need: list[int] = []
        for i in list(active):
            try:
                asked = walks[i].send(None)
            except StopIteration as stop:
                results[i] = stop.value
                del active[i]
                continue
            need.extend(asked)
        if need:
            if fetch is None:
                raise RuntimeError("a contour walk needs ids that nobody can compute")
            fetch(sorted(set(need)))
    return results


# --------------------------------------------------------------------------- public API
def _check_ids(object_id: Any) -> np.ndarray:
    a = to_numpy(object_id)
    if a.ndim == 3 and a.shape[-1] == 1:
        a = a[..., 0]
    if a.ndim != 2:
        raise ParameterError(f"object_id: expected a 2-D (H, W) id buffer, got shape {a.shape}")
    if a.dtype.kind == "f":
        if not np.all(np.isfinite(a)) or np.any(a < 0) or np.any(a != np.round(a)):
            raise ParameterError("object_id: ids must be finite non-negative integers")
    elif a.dtype.kind not in "biu":
        raise ParameterError(f"object_id: expected integer ids, got dtype {a.dtype}")
    elif a.size and a.dtype.kind == "i" and a.min() < 0:
        raise ParameterError("object_id: ids must be non-negative")
    if a.size and a.max() >= int(OUTSIDE):
        raise ParameterError(f"object_id: ids must be below {int(OUTSIDE)}")
    return np.ascontiguousarray(a, dtype=np.uint32)


def check_only(only: Any) -> list[int] | None:
    """``only`` (object ids to trace) as a list of ints, or an error naming it."""
    if only is None:
        return None
    bad = ParameterError(f"only = {only!r}: expected an iterable of object ids (integers >= 0)")
    if isinstance(only, (str, bytes)) or not isinstance(only, Iterable):
        raise bad
    out = []
    for v in only:
        if isinstance(v, bool) or not isinstance(v, (int, np.integer)) or not 0 <= v < OUTSIDE:
            raise bad
        out.append(int(v))
    return out


def check_ids(object_id: Any) -> np.ndarray:
    """``object_id`` as a checked (H, W) uint32 id buffer (a one-line error otherwise)."""
    return _check_ids(object_id)


def check_method(method: str) -> str:
    if method not in METHODS:
        raise ParameterError(f"method = {method!r}: expected one of {', '.join(METHODS)}")
    return method


def _name(objects: Mapping[int, str] | None, k: int) -> str:
    if objects is None:
        return f"object_{k}"
    return objects.get(k, f"object_{k}")


def contours_from_grid(
    grid: Grid,
    objects: Mapping[int, str] | None,
    method: str,
    fetch: Callable[[list[int]], None] | None = None,
    only: Iterable[int] | None = None,
    cracks: tuple[np.ndarray, np.ndarray] | None = None,
) -> list[Contour]:
    """The contours of a (complete or closed partial) grid; ``fetch`` serves code-direction walks
    that leave the known pixels (ray-cast mode); ``cracks`` as :func:`cycles` takes them. Sorted
    by object id, then start pixel."""
    cyc = cycles(grid, cracks)
    order = np.argsort(cyc.object_id, kind="stable")
    if only is not None:
        wanted = np.asarray(sorted(set(int(v) for v in only)), dtype=np.int64)
        order = order[np.isin(cyc.object_id[order], wanted)]
    if method == "border":
        return [
            Contour(
                int(cyc.object_id[i]),
                _name(objects, int(cyc.object_id[i])),
                cyc.points[cyc.offsets[i] : cyc.offsets[i + 1]],
                True,
                bool(cyc.is_hole[i]),
            )
            for i in order
        ]
    if fetch is not None and grid.known is not None and len(cyc.points):
        # The walks read the 3x3 ring of the pixels they visit, which are contour pixels: ask
        # for all those rings in one batch rather than one walk step at a time.
        pts = grid.index(cyc.points[:, 0], cyc.points[:, 1])
        ring = (pts[:, None] + np.asarray(grid.offsets8())[None, :]).reshape(-1)
        missing = distinct(ring[~grid.known[ring]])
        if len(missing):
            fetch(missing.tolist())
    ids_list = grid.ids.tolist()
    known_list = grid.known.tolist() if grid.known is not None else None

    def fetch_lists(need: list[int]) -> None:
        assert fetch is not None and known_list is not None
        fetch(need)
        for j in need:
            ids_list[j] = int(grid.ids[j])
            known_list[j] = True

    walks = [
        code_direction_walk(ids_list, known_list, int(cyc.start[i]), grid.stride) for i in order
    ]
    done = run_walks(walks, fetch_lists if fetch is not None else None)
    return [
        Contour(
            int(cyc.object_id[i]),
            _name(objects, int(cyc.object_id[i])),
            grid.xy(np.asarray(chain, np.int64)),
            closed and _holds_piece(grid, chain, cyc.points[cyc.offsets[i] : cyc.offsets[i + 1]]),
            bool(cyc.is_hole[i]),
        )
        for i, (chain, closed) in zip(order, done, strict=True)
    ]


def _holds_piece(grid: Grid, chain: list[int], piece: np.ndarray) -> bool:
    """Whether a walk's chain holds every pixel of its piece's border (the border follower's
    cycle ``piece``, (x, y) points): a walk that stopped next to its start but skipped part of
    the piece is not closed."""
    return bool(np.isin(grid.index(piece[:, 0], piece[:, 1]), np.asarray(chain)).all())


def trace(
    object_id: Any,
    *,
    objects: Mapping[int, str] | None = None,
    method: str = "border",
    only: Iterable[int] | None = None,
) -> list[Contour]:
    """Every contour of every object of an ID buffer.

    ``object_id``: an (H, W) integer id buffer (0 = background), or a
    :class:`~mi_npr.gbuffer.GBuffer` (its ``object_id`` layer and object table). ``objects`` maps
    ids to names (default: the GBuffer's table, else ``object_<id>``). ``method``: ``"border"``
    (default; exact, see the module docstring) or ``"code_direction"`` (the paper's walk).
    ``only``: the object ids to trace (default all). Contours come sorted by object id, then by
    their first pixel in raster order.

    >>> ids = np.zeros((5, 6), np.uint32); ids[1:4, 1:5] = 7
    >>> [c.points.tolist() for c in trace(ids)]  # doctest: +NORMALIZE_WHITESPACE
    [[[1, 1], [2, 1], [3, 1], [4, 1], [4, 2], [4, 3], [3, 3], [2, 3], [1, 3], [1, 2]]]
    """
    check_method(method)
    if objects is not None and not isinstance(objects, Mapping):
        raise ParameterError(
            f"objects = {objects!r}: expected a mapping of object ids to names, "
            f"got {type(objects).__name__}"
        )
    only = check_only(only)
    if isinstance(object_id, GBuffer):
        if objects is None:
            objects = object_id.objects
        object_id = object_id.object_id
    ids = _check_ids(object_id)
    return contours_from_grid(Grid.from_ids(ids), objects, method, only=only)


def contour_layer(contours: Iterable[Contour], shape: tuple[int, int]) -> np.ndarray:
    """The ``contour`` layer: (H, W) uint32 object id on the contours' points, 0 elsewhere."""
    h, w = shape
    out = np.zeros((h, w), dtype=np.uint32)
    for c in contours:
        if len(c.points):
            out[c.points[:, 1], c.points[:, 0]] = c.object_id
    return out

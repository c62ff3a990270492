"""From a scene and a camera to :class:`~mi_npr.strokes.model.Strokes`.

1. The meshes' feature edges (:mod:`mi_npr.strokes.edges`), clipped to the view frustum.
2. **Visibility**: each clipped edge is sampled every ``SPACING`` px on the film (uniformly on
   the film; the 3-D point of film parameter ``u`` is ``s = u w_a / ((1 - u) w_b + u w_a)``
   along the 3-D segment, ``w`` the ends' depths; ``s = u`` for an orthographic camera, whose
   rays are parallel) and each sample's state, QI and ``through_glass``
   (:mod:`mi_npr.strokes.visibility`), is cast. Where two neighbouring
   samples differ, the change is found by ``ITERATIONS`` bisections along the edge (to
   ``SPACING / 2**ITERATIONS`` px) and the edge is split there. A change that starts and ends
   between two samples (an occluder thinner than ``SPACING`` px) is missed. The pieces
   behind more than ``max_qi`` surfaces are then dropped (the rays count to ``max_qi + 1``).
3. **Chaining** of the pieces (:mod:`mi_npr.strokes.chain`), per kind and visibility state.
4. The outlines of the shapes that are not meshes (:mod:`mi_npr.strokes.outlines`).
5. Optionally (``resample``) more vertices along long segments, then per vertex the depth
   seen one pixel to either side across the stroke (``depth_behind``, the farther of the two;
   eq. 5.1's neighbour for the ``thesis`` style: with vertices only at the corners, a crease
   ending on a silhouette would read the background beside both of its ends).

Per-vertex attributes of a chained mesh stroke: the film position and depth of the vertex's
projection, its world position, and the object and primitive of the edge that *leaves* the
vertex (the last vertex of an open stroke: of the edge that arrives).
"""

from __future__ import annotations

import itertools
from collections.abc import Mapping
from typing import Any

import drjit as dr
import mitsuba as mi
import numpy as np

from ..errors import ParameterError, shown
from ..gbuffer import Projection
from ..kernels.edges import dihedral
from ..memory import release_freed_memory
from ..params import Param, check_arg, integer_range, real_range
from ..raycast import cast, film_grid, pixel_rays
from ..raytree.tracer import MAX_DEPTH
from ..scene import ObjectTable, object_table
from .chain import chain_order
from .edges import FeatureEdges, Projector, ViewEdges, forget_topology, homogeneous, view_edges
from .model import KINDS, Stroke, Strokes, sizes
from .order import lexsort_ints
from .outlines import ids_and_depths, outline_strokes
from .raytree import raytree_strokes
from .visibility import SegmentVisibility, jit_array, own_arrays

#: Film distance between visibility samples along an edge, in pixels.
SPACING = 0.5
#: Bisections that place a visibility change (``SPACING / 2**12``: 0.0001 px).
ITERATIONS = 12
#: Pieces shorter than this on the film (pixels) take the state of their neighbour.
MIN_PIECE = 0.05
#: Where ``depth_behind`` looks, in pixels to either side of a vertex.
BESIDE = 1.0
#: Vertices whose ``depth_behind`` is cast at once (bounds the memory of the hits).
BESIDE_BLOCK = 1 << 17


def _film_param_to_3d(u: np.ndarray, wa: np.ndarray, wb: np.ndarray) -> np.ndarray:
    """The 3-D segment parameter of film parameter ``u`` (perspective-correct; ``wa``, ``wb``
    the ends' homogeneous weights: ``u`` itself where they are equal, as for an orthographic
    camera)."""
    return u * wa / ((1.0 - u) * wb + u * wa)


#: Feature edges clipped in one launch, and visibility samples cast in one launch: whole
#: edges are added to a launch of samples until it holds this many (bound the memory of the
#: edges, ~200 bytes each, and of the samples and their rays, ~50 bytes each, whatever the
#: film's size; each launch traces the ray loop again, so the bisections of all the launches
#: wait for one launch after them).
EDGE_CHUNK = 1 << 16
SAMPLES = 1 << 19


def _joined(parts: list[dict[str, np.ndarray]]) -> dict[str, np.ndarray]:
    """The rows of ``parts`` one after the other, a field at a time (each part's copy dropped
    as it is joined); ``parts`` is left empty."""
    out = {key: np.concatenate([p.pop(key) for p in parts]) for key in list(parts[0])}
    parts.clear()
    return out


def _clip(proj: Projector, edges: FeatureEdges) -> tuple[dict[str, Any], dict[str, np.ndarray]]:
    """The parts of ``edges`` inside the view frustum, one row per edge that has one, in
    double precision: ``(jit, rows)``, the clipped ends ``A``, ``B`` (world; three Dr.Jit
    arrays each) and their homogeneous weights ``wa``, ``wb`` (the depths for a perspective
    camera, 1 for an orthographic one) and the edge's ``own`` faces (four Dr.Jit arrays, as
    :class:`~mi_npr.strokes.visibility.SegmentVisibility` takes them); and the same rows in
    numpy with their film ``length``, the number of visibility samples ``count``, whether
    each end is the edge's own (``whole_a``, ``whole_b``: not cut by the frustum), and the
    edge's own fields (``va``, ``vb``, ``kind``, ``object_id``, ``prim``, ``faces``).

    The frustum cuts a segment ``a + s (b - a)`` where one of its ends' homogeneous
    coordinates (:meth:`~mi_npr.strokes.edges.Projector.clip`, affine in ``s``) crosses a
    bound: depth at the near plane, ``0 <= X <= W``, ``0 <= Y <= W`` (Liang-Barsky); a
    bound parallel to a segment outside it leaves nothing of it, nor does an end whose
    coordinates are not all finite."""
    F64 = mi.Float64
    n = len(edges)
    if n == 0:  # Dr.Jit arrays of no entry do not mix with the camera's scalars
        return _clipped_none()
    a = [jit_array(F64, edges.a[:, k]) for k in range(3)]
    b = [jit_array(F64, edges.b[:, k]) for k in range(3)]
    # the camera as evaluated scalars, not literals: one kernel for every view
    m = [[dr.opaque(F64, float(x)) for x in row] for row in proj.matrix]
    near = dr.opaque(F64, proj.near)

    def interval(a: list, b: list) -> tuple[list, list, Any, Any]:
        ha, hb = homogeneous(m, *a), homogeneous(m, *b)
        x0, y0, w0, z0 = ha[0], ha[1], ha[3], ha[proj.depth_row]
        x1, y1, w1, z1 = hb[0], hb[1], hb[3], hb[proj.depth_row]
        lo, hi = dr.zeros(F64, dr.width(x0)), dr.full(F64, 1.0, dr.width(x0))
        for f0, f1 in (
            (z0 - near, z1 - near),
            (x0, x1),
            (w0 - x0, w1 - x1),
            (y0, y1),
            (w0 - y0, w1 - y1),
        ):
            d = f1 - f0
            t = -f0 / d
            lo = dr.select(d > 0, dr.maximum(lo, t), lo)
            hi = dr.select(d < 0, dr.minimum(hi, t), hi)
            lo = dr.select((d == 0) & (f0 < 0), 2.0, lo)
        return ha, hb, lo, hi

    ha, hb, lo, hi = interval(a, b)
    # an end with a coordinate that is not finite (a NaN vertex) has nothing to draw
    finite = dr.isfinite(ha[0] + ha[1] + ha[2] + ha[3] + hb[0] + hb[1] + hb[2] + hb[3])
    e = dr.compress(finite & (hi - lo > 1e-12))
    if dr.width(e) == 0:
        return _clipped_none()
    # the edges kept, their interval made again from their ends (the same arithmetic: the
    # same bits) rather than kept for every edge
    a, b = [dr.gather(F64, x, e) for x in a], [dr.gather(F64, x, e) for x in b]
    ha, hb, lo, hi = interval(a, b)
    A = [x + lo * (y - x) for x, y in zip(a, b, strict=True)]
    B = [x + hi * (y - x) for x, y in zip(a, b, strict=True)]
    # the clipped ends' film positions from the ends' homogeneous coordinates (linear)
    ca = [x + lo * (y - x) for x, y in zip(ha, hb, strict=True)]
    cb = [x + hi * (y - x) for x, y in zip(ha, hb, strict=True)]
    width, height = dr.opaque(F64, proj.width), dr.opaque(F64, proj.height)
    dx = cb[0] / cb[3] * width - ca[0] / ca[3] * width
    dy = cb[1] / cb[3] * height - ca[1] / ca[3] * height
    length = dr.sqrt(dx * dx + dy * dy)
    count = dr.maximum(2, mi.UInt32(dr.ceil(length / SPACING)) + 1)
    wa, wb = ca[3], cb[3]
    dr.eval(e, A, B, wa, wb, length, count, lo, hi)
    idx = np.asarray(e.numpy(), np.int64)
    rows = dict(length=length.numpy(), count=count.numpy().astype(np.int64))
    rows.update(whole_a=lo.numpy() == 0, whole_b=hi.numpy() == 1)
    rows.update(A=np.stack([x.numpy() for x in A], 1), B=np.stack([x.numpy() for x in B], 1))
    rows.update(wa=wa.numpy(), wb=wb.numpy())
    all_rows = len(idx) == n  # every edge in the frustum: the fields as they are
    for k in ("va", "vb", "kind", "object_id", "prim", "faces"):
        rows[k] = getattr(edges, k) if all_rows else getattr(edges, k)[idx]
    rows["faces"] = rows["faces"].astype(np.uint32)  # ids and primitives: 32 bits each
    return dict(A=A, B=B, wa=wa, wb=wb, own=own_arrays(rows["faces"])), rows


def _clipped_none() -> tuple[dict[str, Any], dict[str, np.ndarray]]:
    """:func:`_clip`'s result where no edge is left."""
    edges = FeatureEdges.empty()
    z, z3 = np.zeros(0), np.zeros((0, 3))
    rows = dict(length=z, count=z.astype(np.int64), whole_a=z > 0, whole_b=z > 0)
    rows.update(A=z3, B=z3, wa=z, wb=z)
    rows.update({k: getattr(edges, k) for k in ("va", "vb", "kind", "object_id", "prim")})
    rows["faces"] = edges.faces.astype(np.uint32)
    e3 = [dr.zeros(mi.Float64, 0) for _ in range(3)]
    own = [dr.zeros(mi.UInt32, 0) for _ in range(4)]
    return dict(A=e3, B=e3, wa=e3[0], wb=e3[0], own=own), rows


def _launch_bounds(count: np.ndarray) -> list[tuple[int, int]]:
    """Runs ``[e0, e1)`` of whole edges whose ``count`` samples add up to at most
    :data:`SAMPLES` (or one edge alone), in order."""
    out, e0 = [], 0
    ends = np.cumsum(count)
    while e0 < len(count):
        base = int(ends[e0 - 1]) if e0 else 0
        e1 = max(e0 + 1, int(np.searchsorted(ends, base + SAMPLES, "right")))
        out.append((e0, e1))
        e0 = e1
    return out


def _states(
    scene: mi.Scene,
    table: ObjectTable,
    proj: Projector,
    edges: FeatureEdges,
    max_qi: int,
) -> tuple[dict[str, np.ndarray], np.ndarray, dict[str, np.ndarray]]:
    """The ``edges`` clipped (:func:`_clip`'s rows) and their samples cast (:data:`SAMPLES`
    at a time): the state ``2 QI + through_glass`` of each clipped edge's first sample, and
    where two neighbouring samples of an edge differ, the ``changes``: the edge, the two
    samples' film parameters ``ulo``, ``uhi`` and states ``slo``, ``shi`` (in order along
    each edge). The rays count to ``max_qi + 1``: the parts beyond ``max_qi`` are told apart,
    then dropped. The samples' parameters, points and states are made in Dr.Jit (no array
    per sample in numpy)."""
    U, F64 = mi.UInt32, mi.Float64
    jit, rows = _clip(proj, edges)
    count = rows["count"]
    first = np.concatenate([[0], np.cumsum(count)[:-1]]).astype(np.int64)
    rays = SegmentVisibility.of_jit(
        scene,
        table,
        proj.origin,
        jit.pop("A"),
        jit.pop("B"),
        jit.pop("wa"),
        jit.pop("wb"),
        jit.pop("own"),
        max_qi + 1,
        proj.forward if proj.ortho else None,  # parallel rays from the near plane
        proj.near,
    )
    state0, changes = [], []
    for e0, e1 in _launch_bounds(count):
        at = jit_array(U, (first[e0:e1] - first[e0]).astype(np.uint32))
        size = jit_array(U, count[e0:e1].astype(np.uint32))
        total = int(first[e1 - 1] - first[e0] + count[e1 - 1])
        # each sample's edge: the edges' first samples marked (each edge has its own: two
        # samples at least), summed along the samples; a plain scatter (a reduction into a
        # small array would bake its size into the kernel: a kernel per size)
        mark = dr.zeros(U, total)
        dr.scatter(mark, 1, at)
        owner = dr.cumsum(mark) - 1
        j = dr.arange(U, total)
        k = F64(j) - F64(dr.gather(U, at, owner))
        u = mi.Float(k / F64(dr.gather(U, size, owner) - 1))  # exact in double, then single
        # (the launch's first edge as an evaluated scalar: a literal would make a kernel of
        # the ray loop for every value)
        qi, glass = rays.states(owner + dr.opaque(U, e0), u)
        state = qi * 2 + dr.select(glass, 1, 0)
        dr.eval(state)
        # the changes between neighbouring samples of one edge
        i = dr.arange(U, total - 1)
        i = dr.compress(
            (dr.gather(U, owner, i) == dr.gather(U, owner, i + 1))
            & (dr.gather(U, state, i) != dr.gather(U, state, i + 1))
        )
        got = [dr.gather(U, state, at)]
        if dr.width(i):  # (an array of no entry does not mix with a literal)
            got += [dr.gather(U, x, y) for x, y in ((owner, i), (state, i), (state, i + 1))]
        else:
            got += [dr.zeros(U, 0)] * 3
        dr.eval(*got)
        s0, edge, slo, shi = (np.asarray(x.numpy(), np.int64) for x in got)
        change = np.asarray(i.numpy(), np.int64) + first[e0]
        edge += e0
        state0.append(s0)
        changes.append(
            dict(
                edge=edge,
                ulo=(change - first[edge]) / (count[edge] - 1),
                uhi=(change + 1 - first[edge]) / (count[edge] - 1),
                slo=slo,
                shi=shi,
            )
        )
    z = np.zeros(0, np.int64)
    if not changes:
        return rows, z, dict(edge=z, ulo=z * 0.0, uhi=z * 0.0, slo=z, shi=z)
    return rows, np.concatenate(state0), _joined(changes)


def _rays(
    scene: mi.Scene,
    table: ObjectTable,
    proj: Projector,
    clipped: dict[str, np.ndarray],
    max_qi: int,
) -> SegmentVisibility:
    """The visibility rays to the ``clipped`` edges, counting to ``max_qi + 1``."""
    A, B, wa, wb = clipped["A"], clipped["B"], clipped["wa"], clipped["wb"]
    axis = proj.forward if proj.ortho else None  # parallel rays from the near plane
    return SegmentVisibility(
        scene, table, proj.origin, A, B, wa, wb, clipped["faces"], max_qi + 1, axis, proj.near
    )


def _split(
    length: np.ndarray, state0: np.ndarray, changes: dict[str, np.ndarray], split_u: np.ndarray
) -> tuple[np.ndarray, ...]:
    """The visibility pieces of edges of film length ``length`` whose first sample has state
    ``state0`` and whose state changes at ``split_u`` (``changes``' edge and state after):
    ``(edge, u0, u1, state, first, last)`` per piece, in order along each edge, the edges in
    order (``first``, ``last``: the edge's first and last piece). Each edge's pieces depend on
    that edge alone."""
    n_e = len(length)
    # pieces: per edge, boundaries 0, changes..., 1, each with the state of the samples after
    # its start
    pe = np.concatenate([np.arange(n_e), changes["edge"]])
    u0 = np.concatenate([np.zeros(n_e), split_u])
    st = np.concatenate([state0, changes["shi"]])
    order = np.lexsort((u0, pe))
    pe, u0, st = pe[order], u0[order], st[order]
    u1 = np.append(u0[1:], 1.0)
    last = np.append(pe[1:] != pe[:-1], True)
    u1[last] = 1.0
    # a sliver shorter than MIN_PIECE px takes its neighbour's state: at a mesh vertex the
    # surfaces around the vertex lie within the guard band of the rays to the edge's end
    short = (u1 - u0) * length[pe] < MIN_PIECE
    first_of = np.append(True, pe[1:] != pe[:-1])
    alone = first_of & last
    nxt = np.append(st[1:], -1)
    prv = np.append(-1, st[:-1])
    st = np.where(short & ~alone, np.where(first_of, nxt, prv), st)
    # runs of one state along one edge are one piece
    head = first_of | (st != np.append(-1, st[:-1]))
    g = np.flatnonzero(head)
    pe, u0, st = pe[g], u0[g], st[g]
    u1 = np.append(u0[1:], 1.0)
    last = np.append(pe[1:] != pe[:-1], True)
    u1[last] = 1.0
    first_of = np.append(True, pe[1:] != pe[:-1])
    return pe, u0, u1, st, first_of, last


def _shown(
    proj: Projector,
    clipped: dict[str, np.ndarray],
    pieces: tuple[np.ndarray, ...],
    max_qi: int,
    edge_id: np.ndarray,
) -> dict[str, np.ndarray]:
    """The pieces (:func:`_split`'s) of the ``clipped`` edges that are not behind more than
    ``max_qi`` surfaces, with their 3-D and film ends and their edge's fields; ``edge``: the
    edge's number among all the clipped edges (``edge_id`` of each of these), ``rank``: the
    piece's among its edge's."""
    pe, u0, u1, st, first_of, last = pieces
    rank = np.arange(len(pe)) - np.searchsorted(pe, pe)
    keep = st // 2 <= max_qi
    pe, u0, u1, st, first_of, last, rank = (x[keep] for x in (pe, u0, u1, st, first_of, last, rank))
    A, B, wa, wb = clipped["A"], clipped["B"], clipped["wa"], clipped["wb"]
    s0 = _film_param_to_3d(u0, wa[pe], wb[pe])
    s1 = _film_param_to_3d(u1, wa[pe], wb[pe])
    p0 = A[pe] + s0[:, None] * (B[pe] - A[pe])
    p1 = A[pe] + s1[:, None] * (B[pe] - A[pe])
    xy0, d0 = proj.film(p0)
    xy1, d1 = proj.film(p1)
    out = dict(state=st.astype(np.int64), p0=p0, p1=p1, xy0=xy0, d0=d0, xy1=xy1, d1=d1)
    for k in ("kind", "object_id", "prim", "va", "vb"):
        out[k] = clipped[k][pe]
    out["kind"] = out["kind"].astype(np.int64)
    out.update(edge=edge_id[pe], rank=rank, node_a=first_of & clipped["whole_a"][pe])
    out["node_b"] = last & clipped["whole_b"][pe]
    out["last"] = last
    return out


class _Pieces:
    """Visibility-split pieces of the clipped feature edges (arrays of length P).

    The samples are cast a launch at a time (:func:`_states`); an edge whose samples all
    agree is one piece at once, the others wait with their changes for one bisection launch
    over all of them (each launch traces the ray loop again). The nodes that are not welded
    vertices are numbered from ``edges.max_node() + 1`` on in the order of all the pieces
    (those dropped too), edge by edge, a piece's ``-1 - n`` for its end on the image
    frame."""

    def __init__(
        self,
        scene: mi.Scene,
        table: ObjectTable,
        proj: Projector,
        edges: FeatureEdges | ViewEdges,
        max_qi: int,
    ) -> None:
        shown, counts, waiting, state0, changes = [], [], [], [], []
        n_edges = n_waiting = 0
        first = getattr(edges, "first", False)
        for c in range(0, max(len(edges), 1), EDGE_CHUNK):
            clipped, s0, ch = _states(
                scene, table, proj, edges.take(slice(c, c + EDGE_CHUNK)), max_qi
            )
            changed = np.zeros(len(s0), bool)
            changed[ch["edge"]] = True
            # an edge whose samples agree: one piece, [0, 1] (kept where it is in sight)
            plain = np.flatnonzero(~changed & (s0 // 2 <= max_qi))
            one, n = np.ones(len(plain), bool), len(plain)
            pieces = (np.arange(n), np.zeros(n), np.ones(n), s0[plain], one, one)
            rows = {k: v[plain] for k, v in clipped.items()}
            shown.append(_shown(proj, rows, pieces, max_qi, n_edges + plain))
            counts.append(np.where(changed, 0, 1))  # the others' counts: once split
            # the others wait, with their changes, for the bisections
            wait = np.flatnonzero(changed)
            rows = {k: v[wait] for k, v in clipped.items()}
            rows["edge_id"] = n_edges + wait
            waiting.append(rows)
            state0.append(s0[wait])
            ch["edge"] = n_waiting + np.searchsorted(wait, ch["edge"])
            changes.append(ch)
            n_edges += len(s0)
            n_waiting += len(wait)
            del clipped, rows
            if first:  # the launch's memory handed back (see the end)
                dr.flush_malloc_cache()
                release_freed_memory()
        counts = np.concatenate(counts)
        if n_waiting:
            rows, ch = _joined(waiting), _joined(changes)
            edge_id = rows.pop("edge_id")
            ulo, uhi = _rays(scene, table, proj, rows, max_qi).bisect(
                ch["edge"], ch["ulo"], ch["uhi"], ch["slo"], ITERATIONS
            )
            pieces = _split(rows["length"], np.concatenate(state0), ch, 0.5 * (ulo + uhi))
            shown.append(_shown(proj, rows, pieces, max_qi, edge_id))
            counts[edge_id] = np.bincount(pieces[0], minlength=len(edge_id))
        out = _joined(shown)
        order = lexsort_ints((out["rank"], out["edge"]))
        out = {k: v[order] for k, v in out.items()}
        # nodes: welded vertices at the edges' own ends, else a number per piece, after all
        # the pieces of the edges before its own; the two pieces of a change share a node
        # (their states differ: a point where two strokes meet, unchained), an end on the
        # image frame is a node of its own
        before = np.concatenate([[0], np.cumsum(counts)[:-1]]).astype(np.int64)
        n = edges.max_node() + 1 + before[out.pop("edge")] + out.pop("rank")
        va, vb, last = out.pop("va"), out.pop("vb"), out.pop("last")
        self.node0 = np.where(out.pop("node_a"), va, n)
        self.node1 = np.where(last, np.where(out.pop("node_b"), vb, -1 - n), n + 1)
        for key, value in out.items():
            setattr(self, key, value)
        if first:
            # what Dr.Jit keeps of the launches for reuse: the next view's would fit in it, a
            # one-off extraction's memory is better handed back
            dr.flush_malloc_cache()

    def __len__(self) -> int:
        return len(self.state)


def _mesh_strokes(pieces: _Pieces, chain_angle: float) -> list[Stroke]:
    if not len(pieces):
        return []
    n_states = int(pieces.state.max()) + 1
    cls = pieces.kind * n_states + pieces.state
    piece, rev, start, closed = chain_order(
        pieces.node0,
        pieces.node1,
        cls,
        pieces.xy1 - pieces.xy0,
        pieces.xy0 - pieces.xy1,
        chain_angle,
    )
    # every chain's vertices in one set of arrays: the start of each piece as walked, and
    # for an open chain the end of its last piece (with that piece's object and primitive)
    count = np.diff(start)
    size = count + ~closed
    first = np.concatenate([[0], np.cumsum(size)[:-1]])
    chain = np.repeat(np.arange(len(count)), count)
    at = first[chain] + np.arange(len(piece)) - start[chain]
    last = start[1:][~closed] - 1
    end_at = first[~closed] + count[~closed]
    total = int(size.sum())

    def gather(a0: np.ndarray, a1: np.ndarray) -> np.ndarray:
        out = np.empty((total, *a0.shape[1:]), a0.dtype)
        r = rev.reshape(-1, *([1] * (a0.ndim - 1)))
        out[at] = np.where(r, a1[piece], a0[piece])
        out[end_at] = np.where(r[last], a0[piece[last]], a1[piece[last]])
        return out

    xy = gather(pieces.xy0, pieces.xy1)
    pos = gather(pieces.p0, pieces.p1)
    dep = gather(pieces.d0, pieces.d1)
    oid = gather(pieces.object_id, pieces.object_id)
    prim = gather(pieces.prim, pieces.prim)
    head = piece[start[:-1]]
    st = pieces.state[head].tolist()
    kinds = pieces.kind[head].tolist()
    ring = (closed & (size >= 3)).tolist()
    bounds = np.append(first, total).tolist()
    oid, prim = oid.astype(np.uint32, copy=False), prim.astype(np.uint32, copy=False)
    return [
        Stroke.trusted(
            KINDS[kinds[c]],
            xy[a:b],
            pos[a:b],
            dep[a:b],
            oid[a:b],
            prim[a:b],
            st[c] // 2,
            bool(st[c] % 2),
            ring[c],
        )
        for c, (a, b) in enumerate(itertools.pairwise(bounds))
    ]


def cast_depth_range(scene: mi.Scene, sensor: mi.Sensor, table: ObjectTable) -> tuple[float, float]:
    """The nearest and farthest finite depth of the pixel-centre hits: the range of the
    G-buffer's ``Z`` layer, cast here when no G-buffer is given ((0, 1) if nothing is hit)."""
    w, h = (int(v) for v in sensor.film().crop_size())
    x, y = film_grid(w, h)
    hits = cast(scene, pixel_rays(sensor, x, y), table, detail="minimal")
    z = np.asarray(hits.depth(sensor).numpy())
    z = z[np.isfinite(z)]
    return (float(z.min()), float(z.max())) if z.size else (0.0, 1.0)


def resampled(stroke: Stroke, spacing: float, ortho: bool = False) -> Stroke:
    """``stroke`` with vertices added so that none of its segments is longer than ``spacing``
    px on the film: film positions evenly along each segment, world positions and depths
    perspective-correct (exact on a straight 3-D segment; linear for an ``ortho`` camera),
    object and primitive those of the segment's first vertex."""
    return resampled_all([stroke], spacing, ortho)[0]


def resampled_all(strokes: list[Stroke], spacing: float, ortho: bool = False) -> list[Stroke]:
    """:func:`resampled` of every stroke, as array operations over all their vertices."""
    size = sizes(strokes)
    todo = np.flatnonzero(size >= 2).tolist()
    out = list(strokes)
    if not todo:
        return out
    sub = [strokes[i] for i in todo]
    n = size[todo]
    closed = np.array([s.closed for s in sub])
    p = np.concatenate([s.points for s in sub])
    pos = np.concatenate([s.position for s in sub])
    dep = np.concatenate([s.depth for s in sub])
    oid = np.concatenate([s.object_id for s in sub])
    prim = np.concatenate([s.prim for s in sub])
    first = np.concatenate([[0], np.cumsum(n)[:-1]])
    # the segments: every vertex of a closed stroke, all but the last of an open one
    n_seg = np.where(closed, n, n - 1)
    seg_of = np.repeat(np.arange(len(sub)), n_seg)
    ends = first[seg_of] + np.arange(len(seg_of)) - np.repeat(np.cumsum(n_seg) - n_seg, n_seg)
    nxt = np.where(ends + 1 == first[seg_of] + n[seg_of], first[seg_of], ends + 1)
    seg = np.hypot(*(p[nxt] - p[ends]).T)
    k = np.maximum(1, np.ceil(seg / spacing).astype(np.int64))
    owner = np.repeat(np.arange(len(ends)), k)
    u = (np.arange(len(owner)) - np.repeat(np.cumsum(k) - k, k)) / k[owner]
    a, b = ends[owner], nxt[owner]
    # an open stroke's last vertex after its last segment's samples
    count = np.bincount(seg_of, weights=k, minlength=len(sub)).astype(np.int64) + ~closed
    start = np.concatenate([[0], np.cumsum(count)[:-1]])
    total = int(count.sum())
    A = np.empty(total, np.int64)
    U = np.zeros(total)
    body = np.ones(total, bool)
    body[(start + count - 1)[~closed]] = False
    A[body], U[body] = a, u
    B = A.copy()
    B[body] = b
    A[~body] = B[~body] = (first + n - 1)[~closed]
    s3 = U.copy() if ortho else _film_param_to_3d(U, dep[A], dep[B])
    s3[~body] = 0.0
    P = p[A] + U[:, None] * (p[B] - p[A])
    Q = pos[A] + s3[:, None] * (pos[B] - pos[A])
    if ortho:
        D = dep[A] + U * (dep[B] - dep[A])
    else:
        D = 1.0 / ((1.0 - U) / dep[A] + U / dep[B])
    for j, (i, s) in enumerate(zip(todo, sub, strict=True)):
        r = slice(start[j], start[j] + count[j])
        out[i] = Stroke(
            kind=s.kind,
            points=P[r],
            position=Q[r],
            depth=D[r],
            object_id=oid[A[r]],
            prim=prim[A[r]],
            qi=s.qi,
            through_glass=s.through_glass,
            closed=s.closed,
        )
    return out


def _normals(points: np.ndarray, size: np.ndarray, closed: np.ndarray) -> np.ndarray:
    """:func:`~mi_npr.strokes.outlines.normals_2d` of many polylines at once: ``points``
    (M, 2) their vertices one after the other, ``size`` and ``closed`` (S,) each one's."""
    first = np.concatenate([[0], np.cumsum(size)[:-1]])
    last = first + size - 1
    owner = np.repeat(np.arange(len(size)), size)
    i = np.arange(len(points))
    ring = closed[owner]
    # the neighbours of a vertex; past an end: the other end (closed), the vertex (open)
    nxt = np.where(i == last[owner], np.where(ring, first[owner], i), i + 1)
    prv = np.where(i == first[owner], np.where(ring, last[owner], i), i - 1)
    t = points[nxt] - points[prv]
    length = np.hypot(t[:, 0], t[:, 1])
    with np.errstate(invalid="ignore", divide="ignore"):
        u = np.where(length[:, None] > 0, t / length[:, None], 0.0)
    return np.stack([-u[:, 1], u[:, 0]], -1)


def _depth_seen(
    scene: mi.Scene, sensor: mi.Sensor, table: ObjectTable, xy: np.ndarray, camera: Projection
) -> np.ndarray:
    """The depth (N,) of the first opaque surface seen through film positions ``xy`` (N, 2)
    (:func:`~mi_npr.strokes.outlines.probe`'s ``depth``, +inf on a miss), from the hits'
    positions alone."""
    return ids_and_depths(scene, sensor, table, xy, camera)[1]


def _add_depth_behind(
    scene: mi.Scene,
    sensor: mi.Sensor,
    table: ObjectTable,
    strokes: list[Stroke],
    camera: Projection,
) -> None:
    if not strokes:
        return
    size = sizes(strokes)
    pts = np.concatenate([s.points for s in strokes])
    nrm = _normals(pts, size, np.array([s.closed for s in strokes]))
    # the two sides of a block of vertices at a time (memory: the hits of one block)
    behind = np.empty(len(pts))
    for b in range(0, len(pts), BESIDE_BLOCK):
        p, n = pts[b : b + BESIDE_BLOCK], nrm[b : b + BESIDE_BLOCK]
        depth = _depth_seen(
            scene, sensor, table, np.concatenate([p + BESIDE * n, p - BESIDE * n]), camera
        )
        behind[b : b + len(p)] = np.maximum(depth[: len(p)], depth[len(p) :])
    for s, part in zip(strokes, np.split(behind, np.cumsum(size)[:-1]), strict=True):
        s.depth_behind = part


#: The largest ``max_qi``.
MAX_QI = 64

#: What the extraction takes (the ``strokes`` drawing's geometric parameters; the defaults are
#: the drawing's).
EXTRACT_PARAMS: tuple[Param, ...] = (
    Param(
        "crease_angle", float, 134.0, "draw creases below this dihedral angle (0 = off)", dihedral
    ),
    Param(
        "chain_angle",
        float,
        60.0,
        "strokes turn by less than this at a joint, degrees",
        real_range(0, 180),
    ),
    Param(
        "max_qi",
        int,
        1,
        "hidden lines behind more surfaces than this are not drawn (0: visible lines only; 1: "
        "an object's own back edges and what lies behind one sheet)",
        integer_range(0, MAX_QI),
    ),
    Param(
        "raytree_depth",
        int,
        0,
        "levels of ray trees for reflection, refraction and shadow strokes (0: none)",
        integer_range(0, MAX_DEPTH),
    ),
)
_P = {p.name: p for p in EXTRACT_PARAMS}


def _arg(name: str, value: Any) -> Any:
    """``value`` checked against :data:`EXTRACT_PARAMS` (``None`` is no value here)."""
    if value is None:
        raise ParameterError(f"extract_strokes: parameter {name!r} = None: give a value")
    return check_arg("extract_strokes", _P[name], value)


def _depth_range(value: Any) -> tuple[float, float]:
    try:
        lo, hi = (float(v) for v in value)
        ok = np.isfinite(lo) and np.isfinite(hi) and lo <= hi
    except (TypeError, ValueError):
        ok = False
    if not ok:
        raise ParameterError(
            f"extract_strokes: depth_range = {shown(value)}: expected (near, far), finite, "
            "near <= far"
        )
    return lo, hi


def _pairs(value: Any) -> np.ndarray:
    """``intersect`` checked: pairs of object ids, an integer array (K, 2) >= 0."""
    try:
        a = np.asarray(value)
        ok = a.ndim == 2 and a.shape[1] == 2
        ok = ok and (a.size == 0 or (np.issubdtype(a.dtype, np.integer) and bool((a >= 0).all())))
    except (TypeError, ValueError):
        ok = False
    if not ok:
        raise ParameterError(
            f"extract_strokes: intersect = {shown(value)}: expected pairs of object ids, "
            "integers >= 0 of shape (K, 2)"
        )
    return a.astype(np.int64)


def extract_strokes(
    scene: mi.Scene,
    sensor: mi.Sensor,
    table: ObjectTable | None = None,
    *,
    crease_angle: float = _P["crease_angle"].default,
    chain_angle: float = _P["chain_angle"].default,
    max_qi: int = _P["max_qi"].default,
    raytree_depth: int = _P["raytree_depth"].default,
    depth_range: tuple[float, float] | None = None,
    objects: Mapping[int, str] | None = None,
    params: Mapping[str, Any] | None = None,
    resample: float | None = None,
    depth_behind: bool = True,
    intersect: np.ndarray | None = None,
    keep_topology: bool = True,
) -> Strokes:
    """Every stroke of ``scene`` seen by ``sensor`` (module docstring). ``table``: the scene's
    object table (built if not given); ``depth_range``: the frame's nearest and farthest finite
    depth (default: :func:`cast_depth_range`); ``resample``: the longest segment on the film, in
    pixels (:func:`resampled`; ``None``: vertices only where the geometry turns), so that
    per-vertex attributes such as ``depth_behind`` are sampled along straight edges too;
    ``max_qi``: the parts of mesh edges behind more than ``max_qi`` surfaces are left out (the
    visibility rays stop counting there, which is what makes hidden lines affordable on a
    large model, where most edges lie deep inside it); ``raytree_depth``: levels of the ray
    trees whose reflection, refraction and shadow lines are added (:mod:`~mi_npr.strokes.raytree`;
    0: none; the hard-shadow lights); ``depth_behind``: sample each vertex's
    ``Stroke.depth_behind`` (two rays a vertex; ``False`` leaves it ``None``, for a use that
    never reads it, such as a style without ``gray``); ``intersect``: the pairs of meshes
    ((K, 2) object ids) whose intersection lines are looked for (default every pair; those a
    view's id image shows side by side, :func:`~mi_npr.strokes.intersect.touching_pairs`, for
    its visible lines); ``keep_topology``: keep the meshes' topology for the next view
    (:func:`~mi_npr.strokes.edges.topology`; ``False``, for a scene seen once, drops it once
    this view's edges are classified: the faces' planes at once, the rows that the visibility
    rays read when the mesh strokes are found). Parameters as in
    :data:`EXTRACT_PARAMS`."""
    crease_angle = _arg("crease_angle", crease_angle)
    chain_angle = _arg("chain_angle", chain_angle)
    max_qi = _arg("max_qi", max_qi)
    raytree_depth = _arg("raytree_depth", raytree_depth)
    if depth_range is not None:
        depth_range = _depth_range(depth_range)
    if resample is not None and not (
        isinstance(resample, (int, float)) and not isinstance(resample, bool) and resample > 0
    ):
        raise ParameterError(f"extract_strokes: resample = {shown(resample)}: must be > 0 px")
    if intersect is not None:
        intersect = _pairs(intersect)
    table = table if table is not None else object_table(scene)
    proj = Projector(sensor)
    camera = proj.camera
    edges = view_edges(
        table,
        proj.origin,
        crease_angle,
        intersect=True if intersect is None else intersect,
        direction=proj.forward if proj.ortho else None,
    )
    first = edges.first
    if not keep_topology:  # the view's rows alone are read from here on
        forget_topology(table, edges)
    pieces = _Pieces(scene, table, proj, edges, max_qi)
    del edges
    strokes = _mesh_strokes(pieces, chain_angle)
    del pieces
    strokes += outline_strokes(scene, sensor, table, camera, depth_range)
    if raytree_depth:
        strokes += raytree_strokes(scene, sensor, table, camera, raytree_depth)
    strokes = [s for s in strokes if len(s) >= 2]
    if resample:
        strokes = resampled_all(strokes, resample, ortho=proj.ortho)
    if depth_behind:
        _add_depth_behind(scene, sensor, table, strokes, camera)
    if depth_range is None:
        depth_range = cast_depth_range(scene, sensor, table)
    order = {k: i for i, k in enumerate(KINDS)}
    strokes.sort(key=lambda s: (order[s.kind], s.qi, s.through_glass))
    if first:  # a one-off extraction: its temporaries handed back (see ViewEdges.first)
        release_freed_memory()
    return Strokes(
        strokes,
        proj.width,
        proj.height,
        objects=dict(objects if objects is not None else table.names),
        depth_range=(float(depth_range[0]), float(depth_range[1])),
        camera=proj.camera,
        params=dict(params or {}),
    )

"""Chaining: straight pieces that share endpoints joined into polylines.

Each piece has two ends, each at a *node* (a welded mesh vertex, or a point that belongs to this
piece alone: a visibility change, a cut by the image frame), and a *class*: its edge kind and
visibility state. At a node, two ends of one class are joined when the stroke turns there by
less than ``max_turn`` degrees (the angle between the direction it arrives in and the one it
leaves in, on the film). A joint where either piece is shorter than :data:`SHORT` px on the film
never breaks a chain by turning: on a finely tessellated surface the polygonal silhouette
zig-zags between sub-pixel edges, and the turns there are the tessellation's, not corners of
the drawing (a piece of zero length turns by 0).
Where three or more ends of a class meet (a junction), the straightest pair is joined first,
then the straightest of the ends left, and so on (ties: the lower end numbers, end ``e`` being
piece ``e % P``'s end ``e // P``): the bar of a T runs on and its stem ends there, as a
draughtsman draws it; a corner where every turn is sharper than ``max_turn`` ends them all.

Pieces of different classes never join, so a stroke ends where the kind or the visibility
changes. Every piece belongs to exactly one chain, once: no edge is drawn twice. A chain that
returns to its first piece is closed.
"""

from __future__ import annotations

import math

import numpy as np

from .order import lexsort_ints

#: Pieces shorter than this on the film (pixels) never break a chain by turning.
SHORT = 1.0


def _links(
    node0: np.ndarray,
    node1: np.ndarray,
    cls: np.ndarray,
    dir0: np.ndarray,
    dir1: np.ndarray,
    max_turn: float,
    short: float = SHORT,
) -> np.ndarray:
    """``link`` (2P,): the end joined to each end (-1: none); end ``e`` is piece ``e % P``'s
    end ``e // P``."""
    n = len(cls)
    ends_node = np.concatenate([node0, node1]).astype(np.int64)
    ends_cls = np.concatenate([cls, cls]).astype(np.int64)
    ends_dir = np.concatenate([dir0, dir1]).astype(np.float64)
    order = lexsort_ints((ends_cls, ends_node))
    key_node, key_cls = ends_node[order], ends_cls[order]
    new = np.ones(len(order), bool)
    new[1:] = (key_node[1:] != key_node[:-1]) | (key_cls[1:] != key_cls[:-1])
    starts = np.flatnonzero(new)
    sizes = np.diff(np.append(starts, len(order)))
    group = np.repeat(np.arange(len(starts)), sizes)
    # every pair of ends (i < j in the sorted order) within a group
    last = np.repeat(starts + sizes, sizes)  # one past the group's end, per sorted position
    count = last - np.arange(len(order)) - 1
    i = np.repeat(np.arange(len(order)), count)
    j = i + 1 + (np.arange(count.sum()) - np.repeat(np.cumsum(count) - count, count))
    e1, e2 = order[i], order[j]
    e1, e2 = np.minimum(e1, e2), np.maximum(e1, e2)
    g = group[i]
    u1, u2 = ends_dir[e1], ends_dir[e2]
    l1, l2 = np.hypot(*u1.T), np.hypot(*u2.T)
    with np.errstate(invalid="ignore", divide="ignore"):
        # arriving along -u1, leaving along u2: cos of the turn = cos angle(-u1, u2)
        cos = np.where((l1 == 0) | (l2 == 0), 1.0, -np.einsum("ij,ij->i", u1, u2) / (l1 * l2))
    ok = e1 % n != e2 % n
    if max_turn < 180:
        ok &= (l1 < short) | (l2 < short) | (cos > math.cos(math.radians(max_turn)))
    g, cos, e1, e2 = g[ok], cos[ok], e1[ok], e2[ok]
    # greedy: per group, the straightest pair of unused ends, one pair per group a round
    rank = np.lexsort((e2, e1, -cos, g))
    g, e1, e2 = g[rank], e1[rank], e2[rank]
    used = np.zeros(2 * n, bool)
    first1, first2 = [], []
    while len(g):
        live = ~used[e1] & ~used[e2]
        g, e1, e2 = g[live], e1[live], e2[live]
        if not len(g):
            break
        _, at = np.unique(g, return_index=True)  # the first (straightest) left in each group
        first1.append(e1[at])
        first2.append(e2[at])
        used[e1[at]] = used[e2[at]] = True
    e1 = np.concatenate(first1) if first1 else np.zeros(0, np.int64)
    e2 = np.concatenate(first2) if first2 else np.zeros(0, np.int64)
    link = np.full(2 * n, -1, np.int64)
    link[e1], link[e2] = e2, e1
    return link


def _jump(ptr: np.ndarray, value: np.ndarray, op: np.ufunc) -> tuple[np.ndarray, np.ndarray]:
    """Pointer jumping: ``op`` of ``value`` along each state's chain of pointers, ``ptr``
    pointing to itself at a chain's root (whose value must be neutral for ``op``), and the
    state each one's pointer reaches (the root; a state of a cycle where there is none)."""
    ptr, value = ptr.copy(), value.copy()
    act = np.flatnonzero(ptr[ptr] != ptr)
    for _ in range(len(ptr).bit_length() + 1):
        if not len(act):
            break
        p = ptr[act]
        value[act] = op(value[act], value[p])
        ptr[act] = ptr[p]
        act = act[ptr[ptr[act]] != ptr[act]]
    return value, ptr


def chain_order(
    node0: np.ndarray,
    node1: np.ndarray,
    cls: np.ndarray,
    dir0: np.ndarray,
    dir1: np.ndarray,
    max_turn: float,
    short: float = SHORT,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The chains of ``P`` pieces as flat arrays: ``piece`` (P,) in chain order, ``reverse``
    (P,) (walked from its end 1 to its end 0), ``start`` (C + 1,) the offsets of the ``C``
    chains in them, and ``closed`` (C,).

    ``node0``, ``node1`` (P,): the nodes of each piece's ends; ``cls`` (P,): its class;
    ``dir0``, ``dir1`` (P, 2): the film vector of the piece leaving each end (from end 0
    to end 1, and back; its length is the piece's on the film); ``short``: :data:`SHORT`.

    Chains are walked in this order: the open ones first, each from the lower-numbered piece
    of its two end pieces, from its free end (end 0 for a lone piece), in the order of that
    piece; then the closed ones, each from its lowest-numbered piece, from end 0, in the order
    of that piece. Found without a loop over pieces: a *state* ``p + side P`` is "piece ``p``
    entered at its end ``side``", each state has one successor (the piece joined at the other
    end), and pointer jumping over the predecessors gives every state its chain's first state
    and its rank there (``O(P log P)``)."""
    n = len(cls)
    z = np.zeros(0, np.int64)
    if n == 0:
        return z, z.astype(bool), np.zeros(1, np.int64), z.astype(bool)
    link = _links(node0, node1, cls, dir0, dir1, max_turn, short)
    state = np.arange(2 * n)
    piece, side = state % n, state // n
    exit_end = piece + (1 - side) * n
    nxt = link[exit_end]
    succ = np.where(nxt >= 0, (nxt % n) + (nxt // n) * n, -1)  # the joined end is the entry
    pred = np.full(2 * n, -1, np.int64)
    pred[succ[succ >= 0]] = state[succ >= 0]
    zero = np.zeros(2 * n, np.int64)
    # closed loops: the states whose predecessors never end; each is cut before the state
    # "its lowest piece entered at end 0" (the other orientation's cycle is not cut)
    _, root = _jump(np.where(pred >= 0, pred, state), zero, np.add)
    loop = pred[root] >= 0
    if loop.any():
        lowest, _ = _jump(np.where(loop, succ, state), piece, np.minimum)
        pred[loop & (piece == lowest) & (side == 0)] = -1
    # every state's first state (its head) and its rank from it
    rank, head = _jump(np.where(pred >= 0, pred, state), (pred >= 0).astype(np.int64), np.add)
    hp, hs = piece[head], side[head]
    # the last state of each open chain: from it, the chain's other end piece
    last_of = np.zeros(2 * n, np.int64)
    tail = succ < 0
    last_of[head[tail]] = state[tail]
    other = piece[last_of[head]]
    closed_head = loop[head]
    # each open chain twice (once from each end): keep the walk from its lower end piece;
    # each loop twice (its two orientations): keep the one that was cut
    keep = np.where(closed_head, pred[head] < 0, (hp < other) | ((hp == other) & (hs == 0)))
    s = np.flatnonzero(keep)
    # open chains before closed ones, by their first piece, then along the chain
    order = lexsort_ints((rank[s], hp[s], closed_head[s]))
    s = s[order]
    new = np.append(True, head[s][1:] != head[s][:-1])
    start = np.append(np.flatnonzero(new), len(s))
    return piece[s], side[s] == 1, start, closed_head[s][new]


def chain_pieces(
    node0: np.ndarray,
    node1: np.ndarray,
    cls: np.ndarray,
    dir0: np.ndarray,
    dir1: np.ndarray,
    max_turn: float,
    short: float = SHORT,
) -> list[tuple[list[tuple[int, bool]], bool]]:
    """The chains of ``P`` pieces: ``(steps, closed)`` where ``steps`` lists ``(piece,
    reversed)`` in order (``reversed``: walked from its end 1 to its end 0); the arguments and
    the order are :func:`chain_order`'s."""
    piece, rev, start, closed = chain_order(node0, node1, cls, dir0, dir1, max_turn, short)
    return [
        (list(zip(piece[a:b].tolist(), rev[a:b].tolist(), strict=True)), bool(c))
        for a, b, c in zip(start[:-1].tolist(), start[1:].tolist(), closed.tolist(), strict=True)
    ]

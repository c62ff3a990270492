"""Chaining: straight pieces that share endpoints joined into polylines.

Each piece has two ends, each at a *node* (a welded mesh vertex, or a point that belongs to this
piece alone: a visibility change, a cut by the image frame), and a *class*: its edge kind and
visibility state. At a node, the ends of one class are joined when

- exactly two ends of that class meet there (three or more: a T- or Y-junction of that class,
  where every stroke of the class ends), and
- the stroke turns there by less than ``max_turn`` degrees (the angle between the direction it
  arrives in and the one it leaves in, on the film; a piece of zero length on the film never
  breaks a chain).

Pieces of different classes never join, so a stroke ends where the kind or the visibility
changes. Every piece belongs to exactly one chain, once: no edge is drawn twice. A chain that
returns to its first piece is closed.
"""

from __future__ import annotations

import math

import numpy as np


def chain_pieces(
    node0: np.ndarray,
    node1: np.ndarray,
    cls: np.ndarray,
    dir0: np.ndarray,
    dir1: np.ndarray,
    max_turn: float,
) -> list[tuple[list[tuple[int, bool]], bool]]:
    """The chains of ``P`` pieces: ``(steps, closed)`` where ``steps`` lists ``(piece,
    reversed)`` in order (``reversed``: walked from its end 1 to its end 0).

    ``node0``, ``node1`` (P,): the nodes of each piece's ends; ``cls`` (P,): its class;
    ``dir0``, ``dir1`` (P, 2): the film direction of the piece leaving each end (from end 0
    towards end 1, and back)."""
    n = len(cls)
    ends_node = np.concatenate([node0, node1]).astype(np.int64)
    ends_cls = np.concatenate([cls, cls]).astype(np.int64)
    ends_dir = np.concatenate([dir0, dir1]).astype(np.float64)
    # end e: piece e % n, side e // n
    order = np.lexsort((ends_cls, ends_node))
    key_node, key_cls = ends_node[order], ends_cls[order]
    new = np.ones(len(order), bool)
    new[1:] = (key_node[1:] != key_node[:-1]) | (key_cls[1:] != key_cls[:-1])
    starts = np.flatnonzero(new)
    sizes = np.diff(np.append(starts, len(order)))
    link = np.full(2 * n, -1, np.int64)
    cos_max = math.cos(math.radians(max_turn))
    for s in starts[sizes == 2]:
        e1, e2 = int(order[s]), int(order[s + 1])
        if e1 % n == e2 % n:
            continue
        u1, u2 = ends_dir[e1], ends_dir[e2]
        l1, l2 = math.hypot(*u1), math.hypot(*u2)
        if l1 > 0 and l2 > 0:
            # arriving along -u1, leaving along u2: turn = angle(-u1, u2)
            if -float(np.dot(u1, u2)) / (l1 * l2) <= cos_max and max_turn < 180:
                continue
        link[e1], link[e2] = e2, e1
    used = np.zeros(n, bool)
    chains: list[tuple[list[tuple[int, bool]], bool]] = []

    def walk(p: int, entry_side: int) -> tuple[list[tuple[int, bool]], bool]:
        steps: list[tuple[int, bool]] = []
        cur, side = p, entry_side
        while True:
            used[cur] = True
            steps.append((cur, side == 1))
            exit_end = cur + (1 - side) * n
            nxt = int(link[exit_end])
            if nxt < 0:
                return steps, False
            q, q_side = nxt % n, nxt // n
            if used[q]:
                return steps, q == p
            cur, side = q, q_side

    for p in range(n):
        if used[p]:
            continue
        if link[p] < 0:
            chains.append(walk(p, 0))
        elif link[p + n] < 0:
            chains.append(walk(p, 1))
    for p in range(n):  # what is left: closed loops
        if not used[p]:
            chains.append(walk(p, 0))
    return chains

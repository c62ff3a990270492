"""Eq. 5.1 on rendered G-buffers: the contour of a sphere is 1 px thick and inside its mask."""

from __future__ import annotations

import numpy as np
import pytest

import mi_npr
from mi_npr import kernels as K

BALL = '<shape type="sphere" id="ball"><point name="center" x="0.3" y="-0.2" z="4"/></shape>'
WALL = (
    '<shape type="rectangle" id="wall"><transform name="to_world">'
    '<scale value="30"/><translate z="20"/></transform></shape>'
)
C, T = (next(p.default for p in K.LINES_PARAMS if p.name == n) for n in ("c", "t"))


def _boundaries(mask):
    """Pixels of ``mask`` with an 8-neighbour (resp. a 4-neighbour) outside it."""
    h, w = mask.shape
    pad = np.pad(mask, 1, mode="edge")
    out8 = np.zeros_like(mask)
    out4 = np.zeros_like(mask)
    for dy in (-1, 0, 1):
        for dx in (-1, 0, 1):
            outside = ~pad[1 + dy : 1 + dy + h, 1 + dx : 1 + dx + w]
            out8 |= outside
            if abs(dy) + abs(dx) == 1:
                out4 |= outside
    return mask & out8, mask & out4


@pytest.mark.parametrize(("width", "height"), [(32, 24), (64, 48), (128, 96)])
@pytest.mark.parametrize("backdrop", ["wall", "background"])
def test01_sphere_contour_is_one_pixel_inside_the_mask(write_scene, width, height, backdrop):
    body = BALL + (WALL if backdrop == "wall" else "")
    gb = mi_npr.render(write_scene(body, width=width, height=height))
    ball = gb.object_id == gb.find_object("ball")
    # Against the background the frame's range ends at the sphere's rim: give a far plane.
    far = None if backdrop == "wall" else 20.0
    p = np.asarray(K.depth_contours(K.normalize_depth(gb.numpy("Z"), far=far), C, T))
    lit = p > 0
    rim8, rim4 = _boundaries(ball)
    assert not (lit & ~ball).any()  # inside the sphere's mask
    assert not (lit & ~rim8).any()  # on its boundary: 1 px thick
    assert (lit | ~rim4).all()  # every pixel with a 4-neighbour off the sphere is drawn
    assert np.all(p[lit] == 1.0)  # a clear depth step: full strength, no gray fringe


def test02_frame_range_loses_the_farthest_rim(write_scene):
    """The documented caveat of the default normalisation: the farthest object pixel gets the
    background's depth 1, so its contour against the background vanishes; ``far`` fixes it."""
    gb = mi_npr.render(write_scene(BALL, width=64, height=48))
    z = np.where(np.isfinite(gb.numpy("Z")), gb.numpy("Z"), -np.inf)
    farthest = np.unravel_index(np.argmax(z), z.shape)
    frame = np.asarray(K.depth_contours(K.normalize_depth(gb.numpy("Z")), C, T))
    fixed = np.asarray(K.depth_contours(K.normalize_depth(gb.numpy("Z"), far=20.0), C, T))
    assert frame[farthest] == 0.0 and fixed[farthest] == 1.0
    assert np.asarray(K.lines(gb))[farthest] == 1.0  # the chain's background is beyond


def test03_lines_of_a_box_in_front_of_a_wall(write_scene):
    """The whole chain on a rendered box: its outline, 1 px, and nothing on the wall."""
    box = (
        '<shape type="cube" id="box"><transform name="to_world">'
        '<rotate y="1" angle="30"/><scale value="0.8"/><translate z="5"/></transform></shape>'
    )
    gb = mi_npr.render(write_scene(box + WALL, width=64, height=48))
    inside = gb.object_id == gb.find_object("box")
    ink = np.asarray(K.lines(gb, id_edges=False, crease_angle=0.0)) > 0  # depth alone
    rim8, rim4 = _boundaries(inside)
    assert not (ink & ~rim8).any()
    assert ink[rim4].mean() > 0.9  # eq. 5.2 may shorten the ends of lines, nothing else
    drawn = np.asarray(K.lines(gb)) > 0  # the defaults: + boundaries + creases
    assert not (drawn & ~inside).any()  # still nothing on the wall
    crease = drawn & ~rim8
    assert crease.any()  # the box's vertical crease shows now, 1 px wide
    assert crease.sum(axis=1).max() == 1

"""The stroke types: :class:`Stroke` (one polyline with per-vertex attributes) and
:class:`Strokes` (every stroke of one image, with what is needed to read them).

Film coordinates: ``x`` to the right, ``y`` down, pixel ``(i, j)`` spans ``[i, i+1] x [j, j+1]``
(its centre is ``(i + 0.5, j + 0.5)``), one SVG user unit per pixel.
"""

from __future__ import annotations

from collections.abc import Iterator, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from ..errors import ParameterError
from ..gbuffer import Projection

#: Every edge kind, in drawing order (later kinds are drawn over earlier ones). ``reflection``,
#: ``refraction`` and ``shadow`` are the ray trees' lines (:mod:`mi_npr.strokes.raytree`).
KINDS = (
    "silhouette",
    "border",
    "crease",
    "material",
    "intersection",
    "reflection",
    "refraction",
    "shadow",
)


@dataclass(eq=False)
class Stroke:
    """One stroke: an ordered polyline of ``N`` vertices and what each vertex is.

    The kind and the visibility state (``qi``, ``through_glass``) hold for the whole stroke:
    strokes are split where either changes. ``closed``: the last vertex joins the first (it is
    not repeated).
    """

    kind: str
    points: np.ndarray  # (N, 2) float64: film x, y (sub-pixel)
    position: np.ndarray  # (N, 3) float64: world-space point
    depth: np.ndarray  # (N,) float64: camera depth along the view axis (the Z layer's)
    object_id: np.ndarray  # (N,) uint32: object of the face drawn at this vertex
    prim: np.ndarray  # (N,) uint32: primitive (triangle) index in that object
    qi: int = 0  # quantitative invisibility: opaque surfaces in front (0: visible)
    through_glass: bool = False  # seen through at least one dielectric surface
    closed: bool = False
    #: (N,) float64: camera depth of the farthest surface seen one pixel to either side of the
    #: vertex (+inf: the background); eq. 5.1's neighbour depth (:mod:`mi_npr.strokes.style`).
    depth_behind: np.ndarray | None = None

    def __post_init__(self) -> None:
        if self.kind not in KINDS:
            raise ParameterError(f"stroke kind {self.kind!r}: expected one of {', '.join(KINDS)}")
        n = len(self.points)
        self.points = np.asarray(self.points, np.float64).reshape(n, 2)
        self.position = np.asarray(self.position, np.float64).reshape(n, 3)
        self.depth = np.asarray(self.depth, np.float64).reshape(n)
        self.object_id = np.asarray(self.object_id, np.uint32).reshape(n)
        self.prim = np.asarray(self.prim, np.uint32).reshape(n)
        if self.depth_behind is not None:
            self.depth_behind = np.asarray(self.depth_behind, np.float64).reshape(n)

    @classmethod
    def trusted(
        cls,
        kind: str,
        points: np.ndarray,
        position: np.ndarray,
        depth: np.ndarray,
        object_id: np.ndarray,
        prim: np.ndarray,
        qi: int,
        through_glass: bool,
        closed: bool,
    ) -> Stroke:
        """A stroke of arrays that already have the dtypes and shapes of the fields (the
        extraction's own, made by the thousand): built without the checks."""
        s = object.__new__(cls)
        s.__dict__.update(
            kind=kind,
            points=points,
            position=position,
            depth=depth,
            object_id=object_id,
            prim=prim,
            qi=qi,
            through_glass=through_glass,
            closed=closed,
            depth_behind=None,
        )
        return s

    def __len__(self) -> int:
        return len(self.points)

    @property
    def visible(self) -> bool:
        """No opaque surface in front (``qi == 0``)."""
        return self.qi == 0

    def length(self) -> float:
        """Length in pixels along the polyline (the closing segment included when closed)."""
        p = np.concatenate([self.points, self.points[:1]]) if self.closed else self.points
        return float(np.hypot(*np.diff(p, axis=0).T).sum()) if len(p) > 1 else 0.0


def sizes(strokes: Sequence[Stroke]) -> np.ndarray:
    """The number of vertices of each of ``strokes`` (int64): ``len`` of each one's points,
    without a Python call per stroke to ``Stroke.__len__``."""
    return np.fromiter((len(s.points) for s in strokes), np.int64, len(strokes))


@dataclass
class Strokes:
    """Every stroke of one image of ``width`` x ``height`` pixels, seen by ``camera``.

    ``objects``: object id -> name (the object table's); ``depth_range``: the frame's nearest
    and farthest finite depth (what eq. 5.1 normalises with, :mod:`mi_npr.strokes.style`).
    """

    strokes: list[Stroke]
    width: int
    height: int
    objects: Mapping[int, str] = field(default_factory=dict)
    depth_range: tuple[float, float] = (0.0, 1.0)
    camera: Projection | None = None
    #: The extraction's parameters (crease angle, chain angle, max_qi), for the files' headers.
    params: Mapping[str, Any] = field(default_factory=dict)

    def __iter__(self) -> Iterator[Stroke]:
        return iter(self.strokes)

    def __len__(self) -> int:
        return len(self.strokes)

    def __getitem__(self, i: int) -> Stroke:
        return self.strokes[i]

    def of_kind(self, kind: str) -> list[Stroke]:
        """The strokes of edge kind ``kind``."""
        return [s for s in self.strokes if s.kind == kind]

    def visible(self) -> list[Stroke]:
        """The strokes with ``qi == 0``."""
        return [s for s in self.strokes if s.qi == 0]

    def name_of(self, object_id: int) -> str:
        """The name of object ``object_id`` (``object_<id>`` if not in the table)."""
        return str(self.objects.get(int(object_id), f"object_{int(object_id)}"))

"""The :class:`Contour` type: one traced contour piece of one object, as pixel positions."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True, eq=False)
class Contour:
    """One contour piece of one object, as a chain of pixels in tracing order.

    ``points`` is an ``(N, 2)`` ``int32`` array of pixel positions ``(x, y)``: ``x`` is the
    column, ``y`` the row (row 0 at the top), consecutive points are 8-neighbours. ``closed``
    says the chain comes back to its first point (its last and first points are 8-neighbours, or
    it is a single pixel). ``is_hole`` says the piece bounds a hole of the object (another object
    or the background seen through it) rather than its outside.

    Two contours are equal when every field is (``points`` compared element-wise).
    """

    object_id: int
    name: str
    points: np.ndarray
    closed: bool = True
    is_hole: bool = False

    def __post_init__(self) -> None:
        pts = np.ascontiguousarray(np.asarray(self.points).reshape(-1, 2), dtype=np.int32)
        pts.flags.writeable = False
        object.__setattr__(self, "points", pts)
        object.__setattr__(self, "object_id", int(self.object_id))
        object.__setattr__(self, "closed", bool(self.closed))
        object.__setattr__(self, "is_hole", bool(self.is_hole))

    def __len__(self) -> int:
        return len(self.points)

    @property
    def xs(self) -> np.ndarray:
        """The columns of the points."""
        return self.points[:, 0]

    @property
    def ys(self) -> np.ndarray:
        """The rows of the points."""
        return self.points[:, 1]

    def __eq__(self, other: object) -> bool:
        if not isinstance(other, Contour):
            return NotImplemented
        return (
            self.object_id == other.object_id
            and self.name == other.name
            and self.closed == other.closed
            and self.is_hole == other.is_hole
            and np.array_equal(self.points, other.points)
        )

    __hash__ = None  # type: ignore[assignment]

    def __repr__(self) -> str:
        kind = "hole" if self.is_hole else "outer"
        end = "closed" if self.closed else "open"
        first = tuple(int(v) for v in self.points[0]) if len(self.points) else None
        return (
            f"Contour({self.name!r}, id={self.object_id}, {kind}, {end}, "
            f"{len(self.points)} px from {first})"
        )

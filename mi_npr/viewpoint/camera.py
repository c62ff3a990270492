"""The best view as a Mitsuba camera, and the viewing sphere as a picture.

:func:`sensor_xml` writes a :class:`~mi_npr.viewpoint.BestView` as a Mitsuba scene file holding
one ``perspective`` sensor (:func:`mi_npr.camera.sensor_xml`, the one writer of a camera as a
sensor): its ``lookat`` and the search's field of view, with the clip planes, sampler and film
(size and reconstruction filter; not a crop window, since the view is rated over the whole film)
of the scene's own sensor. The file loads on its own, can be ``<include>``d in a scene, and its
``<sensor>`` element pasted into one.

:func:`sphere_image` draws the quality over the viewing sphere with matplotlib (the ``plots``
extra): two orthographic views of the sphere, the hemisphere facing ``front`` and the opposite
one, coloured by quality (viridis, with a colour bar), with the three great circles that bound
the 8 spherical triangles of Fig. 1, the evaluated viewpoints as dots and the best one as a red
ring. The quality between the rated directions is interpolated on the sphere (a von Mises-Fisher
kernel as wide as their spacing).
"""

from __future__ import annotations

import math

import mitsuba as mi
import numpy as np

from .. import camera as C
from ..camera.sensor import DEFAULT_WIDTH
from ..scene import sensor_of
from .search import BestView


def sensor_xml(best: BestView, scene: mi.Scene, sensor: int | mi.Sensor = 0) -> str:
    """The XML text of a file holding ``best`` as a Mitsuba sensor with the id ``best_view``
    (module docstring).

    Copied from the scene's ``sensor``: what :func:`mi_npr.camera.sensor_xml` copies. Written:
    ``fov`` = the horizontal field of view used by the search. A scene without a sensor gets a
    :data:`mi_npr.camera.sensor.DEFAULT_WIDTH` pixel wide film of the search's aspect ratio and
    :data:`~mi_npr.camera.sensor.DEFAULT_SPP` samples per pixel.
    """
    like, size = None, None
    if scene.sensors() or isinstance(sensor, mi.Sensor):
        like = sensor_of(scene, sensor)
    else:
        w = DEFAULT_WIDTH
        size = (w, max(1, round(w * best.size[1] / best.size[0])))
    comment = (
        f"best view by mi-npr: measure {best.measure}, quality {best.quality:.6g}, "
        f"depth {best.depth}, {best.evaluations} evaluations at {best.size[0]}x{best.size[1]}"
    )
    cam = C.Camera(best.origin, best.target, best.up, best.fov)
    return C.sensor_xml(cam, like, size=size, name="best_view", comment=comment)


# -- the viewing sphere as a picture ----------------------------------------------------------

#: How to get matplotlib, which draws the quality sphere (the ``plots`` extra).
PLOTS_HINT = "pip install 'mi-npr[plots]'"


def plots_missing() -> str | None:
    """``None`` where matplotlib can be imported, else a one-line note saying how to get it."""
    try:
        import matplotlib  # noqa: F401
    except ImportError:
        return f"matplotlib is not installed ({PLOTS_HINT})"
    return None


def _interpolate(points: np.ndarray, directions: np.ndarray, values: np.ndarray) -> np.ndarray:
    """Smooth interpolation of ``values`` given at unit ``directions`` onto unit ``points``:
    a normalised von Mises-Fisher kernel as wide as the samples' mean spacing."""
    spacing = math.sqrt(4.0 * math.pi / len(directions))
    kappa = 1.0 / spacing**2
    out = np.empty(len(points))
    for s in range(0, len(points), 4096):
        c = points[s : s + 4096] @ directions.T
        w = np.exp(kappa * (c - c.max(axis=1, keepdims=True)))
        out[s : s + 4096] = (w @ values) / w.sum(axis=1)
    return out


def _disc_frame(front: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    _, left, up = C.view_frame(front, np.zeros(3))  # a camera at `front` looking at the centre
    return -left, up  # image right, image up


def _unit(v: np.ndarray) -> np.ndarray:
    v = np.asarray(v, np.float64).reshape(-1, 3)
    return v / np.linalg.norm(v, axis=-1, keepdims=True)


def sphere_image(
    directions: np.ndarray,
    qualities: np.ndarray,
    best: np.ndarray | None = None,
    evaluated: np.ndarray | None = None,
    front: np.ndarray | None = None,
    size: int = 240,
    title: str = "",
    labels: tuple[str, str] = ("front", "back"),
) -> np.ndarray:
    """An RGB uint8 picture of the viewing sphere coloured by quality (module docstring).

    ``directions`` (S, 3) and ``qualities`` (S,) are samples of the quality (e.g. from
    :func:`~mi_npr.viewpoint.quality_map`); ``best`` (3,) and ``evaluated`` (E, 3) are
    directions from the centre (or viewpoints relative to the target); ``front`` is the direction
    the left disc faces (default +z), ``labels`` the captions of the two discs. Each disc is
    ``size`` pixels wide. Needs matplotlib (the ``plots`` extra): an ``ImportError`` saying so
    where it is missing.
    """
    if why := plots_missing():
        raise ImportError(f"sphere_image: {why}")
    # imported here: matplotlib is optional (the plots extra) and slow to import
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure
    from matplotlib.patches import Circle

    d = _unit(directions)
    q = np.asarray(qualities, np.float64).reshape(-1)
    lo, hi = (float(q.min()), float(q.max())) if q.size else (0.0, 1.0)
    hi = hi if hi > lo else lo + 1.0
    front = _unit([0.0, 0.0, 1.0] if front is None else front)[0]
    m, top, below = 12, 24 if title else 8, 64  # margins in pixels: sides, title, labels + bar
    W, H = 2 * size + 3 * m, top + size + below
    fig = Figure(figsize=(W / 100, H / 100), dpi=100)
    FigureCanvasAgg(fig)
    yy, xx = np.mgrid[0:size, 0:size]
    u, v = (xx + 0.5) / size * 2 - 1, 1 - (yy + 0.5) / size * 2
    inside = u * u + v * v < 1.0
    t = np.linspace(0, 2 * np.pi, 361)[:, None]
    E = np.eye(3)  # the great circles x = 0, y = 0, z = 0:
    circles = [np.cos(t) * E[(i + 1) % 3] + np.sin(t) * E[(i + 2) % 3] for i in range(3)]
    marks = []  # (directions, scatter style)
    if evaluated is not None:
        marks.append((_unit(evaluated), dict(s=14, c="white", edgecolors="black", linewidths=0.6)))
    if best is not None:
        marks.append((_unit(best), dict(s=90, facecolors="none", edgecolors="red", linewidths=2)))
    image = None
    for k, fr in enumerate((front, -front)):
        right, up = _disc_frame(fr)
        if k == 1:
            right = -right  # seen from behind: the two discs join like a map
        ax = fig.add_axes(((m + k * (size + m)) / W, below / H, size / W, size / H))
        ax.set_axis_off()
        ax.set(xlim=(-1, 1), ylim=(-1, 1), aspect="equal")
        values = np.full((size, size), np.nan)
        if d.size:
            p = u[inside, None] * right + v[inside, None] * up
            p += np.sqrt(np.clip(1 - u[inside] ** 2 - v[inside] ** 2, 0, 1))[:, None] * fr
            values[inside] = _interpolate(p, d, q)
        image = ax.imshow(values, cmap="viridis", vmin=lo, vmax=hi, extent=(-1, 1, -1, 1),
                          interpolation="nearest")  # fmt: skip
        ax.add_patch(Circle((0, 0), 1, fill=False, lw=1, color="0.2"))
        for c in circles:
            x, y = c @ right, c @ up
            hidden = c @ fr < 0
            ax.plot(np.where(hidden, np.nan, x), np.where(hidden, np.nan, y), lw=0.7, color="0.2")
        for pts, style in marks:
            pts = pts[pts @ fr > 0]
            ax.scatter(pts @ right, pts @ up, zorder=3, **style)
        ax.text(0.5, -0.02, labels[k], transform=ax.transAxes, ha="center", va="top", fontsize=8)
    cax = fig.add_axes((m / W, 22 / H, (W - 2 * m) / W, 10 / H))
    fig.colorbar(image, cax=cax, orientation="horizontal").ax.tick_params(labelsize=7)
    if title:
        fig.text(m / W, 1 - 6 / H, title, va="top", fontsize=8)
    fig.canvas.draw()
    return np.asarray(fig.canvas.buffer_rgba())[..., :3].copy()

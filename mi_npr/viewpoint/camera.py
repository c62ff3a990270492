"""The best view as a Mitsuba camera, and the viewing sphere as a picture.

:func:`sensor_xml` writes a :class:`~mi_npr.viewpoint.BestView` as a ``perspective`` sensor with
a ``lookat`` transform, and with the field of view, clip planes, sampler and film (size and
reconstruction filter; not a crop window, since the view is rated over the whole film) of the
scene's own sensor. The ``<sensor>`` element is wrapped in a
``<scene version="3.0.0">`` root, because Mitsuba loads or includes only files with a versioned
root and rejects a ``version`` attribute on a nested ``<sensor>``: so the file loads on its own
(``mi.load_file`` gives a scene with that one sensor), ``<include filename="..."/>`` adds its
sensor to a scene, and the ``<sensor>`` element can be pasted into a scene in place of its own.

:func:`sphere_image` draws the quality over the viewing sphere with numpy (Pillow only writes
the labels): two orthographic views of the sphere, the hemisphere facing ``front`` and the
opposite one, coloured by quality (viridis), with the three great circles that bound the 8
spherical triangles of Fig. 1, the evaluated viewpoints as dots and the best one as a red ring.
"""

from __future__ import annotations

import math
from xml.sax.saxutils import quoteattr

import mitsuba as mi
import numpy as np

from ..scene import sensor_of
from .search import BestView

_FILTERS = {
    "BoxFilter": "box",
    "TentFilter": "tent",
    "GaussianFilter": "gaussian",
    "LanczosSincFilter": "lanczos",
    "MitchellNetravaliFilter": "mitchell",
    "CatmullRomFilter": "catmullrom",
}
_SAMPLERS = {
    "IndependentSampler": "independent",
    "StratifiedSampler": "stratified",
    "MultijitterSampler": "multijitter",
    "OrthogonalSampler": "orthogonal",
    "LowDiscrepancySampler": "ldsampler",
}


def _vec(v: np.ndarray) -> str:
    return ", ".join(f"{float(x) + 0.0:.9g}" for x in v)  # + 0.0: no "-0"


def _rfilter_xml(film: mi.Film) -> str:
    rf = film.rfilter()
    kind = _FILTERS.get(rf.class_name())
    if kind is None:  # an unknown filter: hdrfilm's default (gaussian) rather than a bad guess
        return ""
    r = float(rf.radius())
    if kind == "gaussian":  # Mitsuba's gaussian has radius = 4 stddev
        return f'<rfilter type="gaussian"><float name="stddev" value="{r / 4:.9g}"/></rfilter>'
    if kind == "tent":
        return f'<rfilter type="tent"><float name="radius" value="{r:.9g}"/></rfilter>'
    if kind == "lanczos":
        return f'<rfilter type="lanczos"><integer name="lobes" value="{round(r)}"/></rfilter>'
    return f'<rfilter type="{kind}"/>'


#: Film and sampler written for a scene that has no sensor to copy them from.
DEFAULT_WIDTH = 512
DEFAULT_SPP = 16


def _sensor_settings(best: BestView, scene: mi.Scene, sensor: int | mi.Sensor) -> dict:
    """What the written sensor copies from the scene's (module docstring)."""
    if not scene.sensors() and not isinstance(sensor, mi.Sensor):
        w = DEFAULT_WIDTH
        h = max(1, round(w * best.size[1] / best.size[0]))
        return dict(near=1e-2, far=1e4, size=(w, h), rfilter="", sampler="independent",
                    spp=DEFAULT_SPP)  # fmt: skip
    s = sensor_of(scene, sensor)
    params = mi.traverse(s)
    film = s.film()
    size = tuple(int(v) for v in film.size())
    return dict(
        near=float(params["near_clip"]) if "near_clip" in params else 1e-2,
        far=float(params["far_clip"]) if "far_clip" in params else 1e4,
        size=size,
        rfilter=_rfilter_xml(film),
        sampler=_SAMPLERS.get(s.sampler().class_name(), "independent"),
        spp=int(s.sampler().sample_count()),
    )


def sensor_xml(best: BestView, scene: mi.Scene, sensor: int | mi.Sensor = 0) -> str:
    """The XML text of a file holding ``best`` as a Mitsuba sensor (module docstring).

    Copied from the scene's ``sensor``: near/far clip, sampler type and sample count, film
    width/height (not its crop window: the view is rated, and written, for the whole film),
    reconstruction filter (type and size; a ``mitchell`` filter's
    B and C fall back to their defaults). Written: ``fov`` = the horizontal field of view used
    by the search, with ``fov_axis="x"``. A scene without a sensor gets a ``DEFAULT_WIDTH``
    pixel wide film of the search's aspect ratio, ``DEFAULT_SPP`` samples per pixel.
    """
    st = _sensor_settings(best, scene, sensor)
    w, h = st["size"]
    rfilter = f"\n            {st['rfilter']}" if st["rfilter"] else ""
    comment = (
        f"best view by mi-npr: measure {best.measure}, quality {best.quality:.6g}, "
        f"depth {best.depth}, {best.evaluations} evaluations at {best.size[0]}x{best.size[1]}"
    )
    return f"""<?xml version="1.0" encoding="utf-8"?>
<!-- {comment}.
     Load this file on its own, <include> it in a scene, or paste the <sensor> element. -->
<scene version="3.0.0">
    <sensor type="perspective" id={quoteattr("best_view")}>
        <float name="fov" value="{best.fov:.9g}"/>
        <string name="fov_axis" value="x"/>
        <float name="near_clip" value="{st["near"]:.9g}"/>
        <float name="far_clip" value="{st["far"]:.9g}"/>
        <transform name="to_world">
            <lookat origin="{_vec(best.origin)}"
                    target="{_vec(best.target)}"
                    up="{_vec(best.up)}"/>
        </transform>
        <sampler type="{st["sampler"]}">
            <integer name="sample_count" value="{st["spp"]}"/>
        </sampler>
        <film type="hdrfilm">
            <integer name="width" value="{w}"/>
            <integer name="height" value="{h}"/>{rfilter}
        </film>
    </sensor>
</scene>
"""


# -- the viewing sphere as a picture ----------------------------------------------------------

# viridis at 9 evenly spaced stops (matplotlib's table), interpolated linearly.
_VIRIDIS = np.array(
    [
        [68, 1, 84], [71, 44, 122], [59, 81, 139], [44, 113, 142], [33, 144, 141],
        [39, 173, 129], [92, 200, 99], [170, 220, 50], [253, 231, 37],
    ],
    dtype=np.float64,
)  # fmt: skip


def colormap(t: np.ndarray) -> np.ndarray:
    """Viridis colours (float RGB in [0, 255]) for values ``t`` in [0, 1]."""
    t = np.clip(np.nan_to_num(np.asarray(t, np.float64)), 0.0, 1.0) * (len(_VIRIDIS) - 1)
    i = np.minimum(t.astype(np.int64), len(_VIRIDIS) - 2)
    f = (t - i)[..., None]
    return _VIRIDIS[i] * (1 - f) + _VIRIDIS[i + 1] * f


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
    from .idbuffer import view_frame

    _, left, up = view_frame(front, np.zeros(3))  # a camera at `front` looking at the centre
    return -left, up  # image right, image up


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
    ``size`` pixels wide.
    """
    from PIL import Image, ImageDraw

    d = np.asarray(directions, np.float64).reshape(-1, 3)
    d = d / np.linalg.norm(d, axis=-1, keepdims=True)
    q = np.asarray(qualities, np.float64).reshape(-1)
    lo, hi = (float(q.min()), float(q.max())) if q.size else (0.0, 1.0)
    span = hi - lo if hi > lo else 1.0
    front = np.array([0.0, 0.0, 1.0]) if front is None else np.asarray(front, np.float64)
    front = front / np.linalg.norm(front)
    m, top, bar = 12, 22 if title else 8, 44
    W, H = 2 * size + 3 * m, top + size + 18 + bar
    img = np.full((H, W, 3), 255.0)
    yy, xx = np.mgrid[0:size, 0:size]
    u = (xx + 0.5) / size * 2 - 1
    v = 1 - (yy + 0.5) / size * 2
    inside = u * u + v * v < 1.0
    zz = np.sqrt(np.clip(1 - u * u - v * v, 0, 1))
    marks: list[tuple[np.ndarray, int, tuple[int, int, int]]] = []
    if evaluated is not None:
        for e in np.asarray(evaluated, np.float64).reshape(-1, 3):
            marks.append((e, 2, (255, 255, 255)))
    if best is not None:
        marks.append((np.asarray(best, np.float64), 5, (230, 30, 30)))
    for k, fr in enumerate((front, -front)):
        right, up = _disc_frame(fr)
        if k == 1:
            right = -right  # seen from behind: the two discs join like a map
        p = u[..., None] * right + v[..., None] * up + zz[..., None] * fr
        p = p[inside]
        col = colormap((_interpolate(p, d, q) - lo) / span) if d.size else np.full((len(p), 3), 200)
        near_edge = np.min(np.abs(p), axis=1) < 1.2 / size  # the great circles x, y, z = 0
        col[near_edge] *= 0.35
        shade = 0.75 + 0.25 * (p @ fr)  # a little limb darkening, so it reads as a sphere
        disc = np.full((size, size, 3), 255.0)
        disc[inside] = col * shade[:, None]
        for mk, r, rgb in marks:
            mk = mk / np.linalg.norm(mk)
            if mk @ fr <= 0:
                continue
            cx, cy = (mk @ right + 1) / 2 * size, (1 - mk @ up) / 2 * size
            dist = np.hypot(xx + 0.5 - cx, yy + 0.5 - cy)
            disc[dist <= r + 1.0] = 0.0
            disc[dist <= r] = rgb
        x0 = m + k * (size + m)
        img[top : top + size, x0 : x0 + size] = disc
    # colour bar
    by, bx, bw = top + size + 18, m, W - 2 * m
    img[by : by + 12, bx : bx + bw] = colormap(np.linspace(0, 1, bw))[None]
    out = Image.fromarray(np.clip(img + 0.5, 0, 255).astype(np.uint8))
    draw = ImageDraw.Draw(out)
    if title:
        draw.text((m, 5), title, fill=(0, 0, 0))
    draw.text((m, top + size + 3), labels[0], fill=(0, 0, 0))
    draw.text((2 * m + size, top + size + 3), labels[1], fill=(0, 0, 0))
    draw.text((bx, by + 15), f"{lo:.4g}", fill=(0, 0, 0))
    label = f"{hi:.4g}"
    draw.text((bx + bw - 6 * len(label), by + 15), label, fill=(0, 0, 0))
    return np.asarray(out)

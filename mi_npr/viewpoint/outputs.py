"""What ``mi-npr best-view`` writes: the camera, a render from it, the quality sphere.

The files, in ``outdir``: ``<stem>_best_view.xml`` (the best view as a Mitsuba sensor,
:func:`~mi_npr.viewpoint.sensor_xml`), ``<stem>_best_view.png`` (the scene rendered from that
sensor, read back from the written file, with the scene's own integrator: what a user gets who
puts the sensor in the scene) and ``<stem>_quality_sphere.png`` (the viewing sphere coloured by
quality, :func:`~mi_npr.viewpoint.sphere_image`; the left disc faces the scene's own camera;
skipped with ``sphere=False`` (``--no-sphere``) or where matplotlib, the ``plots`` extra, is
missing). The picture costs no ray casting: it interpolates the qualities the search rated (plus
``samples`` more viewpoints if asked) into a fixed 2 x 240 pixel image.
Every file goes through :mod:`mi_npr.io` (temporary name, then rename).

**An empty or black view.** After the render, :func:`view_warning` looks at it: more than
:data:`EMPTY_FRACTION` of the best view's ID buffer background (no object hit, or a one-sided
face seen from behind: the measures' rule; ignored objects are not empty), or a mean linear
luminance of the rendered beauty under :data:`DARK_LUMINANCE`, gives a ``warnings.warn`` (the
CLI prints it as one line on stderr): the measures rated what they could see, and the scene may
need ``--allow-below``, ``--ignore`` or lights that reach the view.
"""

from __future__ import annotations

import os
import warnings
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import mitsuba as mi
import numpy as np

from .. import io
from ..camera import camera_of, fibonacci_sphere
from ..errors import SceneError
from ..params import check_arg, entry
from ..render import render
from ..scene import load_scene, merge_defines, sensor_of
from ..session import resize_sensor
from . import idbuffer
from .camera import plots_missing, sensor_xml, sphere_image
from .measures import check_measure
from .search import SEARCH_PARAMS, BestView, Viewing, check_shapes, search, viewing

#: Extra viewpoints rated for the quality sphere picture (Fibonacci lattice, allowed side
#: only): none by default, the search's own evaluations are drawn.
SPHERE_SAMPLES = 0
#: Bounds of :func:`view_warning`: the fraction of background pixels over which a view is
#: "mostly empty", the mean linear luminance (Rec. 709) under which it is "black".
EMPTY_FRACTION = 0.9
DARK_LUMINANCE = 0.01


def view_warning(empty: float, beauty: np.ndarray) -> str | None:
    """Why a rendered best view is not worth looking at (module docstring), or ``None``.
    ``empty``: the fraction of its pixels that are background; ``beauty`` (H, W, 3) linear RGB."""
    rgb = np.asarray(beauty, np.float64)[..., :3]
    lum = rgb @ np.array([0.2126, 0.7152, 0.0722]) if rgb.size else np.zeros(1)
    if not np.isfinite(lum).all():  # (the copy only where it changes something)
        lum = np.nan_to_num(lum)
    mean = float(np.mean(lum))
    why = []
    if empty > EMPTY_FRACTION:
        why.append(f"{100 * empty:.0f}% of it is background")
    if mean < DARK_LUMINANCE:
        why.append(f"its mean luminance is {mean:.3g}")
    return " and ".join(why) if why else None


def write_best_view(
    scene_path: str | os.PathLike[str],
    outdir: str | os.PathLike[str],
    measure: str,
    depth: int = 3,
    res: int = 128,
    *,
    stem: str | None = None,
    samples: int = SPHERE_SAMPLES,
    seed: int = 0,
    ignore: Sequence[str] = (),
    allow_below: bool = False,
    sphere: bool = True,
    defines: Mapping[str, Any] | None = None,
    resolution: tuple[int | None, int | None] | None = None,
    spp: int | None = None,
    frame: Sequence[str] = (),
    **more: Any,
) -> tuple[BestView, dict[str, Path]]:
    """Search the best view of the XML scene and write the three files (module docstring).

    ``ignore`` names objects whose pixels count as background, ``allow_below`` lets viewpoints
    below the scene's ground compete (:func:`best_view`); ``frame`` names the objects framed
    (default: the objects that matter); ``sphere=False`` skips the picture.
    Warns (``warnings.warn``) when the best view's render is mostly empty or black.
    ``defines`` fill the XML's ``<default>``s (the written film is the film they give). Returns
    the :class:`BestView` and the written paths by kind (``sensor``, ``render``, ``sphere``;
    no ``sphere`` where :func:`~mi_npr.viewpoint.plots_missing` says why).
    """
    check_measure(measure)
    depth = check_arg("write_best_view", entry(SEARCH_PARAMS, "depth"), depth)
    res = check_arg("write_best_view", entry(SEARCH_PARAMS, "res"), res)
    defines = merge_defines(defines, more)
    if spp is not None:  # --spp: the XML's spp default where the scene declares one (it may
        defines["spp"] = spp  # read ``$spp`` before an include declares it), else the sampler's
    scene = load_scene(scene_path, defines)
    if scene.sensors() and resolution is not None:  # --width/--height: the written film
        resize_sensor(scene.sensors()[0], resolution, None)
    try:
        check_shapes(scene)
    except SceneError as e:
        raise SceneError(f"{scene_path}: {e}") from None
    d = io.check_writable_dir(outdir, create=True)
    stem = stem or Path(scene_path).stem
    view = viewing(scene, res=res, ignore=ignore, allow_below=allow_below, frame=frame)
    best = search(scene, view, measure, depth)
    out: dict[str, Path] = {}
    with io.output_set():  # the XML and its PNGs together, or none of them
        text = sensor_xml(best, scene)
        sensor = mi.load_string(text).sensors()[0]
        out["sensor"] = io.write_text(d / f"{stem}_best_view.xml", text)
        gb = render(scene, sensor=sensor, seed=seed)
        out["render"] = io.write_png(d / f"{stem}_best_view.png", gb.beauty)
        ids = idbuffer.sparse_areas(
            scene, [best.origin], best.target, best.fov, best.size, best.world_up, view.polygons
        )
        empty = float(ids.values[ids.cols == 0].sum() / max(ids.values.sum(), 1))
        why = view_warning(empty, np.asarray(gb.beauty))
        if sphere and not plots_missing():  # the picture needs matplotlib (the plots extra)
            out["sphere"] = io.write_png(
                d / f"{stem}_quality_sphere.png", _sphere_picture(scene, view, best, stem, samples),
                linear=False,
            )  # fmt: skip
    if why:  # after the files are in place: a warning turned into an error keeps them
        warnings.warn(f"{stem}: the best view ({measure}) is mostly empty or black: {why}",
                      stacklevel=2)  # fmt: skip
    return best, out


def _sphere_picture(
    scene: mi.Scene, view: Viewing, best: BestView, stem: str, samples: int
) -> np.ndarray:
    """The quality sphere from the search's evaluations (and ``samples`` more viewpoints)."""
    dirs, q = best.viewpoints - best.target, best.qualities
    if samples:
        extra = fibonacci_sphere(int(samples))
        extra = extra[view.allowed(extra)]
        dirs = np.concatenate([dirs, extra])
        q = np.concatenate([q, view.qualities(scene, view.origins(extra), best.measure)])
    front = camera_of(sensor_of(scene)).origin - view.target if scene.sensors() else None
    if front is not None and not np.any(front):
        front = None
    return sphere_image(
        dirs,
        q,
        best.direction,
        best.viewpoints - best.target,
        front,
        title=f"{stem}: {best.measure}, best {best.quality:.4g} (red), evaluated (white)",
        labels=("seen from the scene's camera", "opposite side"),
    )

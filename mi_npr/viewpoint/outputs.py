"""What ``mi-npr best-view`` writes: the camera, a render from it, the quality sphere.

The files, in ``outdir``: ``<stem>_best_view.xml`` (the best view as a Mitsuba sensor,
:func:`~mi_npr.viewpoint.sensor_xml`), ``<stem>_best_view.png`` (the scene rendered from that
sensor, read back from the written file, with the scene's own integrator: what a user gets who
puts the sensor in the scene) and ``<stem>_quality_sphere.png`` (the viewing sphere coloured by
quality, :func:`~mi_npr.viewpoint.sphere_image`; the left disc faces the scene's own camera;
skipped where matplotlib, the ``plots`` extra, is missing).
Every file goes through :mod:`mi_npr.io` (temporary name, then rename).
"""

from __future__ import annotations

import os
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import mitsuba as mi
import numpy as np

from .. import io
from ..errors import SceneError
from ..params import check_arg, cli_param
from ..render import render
from ..scene import camera_of, load_scene, merge_defines, sensor_of
from .camera import plots_missing, sensor_xml, sphere_image
from .measures import check_measure
from .search import BestView, check_shapes, sample_sphere, search, viewing

#: Viewpoints rated for the quality sphere picture (Fibonacci lattice).
SPHERE_SAMPLES = 256


def write_best_view(
    scene_path: str | os.PathLike[str],
    outdir: str | os.PathLike[str],
    measure: str,
    depth: int = 4,
    res: int = 128,
    *,
    stem: str | None = None,
    samples: int = SPHERE_SAMPLES,
    seed: int = 0,
    ignore: Sequence[str] = (),
    defines: Mapping[str, Any] | None = None,
    **more: Any,
) -> tuple[BestView, dict[str, Path]]:
    """Search the best view of the XML scene and write the three files (module docstring).

    ``ignore`` names objects whose pixels count as background (:func:`best_view`).
    ``defines`` fill the XML's ``<default>``s (the written film is the film they give). Returns
    the :class:`BestView` and the written paths by kind (``sensor``, ``render``, ``sphere``;
    no ``sphere`` where :func:`~mi_npr.viewpoint.plots_missing` says why).
    """
    check_measure(measure)
    depth = check_arg("write_best_view", cli_param("best-view", "--depth"), depth)
    res = check_arg("write_best_view", cli_param("best-view", "--res"), res)
    scene = load_scene(scene_path, merge_defines(defines, more))
    try:
        check_shapes(scene)
    except SceneError as e:
        raise SceneError(f"{scene_path}: {e}") from None
    d = io.check_writable_dir(outdir, create=True)
    stem = stem or Path(scene_path).stem
    view = viewing(scene, res=res, ignore=ignore)
    best = search(scene, view, measure, depth)
    out: dict[str, Path] = {}
    with io.output_set():  # the XML and its PNGs together, or none of them
        text = sensor_xml(best, scene)
        sensor = mi.load_string(text).sensors()[0]
        out["sensor"] = io.write_text(d / f"{stem}_best_view.xml", text)
        gb = render(scene, sensor=sensor, seed=seed)
        out["render"] = io.write_png(d / f"{stem}_best_view.png", gb.beauty)
        if plots_missing():  # the picture needs matplotlib (the plots extra): skipped
            return best, out
        dirs, q = sample_sphere(scene, view, measure, samples)
        front = camera_of(sensor_of(scene)).origin - view.target if scene.sensors() else None
        if front is not None and not np.any(front):
            front = None
        picture = sphere_image(
            dirs,
            q,
            best.direction,
            best.viewpoints - best.target,
            front,
            title=f"{stem}: {measure}, best {best.quality:.4g} (red), evaluated (white)",
            labels=("seen from the scene's camera", "opposite side"),
        )
        out["sphere"] = io.write_png(d / f"{stem}_quality_sphere.png", picture, linear=False)
    return best, out

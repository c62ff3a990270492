"""Batches: one job per input with a progress bar, where one failure does not stop the others.

- :func:`run_jobs`: the in-process loop of ``mi-npr render`` (one job per scene).
- :func:`run`: ``mi-npr batch``, scenes x viewpoints (a :mod:`mi_npr.views` spec, or a list of
  :class:`~mi_npr.camera.Camera` given in memory) on Dask distributed: a ``LocalCluster``
  started here (``workers``; ``workers=0`` renders in this process), a running cluster
  (``scheduler="tcp://host:port"``) or a ``distributed.Client`` of the caller.

One job = one scene x one view, written to ``OUT/<scene stem>/<view id>.exr`` (+ the PNG/SVG
files ``mi-npr render`` writes, :func:`mi_npr.io.write_layered_outputs`) by the worker, all
together or none (atomic output sets). Before anything renders, the names every job would write
(:func:`job_files`, read off the writer) are checked across jobs and scenes
(:func:`check_outputs`): no file is written by two jobs. The worker returns the job's manifest
row (with ``workers=0``, a writer thread writes a job's files while the next jobs render,
:class:`_Writer`); only this process (the client) appends rows to ``OUT/manifest.jsonl``
(:mod:`mi_npr.io.manifest`), one line per finished or failed job, so a kill at any moment
leaves whole lines and whole output sets. ``resume`` skips a job only when its last row says
``done`` with the run's :func:`job_key` (scene content with every referenced file, settings,
the view's camera, mi-npr version) and every output it lists is inside OUT with the recorded
size; every other job runs again, and the files of its earlier set that the new one does not
write go with it.

Workers keep the scenes they loaded (an LRU of :data:`SCENE_CACHE` scenes keyed by path, content
hash and load settings) with their cameras, so a worker loads each scene once and its compiled
kernels serve every view; jobs are submitted scene by scene. ``threads_per_worker`` caps each
worker's Dr.Jit threads (``dr.set_thread_count``); a worker process runs one job at a time.
A job that raises, or whose worker dies (Dask's ``KilledWorker``), or that goes without
progress past its bound (``job_timeout``; the client stops it and restarts its worker), is
retried ``retries`` times, then recorded as ``failed`` with a one-line error while the others
go on.
"""

from __future__ import annotations

import contextlib
import functools
import hashlib
import itertools
import json
import logging
import os
import queue
import socket
import stat
import sys
import tempfile
import threading
import time
import warnings
from collections import OrderedDict
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any
from xml.etree import ElementTree as ET

import drjit as dr
import mitsuba as mi
import numpy as np
from tqdm import tqdm

from . import io
from ._variant import set_variant
from ._version import __version__
from .camera import camera_of, resolve, sensor_for
from .compose import raw_beauty
from .drawings import DRAWINGS, of_plugin, split_params
from .errors import (
    NprError,
    NprWarning,
    ParameterError,
    SceneError,
    check_input_file,
    for_terminal,
    one_line,
    shown,
)
from .io import check_writable_dir
from .io.manifest import MANIFEST, Appender, check_manifest, read_rows, scene_hash
from .memory import share_malloc_arena
from .params import (
    MAX_RETRIES,
    MAX_THREADS,
    MAX_WORKERS,
    Param,
    check_arg,
    integer_range,
    name_list,
    real_range,
)
from .pipeline import render_layers
from .render import render_views, views_per_launch
from .scene import scene_files
from .session import RENDER_PARAMS, SceneSession
from .viewpoint.outputs import view_warning
from .views import ViewSpec, cameras, parse_views


@dataclass
class JobResult:
    """What one job produced, or why it failed."""

    item: str
    outputs: list[Path] = field(default_factory=list)
    error: str | None = None
    seconds: float = 0.0

    @property
    def ok(self) -> bool:
        return self.error is None


def parse_define(text: str) -> tuple[str, str]:
    """``"name=value"`` -> ``(name, value)``; :class:`ParameterError` if malformed."""
    if not isinstance(text, str):
        raise ParameterError(f"-D {shown(text)}: expected the text name=value")
    name, sep, value = text.partition("=")
    name = name.strip()
    if not sep:
        raise ParameterError(f"-D {text!r}: expected name=value")
    if not name or not name.replace("_", "a").isalnum():
        raise ParameterError(f"-D {text!r}: {name!r} is not a valid parameter name")
    return name, value


def check_unique_stems(paths: Sequence[str]) -> None:
    """Two inputs with the same file stem would overwrite each other's outputs."""
    seen: dict[str, str] = {}
    for p in paths:
        stem = Path(p).stem
        if stem in seen and seen[stem] != p:
            raise ParameterError(f"{seen[stem]} and {p} would both write outputs named {stem!r}")
        seen[stem] = p


# -- the files of a job -----------------------------------------------------------------------

#: The stem of the probe render whose files :func:`job_files` reads off.
_PROBE_STEM = "STEM"


@functools.lru_cache(maxsize=32)
def job_files(
    drawings: tuple[str, ...] = (), only: str | None = None, svg_image: str = "embed"
) -> tuple[str, ...]:
    """What :func:`mi_npr.io.write_layered_outputs` appends to a job's stem for every file it
    writes with ``drawings`` on (and its ``only``, ``svg_image``): ``(".exr", ".png",
    "_lines.png", "_lines.svg")`` for the lines. Read off the writer itself, not a list kept
    beside it: a 4 x 4 render of a sphere with those drawings is written once per process into
    a temporary folder. Every name the writer gives starts with the stem (checked here), so
    two stems can only clash when one is a prefix of the other (:func:`check_outputs`)."""
    scene = mi.load_dict(
        {
            "type": "scene",
            "integrator": {"type": "path", "max_depth": 2},
            "ball": {"type": "sphere", "radius": 0.5},
            "camera": {
                "type": "perspective",
                "to_world": mi.ScalarTransform4f().look_at([0, 0, -3], [0, 0, 0], [0, 1, 0]),
                "film": {"type": "hdrfilm", "width": 4, "height": 4},
            },
        },
        optimize=False,
    )
    result = render_layers(scene, drawings, scene_drawings=False, spp=1)
    with tempfile.TemporaryDirectory(prefix="mi-npr-probe-") as d:
        written = io.write_layered_outputs(result, d, _PROBE_STEM, only=only, svg_image=svg_image)
    names = [p.name for p in written]
    if not all(n.startswith(_PROBE_STEM) for n in names):
        raise RuntimeError(f"the writer names files without their stem: {names}")
    return tuple(n[len(_PROBE_STEM) :] for n in names)


def scene_drawings(path: str | os.PathLike[str], defines: Mapping[str, Any] | None) -> set[str]:
    """The drawings a scene draws on its own (its integrator is a drawing's plugin, in the
    file or an include); every drawing when an integrator's type is a ``$define``."""
    found: set[str] = set()
    for xml in [Path(path), *(f for f in scene_files(path, defines) if f.suffix == ".xml")]:
        try:
            root = ET.parse(xml).getroot()
        except (ET.ParseError, OSError, RecursionError):
            continue
        for el in root.iter("integrator"):
            kind = el.get("type", "")
            if "$" in kind:
                return set(DRAWINGS)
            d = of_plugin(kind)
            if d is not None:
                found.add(d.name)
    return found


def check_outputs(
    jobs: Sequence[tuple[str, str | os.PathLike[str], str, Sequence[str]]],
    *,
    only: str | None = None,
    svg_image: str = "embed",
) -> None:
    """A :class:`ParameterError` naming both jobs when two of ``jobs`` would write one file,
    before anything renders. ``jobs``: ``(label, directory, stem, drawings)``; each writes the
    files of :func:`job_files` in its directory (view ``v`` with the lines writes
    ``v_lines.png``, the beauty of view ``v_lines`` too)."""
    by_dir: dict[str, list[tuple[str, str, tuple[str, ...]]]] = {}
    for label, directory, stem, drawings in jobs:
        key = os.path.abspath(directory)
        by_dir.setdefault(key, []).append((label, stem, tuple(sorted(drawings))))
    for directory, entries in by_dir.items():
        stems = sorted({stem for _, stem, _ in entries})
        prefixed = any(b.startswith(a) for a, b in itertools.pairwise(stems))
        if not prefixed and len(stems) == len(entries):
            continue  # no stem begins another: no two names can be equal
        owner: dict[str, str] = {}
        for label, stem, drawings in entries:
            for suffix in job_files(drawings, only, svg_image):
                name = stem + suffix
                if name in owner and owner[name] != label:
                    raise ParameterError(
                        f"{owner[name]} and {label} would both write "
                        f"{os.path.join(directory, name)}: rename one of them"
                    )
                owner[name] = label


def run_jobs(
    items: Sequence[str],
    job: Callable[[str], list[Path]],
    progress: bool = True,
    traceback: bool = False,
    desc: str = "rendering",
    on_result: Callable[[JobResult], tuple[str, bool]] | None = None,
) -> list[JobResult]:
    """Run ``job`` on every item; a failing item is recorded and the next one runs.

    ``on_result(result) -> (line, is_error)``: a line printed as soon as that item is done
    (stderr for errors, stdout otherwise), above the progress bar when there is one."""
    results: list[JobResult] = []
    bar: Any = None
    if progress and len(items) > 1:
        bar = tqdm(total=len(items), desc=desc, unit="scene", leave=True)
    for item in items:
        if bar is not None:
            bar.set_postfix_str(Path(item).name)
        t0 = time.perf_counter()
        res = JobResult(item)
        try:
            res.outputs = job(item)
        except NprError as e:  # one line; name the input when the message does not
            res.error = str(e) if item in str(e) else f"{item}: {e}"
        except Exception as e:
            if traceback:
                raise
            res.error = f"{item}: internal error: {type(e).__name__}: {one_line(e)}"
        res.seconds = time.perf_counter() - t0
        results.append(res)
        if on_result is not None:
            line, is_error = on_result(res)
            stream = sys.stderr if is_error else sys.stdout
            if bar is not None:
                bar.write(line, file=stream)
            else:
                print(line, file=stream, flush=True)
        if bar is not None:
            bar.update(1)
    if bar is not None:
        bar.close()
    return results


# -- scenes x views on Dask ----------------------------------------------------------------

#: Scenes a worker keeps loaded (least recently used goes first).
SCENE_CACHE = 4

#: Where a LocalCluster's dashboard listens: this machine only, on a free port (``host:port``;
#: ``:8787`` would be every interface).
DASHBOARD = "127.0.0.1:0"

#: Where the jobs run (``mi-npr batch``, and ``mi-npr path`` with its frames as jobs).
CLUSTER_PARAMS: tuple[Param, ...] = (
    Param(
        "workers",
        int,
        None,
        "worker processes of the local cluster (default: one per core; 0: this process)",
        integer_range(0, MAX_WORKERS),
    ),
    Param(
        "threads_per_worker",
        int,
        None,
        "Dr.Jit threads of each worker (default: the cores shared out)",
        integer_range(1, MAX_THREADS),
    ),
    Param("retries", int, 0, "retries of a failed job", integer_range(0, MAX_RETRIES)),
    Param(
        "job_timeout",
        float,
        None,
        "seconds a job may go without progress before it is stopped and its worker replaced "
        "(default: 300, plus 1 per 10,000 samples while it renders)",
        real_range(0.0, 1e7, open_lo=True),
    ),
)

#: How a batch renders its views: many views of a scene in one launch, and whether with the
#: scene's beauty (``mi-npr dataset``'s flags, with its own defaults).
LAUNCH_PARAMS: tuple[Param, ...] = (
    Param(
        "views_per_launch",
        int,
        1,
        "views of a scene whose G-buffers are rendered in one launch (0: as many as fit "
        "2**19 rays); the outputs are those of one view at a time",
        integer_range(0, 4096),
    ),
    Param(
        "beauty",
        bool,
        True,
        "render the beauty with the scene's integrator (false: the G-buffer pass's headlight "
        "shading, no extra render, and no image under the SVG drawings)",
    ),
)

#: A job's bound without progress (:data:`CLUSTER_PARAMS` ``job_timeout``): this many seconds
#: per step (loading the scene and placing the cameras, rendering, writing) ...
JOB_TIMEOUT = 300.0
#: ... plus one second per this many samples (film pixels x spp) while it renders.
SAMPLES_PER_SECOND = 1e4
#: The Dask event topic of the jobs' progress (worker -> client), followed by the batch's tag.
PROGRESS_TOPIC = "mi-npr-progress"
#: How often the client looks for jobs past their bound (seconds).
POLL = 0.2


@dataclass(frozen=True)
class Job:
    """One scene x one view: ``id`` is ``<scene stem>/<view id>``; ``key`` what makes two
    renders of it equal (:func:`job_key`), compared by ``resume``."""

    scene: str
    scene_hash: str
    view: str
    key: str = ""

    @property
    def stem(self) -> str:
        return Path(self.scene).stem

    @property
    def id(self) -> str:
        return f"{self.stem}/{self.view}"


@dataclass(frozen=True)
class BatchSettings:
    """What every job of a batch shares (sent to the workers)."""

    outdir: str
    views: Any  # a mi_npr.views.ViewSpec
    drawings: tuple[str, ...] = ()
    params: tuple[tuple[str, Any], ...] = ()
    width: int | None = None
    height: int | None = None
    spp: int | None = None
    seed: int = 0
    defines: tuple[tuple[str, Any], ...] = ()
    variant: str | None = None
    threads: int | None = None
    line_color: tuple[float, ...] | None = None
    paper: tuple[float, ...] | None = None
    #: outputs in ``outdir`` itself, not ``outdir/<scene stem>`` (one scene: a camera path)
    flat: bool = False
    #: seconds a job may go without progress (``None``: :data:`JOB_TIMEOUT` and the render's
    #: samples)
    job_timeout: float | None = None
    #: the Dask event topic its jobs report their progress on (one per batch: two batches on
    #: one client never mix their jobs' progress)
    topic: str = PROGRESS_TOPIC
    #: views of one scene whose G-buffers are rendered in one launch
    #: (:func:`mi_npr.render.render_views`; 0: as many as :func:`~mi_npr.render.views_per_launch`
    #: allows); the outputs are those of one view at a time
    views_per_launch: int = 1
    #: the scene's integrator renders ``R G B``; else the G-buffer pass's headlight shading
    beauty: bool = True
    #: the objects orbits, spheres and best views frame (``--frame``; none: those that matter)
    frame: tuple[str, ...] = ()

    def flags(self) -> dict[str, Any]:
        """What makes two renders of a job equal (compared by ``resume``), JSON-ready."""
        return {
            "views": self.views.text,
            "drawings": list(self.drawings),
            "params": {k: list(v) if isinstance(v, tuple) else v for k, v in self.params},
            "width": self.width,
            "height": self.height,
            "spp": self.spp,
            "seed": self.seed,
            "defines": {k: str(v) for k, v in self.defines},
            "variant": self.variant,
            "line_color": list(self.line_color) if self.line_color else None,
            "paper": list(self.paper) if self.paper else None,
            **({} if self.beauty else {"beauty": False}),  # earlier runs' keys stay valid
            **({"frame": list(self.frame)} if self.frame else {}),
        }


def job_key(settings: BatchSettings, job: Job) -> str:
    """What ``resume`` compares, as ``sha256:<hex>``: the scene's content hash (the file and
    every file it references, ``$name`` resolved by the defines), the settings of
    :meth:`BatchSettings.flags` (defines, drawings and their parameters, size, spp, seed,
    variant, colours), the view (a given camera's values; else the view spec, whose cameras
    follow from the scene) and the mi-npr version."""
    flags = settings.flags()
    camera = settings.views.camera(job.view)
    flags["views"] = camera.to_dict() if camera is not None else settings.views.text
    data = {"scene": job.scene_hash, "flags": flags, "view": job.view, "version": __version__}
    text = json.dumps(data, sort_keys=True, allow_nan=False, default=str)
    return "sha256:" + hashlib.sha256(text.encode()).hexdigest()


_JOB_LOCK = threading.Lock()  # one job at a time per process (output sets, the render lock)
#: The G-buffers of this worker's last launch of many views, by view id, each taken by its job
#: (one launch kept: memory stays bounded); ``key`` names the scene, settings and launch.
_LAUNCH: dict[str, Any] = {"key": None, "views": {}}
_SCENES: OrderedDict[tuple, tuple[Any, dict[str, Any]]] = OrderedDict()
_THREADS: list[int | None] = [None]
#: Whether this process is a Dask worker (found by the first job).
_ON_WORKER: list[bool | None] = [None]


def _dask_worker_address() -> str | None:
    """The address of the Dask worker this code runs in (``None``: none)."""
    try:  # imported here, like all of Dask: slow to import, and needed only by a batch on Dask
        from distributed import get_worker

        return str(get_worker().address)
    except (ImportError, ValueError):
        return None


def _on_dask_worker() -> bool:
    """Whether this code runs in a Dask worker."""
    return _dask_worker_address() is not None


def _worker_name() -> str:
    return _dask_worker_address() or f"local:{socket.gethostname()}:{os.getpid()}"


def _configure(settings: BatchSettings) -> None:
    """This process's variant and Dr.Jit thread cap (once; again only if they change); in a
    Dask worker, one malloc arena for its threads (:func:`mi_npr.memory.share_malloc_arena`:
    the worker is a process of mi-npr's own)."""

    if _ON_WORKER[0] is None:
        _ON_WORKER[0] = _on_dask_worker()
        if _ON_WORKER[0]:
            share_malloc_arena()
    if settings.variant and mi.variant() != settings.variant:
        set_variant(settings.variant)
    if settings.threads and _THREADS[0] != settings.threads:
        dr.set_thread_count(settings.threads)
        _THREADS[0] = settings.threads


def _scene(settings: BatchSettings, job: Job) -> tuple[Any, dict[str, Any]]:
    """The loaded scene of ``job`` and its cameras by view id, from this worker's cache."""

    size = (
        None
        if settings.width is None and settings.height is None
        else (settings.width, settings.height)
    )
    key = (job.scene, job.scene_hash, settings.defines, size, settings.spp, settings.views)
    if key in _SCENES:
        _SCENES.move_to_end(key)
        return _SCENES[key]
    session = SceneSession.open(
        job.scene, spp=settings.spp, defines=dict(settings.defines), resolution=size
    )
    with session.step("placing the cameras"):
        cams = dict(cameras(settings.views, session.scene, session.sensor, settings.frame))
    _SCENES[key] = (session, cams)
    while len(_SCENES) > SCENE_CACHE:
        _SCENES.popitem(last=False)
    return session, cams


def _row(settings: BatchSettings, job: Job, attempt: int, **fields: Any) -> dict[str, Any]:
    """A manifest row of ``job``, failed until a render fills it in (``fields`` override)."""
    return {
        "job": job.id,
        "key": job.key,
        "version": __version__,
        "scene": job.scene,
        "scene_hash": job.scene_hash,
        "view": job.view,
        "camera": None,
        "flags": settings.flags(),
        "outputs": [],
        "status": "failed",
        "error": None,
        "attempt": attempt,
        "worker": None,
        **fields,
    }


def _view_warning(job: Job, gb: Any) -> str | None:
    """Best view's test of a view not worth looking at (mostly background, or black: an orbit
    around a room of one-sided walls sees their backs), as a one-line warning, or ``None``."""

    why = view_warning(float(np.mean(gb.object_id == 0)), raw_beauty(gb))
    return None if why is None else f"{job.id}: the view is probably useless: {why}"


def _progress(settings: BatchSettings, samples: int | None = None) -> None:
    """Tell the client (on Dask) that this worker's job made progress, and how long its next
    step may take: ``job_timeout``, else :data:`JOB_TIMEOUT` plus ``samples`` /
    :data:`SAMPLES_PER_SECOND` (the render of ``samples`` samples)."""
    try:  # imported here: see _dask_worker_address
        from distributed import get_worker

        worker = get_worker()
        key = worker.get_current_task()
    except (ImportError, ValueError):
        return  # not on a Dask worker: nothing watches the job
    limit = settings.job_timeout or JOB_TIMEOUT + (samples or 0) / SAMPLES_PER_SECOND
    worker.log_event(settings.topic, {"key": str(key), "worker": worker.address, "limit": limit})


def _samples(sensor: Any, spp: int | None) -> int:
    w, h = (int(v) for v in sensor.film().crop_size())
    return w * h * (spp or int(sensor.sampler().sample_count()))


def render_job(settings: BatchSettings, job: Job, attempt: int = 1) -> dict[str, Any]:
    """Render and write one job; its manifest row (``status`` ``done`` or ``failed`` with a
    one-line ``error``). Runs on a worker; never raises for a failing job. On Dask it reports
    its progress (:func:`_progress`) before each step, so the client can stop it when a step
    takes longer than its bound."""

    row, files, t0 = _render_files(settings, job, attempt)
    if files is not None:
        _progress(settings)
        _write_files(settings, job, row, *files)
    return _finished(row, t0)


def _render_files(
    settings: BatchSettings, job: Job, attempt: int
) -> tuple[dict[str, Any], tuple[Path, list[tuple[str, Any]]] | None, float]:
    """The render of :func:`render_job` without the writing: its row (``failed``, with the
    error, if the render failed), the folder and the files to write (numpy arrays and texts:
    :func:`mi_npr.io.layered_files`; ``None`` after a failure), and its start time."""

    t0 = time.perf_counter()
    row = _row(settings, job, attempt, worker=_worker_name())
    with _JOB_LOCK, _job_errors(job, row):
        _progress(settings)
        _configure(settings)
        session, cams = _scene(settings, job)
        camera = cams[job.view]
        row["camera"] = (camera or camera_of(session.sensor)).to_dict()
        _progress(settings, _samples(session.sensor, session.spp))
        launched = None
        if settings.views_per_launch != 1 or not settings.beauty:
            sensor, launched = _launched(settings, job, session, cams)
        else:
            sensor = _sensor(settings, session, job.view, camera)
        result = render_layers(
            session.scene,
            settings.drawings,
            dict(settings.params),
            sensor=sensor,
            spp=session.spp,
            seed=settings.seed,
            gbuffer=launched,
        )
        outdir = check_writable_dir(
            Path(settings.outdir) / ("" if settings.flat else job.stem), create=True
        )
        files = io.layered_files(
            result,
            outdir,
            job.view,
            line_color=settings.line_color,
            paper=settings.paper,
            # without a beauty there is nothing to lay under the SVG drawings
            svg_image="embed" if settings.beauty else "none",
        )
        row["warning"] = _view_warning(job, result.gbuffer)
        return row, (outdir, files), t0
    return row, None, t0


@contextlib.contextmanager
def _job_errors(job: Job, row: dict[str, Any]) -> Any:
    """A job's failure as its row's one-line ``error``, never raised."""
    try:
        yield
    except NprError as e:
        row["error"] = f"{job.id}: {one_line(e)}"
    except Exception as e:
        row["error"] = f"{job.id}: internal error: {type(e).__name__}: {one_line(e)}"


def _write_files(
    settings: BatchSettings,
    job: Job,
    row: dict[str, Any],
    outdir: Path,
    files: list[tuple[str, Any]],
) -> None:
    """Write a job's files all together (:func:`mi_npr.io.write_files`) and fill in its row:
    ``done`` with the outputs and their sizes, or ``failed`` with the error. No Dr.Jit: it may
    run in the batch's writer thread (:class:`_Writer`)."""
    with _job_errors(job, row):
        written = io.write_files(outdir, files)
        row["outputs"] = [os.path.relpath(p, settings.outdir) for p in written]
        row["sizes"] = [os.stat(p).st_size for p in written]
        row["status"] = "done"
    if row["status"] != "done":  # a failed job's row, as when its render fails
        row.pop("warning", None)


def _finished(row: dict[str, Any], t0: float) -> dict[str, Any]:
    row["seconds"] = round(time.perf_counter() - t0, 6)
    row["finished"] = time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime())
    return row


def _launched(
    settings: BatchSettings, job: Job, session: Any, cams: dict[str, Any]
) -> tuple[Any, Any]:
    """The sensor and the G-buffer of ``job``'s view from the launch of its group of views (the
    view spec's views in order, :attr:`BatchSettings.views_per_launch` at a time), rendered
    here unless this worker's last launch holds it; without :attr:`BatchSettings.beauty`, no
    beauty."""
    if _LAUNCH.get("cams") is not cams:  # the views' order, once per scene (not once a job)
        _LAUNCH["cams"], _LAUNCH["order"] = cams, {v: i for i, v in enumerate(cams)}
    w, h = (int(v) for v in session.sensor.film().crop_size())
    k = settings.views_per_launch or views_per_launch(w, h)
    first = _LAUNCH["order"][job.view] // k * k
    key = (job.scene, job.scene_hash, id(session), settings, first)
    if _LAUNCH["key"] != key or job.view not in _LAUNCH["views"]:
        _LAUNCH["key"], _LAUNCH["views"] = None, {}  # the old launch's memory goes first
        group = list(itertools.islice(cams, first, first + k))
        sensors = [_sensor(settings, session, v, cams[v]) for v in group]
        integ = session.scene.integrator()
        beauty = None
        if settings.beauty:
            beauty = integ.beauty if hasattr(integ, "npr_gbuffer") else integ
        gbs = render_views(session, sensors, beauty, session.spp, settings.seed)
        _LAUNCH["key"], _LAUNCH["views"] = (
            key,
            dict(zip(group, zip(sensors, gbs, strict=True), strict=True)),
        )
    return _LAUNCH["views"].pop(job.view)


def _sensor(settings: BatchSettings, session: Any, view: str, camera: Any) -> Any:
    """The sensor of ``view``: the scene's, or one at its camera (a missing up or fov is the
    scene sensor's; errors name the file and camera)."""
    if camera is None:
        return session.sensor
    return sensor_for(resolve(camera, session.sensor, settings.views.where(view)), session.sensor)


def inside(outdir: Path, name: Any) -> Path | None:
    """``outdir / name`` when ``name`` is a relative path that stays inside ``outdir`` (no
    ``..``, not absolute, no link leading out), else ``None``: a manifest row never makes
    mi-npr read, trust or remove a file elsewhere."""
    if not isinstance(name, str) or not name or os.path.isabs(name):
        return None
    parts = Path(name).parts
    if ".." in parts:
        return None
    p = outdir / name
    root = os.path.realpath(outdir)
    if os.path.commonpath([root, os.path.realpath(p)]) != root:
        return None
    return p


def _done(row: Mapping[str, Any], job: Job, outdir: Path) -> bool:
    """Whether a manifest row shows ``job`` done with the same key (:func:`job_key`), every
    output still inside ``outdir`` with the size the row recorded."""
    outputs, sizes = row.get("outputs"), row.get("sizes")
    if row.get("status") != "done" or row.get("key") != job.key:
        return False
    if not isinstance(outputs, list) or not outputs or not isinstance(sizes, list):
        return False
    if len(sizes) != len(outputs):
        return False
    for name, size in zip(outputs, sizes, strict=True):
        p = inside(outdir, name)
        if p is None or isinstance(size, bool) or not isinstance(size, int):
            return False
        try:
            st = os.stat(p)
        except OSError:
            return False
        if not stat.S_ISREG(st.st_mode) or st.st_size != size:
            return False
    return True


def _check_params(drawings: Sequence[str], params: Mapping[str, Any]) -> tuple:
    """The drawing parameters, each checked by the drawings that take it
    (:func:`mi_npr.drawings.split_params`), as sorted ``(name, value)`` pairs."""

    out: dict[str, Any] = {}
    for taken in split_params(drawings, params, "batch").values():
        out.update(taken)
    return tuple(sorted(out.items()))


def plan(
    scenes: Sequence[str | os.PathLike[str]],
    views: Any,
    defines: Mapping[str, Any] | None = None,
) -> tuple[list[Job], Any]:
    """The jobs of ``scenes`` x ``views`` (scene by scene) and the parsed view spec; ``views``
    is a spec (text or :class:`~mi_npr.views.ViewSpec`) or a list of cameras; ``defines``
    resolve the scenes' ``$name`` file names (:func:`~mi_npr.io.manifest.scene_hash`)."""

    if isinstance(views, ViewSpec):
        spec = views
    elif isinstance(views, (str, os.PathLike)):
        spec = parse_views(os.fspath(views))
    elif isinstance(views, Sequence):
        spec = ViewSpec.of_cameras(views, "views")
    else:
        raise ParameterError(f"views = {views!r}: expected a spec or a list of cameras")
    if isinstance(scenes, (str, os.PathLike)):
        scenes = [scenes]
    if not isinstance(scenes, Sequence):
        raise ParameterError(f"scenes = {shown(scenes)}: expected a scene file or a list of them")
    if not scenes:
        raise ParameterError("scenes: give at least one scene")
    paths = [str(check_input_file(s, SceneError).resolve()) for s in scenes]
    check_unique_stems(paths)
    jobs = []
    for p in dict.fromkeys(paths):
        h = scene_hash(p, defines)
        jobs.extend(Job(p, h, v) for v in spec.ids())
    return jobs, spec


def run(
    scenes: Sequence[str | os.PathLike[str]] | str | os.PathLike[str],
    views: Any = "scene",
    client: Any = None,
    *,
    out: str | os.PathLike[str],
    drawings: Sequence[str] = (),
    params: Mapping[str, Any] | None = None,
    width: int | None = None,
    height: int | None = None,
    spp: int | None = None,
    seed: int = 0,
    defines: Mapping[str, Any] | None = None,
    workers: int | None = None,
    threads_per_worker: int | None = None,
    scheduler: str | None = None,
    resume: bool = False,
    retries: int = 0,
    job_timeout: float | None = None,
    progress: bool = True,
    line_color: Sequence[float] | None = None,
    paper: Sequence[float] | None = None,
    flat: bool = False,
    dashboard: str = DASHBOARD,
    on_dashboard: Callable[[str], None] | None = None,
    views_per_launch: int = 1,
    beauty: bool = True,
    frame: Sequence[str] = (),
) -> list[dict[str, Any]]:
    """Render every scene of ``scenes`` from every view of ``views`` (module docstring: a
    ``--views`` spec, or a list of :class:`~mi_npr.camera.Camera`, each named by its ``id``)
    into ``out``; the manifest rows of all jobs, in job order (a job skipped by ``resume``: its
    earlier row).

    ``flat`` writes one scene's views into ``out`` itself (``out/<view id>.exr``; the camera
    paths of :mod:`mi_npr.paths`). ``client``: a ``distributed.Client`` to run on; else
    ``scheduler`` (an address, reached within Dask's connect timeout,
    ``distributed.comm.timeouts.connect``, 30 s by default) to connect to; else a
    ``LocalCluster`` of ``workers`` processes started and closed here (default: one per core;
    never more than jobs, and more than cores only when asked, with a warning); ``workers=0``
    renders in this process, without Dask. The LocalCluster's dashboard listens on
    ``dashboard`` (``host:port``; default this machine only, a free port) and its link is
    given to ``on_dashboard``. ``views_per_launch`` and ``beauty``: :data:`LAUNCH_PARAMS`.
    ``frame``: the objects that orbits, spheres and best views frame, by name (default: the
    objects that matter, :func:`mi_npr.camera.framed_shapes`).

    On Dask, a job that goes without progress for longer than its bound (``job_timeout``
    seconds per step, default :data:`JOB_TIMEOUT` plus its samples over
    :data:`SAMPLES_PER_SECOND`) is stopped, its worker restarted, and the job retried while it
    has ``retries`` left, else recorded as failed with the reason; the batch goes on. A job
    retried carries the errors of its earlier attempts in its row's ``retried``.

    >>> import tempfile
    >>> rows = mi_npr.batch.run(["scenes_xml/scene1.xml"], "orbit:2", out=tempfile.mkdtemp(),
    ...                         drawings=["lines"], width=32, height=24, spp=1, workers=0,
    ...                         progress=False)
    >>> [(r["view"], r["status"]) for r in rows]
    [('orbit_000', 'done'), ('orbit_001', 'done')]
    """

    table = {p.name: p for p in (*RENDER_PARAMS, *CLUSTER_PARAMS, *LAUNCH_PARAMS)}

    def arg(name: str, value: Any) -> Any:
        return None if value is None else check_arg("batch", table[name], value)

    width, height, spp = arg("width", width), arg("height", height), arg("spp", spp)
    seed, workers = arg("seed", seed), arg("workers", workers)
    threads_per_worker, retries = (
        arg("threads_per_worker", threads_per_worker),
        arg("retries", retries),
    )
    job_timeout = arg("job_timeout", job_timeout)
    views_per_launch, beauty = arg("views_per_launch", views_per_launch), arg("beauty", beauty)
    jobs, spec = plan(scenes, views, defines)
    outdir = check_writable_dir(out, create=True)
    settings = BatchSettings(
        outdir=str(outdir.resolve()),
        views=spec,
        drawings=tuple(dict.fromkeys(drawings)),
        params=_check_params(drawings, dict(params or {})),
        width=width,
        height=height,
        spp=spp,
        seed=seed,
        defines=tuple(sorted((k, str(v)) for k, v in (defines or {}).items())),
        variant=mi.variant(),
        threads=threads_per_worker,
        line_color=tuple(float(v) for v in line_color) if line_color else None,
        paper=tuple(float(v) for v in paper) if paper else None,
        flat=flat,
        job_timeout=job_timeout,
        views_per_launch=views_per_launch,
        beauty=beauty,
        frame=name_list("frame", frame),
    )
    if flat and len({j.scene for j in jobs}) > 1:
        raise ParameterError("flat outputs are for one scene (its views' files would collide)")
    own = {j.scene: scene_drawings(j.scene, defines) for j in jobs}
    check_outputs(
        [
            (j.id, outdir if flat else outdir / j.stem, j.view, (*settings.drawings, *own[j.scene]))
            for j in jobs
        ]
    )
    manifest = outdir / MANIFEST
    check_manifest(manifest)
    jobs = [replace(j, key=job_key(settings, j)) for j in jobs]
    earlier: dict[str, list[dict[str, Any]]] = {}
    for r in read_rows(manifest):
        earlier.setdefault(str(r.get("job")), []).append(r)
    rows: dict[str, dict[str, Any]] = {}
    if resume:
        for job in jobs:
            r = earlier.get(job.id, [None])[-1]
            if r is not None and _done(r, job, outdir):
                rows[job.id] = r
    pending = [j for j in jobs if j.id not in rows]
    bar: Any = None
    if progress and pending:
        bar = tqdm(total=len(jobs), initial=len(rows), desc="batch", unit="job")

    rows_file = Appender(manifest)

    def record(row: dict[str, Any]) -> None:
        rows_file.append(row)
        rows[row["job"]] = row
        if row["status"] == "done":
            _remove_replaced(outdir, row, earlier.get(row["job"], []), jobs, flat)
        if row["status"] != "done":
            message = f"mi-npr: error: {row['error']}"
        elif row.get("warning"):
            message = f"mi-npr: warning: {row['warning']}"
        else:
            message = None
        if bar is not None:  # without a bar, the caller reads the rows (the CLI prints them)
            if message is not None:
                bar.write(for_terminal(message), file=sys.stderr)
            bar.update(1)

    try:
        if pending:
            if client is None and scheduler is None and workers == 0:
                _run_here(settings, pending, retries, record)
            else:
                _run_dask(
                    settings,
                    pending,
                    retries,
                    record,
                    client,
                    scheduler,
                    workers,
                    dashboard,
                    on_dashboard,
                )
    finally:
        if bar is not None:
            bar.close()
        rows_file.close()
    _warn_left(outdir, earlier, jobs, flat)
    return [rows[j.id] for j in jobs if j.id in rows]


def _claimed(name: str, jobs: Sequence[Job], flat: bool) -> bool:
    """Whether a file ``name`` (relative to OUT) may be one that a job of this run writes:
    it is in a job's folder and starts with its view id (every name the writer gives does,
    :func:`job_files`)."""
    folder, _, base = name.replace(os.sep, "/").rpartition("/")
    return any((flat or folder == j.stem) and base.startswith(j.view) for j in jobs)


def _remove_replaced(
    outdir: Path,
    row: Mapping[str, Any],
    before: Sequence[Mapping[str, Any]],
    jobs: Sequence[Job],
    flat: bool,
) -> None:
    """The files of a job's earlier sets (its earlier rows) that its new set does not hold:
    removed with the set (a ``--resume`` without ``--lines`` leaves no old drawing), unless a
    job of this run may write that name, which a warning names instead."""
    new = set(row.get("outputs") or [])
    old = {n for r in before if isinstance(r.get("outputs"), list) for n in r["outputs"]}
    kept = []
    for name in sorted(n for n in old - new if isinstance(n, str)):
        p = inside(outdir, name)
        if p is None or not p.is_file():
            continue
        others = [j for j in jobs if j.id != row.get("job")]
        if _claimed(name, others, flat):
            kept.append(name)
            continue
        with contextlib.suppress(OSError):
            p.unlink()
    if kept:
        warnings.warn(
            f"{row.get('job')}: files of its earlier set left in {outdir}: {', '.join(kept)}",
            NprWarning,
            stacklevel=4,
        )


def _warn_left(
    outdir: Path,
    earlier: Mapping[str, Sequence[Mapping[str, Any]]],
    jobs: Sequence[Job],
    flat: bool,
) -> None:
    """A warning naming the files of earlier jobs that this run does not have, beside its
    own (frames of a longer path, the views of a larger orbit): they are no part of this
    set."""
    ids = {j.id for j in jobs}
    folders = {"" if flat else j.stem for j in jobs}
    left: list[str] = []
    for job, rs in earlier.items():
        if job in ids:
            continue
        for name in rs[-1].get("outputs") or []:
            p = inside(outdir, name)
            folder = os.path.dirname(name) if isinstance(name, str) else None
            if p is not None and folder in folders and p.is_file():
                left.append(name)
    if left:
        shown = ", ".join(sorted(left)[:4]) + (", ..." if len(left) > 4 else "")
        warnings.warn(
            f"{outdir}: {len(left)} files of earlier jobs that this run does not have are "
            f"left beside its outputs ({shown})",
            NprWarning,
            stacklevel=3,
        )


#: Jobs whose files wait for the batch's writer thread (:class:`_Writer`) at most, besides the
#: one it is writing: the next views render meanwhile, and memory holds a few views' files.
WRITE_AHEAD = 2
#: Views of more pixels than this are written in line: their layers, copied for the writer,
#: would hold as much memory as their render.
WRITE_AHEAD_PIXELS = 1 << 20


class _Writer:
    """One thread that writes jobs' files (:func:`_write_files`: numpy, zlib, OpenEXR and
    files, no Dr.Jit) while the batch's thread renders the next jobs; :meth:`submit` waits while
    :data:`WRITE_AHEAD` jobs wait. The rows of the jobs written (``done``, or ``failed`` with
    the error) come back to the batch's thread, in order, through :meth:`done`; only that
    thread records them."""

    def __init__(self, settings: BatchSettings) -> None:
        self.settings = settings
        self.todo: queue.Queue[Any] = queue.Queue(maxsize=WRITE_AHEAD)
        self.rows: queue.Queue[tuple[Job, dict[str, Any]]] = queue.Queue()
        self.thread = threading.Thread(target=self._run, name="mi-npr-writer", daemon=True)
        self.thread.start()

    def _run(self) -> None:
        while (item := self.todo.get()) is not None:
            job, row, files, t0 = item
            try:
                _write_files(self.settings, job, row, *files)
            except BaseException as e:  # whatever happens, the job's row goes back
                row["status"] = "failed"
                row["error"] = f"{job.id}: internal error: {type(e).__name__}: {one_line(e)}"
            self.rows.put((job, _finished(row, t0)))

    def submit(self, job: Job, row: dict[str, Any], files: Any, t0: float) -> None:
        self.todo.put((job, row, files, t0))

    def done(self) -> list[tuple[Job, dict[str, Any]]]:
        """The jobs written since the last call, with their rows."""
        out = []
        with contextlib.suppress(queue.Empty):
            while True:
                out.append(self.rows.get_nowait())
        return out

    def close(self) -> list[tuple[Job, dict[str, Any]]]:
        """Write what waits, stop the thread; :meth:`done`."""
        self.todo.put(None)
        self.thread.join()
        return self.done()


def _pixels(files: tuple[Path, list[tuple[str, Any]]]) -> int:
    """The pixels of a job's EXR (the largest of its files)."""
    return max(
        (a.size for _, d in files[1] if isinstance(d, io.ExrImage) for a in d.channels.values()),
        default=0,
    )


def _run_here(settings: BatchSettings, jobs: Sequence[Job], retries: int, record: Callable) -> None:
    """The batch in this process, job after job (``workers=0``); a thread cap holds for the
    batch only. Each job's files are written by a :class:`_Writer` while the next jobs render
    (in line above :data:`WRITE_AHEAD_PIXELS` pixels); a job is recorded once its files are in
    place, or failed, after its ``retries`` (a job whose writing failed is rendered again)."""

    before = dr.thread_count()
    writer: _Writer | None = None

    def attempts(job: Job, first: int) -> dict[str, Any] | None:
        """The job from attempt ``first`` on: its final row, or ``None`` when it went to the
        writer (its row comes back through it)."""
        nonlocal writer
        for attempt in range(first, retries + 2):
            row, files, t0 = _render_files(settings, job, attempt)
            if files is not None and _pixels(files) <= WRITE_AHEAD_PIXELS:
                if writer is None:
                    writer = _Writer(settings)
                writer.submit(job, row, files, t0)
                return None
            if files is not None:
                _write_files(settings, job, row, *files)
            _finished(row, t0)
            if row["status"] == "done":
                break
        return row

    def written(done: list[tuple[Job, dict[str, Any]]], retry: bool = True) -> None:
        for job, row in done:
            if retry and row["status"] != "done" and row["attempt"] <= retries:
                again = attempts(job, row["attempt"] + 1)
                if again is None:
                    continue
                row = again
            record(row)

    try:
        for job in jobs:
            row = attempts(job, 1)
            if row is not None:
                record(row)
            if writer is not None:
                written(writer.done())
        while writer is not None:  # the last jobs' files, and the retries they cause
            last, writer = writer, None
            written(last.close())
    finally:
        if writer is not None:  # stopped by an error: what was rendered is written, recorded
            written(writer.close(), retry=False)
        if settings.threads:
            dr.set_thread_count(before)
            _THREADS[0] = None


def local_cluster(workers: int, **kwargs: Any) -> Any:
    """A ``LocalCluster`` of ``workers`` single-threaded processes for batches (a worker runs
    one job at a time; Dr.Jit's own threads do the parallel work). Its scheduler sends every
    task to the workers at once (``worker-saturation`` inf): a worker never waits for its next
    job, and work stealing still balances them. Close it (or use it in ``with``)."""
    import dask  # imported here: see _dask_worker_address
    from distributed import LocalCluster

    options = dict(threads_per_worker=1, processes=True, dashboard_address=DASHBOARD)
    options.update(silence_logs=logging.ERROR, **kwargs)
    with dask.config.set({"distributed.scheduler.worker-saturation": float("inf")}):
        return LocalCluster(n_workers=workers, **options)


def _default_workers(workers: int | None, jobs: int, threads: int | None) -> tuple[int, int]:
    """Workers of a LocalCluster and the Dr.Jit threads each uses (default: the cores shared
    out). Default: one per core, at most one per job. Asked for: never more than the jobs (an
    idle worker only costs its start-up; a warning says so), more than the cores with a
    warning."""
    cores = os.cpu_count() or 1
    if not workers:
        n = max(1, min(cores, jobs))
    else:
        n = workers
        if n > jobs:
            warnings.warn(
                f"workers = {n}: only {jobs} job{'s' * (jobs != 1)} to run, so {jobs} "
                f"worker{'s' * (jobs != 1)} started",
                NprWarning,
                stacklevel=3,
            )
            n = jobs
        if n > cores:
            warnings.warn(
                f"workers = {n}: more workers than the {cores} cores (they share them)",
                NprWarning,
                stacklevel=3,
            )
    return n, threads or max(1, cores // n)


def _connect(scheduler: str) -> Any:
    """A ``distributed.Client`` of the scheduler at ``scheduler``, or a :class:`ParameterError`
    naming ``--scheduler`` within Dask's connect timeout: a malformed address, nothing
    listening, a silent port, or a peer that is no Dask scheduler (an HTTP server)."""
    import asyncio  # imported here, with Dask: only a batch on a running scheduler needs it

    import dask  # imported here: see _dask_worker_address
    from dask.utils import parse_timedelta
    from distributed import Client
    from distributed.comm import connect
    from distributed.comm.addressing import parse_address, parse_host_port
    from distributed.security import Security

    where = f"--scheduler {scheduler!r}"
    try:
        scheme, loc = parse_address(scheduler)
        if scheme not in ("tcp", "tls"):
            raise ValueError(f"scheme {scheme!r}")
        _, port = parse_host_port(loc)
        if not 0 < int(port) < 65536:
            raise ValueError(f"port {port}")
    except (ValueError, TypeError) as e:
        raise ParameterError(
            f"{where}: not a scheduler address ({one_line(e)}; expected tcp://HOST:PORT)"
        ) from None
    bound = parse_timedelta(dask.config.get("distributed.comm.timeouts.connect"), "s") or 30.0
    args = Security().get_connection_args("client")

    async def identity() -> Any:
        comm = await connect(scheduler, timeout=bound, **args)
        try:
            await comm.write({"op": "identity", "reply": True})
            return await comm.read()
        finally:
            comm.abort()

    try:
        answer = asyncio.run(asyncio.wait_for(identity(), bound))
    except (TimeoutError, asyncio.TimeoutError, OSError) as e:
        why = one_line(e) if str(e) else f"no answer within {bound:g} s"
        raise ParameterError(f"{where}: cannot connect ({why})") from None
    except Exception as e:  # the peer's bytes are no Dask message (MemoryError, ValueError)
        raise ParameterError(
            f"{where}: not a Dask scheduler (its answer cannot be read: {type(e).__name__})"
        ) from None
    if not isinstance(answer, dict) or answer.get("type") != "Scheduler":
        kind = answer.get("type") if isinstance(answer, dict) else type(answer).__name__
        raise ParameterError(f"{where}: not a Dask scheduler (it is a {kind})")
    try:
        return Client(scheduler, timeout=bound)
    except (OSError, TimeoutError) as e:
        raise ParameterError(f"{where}: cannot connect ({one_line(e)})") from None


def _run_dask(
    settings: BatchSettings,
    jobs: Sequence[Job],
    retries: int,
    record: Callable,
    client: Any,
    scheduler: str | None,
    workers: int | None,
    dashboard: str = DASHBOARD,
    on_dashboard: Callable[[str], None] | None = None,
) -> None:
    """The batch on Dask: one task per job, submitted scene by scene; a failed task (or one
    whose worker died, or one stopped past its bound without progress) is submitted again
    while it has retries left."""
    from distributed import Client, as_completed  # imported here: see _dask_worker_address

    own_cluster = own_client = None
    try:
        if client is None:
            if scheduler is not None:
                client = own_client = _connect(scheduler)
            else:
                n, threads = _default_workers(workers, len(jobs), settings.threads)
                own_cluster = local_cluster(n, dashboard_address=dashboard)
                settings = replace(settings, threads=threads)
                client = own_client = Client(own_cluster)
                if on_dashboard is not None and own_cluster.dashboard_link:
                    on_dashboard(str(own_cluster.dashboard_link))
        _watch(settings, jobs, retries, record, client, as_completed)
    finally:
        if own_client is not None:
            own_client.close()
        if own_cluster is not None:
            own_cluster.close()


def _watch(
    settings: BatchSettings,
    jobs: Sequence[Job],
    retries: int,
    record: Callable,
    client: Any,
    as_completed: Any,
) -> None:
    """Submit ``jobs``, record each one's row as it ends, and stop the jobs that go past their
    bound without progress: the task is cancelled, its worker restarted (a worker without a
    nanny is stopped), and the job retried or recorded as failed with the reason."""
    tag = f"{os.getpid()}-{time.time_ns()}"
    settings = replace(settings, topic=f"{PROGRESS_TOPIC}-{tag}")
    attempts: dict[str, tuple[Job, int, Any]] = {}  # task key -> (job, attempt, future)
    earlier: dict[str, list[str]] = {}  # job id -> errors of its earlier attempts
    seen: dict[str, tuple[float, float, str]] = {}  # task key -> (last progress, bound, worker)
    lock = threading.Lock()

    def on_progress(event: Any) -> None:
        _, msg = event
        if isinstance(msg, dict) and "key" in msg:
            with lock:
                seen[str(msg["key"])] = (time.monotonic(), float(msg["limit"]), msg["worker"])

    def submit(job: Job, attempt: int, priority: int) -> Any:
        fut = client.submit(
            render_job,
            settings,
            job,
            attempt,
            key=f"mi-npr-{job.id}-{attempt}-{tag}",
            pure=False,
            priority=priority,
        )
        attempts[str(fut.key)] = (job, attempt, fut)
        return fut

    def finish(job: Job, attempt: int, row: dict[str, Any]) -> bool:
        """Record ``row``, or retry the job (True) while it has retries left."""
        if row["status"] != "done" and attempt <= retries:
            earlier.setdefault(job.id, []).append(str(row["error"]))
            futures.add(submit(job, attempt + 1, len(jobs)))
            return True
        if job.id in earlier:
            row["retried"] = earlier.pop(job.id)
        record(row)
        return False

    client.subscribe_topic(settings.topic, on_progress)
    try:
        futures = as_completed([submit(j, 1, len(jobs) - i) for i, j in enumerate(jobs)])
        while attempts:
            done = futures.next_batch(block=False) if futures.has_ready() else []
            for fut in done:
                key = str(fut.key)
                if key not in attempts:  # a task stopped past its bound: recorded already
                    continue
                job, attempt, _ = attempts.pop(key)
                with lock:
                    seen.pop(key, None)
                try:
                    row = fut.result()
                except Exception as e:  # the worker died (KilledWorker), the task could not run
                    row = _row(
                        settings,
                        job,
                        attempt,
                        error=f"{job.id}: {type(e).__name__}: {one_line(e)}",
                        seconds=None,
                    )
                fut.release()
                finish(job, attempt, row)
            if not done:
                if not _stop_stalled(settings, client, attempts, seen, lock, finish):
                    time.sleep(POLL)
    finally:
        client.unsubscribe_topic(settings.topic)


def _stop_stalled(
    settings: BatchSettings,
    client: Any,
    attempts: dict[str, tuple[Job, int, Any]],
    seen: dict[str, tuple[float, float, str]],
    lock: threading.Lock,
    finish: Callable[[Job, int, dict[str, Any]], bool],
) -> bool:
    """Stop every running job past its bound without progress (see :func:`_watch`); whether
    there was one."""
    now = time.monotonic()
    with lock:
        stalled = [
            (key, limit, worker)
            for key, (when, limit, worker) in seen.items()
            if key in attempts and now - when > limit
        ]
        for key, _, _ in stalled:
            seen.pop(key, None)
    for key, limit, worker in stalled:
        job, attempt, fut = attempts.pop(key)
        fut.cancel()
        how = _replace_worker(client, worker)
        error = f"{job.id}: no progress in {limit:g} s (job timeout): stopped, {how}"
        row = _row(settings, job, attempt, error=error, worker=worker, seconds=None)
        row["finished"] = time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime())
        finish(job, attempt, row)
    return bool(stalled)


def _replace_worker(client: Any, worker: str) -> str:
    """Restart ``worker`` (its nanny starts a fresh process; the job's thread cannot be
    stopped otherwise), or stop it when it has no nanny; what was done, for the row."""
    try:
        client.restart_workers([worker], raise_for_error=True)
        return f"worker {worker} restarted"
    except Exception:  # no nanny (dask worker --no-nanny), or the restart failed: stop it
        with contextlib.suppress(Exception):
            client.run(os._exit, 1, workers=[worker], wait=False)
        return f"worker {worker} stopped"

"""Line-drawing datasets from mesh collections (``mi-npr dataset``).

:func:`make_dataset` takes meshes (files, folders searched recursively, globs) in OBJ and PLY
(loaded by Mitsuba itself) and STL, glTF and GLB (read by ``trimesh``, written as PLY into
``OUT/meshes/``), checks each, and renders the good ones from every view of a view spec with
:func:`mi_npr.batch.run`: Dask, resume by content, the job bound and the output checks are the
batch's.

**Normalisation.** A mesh is centred on the centre ``c`` of its axis-aligned bounding box and
scaled by ``1 / R``, ``R`` half the box's diagonal: its bounding sphere (the box's, the one
:func:`mi_npr.camera.bounding_sphere` frames) is the unit sphere about the origin. The mesh file
is not changed: the scene's ``to_world`` does it, ``p' = (p - c) / R``.

**Studio** (:data:`STUDIO`). A grey diffuse material (reflectance 0.6), a constant environment of
radiance 0.3 and one directional key light of irradiance 2.5 falling along
``-(1, 2, 1.5)`` (from above, front right in the normalised frame, +y up), rendered by
Mitsuba's ``direct`` integrator; a pinhole camera of 40 degrees horizontal field of view with a
box filter (each pixel's depth, normal and ids are those of its own samples).

**Normals.** A mesh is shaded with the normals its file carries, or Mitsuba's smooth vertex
normals where it has none, except an STL (:data:`FACETED`): it has no normals and is faceted by
definition, so its face normals are used and its sharp edges are creases in the line drawing
(its corners are welded all the same, so that silhouettes chain across its triangles).

**Beauty.** ``R G B`` (and ``<view>.png``) are the studio's ``direct`` render only when
``beauty`` is asked for; by default they are the G-buffer pass's headlight shading
(:func:`mi_npr.render.render_gbuffer` without an integrator), which costs no render of its own,
and the SVG drawings have no image under their strokes (with ``beauty``, the beauty, embedded).
The views of a mesh are rendered ``views_per_launch`` at a time in one launch
(:func:`mi_npr.render.render_views`): the files are those of one view at a time, bit for bit
(a beauty render to its last bits: Mitsuba's film adds samples in its threads' order).

**Views** (:mod:`mi_npr.views`): ``sphere:N`` (the upper half of the viewing sphere), ``orbit:N``
(about +y, starting on +z, 20 degrees above the equator), ``random:N`` (uniform on the whole
sphere, seeded by ``seed``), all at the distance from which the unit sphere fits the image with
the 10% margin (:data:`mi_npr.views.FRAME_MARGIN`) for ``sphere``/``random``; the orbit keeps the
scene camera's distance, which is that same distance.

**Layout of OUT.** ``scenes/<stem>.xml`` one scene per good mesh, ``meshes/<stem>.ply`` the
converted meshes, ``<stem>/<view>.exr`` (depth ``Z``, normals ``N``, ``object_id``,
``prim_id``, ``R G B``), ``<stem>/<view>.png`` (``R G B``), ``<stem>/<view>_lines.png`` /
``_lines.svg`` (the line drawing), ``<stem>/<view>_strokes.svg`` / ``.json`` / ``.png`` (the
strokes), ``manifest.jsonl`` (the batch's log), and :data:`INDEX` ``dataset.jsonl``, the
dataset's manifest, rewritten whole by every run: one row per view of every good mesh
(``mesh``, ``mesh_hash``, ``normalisation``, ``triangles``, ``scene``, ``view``, ``camera``,
``files`` by kind, ``status``, ``error``, ``warning``) and one per bad mesh (``view`` null,
``status`` ``skipped``, ``error`` the reason), and ``dataset.parquet`` with the same rows when
``pyarrow`` is installed (nested fields as JSON text).

**Non-manifold meshes** (an edge shared by more than two triangles, vertices at one position
counted as one, :func:`non_manifold_edges`) render as well as any other: ray casting and the
line chain need no manifold. So by default (``non_manifold="warn"``) such a mesh is rendered and
every row of it has ``warning`` naming the count; ``"skip"`` makes it a bad mesh instead.

Ambiguities resolved: two meshes of one file stem are refused before anything runs (their
outputs would share a folder); a mesh named like a folder of OUT (:data:`RESERVED`) is a bad
mesh; a folder is searched for the formats above only, a file given by
name in another format is a bad mesh.
"""

from __future__ import annotations

import glob
import hashlib
import json
import math
import os
from collections.abc import Sequence
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

import mitsuba as mi
import numpy as np

from . import batch
from .camera import fit_distance
from .errors import InputError, ParameterError, as_path, one_line, shown
from .io._atomic import atomic_output, check_writable_dir
from .meshes import write_ply
from .params import (
    MAX_RES,
    MAX_SPP,
    Param,
    check_arg,
    entry,
    integer_range,
    one_of,
    seed_rule,
)
from .views import FRAME_MARGIN

#: What a non-manifold mesh (an edge shared by more than two triangles) gets: ``warn`` renders
#: it and says so in its rows, ``skip`` reports it as a bad mesh.
NON_MANIFOLD = ("warn", "skip")


#: The film, samples and seed of a dataset (``mi-npr dataset``'s flags).
DATASET_PARAMS: tuple[Param, ...] = (
    Param("width", int, 256, "image width in pixels", integer_range(1, MAX_RES)),
    Param("height", int, 256, "image height in pixels", integer_range(1, MAX_RES)),
    Param("spp", int, 16, "samples per pixel of the beauty", integer_range(1, MAX_SPP)),
    Param("seed", int, 0, "seed of the random:N views and of the samplers", seed_rule),
    Param(
        "non_manifold",
        str,
        "warn",
        "a mesh with an edge shared by more than two triangles: warn (rendered, its manifest "
        "rows say so) or skip (a bad mesh)",
        one_of(NON_MANIFOLD),
    ),
    replace(batch.LAUNCH_PARAMS[0], default=0),
    replace(
        batch.LAUNCH_PARAMS[1],
        default=False,
        doc="render the studio's beauty (direct illumination, spp samples); false: the "
        "G-buffer pass's headlight shading and no image under the SVG drawings",
    ),
)
#: Formats Mitsuba loads itself.
NATIVE = (".obj", ".ply")
#: Formats without normals, faceted by definition: shaded with face normals (so that their
#: sharp edges stay creases: smooth vertex normals would round them off).
FACETED = (".stl",)
#: Formats read by ``trimesh`` and written as PLY.
CONVERTED = (".stl", ".gltf", ".glb")
#: The dataset's manifest in OUT.
INDEX = "dataset.jsonl"
#: Its Parquet copy (written when ``pyarrow`` is installed).
PARQUET = "dataset.parquet"
#: Folders of OUT that a mesh's outputs (``OUT/<stem>/``) must not share.
RESERVED = ("scenes", "meshes")
#: Horizontal field of view of the studio camera (degrees).
FOV = 40.0
#: Elevation of the studio camera above the equator (degrees): the orbit's height.
ELEVATION = 20.0

#: The studio every mesh is rendered in (module docstring); ``{mesh}`` is the shape element.
STUDIO = """<scene version="3.0.0">
    <default name="width" value="256"/>
    <default name="height" value="256"/>
    <default name="spp" value="16"/>
    <integrator type="direct"/>
    <sensor type="perspective">
        <float name="fov" value="{fov}"/>
        <string name="fov_axis" value="x"/>
        <transform name="to_world">
            <lookat origin="{origin}" target="0, 0, 0" up="0, 1, 0"/>
        </transform>
        <sampler type="independent">
            <integer name="sample_count" value="$spp"/>
        </sampler>
        <film type="hdrfilm">
            <integer name="width" value="$width"/>
            <integer name="height" value="$height"/>
            <rfilter type="box"/>
        </film>
    </sensor>
    <emitter type="constant">
        <rgb name="radiance" value="0.3"/>
    </emitter>
    <emitter type="directional">
        <vector name="direction" value="-1, -2, -1.5"/>
        <rgb name="irradiance" value="2.5"/>
    </emitter>
{mesh}
</scene>
"""


@dataclass(frozen=True)
class Mesh:
    """One input mesh, checked: ``error`` says why it is skipped, else ``source`` is the file
    the scene loads (the input, or its PLY in ``OUT/meshes``) and ``centre``/``radius`` its
    bounding sphere (module docstring)."""

    path: str
    stem: str
    digest: str = ""
    source: str = ""
    centre: tuple[float, float, float] = (0.0, 0.0, 0.0)
    radius: float = 0.0
    triangles: int = 0
    error: str | None = None
    warning: str | None = None


def find_meshes(
    inputs: Sequence[str | os.PathLike[str]], exclude: str | os.PathLike[str] | None = None
) -> list[str]:
    """The mesh files of ``inputs``, in order, each once: a file as given, a folder's files of
    the formats of :data:`NATIVE` and :data:`CONVERTED` (recursively, sorted), a glob's matches
    (sorted); :class:`~mi_npr.errors.InputError` naming an input that gives none. A folder's or
    a glob's files inside ``exclude`` are left out (OUT inside the folder searched: its
    converted meshes are no inputs)."""
    if isinstance(inputs, (str, os.PathLike)):
        inputs = [inputs]
    if not isinstance(inputs, (list, tuple)):
        raise ParameterError(
            f"meshes = {shown(inputs)}: expected mesh files, folders or globs (a list of paths)"
        )
    if not inputs:
        raise ParameterError("meshes: give at least one mesh, folder or glob")
    inputs = [as_path(v, "meshes: entry") for v in inputs]
    found: list[str] = []
    known = (*NATIVE, *CONVERTED)
    for given in map(os.fspath, inputs):
        if os.path.isdir(given):
            hits = sorted(
                str(p) for p in Path(given).rglob("*") if p.suffix.lower() in known and p.is_file()
            )
            if not hits:
                raise InputError(f"{given}: no mesh in the folder ({', '.join(known)})")
        elif os.path.exists(given) or not glob.has_magic(given):
            if not os.path.exists(given):
                raise InputError(f"{given}: no such file")
            hits = [given]
        else:
            hits = sorted(p for p in glob.glob(given, recursive=True) if os.path.isfile(p))
            if not hits:
                raise InputError(f"{given}: the glob matches no file")
        if hits != [given]:  # a folder's or a glob's files, not a file named
            hits = [h for h in hits if not _under(h, exclude)]
        found.extend(os.path.abspath(h) for h in hits)
    return list(dict.fromkeys(found))


def _under(path: str, folder: str | os.PathLike[str] | None) -> bool:
    if folder is None:
        return False
    root = os.path.realpath(folder)
    return os.path.commonpath([root, os.path.realpath(path)]) == root


def _digest(path: str) -> str:
    h = hashlib.sha256()
    with open(path, "rb") as f:
        for block in iter(lambda: f.read(1 << 20), b""):
            h.update(block)
    return "sha256:" + h.hexdigest()


def _arrays(path: str) -> tuple[np.ndarray, np.ndarray]:
    """Vertices and triangles of ``path`` as read by ``trimesh`` (all parts of a scene
    together, nothing merged or dropped)."""
    import trimesh  # imported here: slow to import, needed only to build datasets

    loaded = trimesh.load(path, process=False)
    if isinstance(loaded, trimesh.PointCloud):  # vertices without faces: "0 faces", not "empty"
        return np.asarray(loaded.vertices, np.float64), np.zeros((0, 3), np.int64)
    if isinstance(loaded, trimesh.Scene):  # glTF parts (and OBJ objects) as one mesh
        loaded = loaded.to_mesh() if loaded.geometry else trimesh.Trimesh()
    return np.asarray(loaded.vertices, np.float64), np.asarray(loaded.faces, np.int64)


def _welded(V: np.ndarray, F: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``(V, F)`` with coincident vertices merged: an STL repeats every corner per triangle, and
    Mitsuba's smooth vertex normals (what the crease lines read) need the triangles joined."""
    import trimesh  # imported here: see _arrays

    m = trimesh.Trimesh(V, F, process=True)
    return np.asarray(m.vertices), np.asarray(m.faces)


def non_manifold_edges(V: np.ndarray, F: np.ndarray) -> int:
    """How many edges of the triangles ``F`` are shared by more than two of them, vertices at
    one position counted as one (an STL repeats every corner per triangle); an edge is an
    unordered pair of distinct positions, so a degenerate triangle adds only its real edges.

    >>> V = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, -1, 0], [0, 0, 1]], float)
    >>> non_manifold_edges(V, np.array([[0, 1, 2], [1, 0, 3], [0, 1, 4]]))  # a fin on 0-1
    1
    """
    _, weld = np.unique(np.asarray(V), axis=0, return_inverse=True)
    f = weld.reshape(-1)[np.asarray(F, np.int64)]
    e = np.concatenate([f[:, [0, 1]], f[:, [1, 2]], f[:, [2, 0]]])
    e = np.sort(e[e[:, 0] != e[:, 1]], axis=1)
    if len(e) == 0:
        return 0
    _, counts = np.unique(e, axis=0, return_counts=True)
    return int(np.count_nonzero(counts > 2))


def check_mesh(path: str, out: Path, non_manifold: str = "warn") -> Mesh:
    """``path`` checked (unreadable, empty, 0 faces, non-finite or out-of-range vertices, no
    extent, refused by Mitsuba, non-manifold with ``non_manifold="skip"``) and, for a
    converted format, written as PLY into ``out/meshes``; never raises for a bad mesh: its
    :class:`Mesh` has the reason (a non-manifold mesh with ``"warn"``: its ``warning``)."""
    stem = as_path(path, "check_mesh: path").stem
    ext = Path(path).suffix.lower()
    if ext not in NATIVE + CONVERTED:
        return Mesh(path, stem, error=f"{path}: unsupported format {ext or '(none)'}")
    if stem in RESERVED:
        return Mesh(
            path,
            stem,
            error=f"{path}: its outputs would go to OUT/{stem}/, the dataset's "
            f"folder of {stem}: rename the file",
        )
    try:
        digest = _digest(path)
    except OSError as e:
        return Mesh(path, stem, error=f"{path}: unreadable: {e.strerror or e}")
    try:
        V, F = _arrays(path)
    except Exception as e:  # any failure of a reader is the file's problem
        return Mesh(path, stem, digest, error=f"{path}: unreadable: {one_line(e)}")
    why = None
    if len(V) == 0:
        why = "empty: no vertices"
    elif F.ndim != 2 or len(F) == 0:
        why = "0 faces"
    elif not np.all(np.isfinite(V)):
        why = f"{int(np.sum(~np.all(np.isfinite(V), axis=1)))} vertices are NaN or infinite"
    elif F.min() < 0 or F.max() >= len(V):
        why = "a face refers to a vertex that does not exist"
    elif not np.all(np.ptp(V, axis=0).max() > 0):
        why = "no extent: every vertex is at one point"
    if why is not None:
        return Mesh(path, stem, digest, error=f"{path}: {why}")
    warning = None
    shared = non_manifold_edges(V, F)
    if shared:
        s = "s" if shared > 1 else ""
        warning = f"{path}: non-manifold: {shared} edge{s} shared by more than two triangles"
        if non_manifold == "skip":
            return Mesh(path, stem, digest, error=warning)
    source = path
    if ext in CONVERTED:
        source = str(out / "meshes" / f"{stem}.ply")
        check_writable_dir(out / "meshes", create=True)
        write_ply(source, *_welded(V, F))
    try:  # what Mitsuba loads is what renders: its box, and its refusals
        shape = mi.load_dict(
            {"type": "ply" if source.lower().endswith(".ply") else "obj", "filename": source}
        )
    except Exception as e:
        return Mesh(path, stem, digest, error=f"{path}: Mitsuba cannot load it: {one_line(e)}")
    bb = shape.bbox()
    lo = np.asarray(bb.min, np.float64).ravel()[:3]
    hi = np.asarray(bb.max, np.float64).ravel()[:3]
    centre = tuple(float(v) for v in (lo + hi) / 2)
    radius = float(np.linalg.norm(hi - lo) / 2)
    if not (math.isfinite(radius) and radius > 0):
        return Mesh(path, stem, digest, error=f"{path}: no extent")
    triangles = int(shape.face_count())
    return Mesh(path, stem, digest, source, centre, radius, triangles, warning=warning)  # type: ignore[arg-type]


def _num(v: float) -> str:
    return repr(float(v))


def scene_xml(mesh: Mesh) -> str:
    """The studio scene (:data:`STUDIO`) of a good ``mesh``: the mesh normalised, the camera
    on +z raised by :data:`ELEVATION` at the distance that frames the unit sphere."""
    d = FRAME_MARGIN * fit_distance(1.0, FOV, (1, 1))
    e = math.radians(ELEVATION)
    origin = ", ".join(_num(v) for v in (0.0, d * math.sin(e), d * math.cos(e)))
    kind = "ply" if mesh.source.lower().endswith(".ply") else "obj"
    x, y, z = (_num(-v) for v in mesh.centre)
    name = _xml_text(mesh.source)
    faceted = Path(mesh.path).suffix.lower() in FACETED
    normals = '\n        <boolean name="face_normals" value="true"/>' if faceted else ""
    shape = f"""    <shape type="{kind}" id="mesh">
        <string name="filename" value="{name}"/>{normals}
        <transform name="to_world">
            <translate x="{x}" y="{y}" z="{z}"/>
            <scale value="{_num(1.0 / mesh.radius)}"/>
        </transform>
        <bsdf type="diffuse">
            <rgb name="reflectance" value="0.6"/>
        </bsdf>
    </shape>"""
    return STUDIO.format(fov=_num(FOV), origin=origin, mesh=shape)


def _xml_text(text: str) -> str:
    return (
        text.replace("&", "&amp;").replace('"', "&quot;").replace("<", "&lt;").replace(">", "&gt;")
    )


def write_scene(mesh: Mesh, out: Path) -> Path:
    """``out/scenes/<stem>.xml`` for a good ``mesh``, rewritten only when its text changes (a
    resumed run finds the same file)."""
    path = out / "scenes" / f"{mesh.stem}.xml"
    text = scene_xml(mesh)
    try:
        if path.read_text() == text:
            return path
    except OSError:
        pass
    check_writable_dir(path.parent, create=True)
    with atomic_output(path) as tmp:
        Path(tmp).write_text(text)
    return path


def _files(row: dict[str, Any]) -> dict[str, str]:
    """A batch row's outputs by kind: ``exr``, ``png``, ``lines.png``, ``strokes.json`` ..."""
    view = str(row.get("view"))
    out = {}
    for name in row.get("outputs") or []:
        base = os.path.basename(name)
        kind = base[len(view) :].lstrip("_.") if base.startswith(view) else base
        out[kind] = name
    return out


def make_dataset(
    meshes: Sequence[str | os.PathLike[str]] | str | os.PathLike[str],
    out: str | os.PathLike[str],
    views: str = "sphere:8",
    seed: int = 0,
    drawings: Sequence[str] = ("lines", "strokes"),
    width: int = 256,
    height: int = 256,
    spp: int | None = None,
    workers: int | None = None,
    resume: bool = False,
    views_per_launch: int = 0,
    beauty: bool = False,
    non_manifold: str = "warn",
    **options: Any,
) -> list[dict[str, Any]]:
    """Render every good mesh of ``meshes`` (:func:`find_meshes`) in the studio from every view
    of ``views`` into ``out`` (module docstring); the rows of :data:`INDEX`, bad meshes first.

    ``seed`` seeds the ``random:N`` views (``random:N:SEED`` given in full wins) and the
    samplers; ``spp``: the studio's 16 when ``None`` (the beauty's; without ``beauty`` the
    G-buffer pass's headlight shading fills ``R G B``); ``views_per_launch`` views of a mesh
    share one launch (0: :func:`mi_npr.render.views_per_launch`); ``non_manifold`` (one of
    :data:`NON_MANIFOLD`): what a mesh with an edge shared by more than two triangles gets;
    ``options`` go to
    :func:`mi_npr.batch.run` (``params``, ``threads_per_worker``, ``scheduler``, ``client``,
    ``retries``, ``job_timeout``, ``progress``, ``line_color``, ``paper``).

    >>> import tempfile
    >>> from mi_npr.meshes import box, write_ply
    >>> d = tempfile.mkdtemp()
    >>> _ = write_ply(f"{d}/cube.ply", *box())
    >>> rows = make_dataset([f"{d}/cube.ply"], f"{d}/out", "random:2", width=32, height=32,
    ...                     spp=1, workers=0, progress=False)
    >>> [(r["view"], r["status"], sorted(r["files"])[:2]) for r in rows]
    [('random_000', 'done', ['exr', 'lines.png']), ('random_001', 'done', ['exr', 'lines.png'])]
    """
    if not isinstance(views, str):
        raise ParameterError(f"views = {views!r}: expected a spec such as sphere:8 or random:8")
    kind, _, rest = views.partition(":")
    if kind == "random" and ":" not in rest:
        views = f"{views}:{seed}"
    outdir = check_writable_dir(out, create=True).resolve()
    given = meshes if not isinstance(meshes, (str, os.PathLike)) else [meshes]
    paths = find_meshes(given, exclude=outdir)
    stems: dict[str, str] = {}
    for p in paths:
        stem = Path(p).stem
        if stem in stems:
            raise ParameterError(f"{stems[stem]} and {p} would both write outputs named {stem!r}")
        stems[stem] = p
    non_manifold = check_arg("dataset", entry(DATASET_PARAMS, "non_manifold"), non_manifold)
    checked = [check_mesh(p, outdir, non_manifold) for p in paths]
    good = [m for m in checked if m.error is None]
    index: list[dict[str, Any]] = [
        {
            "mesh": m.path,
            "mesh_hash": m.digest or None,
            "view": None,
            "status": "skipped",
            "error": m.error,
        }
        for m in checked
        if m.error is not None
    ]
    if good:
        scenes = {str(write_scene(m, outdir)): m for m in good}
        rows = batch.run(
            list(scenes),
            views,
            out=outdir,
            drawings=drawings,
            width=width,
            height=height,
            spp=spp,
            seed=seed,
            workers=workers,
            resume=resume,
            views_per_launch=views_per_launch,
            beauty=beauty,
            **options,
        )
        for r in rows:
            m = scenes[str(r["scene"])]
            index.append(
                {
                    "mesh": m.path,
                    "mesh_hash": m.digest,
                    "triangles": m.triangles,
                    "normalisation": {"centre": list(m.centre), "scale": 1.0 / m.radius},
                    "scene": os.path.relpath(r["scene"], outdir),
                    "view": r["view"],
                    "camera": r.get("camera"),
                    "files": _files(r),
                    "status": r.get("status"),
                    "error": r.get("error"),
                    "warning": m.warning,
                }
            )
    write_index(outdir, index)
    return index


def write_index(outdir: Path, rows: list[dict[str, Any]]) -> None:
    """:data:`INDEX` (JSON lines) and, with ``pyarrow`` installed, :data:`PARQUET`."""
    text = "".join(json.dumps(r, sort_keys=True, allow_nan=False) + "\n" for r in rows)
    with atomic_output(outdir / INDEX) as tmp:
        Path(tmp).write_text(text)
    try:
        import pyarrow as pa  # imported here: optional, and slow to import
        import pyarrow.parquet as pq
    except ImportError:
        return
    columns = ("mesh", "mesh_hash", "triangles", "scene", "view", "status", "error", "warning")
    nested = ("normalisation", "camera", "files")
    table = pa.table(
        {
            **{c: [r.get(c) for r in rows] for c in columns},
            **{
                c: [None if r.get(c) is None else json.dumps(r[c], sort_keys=True) for r in rows]
                for c in nested
            },
        }
    )
    with atomic_output(outdir / PARQUET) as tmp:
        pq.write_table(table, tmp)

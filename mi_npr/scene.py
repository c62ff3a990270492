"""Loading scenes and their sensors, and naming their objects stably.

Object ids (the ``object_id`` layer) must not depend on the order Mitsuba keeps its shapes in
(``scene.shapes()`` changes with the XML's order and with scene optimisation), and Mitsuba's own
``shape_index`` AOV is wrong on JIT variants (mitsuba3 #955, #1059). So: every top-level shape
gets a *name* (its XML ``id``; a mesh without one is named after its file's stem, other
shapes ``<type>_<hash>`` from their type, bounding box and primitive count; equal names get
``_1``, ``_2``... in a stable order), names are sorted, and ids 1..N follow that order. A lookup
table from Mitsuba's shape registry index to our id turns ``si.shape`` into an id with one gather.

Scenes are loaded with ``optimize=False``: Mitsuba otherwise merges meshes that share a BSDF into
one shape, and separate objects would get one id. They are loaded with at least
:data:`LOAD_THREADS` Dr.Jit threads (the count asked for is restored afterwards): Mitsuba
3.9.1's loader deadlocks on a scene with an EXR texture when Dr.Jit has a single thread. Every
file a scene references (:func:`scene_files`) must be a regular file: a FIFO, a device or a
socket would block the loader forever, so it is refused first ("not a regular file").
"""

from __future__ import annotations

import contextlib
import hashlib
import os
import re
import stat
import threading
import xml.etree.ElementTree as ET
from collections import Counter
from collections.abc import Iterator, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import drjit as dr
import mitsuba as mi
import numpy as np

from .errors import ParameterError, SceneError, check_input_file, one_line
from .params import MAX_RES, MAX_SPP, Param, check_arg, entry, integer_range, seed_rule
from .raycast import require_jit


def _define_value(name: str, value: Any) -> str:
    if isinstance(value, (bool, np.bool_)):
        return "true" if value else "false"
    if isinstance(value, (np.integer, np.floating)):
        value = value.item()
    if isinstance(value, (int, float, str)):
        return str(value)
    raise ParameterError(f"define {name!r}: value {value!r} is not a number, string or bool")


def merge_defines(defines: Mapping[str, Any] | None, more: Mapping[str, Any]) -> dict[str, Any]:
    """The XML ``<default>`` values given as a mapping and as keyword arguments, in one dict.

    The mapping reaches every name, also one that is a keyword of the function it is passed to
    (``render(path, defines={"seed": 3}, seed=0)``: the XML's ``$seed`` and the sampler seed).
    """
    if defines is not None and not isinstance(defines, Mapping):
        raise ParameterError(f"defines: expected a mapping of names to values, got {defines!r}")
    return {**(defines or {}), **more}


#: The film and the sampler of any render, whatever the names of the XML's ``<default>``\ s:
#: the keyword arguments of the render functions and the flags of every command that renders.
RENDER_PARAMS: tuple[Param, ...] = (
    Param("width", int, None, "film width (alone: keeps the aspect)", integer_range(1, MAX_RES)),
    Param("height", int, None, "film height (alone: keeps the aspect)", integer_range(1, MAX_RES)),
    Param("spp", int, None, "samples per pixel of the beauty", integer_range(1, MAX_SPP)),
    Param("seed", int, 0, "sampler seed", seed_rule),
)


def check_resolution(resolution: tuple[int | None, int | None] | None) -> tuple | None:
    """``(W, H)`` with each an int >= 1 or ``None`` (keep the film's aspect), or ``None``."""
    if resolution is None:
        return None
    try:
        w, h = resolution
    except (TypeError, ValueError):
        raise ParameterError(f"resolution = {resolution!r}: expected (width, height)") from None
    for name, v in (("width", w), ("height", h)):
        if v is not None and (not isinstance(v, int) or isinstance(v, bool) or v < 1):
            raise ParameterError(f"{name} = {v!r}: must be a positive integer")
    return None if w is None and h is None else (w, h)


def resize_sensor(
    sensor: mi.Sensor, resolution: tuple[int | None, int | None] | None, spp: int | None
) -> mi.Sensor:
    """Give ``sensor``'s film the size ``resolution`` (a ``None`` side keeps the film's aspect
    ratio) and its sampler ``spp`` samples per pixel, in place; the crop window becomes the
    whole film. The horizontal field of view is kept (Mitsuba stores ``x_fov``), so a wider
    aspect shows less vertically, as resizing the XML's ``<film>`` with ``fov_axis="x"`` does.
    Rays of the resized sensor equal those of a sensor loaded at that size (tested)."""
    if spp is not None:
        sensor.sampler().set_sample_count(spp)
    res = check_resolution(resolution)
    if res is None:
        return sensor
    w0, h0 = (int(v) for v in sensor.film().size())
    w, h = res
    if w is None:
        w = max(1, round(h * w0 / h0))
    if h is None:
        h = max(1, round(w * h0 / w0))
    params = mi.traverse(sensor)
    if "film.size" not in params:
        raise ParameterError(f"{sensor.class_name()}: its film cannot be resized")
    params["film.size"] = mi.ScalarVector2u(w, h)
    params["film.crop_size"] = mi.ScalarVector2u(w, h)
    if "film.crop_offset" in params:
        params["film.crop_offset"] = mi.ScalarPoint2u(0, 0)
    params.update()
    return sensor


#: Folders where scenes look for the files they name (meshes, textures, includes), as Mitsuba's
#: own ``mitsuba -a``: ``os.pathsep``-separated, searched before the scene's own folder. The
#: command line's ``-a PATH`` sets it, so a batch's worker processes inherit it.
SEARCH_PATH_ENV = "MI_NPR_SEARCH_PATH"


def search_paths() -> list[str]:
    """The folders of :data:`SEARCH_PATH_ENV`, each checked to exist."""
    out = []
    for p in filter(None, os.environ.get(SEARCH_PATH_ENV, "").split(os.pathsep)):
        if not os.path.isdir(p):
            raise ParameterError(f"search path {p!r} ({SEARCH_PATH_ENV}): not a folder")
        out.append(os.path.abspath(p))
    return out


def _use_search_paths() -> None:
    """Put :func:`search_paths` first in Mitsuba's file resolver (once each)."""
    resolver = mi.file_resolver()
    have = {str(resolver[i]) for i in range(len(resolver))}
    for p in reversed(search_paths()):
        if p not in have:
            resolver.prepend(p)


#: The fewest Dr.Jit threads a scene is loaded with (module docstring).
LOAD_THREADS = 2


@contextlib.contextmanager
def loading_threads() -> Iterator[None]:
    """Run the block with at least :data:`LOAD_THREADS` Dr.Jit threads, then restore the count
    (a batch worker's one thread): Mitsuba 3.9.1 deadlocks loading an EXR texture otherwise."""
    n = dr.thread_count()
    if n >= LOAD_THREADS:
        yield
        return
    dr.set_thread_count(LOAD_THREADS)
    try:
        yield
    finally:
        dr.set_thread_count(n)


def _check_referenced(path: str, values: Mapping[str, str]) -> None:
    """A :class:`SceneError` for a file the scene names that exists but is no regular file
    (a FIFO, device or socket would block the loader); missing files are Mitsuba's to report."""
    for f in scene_files(path, values):
        try:
            mode = os.stat(f).st_mode
        except OSError:
            continue
        if not stat.S_ISREG(mode):
            what = "is a directory" if stat.S_ISDIR(mode) else "not a regular file"
            raise SceneError(f"{path}: {f}: {what}")


#: The scene's own integrator type while :func:`load_scene` loads a scene whose integrator a
#: define (``-D integrator=npr_lines``) replaced with one of mi-npr's: see
#: :func:`replaced_integrator`. Process-wide, not a context variable: Mitsuba instantiates
#: plugins on its own loader threads; the lock keeps two such loads from mixing their values.
_REPLACED: list[str | None] = [None]
_REPLACED_LOCK = threading.Lock()


@contextlib.contextmanager
def _replacing(own: str | None) -> Iterator[None]:
    if own is None:
        yield
        return
    with _REPLACED_LOCK:
        _REPLACED[0] = own
        try:
            yield
        finally:
            _REPLACED[0] = None


def replaced_integrator() -> str | None:
    """While a scene loads: the plugin type of the scene's own integrator (its
    ``<default name="integrator" value="path"/>``) when a define set ``integrator`` to one of
    mi-npr's plugins (``npr_*``), else ``None``. The mi-npr integrator then takes the scene's
    integrator, built with the properties it does not know itself (``max_depth``,
    ``rr_depth``, ``hide_emitters``...), as its beauty, instead of refusing them: the scene's
    own settings keep rendering the beauty, and the drawing goes on top."""
    return _REPLACED[0]


def load_scene(
    scene: str | os.PathLike[str] | mi.Scene,
    /,
    defines: Mapping[str, Any] | None = None,
    **more: Any,
) -> mi.Scene:
    r"""A ``mi.Scene`` from an XML path (``defines`` and keyword arguments fill its
    ``<default>``s), or ``scene`` itself.

    ``width``, ``height`` and ``spp`` size every scene, whatever its ``<default>``\ s are named
    (as the command line's ``--width --height --spp``): a scene that declares the default gets
    the value there; any other gets its sensors' films and samplers resized after loading
    (:func:`resize_sensor`; one of ``width``/``height`` alone keeps the film's aspect).

    Files the scene names are looked for in :func:`search_paths` first, then as Mitsuba
    does. Errors (missing file, malformed XML, unknown parameter, unused define) raise
    :class:`~mi_npr.errors.SceneError` with a one-line message that names the file.
    """
    defines = merge_defines(defines, more)
    if isinstance(scene, mi.Scene):
        if defines:
            raise ParameterError(
                f"defines ({', '.join(defines)}) only apply when loading a scene from a file"
            )
        return scene
    if not isinstance(scene, (str, os.PathLike)):
        raise ParameterError(f"expected a scene or an XML path, got {type(scene).__name__}")
    path = os.fspath(scene)
    check_input_file(path, SceneError)
    declared = declared_defaults(path)
    size = {k: _size(k, defines.pop(k)) for k in _SIZE if k in defines and k not in declared}
    values = {k: _define_value(k, v) for k, v in defines.items()}
    _use_search_paths()
    _check_referenced(path, values)
    own = default_values(path).get("integrator", "")
    replaced = str(values.get("integrator", ""))
    beauty = own if replaced.startswith("npr_") and own and not own.startswith("npr_") else None
    try:
        with loading_threads(), _replacing(beauty):
            loaded = mi.load_file(path, optimize=False, **values)
    except Exception as e:  # Mitsuba raises RuntimeError for every parse/instantiation problem
        unused = re.findall(r"\$(\w+)=", str(e)) if "unused parameters" in str(e) else []
        if unused:
            known = ", ".join(sorted(declared_defaults(path))) or "none"
            raise SceneError(
                f"{path}: the scene uses no parameter named {', '.join(unused)} "
                f"(a define it cannot use; its <default>s: {known})"
            ) from None
        msg = one_line(e)
        if path not in msg:
            msg = f"{path}: {msg}"
        low = msg.lower()
        missing = any(m in low for m in ("does not exist", "file not found", "no such file"))
        if "polarized" in low and "polarized" not in str(mi.variant()) and not missing:
            msg += (
                f" (the variant is {mi.variant()}: render it in a polarized one such as "
                "llvm_ad_spectral_polarized, with --variant or mi_npr.set_variant)"
            )
        raise SceneError(msg) from None
    if size:
        res = (size.get("width"), size.get("height"))
        for sensor in loaded.sensors():
            resize_sensor(sensor, None if res == (None, None) else res, size.get("spp"))
    return loaded


#: The film and sampler settings every scene takes, whatever its ``<default>``\ s are named.
_SIZE = ("width", "height", "spp")


def _size(name: str, value: Any) -> int:
    """A ``width``, ``height`` or ``spp`` define as a checked int (a command-line string too)."""
    if isinstance(value, str):
        try:
            value = int(value)
        except ValueError:
            raise ParameterError(f"{name} = {value!r}: must be a positive integer") from None
    return check_arg("load_scene", entry(RENDER_PARAMS, name), value)


def declared_defaults(path: str | os.PathLike[str]) -> set[str]:
    """Names of the ``<default>`` parameters an XML scene declares (its includes too)."""
    return set(default_values(path))


def default_values(path: str | os.PathLike[str]) -> dict[str, str]:
    """The ``<default>`` parameters an XML scene declares (its includes too), name -> the value
    written in the file (the first declaration of a name wins, as in Mitsuba)."""
    names: dict[str, str] = {}
    todo, seen = [os.path.abspath(path)], set()
    while todo:
        p = todo.pop()
        if p in seen or not os.path.isfile(p):
            continue
        seen.add(p)
        try:
            root = ET.parse(p).getroot()
        except ET.ParseError:
            continue  # Mitsuba's loader reports malformed XML with a better message
        for el in root.iter("default"):
            if el.get("name"):
                names.setdefault(el.get("name", ""), el.get("value", ""))
        for el in root.iter("include"):
            if el.get("filename"):
                todo.append(os.path.join(os.path.dirname(p), el.get("filename", "")))
    return names


def _xml_defaults(root: ET.Element) -> dict[str, str]:
    return {
        el.get("name", ""): el.get("value", "") for el in root.iter("default") if el.get("name")
    }


def _substitute(text: str, values: Mapping[str, str]) -> str:
    """``$name`` replaced by its value, as Mitsuba's parser does (longest names first, so
    ``$meshes`` is not ``$mesh`` + ``es``)."""
    if "$" not in text:
        return text
    for name in sorted(values, key=len, reverse=True):
        text = text.replace(f"${name}", values[name])
    return text


def scene_files(
    path: str | os.PathLike[str], defines: Mapping[str, Any] | None = None
) -> list[Path]:
    """Every file an XML scene references, in document order, includes followed recursively:
    ``<include filename>``, ``filename`` attributes and ``<string name="filename">`` values
    (meshes, textures, environment maps, spectra), with ``$name`` replaced by ``defines``
    over the XML's ``<default>``\\ s. A relative name is taken from the naming file's folder,
    else the scene's; a name left with a ``$`` (no value) is skipped. Files that do not exist
    are listed too (Mitsuba reports them when loading); unreadable XML gives none."""
    top = Path(path).resolve()
    given = {k: _define_value(k, v) for k, v in (defines or {}).items()}
    found: list[Path] = []
    seen: set[Path] = {top}

    def visit(xml: Path, inherited: Mapping[str, str]) -> None:
        try:
            root = ET.parse(xml).getroot()
        except (ET.ParseError, OSError, RecursionError):
            return
        values = {**_xml_defaults(root), **inherited}
        for el in root.iter():
            names = []
            if "filename" in el.attrib:
                names.append(el.attrib["filename"])
            if el.get("name") == "filename" and "value" in el.attrib:
                names.append(el.attrib["value"])
            for raw in names:
                name = _substitute(raw, values)
                if not name or "$" in name:
                    continue
                candidates = [(xml.parent / name), (top.parent / name)]
                f = next((c for c in candidates if os.path.lexists(c)), candidates[0])
                f = Path(os.path.abspath(f))
                if f in seen:
                    continue
                seen.add(f)
                found.append(f)
                if el.tag == "include" and f.suffix.lower() == ".xml" and f.is_file():
                    visit(f, values)

    if top.is_file():
        visit(top, given)
    return found


def sensor_of(scene: mi.Scene, sensor: int | mi.Sensor = 0) -> mi.Sensor:
    """The scene's ``sensor``-th sensor (or ``sensor`` itself), with a clear error if absent or
    if its film has no pixels."""
    if not isinstance(sensor, mi.Sensor):
        sensors = scene.sensors()
        if not isinstance(sensor, int) or not 0 <= sensor < len(sensors):
            raise ParameterError(f"sensor {sensor!r}: the scene has {len(sensors)} sensor(s)")
        sensor = sensors[sensor]
    w, h = (int(v) for v in sensor.film().crop_size())
    if w < 1 or h < 1:
        raise SceneError(f"film size {w}x{h}: width and height must be at least 1 pixel")
    return sensor


def shape_bbox(shape: mi.Shape) -> np.ndarray:
    """A shape's world bounding box as a float64 (2, 3) array: ``[min, max]``."""
    bb = shape.bbox()
    lo = np.asarray(bb.min, np.float64).reshape(-1)[:3]
    hi = np.asarray(bb.max, np.float64).reshape(-1)[:3]
    return np.stack([lo, hi])


_MESH_NAME = re.compile(r'^\s*name = "([^"\n]+)"', re.MULTILINE)


def mesh_file_stem(shape: mi.Shape) -> str | None:
    """The file stem of a mesh loaded from a file (``ply``, ``obj``, ``serialized``: the
    ``name`` Mitsuba keeps, the file's name, in its description), else ``None``."""
    if not shape.is_mesh():
        return None
    head = str(shape)[:400]
    m = _MESH_NAME.search(head)
    if not m:
        return None
    stem = os.path.splitext(os.path.basename(m.group(1)))[0]
    return stem or None


def _auto_name(shape: mi.Shape) -> str:
    """A name for a shape without an XML id: the stem of its mesh file
    (``meshes/Brick_01_02_001.ply`` -> ``Brick_01_02_001``), else its type + a hash of its
    bounding box and primitive count. Equal names are numbered by :func:`object_table`."""
    return mesh_file_stem(shape) or _hash_name(shape)


def _hash_name(shape: mi.Shape) -> str:
    bb = shape.bbox()
    nums = [*np.asarray(bb.min, dtype=np.float64).ravel(), *np.asarray(bb.max).ravel()]
    key = ",".join(f"{v:.5g}" for v in nums) + f"|{shape.primitive_count()}"
    kind = shape.class_name().lower()
    return f"{kind}_{hashlib.sha1(key.encode()).hexdigest()[:8]}"


@dataclass
class ObjectTable:
    """Stable object ids for a scene's top-level shapes (1..N, sorted by name; 0 = background)
    and stable material ids for their BSDFs (1..M, sorted by name; 0 = background).

    A material is named by its BSDF's XML ``id``; an unnamed BSDF (declared inside its shape) is
    named after the first shape that uses it (``<object>.bsdf``). Shapes that share one BSDF
    object share its material id. Instances have no BSDF of their own: they get material 0.
    """

    names: dict[int, str]
    shapes: dict[int, mi.Shape] = field(repr=False)
    _lut: Any = field(default=None, repr=False)  # registry index -> id
    materials: dict[int, str] = field(default_factory=dict)
    #: (N + 1,) int64: the material id of every object id (0: the background, instances)
    material_ids: np.ndarray = field(default_factory=lambda: np.zeros(1, np.int64), repr=False)
    _material_lut: Any = field(default=None, repr=False)  # material_ids in Dr.Jit, on first use

    def __len__(self) -> int:
        return len(self.names)

    def id_of(self, name: str) -> int:
        for k, v in self.names.items():
            if v == name:
                return k
        raise KeyError(f"no object named {name!r}")

    def lookup(self, si: Any) -> Any:
        """Object id of each (preliminary) interaction: ``UInt32`` (0 where nothing was hit)."""
        valid = si.is_valid()
        inst = dr.reinterpret_array(mi.UInt32, si.instance)
        idx = dr.select(inst != 0, inst, dr.reinterpret_array(mi.UInt32, si.shape))
        size = dr.width(self._lut)
        ok = valid & (idx < size)
        return dr.select(ok, dr.gather(mi.UInt32, self._lut, dr.minimum(idx, size - 1), ok), 0)

    def material_of(self, object_id: Any) -> Any:
        """Material id of each object id (``UInt32``; 0 for the background)."""
        if self._material_lut is None:
            self._material_lut = mi.UInt32(self.material_ids.astype(np.uint32))
        return dr.gather(mi.UInt32, self._material_lut, object_id)

    def material_names(self) -> dict[int, str]:
        """Object id -> the name of its material (:attr:`materials`); an instance, which has
        no BSDF of its own, is ``<object>.bsdf``."""
        return {
            oid: self.materials.get(int(self.material_ids[oid]), f"{self.names[oid]}.bsdf")
            for oid in self.shapes
        }


def _materials(names: dict[int, str], shapes: dict[int, mi.Shape]) -> tuple[dict, np.ndarray]:
    keyed: dict[int, str] = {}  # BSDF pointer -> name
    owner: dict[int, int] = {}  # object id -> BSDF pointer
    for oid in sorted(shapes):
        shape = shapes[oid]
        bsdf = None if shape.class_name() == "Instance" else shape.bsdf()
        if bsdf is None:
            continue
        owner[oid] = bsdf.ptr
        if bsdf.ptr not in keyed:
            keyed[bsdf.ptr] = bsdf.id() or f"{names[oid]}.bsdf"
    seen: dict[str, int] = {}
    for ptr in sorted(keyed, key=lambda p: keyed[p]):  # equal names: numbered in a stable way
        n = keyed[ptr]
        seen[n] = seen.get(n, -1) + 1
        if seen[n]:
            keyed[ptr] = f"{n}_{seen[n]}"
    order = sorted(keyed, key=lambda p: keyed[p])
    mid = {ptr: k + 1 for k, ptr in enumerate(order)}
    lut = np.zeros(len(shapes) + 1, np.uint32)
    for oid, ptr in owner.items():
        lut[oid] = mid[ptr]
    return {mid[p]: keyed[p] for p in order}, lut


def object_table(scene: mi.Scene) -> ObjectTable:
    """Build the :class:`ObjectTable` of ``scene`` (see the module docstring for the rules)."""

    require_jit("the object table")
    shapes = list(scene.shapes())
    names = []
    for s in shapes:
        sid = s.id()
        names.append(sid if sid else _auto_name(s))
    # Equal names (two shapes of one mesh file, identical unnamed shapes): numbered in the order
    # of their geometry hash, which does not depend on the XML's order.
    seen: dict[str, int] = {}
    dup = {n for n, k in Counter(names).items() if k > 1}
    tie = {i: _hash_name(shapes[i]) if names[i] in dup else "" for i in range(len(shapes))}
    order = sorted(range(len(shapes)), key=lambda i: (names[i], tie[i]))
    for i in order:
        n = names[i]
        if n in seen:
            seen[n] += 1
            names[i] = f"{n}_{seen[n]}"
        else:
            seen[n] = 0
    order = sorted(range(len(shapes)), key=lambda i: names[i])
    table = {k + 1: names[i] for k, i in enumerate(order)}
    by_shape = {k + 1: shapes[i] for k, i in enumerate(order)}
    ids = np.zeros(len(shapes), dtype=np.uint32)
    for k, i in enumerate(order):
        ids[i] = k + 1
    reg = np.asarray(dr.reinterpret_array(mi.UInt32, scene.shapes_dr()).numpy(), np.uint32)
    lut = np.zeros(int(reg.max()) + 1 if reg.size else 1, dtype=np.uint32)
    lut[reg] = ids
    materials, mat_lut = _materials(table, by_shape)
    return ObjectTable(table, by_shape, mi.UInt32(lut), materials, mat_lut.astype(np.int64))

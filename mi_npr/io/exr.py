"""Multi-layer OpenEXR files holding a whole :class:`~mi_npr.gbuffer.GBuffer`.

One single-part scanline file, ZIP-compressed (lossless), one channel per layer, named as
:mod:`mi_npr.layers` defines (``pass.channel`` with one-letter channels, which Nuke and Blender
read as layers). Pixel types: ``FLOAT`` for float32 layers (bit-exact, ``inf`` and NaN
included) and for ids (``object_id.V``, ``prim_id.V``, ...: whole numbers, exact up to 2**24, so
OpenImageIO-based tools read the id itself, not a [0, 1]-normalised ``UINT``; a larger id is an
:class:`~mi_npr.errors.OutputError`); ``UINT`` only for the ray-tree hash halves. Header
attributes:

=========================  ======================================================================
``worldToCamera``          the OpenEXR standard attribute (Imath ``M44f``, row vectors: ``p * M``):
                           world -> camera space with +x right, +y up, +z the view direction
                           (RenderMan's; Mitsuba's own camera space has +x *left*, so x is
                           mirrored)
``worldToNDC``             the standard attribute (``M44f``, row vectors, then divide by w;
                           perspective cameras only): world -> NDC, (0, 0) the image's top-left
                           corner, (1, 1) its bottom-right, so pixel ``(x, y) = (W * ndc.x, H *
                           ndc.y)``; z = 0 on the near and 1 on the far clip plane
``mi_npr/version``         the mi-npr version that wrote the file
``mi_npr/objects``         JSON object table ``{"1": "floor", "2": "sphere", ...}`` (0 =
                           background)
``mi_npr/camera``          JSON camera: ``to_world`` (Mitsuba convention), resolution, fov, clip
                           planes
``mi_npr/layers``          JSON list of layer names in the GBuffer's order (EXR sorts channels)
``mi_npr/integer_layers``  JSON list of the uint32 layers stored as whole-number ``FLOAT``
``mi_npr/...``             every other metadata string of the GBuffer (scene, spp, variant, ...);
                           a key of the user's without the ``mi_npr/`` prefix goes in as
                           ``mi_npr/meta/<key>`` and comes back as ``<key>``
``cryptomatte/...``        Cryptomatte metadata, when the GBuffer has Cryptomatte layers
=========================  ======================================================================

Writes are atomic (temporary file + rename). ``read_exr(write_exr(gb))`` equals ``gb``, layers
bit for bit, except that the file always records the writer's ``mi_npr/version``. Files written
before the layer names got their one-letter channels (``object_id``, ``edges.real``, ...) are
read under the new names.
"""

from __future__ import annotations

import contextlib
import json
import os
import sys
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import drjit as dr
import numpy as np
import OpenEXR

from .. import layers as L
from .._version import __version__
from ..errors import InputError, NprError, OutputError, as_path, check_input_file
from ..gbuffer import GBuffer, Projection
from ..projection import world_to_camera, world_to_ndc
from ._atomic import atomic_output

_PREFIX = "mi_npr/"
_OBJECTS = _PREFIX + "objects"
_CAMERA = _PREFIX + "camera"
_LAYERS = _PREFIX + "layers"
_VERSION = _PREFIX + "version"
_USER = _PREFIX + "meta/"  # metadata keys given without the prefix
_INTEGER = _PREFIX + "integer_layers"
#: Metadata keys written as they are (other standards' attributes), not under ``mi_npr/``.
_FOREIGN = ("cryptomatte/",)


def _file_layer(path: Path, name: str, a: np.ndarray) -> np.ndarray:
    """The array as stored: ids (uint32, file type ``FLOAT``) as exact float32 whole numbers."""
    if a.dtype == np.uint32 and L.exr_type(name) == "FLOAT":
        top = int(a.max()) if a.size else 0
        if top > L.FLOAT_EXACT:
            raise OutputError(
                f"{path}: layer {name!r} holds id {top}, above 2**24 = {L.FLOAT_EXACT}, "
                "which a FLOAT channel cannot store exactly"
            )
        return np.ascontiguousarray(a, np.float32)
    # A non-contiguous array is written wrong without any error: always pass contiguous ones.
    return np.ascontiguousarray(a)


def _header(gb: GBuffer) -> dict[str, Any]:
    header: dict[str, Any] = {
        "compression": OpenEXR.ZIP_COMPRESSION,
        "type": OpenEXR.scanlineimage,
    }
    for k, v in gb.metadata.items():
        keep = k.startswith(_PREFIX) or k.startswith(_FOREIGN)
        header[k if keep else _USER + k] = str(v)
    header[_VERSION] = __version__
    header[_OBJECTS] = json.dumps({str(k): v for k, v in gb.objects.items()})
    header[_LAYERS] = json.dumps(list(gb.names))
    if gb.camera is not None:
        header[_CAMERA] = json.dumps(gb.camera.to_dict())
        # Imath matrices multiply row vectors (p * M): the transposes of ours.
        header["worldToCamera"] = np.ascontiguousarray(world_to_camera(gb.camera).T, np.float32)
        ndc = world_to_ndc(gb.camera)
        if ndc is not None:
            header["worldToNDC"] = np.ascontiguousarray(ndc.T, np.float32)
    return header


_threads_set: list[int] = []  # the thread count this module last gave OpenEXR


def _threads() -> None:
    """OpenEXR (de)compresses scanline blocks on a thread pool of its own, off (0 threads)
    unless someone sets it: it gets as many threads as Dr.Jit has (a batch worker's
    ``--threads``). A count somebody else has set is left alone."""

    now = OpenEXR.global_thread_count()
    if now == 0 or (_threads_set and now == _threads_set[-1]):
        n = max(1, int(dr.thread_count()))
        if n != now:
            OpenEXR.set_global_thread_count(n)
            _threads_set[:] = [n]


@dataclass(frozen=True)
class ExrImage:
    """What :func:`write_exr` writes, taken out of a :class:`~mi_npr.gbuffer.GBuffer`: the
    header and the channels as numpy arrays (copies), so that the file can be encoded later,
    in another thread, without Dr.Jit (:func:`exr_image`, :func:`write_exr_image`)."""

    header: dict[str, Any]
    channels: dict[str, np.ndarray]


def exr_image(path: str | os.PathLike[str], gbuffer: GBuffer) -> ExrImage:
    """The header and channels of ``gbuffer``'s EXR at ``path`` (the name is for errors: an
    id too large for a ``FLOAT`` channel names the file)."""
    if not isinstance(gbuffer, GBuffer):
        raise TypeError(f"write_exr expects a GBuffer, got {type(gbuffer).__name__}")
    target = as_path(path, "output file")
    layers = {k: gbuffer.numpy(k) for k in gbuffer.names}
    channels = {k: np.array(_file_layer(target, k, v), copy=True) for k, v in layers.items()}
    header = _header(gbuffer)
    ints = [k for k, v in layers.items() if v.dtype != channels[k].dtype]
    if ints:
        header[_INTEGER] = json.dumps(ints)
    return ExrImage(header, channels)


def write_exr_image(path: str | os.PathLike[str], image: ExrImage) -> Path:
    """Write an :class:`ExrImage` to ``path`` (atomically). Returns the path."""
    target = as_path(path, "output file")
    _threads()
    with atomic_output(target) as tmp:
        with OpenEXR.File(image.header, image.channels) as f:
            f.write(tmp)
    return target


def write_exr(path: str | os.PathLike[str], gbuffer: GBuffer) -> Path:
    """Write every layer of ``gbuffer`` to ``path`` (atomically). Returns the path."""
    return write_exr_image(path, exr_image(path, gbuffer))


def _order(names: list[str], stored: str | None) -> list[str]:
    if stored:
        try:
            wanted = [n for n in json.loads(stored) if n in names]
            return wanted + sorted(set(names) - set(wanted))
        except (ValueError, TypeError):
            pass
    canon = [n for n in L.SPECS if n in names]
    return canon + sorted(set(names) - set(canon))


#: The first four bytes of every OpenEXR file.
_MAGIC = bytes([0x76, 0x2F, 0x31, 0x01])


@contextlib.contextmanager
def quiet_library() -> Iterator[None]:
    """Silence file descriptors 1 and 2 for the block: the OpenEXR library prints its own
    messages about a damaged file there (on stdout too). Python's streams are flushed first so
    nothing of ours is lost."""
    sys.stdout.flush()
    sys.stderr.flush()
    saved = [os.dup(1), os.dup(2)]
    try:
        with open(os.devnull, "wb") as null:
            os.dup2(null.fileno(), 1)
            os.dup2(null.fileno(), 2)
        yield
    finally:
        for fd, keep in zip((1, 2), saved, strict=True):
            os.dup2(keep, fd)
            os.close(keep)


def read_exr(path: str | os.PathLike[str]) -> GBuffer:
    """Read an EXR written by :func:`write_exr` (or any single-part scanline EXR)."""
    p = check_input_file(path)
    with open(p, "rb") as fh:
        magic = fh.read(4)
    if magic != _MAGIC:
        raise InputError(f"{p}: not a valid EXR (truncated?)")
    _threads()
    try:
        with quiet_library():  # the library prints its own lines about a damaged file
            f = OpenEXR.File(str(p), separate_channels=True)
            with f:
                parts = len(f.parts)
                # Closing the file clears its header and channel objects: copy what we keep.
                header = dict(f.header())
                raw = {name: np.array(ch.pixels, copy=True) for name, ch in f.channels().items()}
    except Exception:
        raise InputError(f"{p}: not a valid EXR (truncated?)") from None
    if parts != 1:
        raise InputError(f"{p}: multi-part EXR files are not supported")
    raw = {L.LEGACY.get(k, k): v for k, v in raw.items()}
    try:
        integer = set(json.loads(header.get(_INTEGER, "[]")))
    except (ValueError, TypeError):
        integer = set()
    layers: dict[str, np.ndarray] = {}
    for name in _order(list(raw), header.get(_LAYERS)):
        a = raw[name]
        if a.ndim != 2:
            raise InputError(f"{p}: channel {name!r} has shape {a.shape}, expected (H, W)")
        if a.dtype == np.float16:
            a = a.astype(np.float32)
        whole = a.dtype == np.float32 and np.all(a == np.round(a)) and np.all(a >= 0)
        if name in integer and whole:
            a = a.astype(np.uint32)
        layers[name] = a
    if not layers:
        raise InputError(f"{p}: no channels")
    try:
        objects = {int(k): v for k, v in json.loads(header.get(_OBJECTS, "{}")).items()}
        camera = Projection.from_dict(json.loads(header[_CAMERA])) if _CAMERA in header else None
    except (ValueError, TypeError, AttributeError) as e:
        raise InputError(f"{p}: malformed mi-npr header ({e})") from None
    skip = {_OBJECTS, _CAMERA, _LAYERS, _INTEGER}
    meta = {k: v for k, v in header.items() if k.startswith(_PREFIX) and k not in skip}
    meta = {k.removeprefix(_USER): v for k, v in meta.items() if isinstance(v, str)}
    meta.update({k: v for k, v in header.items() if k.startswith(_FOREIGN) and isinstance(v, str)})
    try:
        return GBuffer(layers, objects, camera, meta)
    except NprError as e:  # layers or table that no GBuffer may hold (a float id, id 0, ...)
        raise InputError(f"{p}: {e}") from None


def describe(gb: GBuffer) -> dict[str, Any]:
    """A JSON-friendly summary: size, layers (type, range), object table, camera, metadata."""
    info_layers = []
    for name in gb.names:
        a = gb.numpy(name)
        finite = a[np.isfinite(a)] if a.dtype.kind == "f" else a
        info_layers.append(
            {
                "name": name,
                "type": str(a.dtype),
                "min": float(finite.min()) if finite.size else None,
                "max": float(finite.max()) if finite.size else None,
                "non_finite": int(a.size - finite.size),
                "meaning": L.meaning(name),
            }
        )
    return {
        "width": gb.width,
        "height": gb.height,
        "layers": info_layers,
        "objects": {str(k): v for k, v in gb.objects.items()},
        "camera": gb.camera.to_dict() if gb.camera is not None else None,
        "metadata": dict(gb.metadata),
    }

"""The one type every stage passes: named (H, W) layers, the object table and the camera.

Layout: every layer is a Dr.Jit tensor of shape ``(H, W)`` of the active JIT variant's backend
(``mi.TensorXf`` for float32 layers, ``mi.TensorXu`` for uint32 ones), row 0 at the top of the
image, column 0 at the left. The render pass, the kernels and compositing hand tensors to each
other without leaving Dr.Jit (no host round trip, and on AD variants the gradient graph is
kept); a layer becomes numpy only where a writer or a user asks: ``np.asarray(gb["Z"])`` or
:meth:`GBuffer.numpy` (a view of Dr.Jit's memory on the LLVM backend, a copy on CUDA). numpy
arrays given to a GBuffer are checked and copied into tensors.

>>> import numpy as np
>>> gb = GBuffer({"Z": np.ones((2, 3), np.float32)})
>>> gb.shape, gb.names
((2, 3), ('Z',))
>>> gb.with_layers({"lines": np.zeros((2, 3))}).numpy("lines").dtype
dtype('float32')
"""

from __future__ import annotations

import math
from collections.abc import Iterator, Mapping
from dataclasses import dataclass, field, replace
from typing import Any

import drjit as dr
import mitsuba as mi
import numpy as np

from . import layers as L
from .errors import ParameterError, shown


def to_numpy(x: Any) -> np.ndarray:
    """A numpy view of ``x`` (Dr.Jit arrays and tensors without a copy where possible)."""
    if isinstance(x, np.ndarray):
        return x
    fn = getattr(x, "numpy", None)
    if callable(fn):
        return np.asarray(fn())
    return np.asarray(x)


def tensor_types() -> tuple[type, type]:
    """``(TensorXf, TensorXu)`` of the active JIT variant (LLVM's when none is active)."""
    if mi.variant() is not None and dr.is_jit_v(mi.Float):
        return mi.TensorXf, mi.TensorXu
    from drjit.llvm.ad import TensorXf, TensorXu  # only when no JIT variant is active

    return TensorXf, TensorXu


def _dtype_of(t: Any) -> np.dtype:
    vt = dr.type_v(t)
    if vt == dr.VarType.Float32:
        return np.dtype(np.float32)
    if vt == dr.VarType.UInt32:
        return np.dtype(np.uint32)
    return np.dtype(np.asarray(t).dtype)


def _as_tensor(name: str, value: Any, shape: tuple[int, int] | None) -> Any:
    """Layer ``name`` as a checked (H, W) tensor (see the module docstring)."""
    known = L.spec(name)
    if dr.is_tensor_v(value) and dr.is_jit_v(value):
        shp = tuple(int(v) for v in value.shape)
        if len(shp) == 3 and shp[-1] == 1:
            value, shp = type(value)(value.array, shape=shp[:2]), shp[:2]
        if len(shp) != 2:
            raise ParameterError(f"layer {name!r}: expected a 2-D (H, W) array, got shape {shp}")
        if 0 in shp:
            raise ParameterError(f"layer {name!r}: an empty layer of shape {shp}")
        if shape is not None and shp != shape:
            raise ParameterError(f"layer {name!r}: shape {shp} differs from the others' {shape}")
        vt = dr.type_v(value)
        want = np.dtype(known.dtype) if known is not None else None
        if vt == dr.VarType.Float32 and want in (None, np.dtype(np.float32)):
            return value  # kept as it is: no copy, gradients kept
        if vt == dr.VarType.UInt32 and want in (None, np.dtype(np.uint32)):
            return value
    a = _as_layer(name, value, shape)
    TF, TU = tensor_types()
    return (TU if a.dtype == np.uint32 else TF)(a)


def _as_layer(name: str, value: Any, shape: tuple[int, int] | None) -> np.ndarray:
    a = to_numpy(value)
    if a.ndim == 3 and a.shape[-1] == 1:
        a = a[..., 0]
    if a.ndim != 2:
        raise ParameterError(f"layer {name!r}: expected a 2-D (H, W) array, got shape {a.shape}")
    if 0 in a.shape:
        raise ParameterError(f"layer {name!r}: an empty layer of shape {a.shape}")
    if a.dtype.kind not in "biuf":  # objects, strings, complex numbers: no pixel type
        raise ParameterError(f"layer {name!r}: values of type {a.dtype} are not numbers")
    if shape is not None and a.shape != shape:
        raise ParameterError(f"layer {name!r}: shape {a.shape} differs from the others' {shape}")
    known = L.spec(name)
    if known is not None:
        dtype = np.dtype(known.dtype)
    elif a.dtype.kind in "biu":
        dtype = np.dtype(np.uint32)
    else:
        dtype = np.dtype(np.float32)
    if dtype == np.uint32 and a.dtype.kind == "f":
        if not np.all(np.isfinite(a)) or np.any(a < 0) or np.any(a != np.round(a)):
            raise ParameterError(f"layer {name!r}: integer layer holds non-integer values")
    if dtype == np.uint32 and a.dtype.kind == "i" and a.size and a.min() < 0:
        raise ParameterError(f"layer {name!r}: integer layer holds negative values")
    if dtype == np.uint32 and a.dtype.kind in "iuf" and a.size and a.max() > 0xFFFFFFFF:
        raise ParameterError(f"layer {name!r}: integer layer holds values above 2^32 - 1")
    return np.ascontiguousarray(a, dtype=dtype)


@dataclass(frozen=True)
class Projection:
    """How the image was seen: the sensor's whole transform, lens and film, as rendered
    (Mitsuba's convention: camera looks along +z, +y is up, +x is left).

    ``to_world`` maps camera space to world space (4x4, column vectors, like
    ``sensor.world_transform()``, kept whole: a mirrored or scaled transform is not a
    ``lookat``); ``fov`` is the horizontal field of view in degrees (``None`` for orthographic
    cameras); ``resolution`` is (width, height) of the rendered (crop) window. The pose alone
    is a :class:`mi_npr.camera.Camera` (:func:`mi_npr.camera.camera_of`); this record is what
    the reprojections of :mod:`mi_npr.projection` and the EXR's standard attributes need.
    """

    to_world: np.ndarray
    resolution: tuple[int, int]
    fov: float | None = None
    kind: str = "perspective"
    near_clip: float = 1e-2
    far_clip: float = 1e4

    def __post_init__(self) -> None:
        try:
            m = np.asarray(self.to_world, dtype=np.float64).reshape(4, 4)
        except (TypeError, ValueError):
            m = np.full(1, np.nan)
        if m.shape != (4, 4) or not np.all(np.isfinite(m)):
            raise ParameterError(f"to_world = {shown(self.to_world)}: expected a finite 4x4 matrix")
        object.__setattr__(self, "to_world", m)
        try:
            w, h = self.resolution
        except (TypeError, ValueError):
            w = h = None
        if not all(
            isinstance(v, (int, np.integer)) and not isinstance(v, bool) and v >= 1 for v in (w, h)
        ):
            raise ParameterError(
                f"resolution = {shown(self.resolution)}: expected (width, height), integers >= 1"
            )
        object.__setattr__(self, "resolution", (int(w), int(h)))

    @property
    def origin(self) -> np.ndarray:
        return self.to_world[:3, 3].copy()

    @property
    def forward(self) -> np.ndarray:
        d = self.to_world[:3, 2]
        return d / np.linalg.norm(d)

    @property
    def up(self) -> np.ndarray:
        u = self.to_world[:3, 1]
        return u / np.linalg.norm(u)

    @property
    def world_to_camera(self) -> np.ndarray:
        return np.linalg.inv(self.to_world)

    def to_dict(self) -> dict[str, Any]:
        return {
            "to_world": self.to_world.tolist(),
            "resolution": list(self.resolution),
            "fov": self.fov,
            "kind": self.kind,
            "near_clip": self.near_clip,
            "far_clip": self.far_clip,
        }

    @classmethod
    def from_dict(cls, d: Mapping[str, Any]) -> Projection:
        try:
            return cls(
                to_world=np.asarray(d["to_world"], dtype=np.float64),
                resolution=tuple(d["resolution"]),  # type: ignore[arg-type]
                fov=None if d.get("fov") is None else float(d["fov"]),
                kind=str(d.get("kind", "perspective")),
                near_clip=float(d.get("near_clip", 1e-2)),
                far_clip=float(d.get("far_clip", 1e4)),
            )
        except (KeyError, TypeError, ValueError) as e:
            raise ParameterError(f"camera description is incomplete or malformed: {e}") from e

    def __eq__(self, other: object) -> bool:
        if not isinstance(other, Projection):
            return NotImplemented
        return (
            np.array_equal(self.to_world, other.to_world)
            and self.resolution == other.resolution
            and (
                self.fov == other.fov
                or (
                    self.fov is not None
                    and other.fov is not None
                    and math.isclose(self.fov, other.fov)
                )
            )
            and self.kind == other.kind
            and self.near_clip == other.near_clip
            and self.far_clip == other.far_clip
        )

    __hash__ = None  # type: ignore[assignment]


@dataclass(frozen=True)
class GBuffer:
    """Named per-pixel layers of one image, plus the object table and the camera.

    ``camera`` is the :class:`Projection` the layers were rendered through. ``objects`` maps
    object ids (1..N, as in the ``object_id`` layer) to shape names; 0 is the background and is
    not in the table. ``metadata`` holds free-form strings (scene path, spp,
    variant, mi-npr version) that writers store as file attributes.
    """

    layers: Mapping[str, Any]  # name -> (H, W) Dr.Jit tensor (TensorXf or TensorXu)
    objects: Mapping[int, str] = field(default_factory=dict)
    camera: Projection | None = None
    metadata: Mapping[str, str] = field(default_factory=dict)

    def __post_init__(self) -> None:
        if not self.layers:
            raise ParameterError("a GBuffer needs at least one layer")
        checked: dict[str, Any] = {}
        shape = None
        for name, value in self.layers.items():
            if not isinstance(name, str) or not name:
                raise ParameterError(f"layer names must be non-empty strings, got {name!r}")
            checked[name] = _as_tensor(name, value, shape)
            shape = tuple(int(v) for v in checked[name].shape)
        objects = {int(k): str(v) for k, v in dict(self.objects).items()}
        if 0 in objects:
            raise ParameterError("object id 0 is the background and cannot be in the table")
        object.__setattr__(self, "layers", checked)
        object.__setattr__(self, "objects", dict(sorted(objects.items())))
        object.__setattr__(self, "metadata", {str(k): str(v) for k, v in self.metadata.items()})

    # ----------------------------------------------------------------- access
    @property
    def shape(self) -> tuple[int, int]:
        """(height, width)."""
        h, w = next(iter(self.layers.values())).shape
        return int(h), int(w)

    @property
    def height(self) -> int:
        return self.shape[0]

    @property
    def width(self) -> int:
        return self.shape[1]

    @property
    def names(self) -> tuple[str, ...]:
        return tuple(self.layers)

    def __getitem__(self, name: str) -> Any:
        """The layer as an (H, W) Dr.Jit tensor (``np.asarray`` of it is a numpy array)."""
        try:
            return self.layers[name]
        except KeyError:
            raise KeyError(
                f"no layer {name!r} in this GBuffer (it has: {', '.join(self.layers)})"
            ) from None

    def __contains__(self, name: object) -> bool:
        return name in self.layers

    def __iter__(self) -> Iterator[str]:
        return iter(self.layers)

    def __len__(self) -> int:
        return len(self.layers)

    def get(self, name: str, default: Any = None) -> Any:
        return self.layers.get(name, default)

    def numpy(self, name: str) -> np.ndarray:
        """Layer ``name`` as an (H, W) numpy array (float32 or uint32)."""
        return to_numpy(self[name])

    def dtype(self, name: str) -> np.dtype:
        """The pixel type of layer ``name``: float32 or uint32."""
        return _dtype_of(self[name])

    def stack(self, names: tuple[str, ...] | list[str]) -> np.ndarray:
        """Several layers as one (H, W, len(names)) numpy array (a copy)."""
        return np.stack([self.numpy(n) for n in names], axis=-1)

    @property
    def beauty(self) -> np.ndarray:
        """The beauty render as (H, W, 3) linear RGB (numpy)."""
        return self.stack(L.RGB)

    @property
    def normals(self) -> np.ndarray:
        return self.stack(L.N)

    @property
    def positions(self) -> np.ndarray:
        return self.stack(L.P)

    @property
    def object_id(self) -> np.ndarray:
        return self.numpy(L.OBJECT_ID)

    def object_name(self, object_id: int) -> str:
        if object_id == 0:
            return "background"
        try:
            return self.objects[int(object_id)]
        except KeyError:
            raise KeyError(f"object id {object_id} is not in the object table") from None

    def find_object(self, name: str) -> int:
        """The id of the object called ``name``."""
        for k, v in self.objects.items():
            if v == name:
                return k
        raise KeyError(f"no object named {name!r} (objects: {', '.join(self.objects.values())})")

    # ----------------------------------------------------------------- update
    def with_layers(self, new: Mapping[str, Any]) -> GBuffer:
        """A new GBuffer with ``new`` layers added (or replaced); this one is unchanged."""
        merged = dict(self.layers)
        merged.update(new)
        return replace(self, layers=merged)

    def without(self, *names: str) -> GBuffer:
        return replace(self, layers={k: v for k, v in self.layers.items() if k not in names})

    def with_metadata(self, **items: Any) -> GBuffer:
        md = dict(self.metadata)
        md.update({k: str(v) for k, v in items.items()})
        return replace(self, metadata=md)

    def __repr__(self) -> str:
        chans = ", ".join(f"{k}:{_dtype_of(v)}" for k, v in self.layers.items())
        return (
            f"GBuffer({self.width}x{self.height}, layers=[{chans}], "
            f"objects={len(self.objects)}, camera={'yes' if self.camera else 'no'})"
        )

    def __eq__(self, other: object) -> bool:
        """Bit-exact equality of every layer (NaN equal to NaN), table, camera, metadata."""
        if not isinstance(other, GBuffer):
            return NotImplemented
        if self.names != other.names:
            return False
        for k in self.names:
            a, b = self.numpy(k), other.numpy(k)
            if a.dtype != b.dtype or a.shape != b.shape:
                return False
            if not np.array_equal(a.view(np.uint32), b.view(np.uint32)):
                return False
        return (
            dict(self.objects) == dict(other.objects)
            and self.camera == other.camera
            and dict(self.metadata) == dict(other.metadata)
        )

    __hash__ = None  # type: ignore[assignment]

"""Base class of mi-npr's Mitsuba integrators (re-imported for every active variant).

An mi-npr integrator overrides ``render`` to run its own loop: the exact pixel-centre G-buffer
pass of :mod:`mi_npr.render`, the nested beauty integrator's ``render`` (film filter and spp),
then its post-passes (:meth:`NprIntegrator.post`). So plain ``mi.render(scene)`` returns a
``TensorXf`` of shape (H, W, 3 + len(aov_names())): the beauty (with the integrator's lines or
overlays composited) followed by the channels named by :meth:`aov_names`; integer layers are
stored as float32 there (exact below 2**24). The sensor's film holds the same channels
afterwards (``film.bitmap()``, ``film.write()``); an ``rgba`` film adds ``A`` after ``B``.
``mi_npr.render(scene)`` returns the same layers as a :class:`~mi_npr.gbuffer.GBuffer`, with
integer layers kept as uint32.

Subclasses declare ``PLUGIN`` (the XML name) and ``DRAWING``, the drawing of the registry
(:mod:`mi_npr.drawings`) that they draw, whose parameter table is their ``PARAMS`` and whose
function is their :meth:`post`; they list their channels in :meth:`aov_names`. Plugins hold no
algorithm: the drawing's function serves the CLI, batches and notebooks too.

Under ``mi.render(scene, params=params)``, ``dr.forward`` and ``dr.backward`` run Mitsuba's
``render_forward`` and :meth:`NprIntegrator.render_backward`: automatic differentiation of
:meth:`~NprIntegrator.render`, except that a gradient on the soft lines channel alone
(``npr_lines`` with ``line_model = 'soft'``, ``npr_contours`` with ``contour_model = 'soft'``)
differentiates those lines alone.

Mitsuba binds Python integrators to the variant active when the class is defined, which is why
this module is reloaded by :func:`mi_npr._variant.register_plugins` on every variant change.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any, ClassVar

import drjit as dr
import mitsuba as mi
import numpy as np

from . import cryptomatte
from . import layers as L
from .drawings import DRAWINGS, Drawing, soft_image, soft_model
from .errors import ParameterError
from .gbuffer import GBuffer
from .params import Param, read_props
from .raycast import require_jit
from .render import _headlight, channels, render_gbuffer
from .scene import object_table, replaced_integrator, sensor_of
from .session import SceneSession, check_spp


def pack(gb: GBuffer, names: Sequence[str]) -> mi.TensorXf:
    """The layers ``names`` of ``gb`` interleaved into one float32 (H, W, C) tensor."""
    h, w = gb.shape
    return _interleave(_planar([gb[k] for k in names]), len(names), h, w)


def _planar(planes: Sequence[Any]) -> mi.Float:
    """(H, W) float32 or uint32 tensors (or arrays) one after the other in one Dr.Jit array;
    integer layers become float32 (exact below 2**24). One gather then interleaves it, which is
    faster than a strided scatter per channel or numpy's stack."""
    flat = []
    for a in planes:
        if dr.is_tensor_v(a) and dr.is_jit_v(a):
            v = a.array
        else:
            v = np.ascontiguousarray(a).reshape(-1)
            v = mi.Float(v) if v.dtype == np.float32 else mi.UInt32(v)
        flat.append(v if isinstance(v, mi.Float) else mi.Float(v))
    return dr.concat(flat) if len(flat) > 1 else flat[0]


def _interleave(planar: mi.Float, c: int, h: int, w: int, ones_at: int = -1) -> mi.TensorXf:
    """(H, W, C) from ``c`` planar channels; with ``ones_at >= 0`` a channel of ones is inserted
    there (a film's weight channel), so the result has ``c + 1`` channels."""
    n = h * w
    cc = c + (ones_at >= 0)
    k = dr.arange(mi.UInt32, cc * n)
    ch, px = k % cc, k // cc
    if ones_at < 0:
        return mi.TensorXf(dr.gather(mi.Float, planar, ch * n + px), shape=(h, w, cc))
    src = dr.select(ch < ones_at, ch, ch - 1)
    ones = ch == ones_at
    v = dr.select(ones, 1.0, dr.gather(mi.Float, planar, src * n + px, ~ones))
    return mi.TensorXf(v, shape=(h, w, cc))


def develop_into_film(film: mi.Film, gb: GBuffer, aovs: Sequence[str]) -> mi.TensorXf:
    """``R G B`` and the layers ``aovs`` of ``gb`` as ``mi.render`` returns them, also put into
    ``film`` (unit weights, no filter) as Mitsuba's own integrators leave theirs, so
    ``film.bitmap()`` and ``film.write()`` hold the same channels (an ``rgba`` film adds ``A``
    after ``B``: 1 where the pixel-centre ray hits).

    Films other than an RGB(A) ``hdrfilm`` (mono and spectral variants) are left as the nested
    integrator left them. The film's copy is one more gather from the same planar buffer,
    which Dr.Jit runs when the film is read.
    """
    names = [*L.RGB, *aovs]
    base = film.prepare(list(aovs)) - len(aovs)  # R G B W, or R G B A W
    rgb_film = mi.is_rgb and base in (4, 5) and film.class_name() == "HDRFilm"
    if not rgb_film:
        return pack(gb, names)
    h, w = gb.shape
    alpha = [mi.TensorXf(dr.select(gb[L.OBJECT_ID].array > 0, 1.0, 0.0))] if base == 5 else []
    planes = [*(gb[k] for k in L.RGB), *alpha, *(gb[k] for k in aovs)]
    planar = _planar(planes)
    block = _interleave(planar, len(planes), h, w, ones_at=base - 1)
    film.put_block(mi.ImageBlock(block, offset=film.crop_offset()))
    return _interleave(planar, len(planes), h, w)  # R G B (A) aovs, like Mitsuba's develop()


def _count(v: Any) -> Any:
    """A seed or sample count as a Python int: ``mi.render(scene, params=...)`` passes them as
    one-element Dr.Jit arrays (its differentiable render operation)."""
    if dr.is_array_v(v) and dr.width(v) == 1:
        return int(v[0])
    return v


class _Without:
    """``props`` without the keys ``drop``: what :func:`read_props` needs (``keys``, ``get``)."""

    def __init__(self, props: mi.Properties, drop: Sequence[str]) -> None:
        self._props, self._drop = props, set(drop)

    def keys(self) -> list[str]:
        return [k for k in self._props.keys() if k not in self._drop]

    def get(self, key: str, default: Any = None) -> Any:
        return self._props.get(key, default)


def _refuse_other_objects(plugin: str, props: mi.Properties) -> None:
    """A nested object that is not an integrator (a ``<bsdf>`` put inside the integrator by
    mistake) is an error naming it, not silently ignored."""
    kinds = ("BSDF", "Emitter", "Shape", "Texture", "Sensor", "Medium", "Film", "Sampler")
    for key in props.keys():
        v = props.get(key)
        if isinstance(v, mi.Object) and not isinstance(v, mi.Integrator):
            kind = next((k.lower() for k in kinds if isinstance(v, getattr(mi, k))), "object")
            name = v.id() if hasattr(v, "id") and v.id() else v.class_name()
            raise ParameterError(
                f"{plugin}: a nested <{kind}> ({name}) is not allowed inside it; "
                "only one nested (beauty) integrator is"
            )


#: Every mi-npr integrator's own parameter: Cryptomatte 1.2 layers (:mod:`mi_npr.cryptomatte`).
CRYPTOMATTE = Param(
    "cryptomatte", bool, False, "add CryptoObject and CryptoMaterial layers (Cryptomatte 1.2)"
)


class NprIntegrator(mi.SamplingIntegrator):
    """Common machinery; see the module docstring. Not registered as a plugin itself."""

    PLUGIN: ClassVar[str] = "npr_integrator"
    #: The drawing this plugin draws (``None``: the G-buffer alone).
    DRAWING: ClassVar[Drawing | None] = None
    PARAMS: ClassVar[tuple[Param, ...]] = ()

    def __init__(self, props: mi.Properties) -> None:
        require_jit(self.PLUGIN)
        super().__init__(props)
        nested = [props.get(k) for k in props.keys() if isinstance(props.get(k), mi.Integrator)]
        _refuse_other_objects(self.PLUGIN, props)
        if len(nested) > 1:
            raise ParameterError(f"{self.PLUGIN}: at most one nested (beauty) integrator")
        self.beauty: mi.Integrator | None = nested[0] if nested else None
        known = {p.name for p in (*self.PARAMS, CRYPTOMATTE)}
        foreign = [
            k for k in props.keys() if k not in known and not isinstance(props.get(k), mi.Object)
        ]
        own = replaced_integrator()
        if foreign and self.beauty is None and own is not None:
            # A define replaced the scene's integrator by this one: the scene's own type, with
            # the settings this plugin does not take, renders the beauty.
            self.beauty = mi.load_dict({"type": own, **{k: props.get(k) for k in foreign}})
            props = _Without(props, foreign)
        self.params: dict[str, Any] = read_props(
            self.PLUGIN, (*self.PARAMS, CRYPTOMATTE), props, lambda v: isinstance(v, mi.Object)
        )
        if self.DRAWING is not None:  # the rules between parameters (near < far)
            self.DRAWING.check(self.params, self.PLUGIN)
        self._depth_scales: dict[int, float] = {}

    # ------------------------------------------------------------ the pipeline
    def aov_names(self) -> list[str]:
        """Channels after the beauty's R, G, B in ``mi.render``'s output."""
        return [*L.GBUFFER_AOVS, *self.crypto_aovs()]

    def crypto_aovs(self) -> list[str]:
        """The Cryptomatte channels, last in every integrator's list when ``cryptomatte`` is on."""
        return cryptomatte.aov_names() if self.params.get("cryptomatte") else []

    def post(self, session: SceneSession, gb: GBuffer) -> GBuffer:
        """Add this integrator's drawing to ``gb`` (its layers, composited onto R, G, B)."""
        if self.DRAWING is None:
            return gb
        extra = {}
        if soft_model(self.params) is not None:
            extra["depth_scale"] = self.depth_scale(session.scene)
        return self.DRAWING.draw(session, gb, self.params, **extra).gbuffer

    def depth_scale(self, scene: mi.Scene) -> float:
        """The length that makes the soft line model's depths unitless: ``scene``'s
        bounding-box diagonal the first time this integrator draws it, kept for its later
        renders, so that an optimisation moving a shape does not change what the lines
        measure (their gradients leave the box out)."""
        key = id(scene)  # a Mitsuba scene takes no weak reference
        if key not in self._depth_scales:
            bb = scene.bbox()
            self._depth_scales[key] = float(dr.norm(bb.max - bb.min)) if bb.valid() else 1.0
        return self._depth_scales[key]

    def npr_gbuffer(
        self,
        scene: mi.Scene | SceneSession,
        sensor: int | mi.Sensor = 0,
        spp: int | None = None,
        seed: int = 0,
        source: str | None = None,
    ) -> GBuffer:
        """Everything this integrator produces, as a GBuffer (what ``mi_npr.render`` returns)."""
        if isinstance(scene, SceneSession):
            session = scene
        else:
            require_jit(self.PLUGIN)
            session = SceneSession(scene, sensor_of(scene, sensor), source, check_spp(spp))
        drawings = [self.DRAWING] if self.DRAWING is not None else []
        if self.params.get("cryptomatte"):
            drawings.append(DRAWINGS["cryptomatte"])
        for d in drawings:  # what a drawing refuses, before the beauty is paid for
            d.preflight(session)
        gb = render_gbuffer(session, beauty=self.beauty, spp=spp, seed=seed)
        gb = self.post(session, gb)
        if self.params.get("cryptomatte"):
            gb = DRAWINGS["cryptomatte"].draw(session, gb, {}, seed=seed, spp=spp).gbuffer
        return gb.with_metadata(**{"mi_npr/integrator": self.PLUGIN})

    def render(
        self,
        scene: mi.Scene,
        sensor: int | mi.Sensor = 0,
        seed: int = 0,
        spp: int = 0,
        develop: bool = True,
        evaluate: bool = True,
    ) -> mi.TensorXf:
        """The whole image as ``mi.render`` returns it, (H, W, 3 + len(aov_names())): the exact
        pixel-centre G-buffer pass, the nested integrator's beauty (its film filter, ``spp``
        samples, ``seed``), this integrator's drawing, packed and put into the sensor's film
        (module docstring). ``seed`` and ``spp`` may be one-element Dr.Jit arrays, as
        ``mi.render(scene, params=...)`` passes them."""
        if not develop:
            raise ParameterError(f"{self.PLUGIN}: develop=False is not supported")
        sensor = sensor_of(scene, sensor)
        gb = self.npr_gbuffer(scene, sensor, _count(spp) or None, _count(seed))
        return develop_into_film(sensor.film(), gb, self.aov_names())

    def render_backward(
        self,
        scene: mi.Scene,
        params: Any,
        grad_in: mi.TensorXf,
        sensor: int | mi.Sensor = 0,
        seed: Any = 0,
        spp: int = 0,
    ) -> None:
        """The adjoint of :meth:`render`, which ``dr.backward`` runs through
        ``mi.render(scene, params=params)``: ``grad_in`` (the image's shape) propagated to the
        scene parameters. With a soft model (``line_model`` or ``contour_model = 'soft'``) and
        a gradient on its channel alone (``lines.V``, ``contour_ink.V``: a loss on the
        drawing), only the soft lines are differentiated (their
        interior and boundary terms, :mod:`mi_npr.ad.visibility`); otherwise the whole
        :meth:`render` is, by automatic differentiation (Mitsuba's default, as
        :meth:`render_forward` always is)."""
        sensor = sensor_of(scene, sensor)
        k = self._soft_channel(grad_in)
        if k is None:
            # Recorded loops cannot be differentiated (Mitsuba's default turns them off too).
            with dr.scoped_set_flag(dr.JitFlag.LoopRecord, False):
                image = self.render(scene, sensor, seed, spp)
                dr.backward_from((image * grad_in).array)
            return
        model = soft_model(self.params)
        ink = soft_image(model, scene, sensor, self.params, self.depth_scale(scene))
        c = int(grad_in.shape[2])
        n = dr.width(ink.array)
        g = dr.gather(mi.Float, grad_in.array, dr.arange(mi.UInt32, n) * c + k)
        dr.backward_from(ink.array * g)

    def _soft_channel(self, grad_in: mi.TensorXf) -> int | None:
        """The index of the soft model's layer in ``grad_in``'s channels when a soft model is
        on and no other channel has a gradient, else ``None``."""
        aovs, model = self.aov_names(), soft_model(self.params)
        if model is None or model.layer not in aovs:
            return None
        c = int(grad_in.shape[2])
        k = c - len(aovs) + aovs.index(model.layer)  # R G B (A) come first
        ch = dr.arange(mi.UInt32, dr.width(grad_in.array)) % c
        others = dr.any((grad_in.array != 0.0) & (ch != k))
        return None if bool(others[0] if dr.is_array_v(others) else others) else k

    def sample(
        self,
        scene: mi.Scene,
        sampler: mi.Sampler,
        ray: mi.RayDifferential3f,
        medium: mi.Medium | None = None,
        active: Any = True,
    ) -> tuple[Any, Any, list[Any]]:
        """Per-ray fallback for callers that bypass :meth:`render`: the beauty from the nested
        integrator (or the headlight shading) and the per-ray G-buffer channels (0 for layers
        that need the whole image, such as ``lines``)."""
        table = object_table(scene)
        values = channels(scene, sensor_of(scene, 0), mi.Ray3f(ray), table, shade=False)
        if isinstance(self.beauty, mi.SamplingIntegrator):
            color, valid, _ = self.beauty.sample(scene, sampler, ray, medium, active)
        else:
            si = scene.ray_intersect(mi.Ray3f(ray))
            color, valid = _headlight(si, mi.Ray3f(ray), si.is_valid()), si.is_valid()
        aovs = [mi.Float(values[n]) if n in values else mi.Float(0.0) for n in self.aov_names()]
        return color, valid, aovs

    def to_string(self) -> str:
        args = ", ".join(f"{k}={v!r}" for k, v in self.params.items())
        nested = self.beauty.class_name() if self.beauty is not None else "none"
        return f"{type(self).__name__}[beauty={nested}{', ' if args else ''}{args}]"

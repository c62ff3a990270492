"""The lights of a ray tree: stable light numbers and one deterministic shadow ray per emitter.

Numbering. Every emitter gets a *name*: its XML ``id``; an unnamed area light is named after its
shape (``<object name>.emitter``, the shape's name from :func:`mi_npr.object_table`); any other
unnamed emitter is named ``<type>_<hash of its parameters>``. Names are sorted and numbered 1..K,
like object ids, so reordering the XML does not renumber the lights. Light ``k`` is bit ``k - 1``
of the light mask of a tree node and is written ``Lk`` in a signature.

Visibility (one shadow ray per emitter, no sampling, so a tree is deterministic). A light is
*visible* from a hit point when

- the point is on the side of the surface the tree's ray came from, as seen along the shadow
  ray's direction (a light behind the surface is not visible, whatever the occluders), and
- the shadow ray reaches the light unoccluded:

  ============================  ==============================================================
  emitter                       shadow ray
  ============================  ==============================================================
  point, spot (delta position)  towards the light's position; a spot also needs the point to
                                be inside its cone (``sample_direction``'s weight > 0)
  area (surface)                towards the centre of its shape's bounding box; hitting the
                                light's own shape first counts as reaching it (a sphere light's
                                centre is inside it). A point *on* the light's shape sees it.
  directional                   along the light's direction, to infinity
  envmap, constant (infinite)   the whole environment is one light, tested like a directional
                                light shining straight down from the sky: along the
                                environment's up axis (+y of its ``to_world``, Mitsuba's envmap
                                convention; world +y for ``constant``), to infinity
  ============================  ==============================================================

**Which lights cast shadow edges** (``shadow_lights``; ``npr_raytree``'s parameter, the
command line's ``--shadow-lights``). One shadow ray per light gives a hard shadow boundary,
which is right for lights that cast hard shadows: point, spot and directional lights
(``"hard"``, the default of the ray-tree pass). An area light is approximated by its centre (a
sharp ellipse where the rendered shadow is a soft penumbra) and an environment by one light at
its zenith (a gray line along every top face of a scene lit by the sky), so they join only when
asked: ``"all"`` keeps every light, or a comma-separated list of light names or shell globs
(``"sun,lamp*"``) picks them. Lights left out are not in the trees at all (not numbered, not in
the signatures), so they add no shadow edges and no signature differences.

Emission profiles are not evaluated beyond the spot cone (a one-sided area light is visible
from behind, a textured envmap counts whatever its value in that direction): visibility is
geometric, as in Nehab and Gattass's trees (paper, section 2.2.3).

Everything here works on Dr.Jit arrays of any width (JIT variants).
"""

from __future__ import annotations

import hashlib
from dataclasses import dataclass, field
from fnmatch import fnmatchcase
from typing import Any

import drjit as dr
import mitsuba as mi
import numpy as np

from ..errors import ParameterError
from ..scene import ObjectTable, shape_bbox

#: How each emitter's shadow ray is aimed (see the module docstring).
POSITION, DIRECTION, AREA, ENVIRONMENT = "position", "direction", "area", "environment"


def _kind(emitter: mi.Emitter) -> str:
    flags = int(emitter.flags())
    F = mi.EmitterFlags
    if flags & int(F.Surface):
        return AREA
    if flags & int(F.DeltaDirection):
        return DIRECTION
    if emitter.is_environment() or flags & int(F.Infinite):
        return ENVIRONMENT
    return POSITION  # point, spot, projector and anything that samples a position


def _auto_name(emitter: mi.Emitter) -> str:
    params = mi.traverse(emitter)
    parts = []
    for key in sorted(params.keys()):
        try:
            vals = np.asarray(params[key], dtype=np.float64).ravel()[:16]
            parts.append(key + "=" + ",".join(f"{v:.5g}" for v in vals))
        except (TypeError, ValueError):
            parts.append(key)
    digest = hashlib.sha1("|".join(parts).encode()).hexdigest()[:8]
    return f"{emitter.class_name().lower()}_{digest}"


@dataclass
class LightTable:
    """Stable light numbers 1..K (sorted by name) and how each light's shadow ray is aimed."""

    names: dict[int, str]
    emitters: dict[int, mi.Emitter] = field(repr=False)
    kinds: dict[int, str]
    #: object id of an area light's shape (0 for other lights)
    shape_ids: dict[int, int]

    def __len__(self) -> int:
        return len(self.names)

    @property
    def words(self) -> int:
        """How many uint32 words a light mask takes (32 lights per word; at least one)."""
        return max(1, (len(self.names) + 31) // 32)


#: The lights that cast shadow edges unless asked otherwise (module docstring).
HARD = "hard"
SHADOW_LIGHTS = ("hard", "all")


def check_shadow_lights(value: str) -> str | None:
    """The rule for ``shadow_lights``: ``hard``, ``all`` or comma-separated names/globs."""
    if not isinstance(value, str) or not value.strip():
        return "expected hard, all or comma-separated light names"
    return None


def light_table(scene: mi.Scene, objects: ObjectTable, shadow_lights: str = "all") -> LightTable:
    """Number the emitters of ``scene`` that ``shadow_lights`` keeps (``"all"``, ``"hard"``
    or names/globs; see the module docstring for the rules). A name that matches no light is
    a :class:`~mi_npr.errors.ParameterError`."""
    problem = check_shadow_lights(shadow_lights)
    if problem:
        raise ParameterError(f"shadow_lights = {shadow_lights!r}: {problem}")
    table = _light_table(list(scene.emitters()), objects)
    choice = shadow_lights.strip()
    if choice == "all":
        return table
    if choice == HARD:
        keep = [k for k in table.names if table.kinds[k] in (POSITION, DIRECTION)]
    else:
        globs = [g.strip() for g in choice.split(",") if g.strip()]
        for g in globs:
            if not any(fnmatchcase(n, g) for n in table.names.values()):
                known = ", ".join(table.names.values()) or "none"
                raise ParameterError(f"shadow_lights: no light named {g!r} (lights: {known})")
        keep = [k for k, n in table.names.items() if any(fnmatchcase(n, g) for g in globs)]
    return _light_table([table.emitters[k] for k in keep], objects)


def _light_table(ems: list[mi.Emitter], objects: ObjectTable) -> LightTable:
    shape_name = {s.ptr: objects.names[k] for k, s in objects.shapes.items()}
    shape_id = {s.ptr: k for k, s in objects.shapes.items()}
    names = []
    for e in ems:
        name = e.id()
        if not name and _kind(e) == AREA and e.get_shape() is not None:
            name = shape_name.get(e.get_shape().ptr, "") + ".emitter"
        names.append(name or _auto_name(e))
    seen: dict[str, int] = {}
    for i in sorted(range(len(ems)), key=lambda i: names[i]):
        n = names[i]
        seen[n] = seen.get(n, -1) + 1
        if seen[n]:
            names[i] = f"{n}_{seen[n]}"
    order = sorted(range(len(ems)), key=lambda i: names[i])
    table, emitters, kinds, shapes = {}, {}, {}, {}
    for k, i in enumerate(order, start=1):
        e = ems[i]
        table[k], emitters[k], kinds[k] = names[i], e, _kind(e)
        sh = e.get_shape() if kinds[k] == AREA else None
        shapes[k] = shape_id.get(sh.ptr, 0) if sh is not None else 0
    return LightTable(table, emitters, kinds, shapes)


def sky_direction(emitter: mi.Emitter) -> mi.Vector3f:
    """The direction towards an environment light's zenith: +y of its ``to_world``.

    Testing the sky along the surface normal instead (a first design) drew the silhouettes of
    objects onto the walls behind them as "shadow" edges; a zenith direction puts the sky's
    shadow under the objects, where a viewer expects it.
    """
    return dr.normalize(emitter.world_transform() @ mi.Vector3f(0.0, 1.0, 0.0))


def _bbox_centre(shape: mi.Shape) -> mi.Point3f:
    return mi.Point3f(*(float(v) for v in shape_bbox(shape).mean(axis=0)))


def visible_lights(
    scene: mi.Scene,
    si: mi.SurfaceInteraction3f,
    ray_d: mi.Vector3f,
    obj: Any,
    lights: LightTable,
    objects: ObjectTable,
    active: Any,
) -> list[Any]:
    """The light mask of each hit: ``lights.words`` ``UInt32`` arrays, bit ``k - 1`` = light k.

    ``ray_d`` is the direction of the ray that found ``si``, ``obj`` its object id.
    """
    words = [dr.zeros(mi.UInt32, dr.width(obj)) for _ in range(lights.words)]
    n = si.n
    towards_eye = -ray_d  # the side the tree's ray came from
    eye_side = dr.dot(n, towards_eye)
    centre = mi.Point2f(0.5, 0.5)
    for k, e in lights.emitters.items():
        kind = lights.kinds[k]
        if kind in (ENVIRONMENT, DIRECTION):
            if kind == ENVIRONMENT:
                d = sky_direction(e)
            else:
                d = e.sample_direction(si, centre, active)[0].d
            ok = active & (dr.dot(n, d) * eye_side > 0)
            ok &= ~scene.ray_test(si.spawn_ray(d), ok)
        elif kind == AREA:
            target = _bbox_centre(e.get_shape())
            d = target - si.p
            own = obj == lights.shape_ids[k]
            ok = active & ~own & (dr.dot(n, d) * eye_side > 0)
            pi = scene.ray_intersect_preliminary(si.spawn_ray_to(target), active=ok)
            hit = pi.is_valid()
            blocked = hit & (objects.lookup(pi) != lights.shape_ids[k])
            ok = (ok & ~blocked) | (active & own)
        else:
            ds, w = e.sample_direction(si, centre, active)
            ok = active & (dr.max(mi.unpolarized_spectrum(w)) > 0)
            ok &= dr.dot(n, ds.d) * eye_side > 0
            ok &= ~scene.ray_test(si.spawn_ray_to(ds.p), ok)
        bit = mi.UInt32(1 << ((k - 1) % 32))
        w_i = (k - 1) // 32
        words[w_i] = dr.select(ok, words[w_i] | bit, words[w_i])
    return words

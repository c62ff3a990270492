"""What a scene holds, as a user asks before rendering it (``mi-npr info SCENE.xml``).

:func:`describe_scene` loads the scene the way every render does (:func:`mi_npr.load_scene`:
``<default>``\\ s filled by ``defines``, no shape merging) and lists, JSON-friendly:

- ``defaults``: the ``<default>`` parameters the file declares, with the value written in the
  file and the value this load used;
- ``integrator``: its plugin name and, for an mi-npr integrator, its nested beauty integrator;
- ``sensors``: kind, film size, horizontal fov, samples per pixel, origin and view direction;
- ``objects``: the stable object ids and names every layer uses (:func:`mi_npr.object_table`),
  each with its shape type, primitive count and material;
- ``materials``: the material ids and names (the ``material`` id mode's);
- ``emitters``: each light's name (its XML ``id``, or ``<type>_<k>``) and type.
"""

from __future__ import annotations

import os
from collections.abc import Mapping
from typing import Any

import mitsuba as mi

from .camera import projection_of
from .scene import default_values, load_scene, merge_defines, object_table


def _plugin_name(obj: Any) -> str:
    """The XML type of a Mitsuba object: an mi-npr plugin's ``PLUGIN``, else its class name
    (``PathIntegrator``, ``Sphere``)."""
    return str(getattr(obj, "PLUGIN", None) or obj.class_name())


def describe_scene(
    path: str | os.PathLike[str], defines: Mapping[str, Any] | None = None, **more: Any
) -> dict[str, Any]:
    """The description of the scene at ``path`` (module docstring)."""
    defines = merge_defines(defines, more)
    scene = load_scene(path, defines)
    table = object_table(scene)
    integrator = scene.integrator()
    beauty = getattr(integrator, "beauty", None)
    sensors = []
    for sensor in scene.sensors():
        p = projection_of(sensor)
        sensors.append(
            {
                "kind": p.kind,
                "resolution": list(p.resolution),
                "fov": p.fov,
                "spp": int(sensor.sampler().sample_count()),
                "origin": [float(v) for v in p.origin],
                "direction": [float(v) for v in p.forward],
            }
        )
    names = table.material_names()
    objects = {
        str(k): {
            "name": v,
            "type": table.shapes[k].class_name(),
            "primitives": int(table.shapes[k].primitive_count()),
            "material": names.get(k, ""),
        }
        for k, v in table.names.items()
    }
    emitters = []
    counts: dict[str, int] = {}
    for e in scene.emitters():
        kind = e.class_name()
        counts[kind] = counts.get(kind, 0) + 1
        emitters.append({"name": e.id() or f"{kind.lower()}_{counts[kind]}", "type": kind})
    used = {str(k): str(v) for k, v in defines.items()}
    return {
        "file": os.fspath(path),
        "defaults": {
            name: {"file": value, "used": used.get(name, value)}
            for name, value in default_values(path).items()
        },
        "integrator": {
            "type": _plugin_name(integrator),
            "beauty": None if beauty is None else _plugin_name(beauty),
        },
        "sensors": sensors,
        "objects": objects,
        "materials": {str(k): v for k, v in table.materials.items()},
        "emitters": emitters,
        "variant": str(mi.variant()),
    }

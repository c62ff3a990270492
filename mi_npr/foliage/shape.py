"""The Mitsuba side of the leaf primitives: one ``mi.Mesh`` for all leaves, built in memory.

Mitsuba's XML cannot generate geometry, yet ``leaf_size`` must be a ``<default>`` of the style
scenes. So the ``npr_leaves`` shape plugin builds its mesh when the scene loads: it reads the
plant and/or HLP files named in the XML, calls :func:`~mi_npr.foliage.make_leaves`, and returns
the result of :func:`leaf_mesh`: one triangle mesh (the scene's BVH is built once over it, loading
costs what a PLY of the same size costs) with UVs and a ``face_leaf`` attribute holding every
triangle's leaf index (read back by :func:`~mi_npr.foliage.leaf_id_layer`).
"""

from __future__ import annotations

import os
from typing import Any

import drjit as dr
import mitsuba as mi
import numpy as np

from ..errors import InputError, SceneError
from .leaves import Leaves


def resolve_path(name: str) -> str:
    """``name`` resolved like Mitsuba resolves its own file names (relative to the scene file
    while it loads, then the working directory); a missing file is a one-line ``InputError``."""
    resolved = str(mi.file_resolver().resolve(name))
    if not os.path.isfile(resolved):
        raise InputError(f"{name}: no such file")
    return resolved


def leaf_mesh(leaves: Leaves, name: str, bsdf: mi.BSDF | None = None) -> mi.Mesh:
    """An ``mi.Mesh`` named ``name`` (its object-table name) holding every leaf of ``leaves``."""
    if not len(leaves):
        raise SceneError(f"{name}: no leaves to build (the plant or its HLPs are empty)")
    V, F, UV, face_leaf = leaves.mesh()
    props = mi.Properties()
    props.set_id(name)
    if bsdf is not None:
        props["bsdf"] = bsdf
    mesh = mi.Mesh(name, len(V), len(F), props=props, has_vertex_texcoords=True)
    params = mi.traverse(mesh)
    # The buffers' own types: mi.Float / mi.UInt32 on JIT variants, dynamic arrays on scalar ones.
    floats, ints = type(params["vertex_positions"]), type(params["faces"])
    params["vertex_positions"] = floats(np.ascontiguousarray(V.reshape(-1)))
    params["faces"] = ints(np.ascontiguousarray(F.reshape(-1)))
    params["vertex_texcoords"] = floats(np.ascontiguousarray(UV.reshape(-1)))
    params.update()
    mesh.add_attribute("face_leaf", 1, floats(face_leaf.astype(np.float32)))
    if dr.is_jit_v(mi.Float):
        dr.eval()
    return mesh


def nested_bsdf(props: mi.Properties, plugin: str) -> Any:
    """The one nested BSDF of a plugin's properties (or ``None``)."""
    found = [props.get(k) for k in props.keys() if isinstance(props.get(k), mi.BSDF)]
    if len(found) > 1:
        raise SceneError(f"{plugin}: at most one nested BSDF")
    return found[0] if found else None

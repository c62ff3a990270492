"""``npr_leaves``: a shape that builds a plant's leaf primitives when the scene loads.

Thesis section 4.3 draws *leaf primitives* instead of a plant's own leaves: their size sets how
dense the silhouette edges are. XML cannot generate geometry, so this plugin does, from the files
it names, with :func:`mi_npr.foliage.make_leaves`: ONE triangle mesh for all leaves (fast to load
and to trace), with UVs and the per-triangle leaf index (``face_leaf`` attribute) that becomes the
``leaf_id.V`` layer. Because the mesh is made at load time, ``leaf_size`` and every other parameter
can be a ``<default>`` of the scene (``mi-npr render tree.xml -D leaf_size=0.2``). The same
arguments give the same leaves (``seed``).

.. list-table::
   :header-rows: 1

   * - Parameter
     - Type
     - Default
     - Meaning
   * - ``hlps``
     - string
     - none
     - HLP JSON file (relative to the scene); needed by placements ``surface``/``volume`` and
       orientations ``hlp``/``van_gogh``.
   * - ``plant``
     - string
     - none
     - Plant file (PLY/OBJ mesh of leaves or point set with normals); needed by placement
       ``leaves``.
   * - ``leaf_size``
     - float
     - 0.1
     - Length of every leaf primitive, in scene units (> 0); the number of leaves follows so
       that the covered area stays the same.
   * - ``leaf_shape``
     - string
     - quad
     - ``quad``, ``disc``, ``ellipse``, ``leaf``, or an RGBA PNG (textured alpha leaf).
   * - ``placement``
     - string
     - surface
     - ``leaves`` (at the plant's leaves), ``surface`` (on the HLP surface), ``volume``
       (inside it).
   * - ``orientation``
     - string
     - hlp
     - ``hlp`` (facing the HLP normal), ``leaf`` (as the plant's leaves), ``van_gogh``
       (long axis around the HLP centre), ``random``.
   * - ``coverage``
     - float
     - 1
     - Leaf area over the plant's leaf area (or the HLP surface's area) (> 0).
   * - ``tilt``
     - float
     - 25
     - Random tilt of the leaves, in degrees [0, 90].
   * - ``seed``
     - integer
     - 0
     - Seed of the random placement and orientation.
   * - ``max_leaves``
     - integer
     - 1000000
     - A leaf size needing more leaves is an error.
   * - (nested bsdf)
     - bsdf
     - diffuse
     - The leaves' material, typically ``npr_foliage``.

The shape takes no ``to_world``: the leaves live in the plant's own coordinates, where the HLPs
of ``npr_foliage`` are evaluated too (move the camera, or transform the plant file).

XML::

    <shape type="npr_leaves" id="leaves">
        <string name="plant" value="meshes/foliage_tree_plant.ply"/>
        <string name="hlps" value="meshes/foliage_tree_hlps.json"/>
        <float name="leaf_size" value="$leaf_size"/>
        <string name="leaf_shape" value="leaf"/>
        <string name="placement" value="leaves"/>
        <bsdf type="npr_foliage">
            <string name="hlps" value="meshes/foliage_tree_hlps.json"/>
            <float name="abstraction" value="$abstraction"/>
            <bsdf type="diffuse"><rgb name="reflectance" value="0.2, 0.45, 0.1"/></bsdf>
        </bsdf>
    </shape>
"""

from __future__ import annotations

import math

import mitsuba as mi

from mi_npr.errors import ParameterError
from mi_npr.foliage.hlp import HLPSet
from mi_npr.foliage.leaves import ORIENTATIONS, PLACEMENTS, make_leaves
from mi_npr.foliage.plant import read_plant
from mi_npr.foliage.shape import leaf_mesh, nested_bsdf, resolve_path
from mi_npr.params import Param, integer_range, one_of, read_props, seed_rule


def _positive(v: float) -> str | None:
    return None if math.isfinite(v) and v > 0 else "must be > 0"


def _tilt(v: float) -> str | None:
    return None if 0 <= v <= 90 else "must lie in [0, 90] degrees"


_count = integer_range(1, 100_000_000)


PARAMS = (
    Param("hlps", str, "", "HLP JSON file"),
    Param("plant", str, "", "plant file (PLY/OBJ)"),
    Param("leaf_size", float, 0.1, "length of the leaf primitives", _positive),
    Param("leaf_shape", str, "quad", "quad, disc, ellipse, leaf or an RGBA .png"),
    Param("placement", str, "surface", "leaves, surface or volume", one_of(PLACEMENTS)),
    Param("orientation", str, "hlp", "hlp, leaf, van_gogh or random", one_of(ORIENTATIONS)),
    Param("coverage", float, 1.0, "leaf area over the foliage's area", _positive),
    Param("tilt", float, 25.0, "random tilt in degrees", _tilt),
    Param("seed", int, 0, "seed of placement and orientation", seed_rule),
    Param("max_leaves", int, 1_000_000, "largest number of leaves", _count),
)


def _npr_leaves(props: mi.Properties) -> mi.Mesh:
    name = props.id() or "leaves"
    plugin = f"npr_leaves {name!r}"
    p = read_props(plugin, PARAMS, props, lambda v: isinstance(v, mi.Object))
    if not p["hlps"] and not p["plant"]:
        raise ParameterError(f"{plugin}: give 'hlps' (an HLP JSON file), 'plant', or both")
    hlps = HLPSet.load(resolve_path(p["hlps"])) if p["hlps"] else None
    plant = read_plant(resolve_path(p["plant"])) if p["plant"] else None
    shape = p["leaf_shape"]
    if shape.lower().endswith(".png"):
        shape = resolve_path(shape)
    try:
        leaves = make_leaves(
            hlps,
            plant,
            leaf_size=p["leaf_size"],
            shape=shape,
            placement=p["placement"],
            orientation=p["orientation"],
            coverage=p["coverage"],
            tilt=p["tilt"],
            seed=p["seed"],
            max_leaves=p["max_leaves"],
        )
    except ParameterError as e:
        raise ParameterError(f"{plugin}: {e}") from None
    return leaf_mesh(leaves, name, nested_bsdf(props, plugin))


mi.register_shape("npr_leaves", _npr_leaves)

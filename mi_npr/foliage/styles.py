"""The thesis's four foliage drawing styles (Fig. 4.8), as presets and as ready scenes.

===================  ==========================================================================
style                what it does
===================  ==========================================================================
``small_leaves``     (a) small leaf primitives at the plant's own leaves, an outline on every
                     leaf, little abstraction: many small silhouettes, lighting detail
``large_leaves``     (b) large abstract leaves on the HLP surface, strong abstraction, and lines
                     that fade out in bright areas (``bright_fade``): no detail where it is lit
``van_gogh``         (c) elliptical leaves turned around their HLP centres (orientation
                     ``van_gogh``), 1 px outlines on the nearer leaf
``childrens_book``   (d) flat colours (``bands``: the shading quantized into flat tones) on a
                     smooth blobby crown (full abstraction), bold 2 px outlines
===================  ==========================================================================

A :class:`Style` holds the choices: leaf shape, placement, orientation, leaf size (relative to the
plant's bounding-box diagonal, so a style suits a plant of any scale), abstraction, coverage, tilt,
colour bands, leaf colour and the ``npr_lines`` parameters. :func:`scene_xml` turns a style and a
plant's files into a Mitsuba scene whose ``<default>``s are ``width``, ``height``, ``spp``,
``integrator`` (``npr_lines``: it carries the style's line parameters, so another integrator must
accept them too), ``beauty`` (``direct``), ``abstraction``, ``leaf_size``, ``leaf_seed`` (the
leaves' random placement; not ``seed``, which ``mi_npr.render`` takes for the sampler), ``sun``
(irradiance) and ``sky`` (radiance, also the background); the leaves are made when the scene loads
(``npr_leaves``), so ``-D leaf_size=...`` works.
:func:`write_foliage_scene` is what ``mi-npr foliage`` runs: HLPs from the plant, the plant and
HLP files, the wood, and the XML, all written atomically beside the XML.

Lighting: a sun from the upper left, slightly behind the camera (so little of the crown is in
shadow and the shading shows the normals, where the abstraction acts), and a sky that is also the
background; ``direct`` illumination (one bounce, what an illustrator shades with).
"""

from __future__ import annotations

import html
import math
import os
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from ..errors import ParameterError
from ..io import check_writable_dir, output_set, write_text
from ..meshes import write_ply
from ..params import Param, check_arg, entry, real_range, seed_rule
from .hlp import HLPS, HLPSet, build_hlps
from .leaves import leaf_template
from .plant import Plant, read_plant
from .procedural import procedural_tree


@dataclass(frozen=True)
class Style:
    """One drawing style (see the module docstring); sizes are relative to the plant's diagonal."""

    name: str
    description: str
    leaf_shape: str
    placement: str
    orientation: str
    leaf_size: float
    abstraction: float
    coverage: float = 1.0
    tilt: float = 25.0
    bands: int = 0
    leaf_color: tuple[float, float, float] = (0.2, 0.42, 0.1)
    lines: Mapping[str, Any] = field(default_factory=dict)


STYLES: dict[str, Style] = {
    s.name: s
    for s in (
        Style(
            "small_leaves",
            "Fig. 4.8 (a): small leaf primitives with thick leaf outlines",
            leaf_shape="leaf",
            placement="leaves",
            orientation="leaf",
            leaf_size=0.035,
            abstraction=0.3,
            tilt=40.0,
            lines={"leaf_edges": 1},
        ),
        Style(
            "large_leaves",
            "Fig. 4.8 (b): large abstract leaves, no detail in bright areas",
            leaf_shape="leaf",
            placement="surface",
            orientation="hlp",
            leaf_size=0.09,
            abstraction=0.85,
            coverage=1.6,
            tilt=60.0,
            lines={"leaf_edges": 1, "bright_fade": 0.35},
        ),
        Style(
            "van_gogh",
            'Fig. 4.8 (c): elliptical "Van Gogh" leaves arranged around the HLP centres',
            leaf_shape="ellipse",
            placement="surface",
            orientation="van_gogh",
            leaf_size=0.06,
            abstraction=0.6,
            coverage=1.8,
            tilt=20.0,
            leaf_color=(0.16, 0.38, 0.12),
            lines={"leaf_edges": 1},
        ),
        Style(
            "childrens_book",
            'Fig. 4.8 (d): "children\'s book" style, flat colours and bold outlines',
            leaf_shape="disc",
            placement="surface",
            orientation="hlp",
            leaf_size=0.07,
            abstraction=1.0,
            coverage=1.6,
            tilt=15.0,
            bands=3,
            leaf_color=(0.25, 0.55, 0.12),
            lines={"leaf_edges": 2, "t": 0.5},
        ),
    )
}


def style(name: str) -> Style:
    """The preset called ``name`` (:data:`STYLES`), or a ``ParameterError`` listing them."""
    try:
        return STYLES[name]
    except KeyError:
        raise ParameterError(f"style {name!r}: expected one of {', '.join(STYLES)}") from None


def diagonal(plant: Plant) -> float:
    lo, hi = plant.bbox()
    return float(np.linalg.norm(hi - lo))


def _fmt(v: Any) -> str:
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, float):
        return f"{v:.6g}"
    return str(v)


def _xml_type(v: Any) -> str:
    return "boolean" if isinstance(v, bool) else "integer" if isinstance(v, int) else "float"


def _vec(v: np.ndarray) -> str:
    return ", ".join(f"{x:.6g}" for x in v)


def camera_for(plant: Plant, fov: float = 30.0) -> tuple[np.ndarray, np.ndarray]:
    """``(origin, target)`` of a camera that looks at the plant from the front (+z), a little from
    above, as close as it can while every corner of the bounding box stays in a field of view of
    ``fov`` degrees both ways (so ``fov_axis="smaller"`` frames it at any aspect ratio)."""
    lo, hi = plant.bbox()
    centre = (lo + hi) / 2
    view = np.array([0.0, 0.18, 1.0]) / math.hypot(0.18, 1.0)  # towards the camera
    right = np.array([1.0, 0.0, 0.0])
    up = np.cross(view, right)
    corners = np.stack(np.meshgrid(*zip(lo, hi, strict=True), indexing="ij"), -1).reshape(-1, 3)
    rel = corners - centre
    spread = np.maximum(np.abs(rel @ right), np.abs(rel @ up))
    tan = math.tan(math.radians(fov) / 2)
    dist = float(np.max(spread / tan + rel @ view)) * 1.04
    dist = max(dist, 1e-6)
    return centre + dist * view, centre


def scene_xml(
    st: Style,
    plant_file: str,
    hlps_file: str,
    plant: Plant,
    wood_file: str | None = None,
    leaf_size: float | None = None,
    abstraction: float | None = None,
    seed: int = 0,
    width: int = 400,
    height: int = 400,
    spp: int = 16,
) -> str:
    """The XML of a foliage scene in style ``st`` (file names relative to the XML, already
    escaped for an XML attribute)."""
    size = leaf_size if leaf_size is not None else st.leaf_size * diagonal(plant)
    a = st.abstraction if abstraction is None else abstraction
    if not (math.isfinite(size) and size > 0):
        raise ParameterError(f"leaf_size = {size!r}: must be > 0")
    if not (math.isfinite(a) and 0 <= a <= 1):
        raise ParameterError(f"abstraction = {a!r}: must lie in [0, 1]")
    origin, target = camera_for(plant)
    lines = "\n".join(
        f'        <{_xml_type(v)} name="{k}" value="{_fmt(v)}"/>' for k, v in st.lines.items()
    )
    lines = lines + "\n" if lines else ""
    wood = ""
    if wood_file is not None:
        wood = f"""
    <shape type="ply" id="wood">
        <string name="filename" value="{wood_file}"/>
        <bsdf type="diffuse"><rgb name="reflectance" value="0.32, 0.22, 0.13"/></bsdf>
    </shape>
"""
    return f"""<!-- {st.description}.
     A foliage scene of mi-npr (style {st.name!r}): the leaves are made when the scene loads
     (npr_leaves), shaded with the leaf/HLP mixed normal (npr_foliage) and outlined (npr_lines).
     mi-npr render THIS.xml -o out -D leaf_size=... -D abstraction=... -->
<scene version="3.0.0">
    <default name="width" value="{width}"/>
    <default name="height" value="{height}"/>
    <default name="spp" value="{spp}"/>
    <default name="integrator" value="npr_lines"/>
    <default name="beauty" value="direct"/>
    <default name="abstraction" value="{_fmt(float(a))}"/>
    <default name="leaf_size" value="{_fmt(float(size))}"/>
    <default name="leaf_seed" value="{seed}"/>
    <default name="sun" value="2.6"/>
    <default name="sky" value="0.55, 0.6, 0.65"/>

    <integrator type="$integrator">
{lines}        <integrator type="$beauty"/>
    </integrator>

    <sensor type="perspective">
        <float name="fov" value="30"/>
        <string name="fov_axis" value="smaller"/>
        <transform name="to_world">
            <lookat origin="{_vec(origin)}" target="{_vec(target)}" up="0, 1, 0"/>
        </transform>
        <sampler type="independent"><integer name="sample_count" value="$spp"/></sampler>
        <film type="hdrfilm">
            <integer name="width" value="$width"/>
            <integer name="height" value="$height"/>
            <rfilter type="box"/>
        </film>
    </sensor>

    <shape type="npr_leaves" id="leaves">
        <string name="plant" value="{plant_file}"/>
        <string name="hlps" value="{hlps_file}"/>
        <float name="leaf_size" value="$leaf_size"/>
        <string name="leaf_shape" value="{st.leaf_shape}"/>
        <string name="placement" value="{st.placement}"/>
        <string name="orientation" value="{st.orientation}"/>
        <float name="coverage" value="{_fmt(st.coverage)}"/>
        <float name="tilt" value="{_fmt(st.tilt)}"/>
        <integer name="seed" value="$leaf_seed"/>
        <bsdf type="npr_foliage">
            <string name="hlps" value="{hlps_file}"/>
            <float name="abstraction" value="$abstraction"/>
            <integer name="bands" value="{st.bands}"/>
            <bsdf type="diffuse">
                <rgb name="reflectance" value="{_vec(np.array(st.leaf_color))}"/>
            </bsdf>
        </bsdf>
    </shape>
{wood}
    <emitter type="directional" id="sun">
        <vector name="direction" x="0.45" y="-0.7" z="-1"/>
        <rgb name="irradiance" value="$sun"/>
    </emitter>
    <emitter type="constant" id="sky">
        <rgb name="radiance" value="$sky"/>
    </emitter>
</scene>
"""


def load_plant(source: str, seed: int = 0, leaves: str = "components") -> Plant:
    """A plant from a file (:func:`~mi_npr.foliage.read_plant`) or ``procedural:tree`` /
    ``procedural:bush`` (:func:`~mi_npr.foliage.procedural_tree` with ``seed``)."""
    if source.startswith("procedural:"):
        return procedural_tree(seed=seed, kind=source.partition(":")[2])
    return read_plant(source, leaves=leaves)


#: Smallest leaf size relative to the plant's bounding-box diagonal: smaller leaves are invisible
#: at any resolution a render can afford, and their count (coverage / size^2) explodes.
MIN_LEAF_FRACTION = 1e-4

#: The settings of :func:`make_scene` (``mi-npr foliage``) that a style does not fix.
FOLIAGE_PARAMS: tuple[Param, ...] = (
    Param(
        "leaf_size",
        float,
        None,
        "leaf primitive length (default: the style's)",
        real_range(0.0, 1e6, open_lo=True),
    ),
    Param(
        "abstraction",
        float,
        None,
        "normal mixing in [0, 1] (default: the style's)",
        real_range(0, 1),
    ),
    HLPS,
    Param("seed", int, 0, "seed of HLPs and leaves", seed_rule),
)


def _check_leaf_size(plant: Plant, leaf_size: float | None) -> None:
    if leaf_size is None:
        return
    leaf_size = check_arg("leaf_size", entry(FOLIAGE_PARAMS, "leaf_size"), leaf_size)
    lo, hi = plant.bbox()
    diag = float(np.linalg.norm(hi - lo))
    if leaf_size < MIN_LEAF_FRACTION * diag:
        raise ParameterError(
            f"leaf_size = {leaf_size!r}: too small for a plant {diag:.4g} across "
            f"(at least {MIN_LEAF_FRACTION * diag:.4g})"
        )


def write_foliage_scene(
    output: str | os.PathLike[str],
    plant: Plant,
    style_name: str,
    leaf_size: float | None = None,
    abstraction: float | None = None,
    k: int | None = None,
    seed: int = 0,
    hlps: HLPSet | None = None,
    assets: str | None = None,
) -> list[Path]:
    """Write ``output`` (the scene XML) and, beside it, ``<assets>_plant.ply``,
    ``<assets>_hlps.json`` and ``<assets>_wood.ply`` (if the plant has wood); ``assets`` defaults
    to the XML's stem. HLPs are built with ``k`` (or the default radius) unless given. Returns the
    written paths; a plant without leaves is a ``ParameterError`` (there would be nothing to draw).
    """
    st = style(style_name)
    if not len(plant):
        raise ParameterError(f"{plant.name}: the plant has no leaves, there is nothing to draw")
    out = Path(output)
    if out.suffix.lower() != ".xml":
        raise ParameterError(f"{out}: the scene file must end in .xml")
    leaf_template(st.leaf_shape)
    _check_leaf_size(plant, leaf_size)
    files = scene_files(out, assets)
    check_writable_dir(out.parent, create=True)
    h = hlps if hlps is not None else build_hlps(plant, k=k, seed=seed)
    rel = {k: os.path.relpath(p, out.parent) for k, p in files.items()}
    for path in rel.values():
        if "$" in path:  # Mitsuba reads $name in any attribute as a parameter, with no escape
            raise ParameterError(f"{path}: a '$' in a file name cannot be used in a Mitsuba scene")
        if any(ord(ch) < 32 for ch in path):
            raise ParameterError(f"{path!r}: control characters cannot be used in an XML scene")
    rel = {k: html.escape(p, quote=True) for k, p in rel.items()}  # & < > " in names
    wood = rel["wood"] if plant.wood is not None else None
    text = scene_xml(st, rel["plant"], rel["hlps"], plant, wood, leaf_size, abstraction, seed)
    with output_set():  # the scene and its assets together, or none of them
        written = [plant.save(files["plant"]), h.save(files["hlps"])]
        if plant.wood is not None:
            written.append(write_ply(files["wood"], *plant.wood))
        written.append(write_text(out, text))
    return written


def make_scene(
    source: str,
    output: str | os.PathLike[str],
    style_name: str,
    *,
    leaf_size: float | None = None,
    abstraction: float | None = None,
    k: int | None = None,
    seed: int = 0,
    leaves: str = "components",
) -> tuple[Plant, list[Path]]:
    """What ``mi-npr foliage`` does: load the plant ``source`` (:func:`load_plant`) and write its
    scene (:func:`write_foliage_scene`), refusing outputs that would overwrite ``source``."""
    if not source.startswith("procedural:"):
        src = Path(source).resolve()
        if any(p.resolve() == src for p in scene_files(output).values()):
            raise ParameterError(f"{source}: -o {output} would overwrite the input plant")
    plant = load_plant(source, seed=seed, leaves=leaves)
    written = write_foliage_scene(
        output, plant, style_name, leaf_size=leaf_size, abstraction=abstraction, k=k, seed=seed
    )
    return plant, written


def scene_files(output: str | os.PathLike[str], assets: str | None = None) -> dict[str, Path]:
    """The files :func:`write_foliage_scene` writes: ``{"xml", "plant", "hlps", "wood"}`` (the
    assets beside the XML, named ``<assets or stem>_plant.ply`` and so on)."""
    out = Path(output)
    stem = assets or out.stem
    d = out.parent
    return {
        "xml": out,
        "plant": d / f"{stem}_plant.ply",
        "hlps": d / f"{stem}_hlps.json",
        "wood": d / f"{stem}_wood.ply",
    }


def write_style_scenes(directory: str | os.PathLike[str]) -> list[Path]:
    """The four ``foliage_<style>.xml`` scenes of ``scenes_xml/`` and their shared assets
    ``meshes/foliage_tree_*`` (procedural tree, seed 0, 1500 leaves)."""
    d = Path(directory)
    plant = procedural_tree(seed=0, n_leaves=1500)
    hlps = build_hlps(plant)
    written: list[Path] = []
    for name in STYLES:
        written += write_foliage_scene(
            d / f"foliage_{name}.xml", plant, name, hlps=hlps, assets="meshes/foliage_tree"
        )
    return sorted(set(written))


if __name__ == "__main__":  # pragma: no cover - regenerates scenes_xml/foliage_*.xml
    import sys

    for p in write_style_scenes(sys.argv[1] if len(sys.argv) > 1 else "scenes_xml"):
        print(p)

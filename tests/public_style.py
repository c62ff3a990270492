"""Small scenes written like public Mitsuba scenes: their own <default> names, a
``path`` integrator with its parameters, one-sided walls, unnamed PLY meshes."""

from __future__ import annotations

import textwrap
from pathlib import Path

import numpy as np

from mi_npr.meshes import write_ply

#: A unit cube centred at the origin (12 triangles).
CUBE_V = np.array(
    [[x, y, z] for x in (-0.5, 0.5) for y in (-0.5, 0.5) for z in (-0.5, 0.5)], np.float32
)
CUBE_F = np.array(
    [
        [0, 1, 3], [0, 3, 2], [4, 6, 7], [4, 7, 5], [0, 4, 5], [0, 5, 1],
        [2, 3, 7], [2, 7, 6], [0, 2, 6], [0, 6, 4], [1, 5, 7], [1, 7, 3],
    ],
    np.int64,
)  # fmt: skip


def _sensor(size: str, origin: str, target: str, spp: str = "$spp") -> str:
    return f"""
    <sensor type="perspective">
        <float name="fov" value="45"/>
        <transform name="to_world"><lookat origin="{origin}" target="{target}" up="0, 1, 0"/>
        </transform>
        <sampler type="independent"><integer name="sample_count" value="{spp}"/></sampler>
        <film type="hdrfilm">{size}<rfilter type="box"/></film>
    </sensor>"""


def room(tmp: Path) -> Path:
    """A Cornell-box-like room of one-sided walls (``rectangle``), two touching boxes and a
    point light; size defaults named ``res``/``aspect``-free (``res`` x ``res``)."""
    walls = []
    for name, t in {
        "floor": '<rotate x="1" angle="-90"/><translate y="-1"/>',
        "ceiling": '<rotate x="1" angle="90"/><translate y="1"/>',
        "back": '<translate z="-1"/>',
        "left": '<rotate y="1" angle="90"/><translate x="-1"/>',
        "right": '<rotate y="1" angle="-90"/><translate x="1"/>',
    }.items():
        walls.append(
            f'<shape type="rectangle" id="{name}"><transform name="to_world">{t}</transform>'
            f'<ref id="white"/></shape>'
        )
    body = "\n".join(walls)
    xml = f"""<scene version="3.0.0">
    <default name="res" value="40"/>
    <default name="spp" value="2"/>
    <integrator type="path"><integer name="max_depth" value="3"/></integrator>
    {
        _sensor(
            '<integer name="width" value="$res"/><integer name="height" value="$res"/>',
            "0, 0, 3.8",
            "0, 0, 0",
        )
    }
    <bsdf type="diffuse" id="white"/>
    <bsdf type="diffuse" id="red"><rgb name="reflectance" value="0.8, 0.1, 0.1"/></bsdf>
    {body}
    <shape type="cube" id="box_a"><transform name="to_world"><scale value="0.3"/>
        <translate x="-0.3" y="-0.7"/></transform><ref id="red"/></shape>
    <shape type="cube" id="box_b"><transform name="to_world"><scale value="0.3"/>
        <translate x="0.3" y="-0.7"/></transform><ref id="red"/></shape>
    <emitter type="point" id="lamp"><point name="position" x="0" y="0.8" z="0.5"/>
        <rgb name="intensity" value="3"/></emitter>
    </scene>"""
    p = tmp / "room.xml"
    p.write_text(textwrap.dedent(xml))
    return p


def ground(tmp: Path, extra_light: str = "") -> Path:
    """A PLY cube (unnamed) on a ground plane, size defaults named ``resx``/``resy``, a point
    light (and ``extra_light``)."""
    write_ply(tmp / "Crate_01.ply", CUBE_V, CUBE_F)
    xml = f"""<scene version="3.0.0">
    <default name="resx" value="48"/>
    <default name="resy" value="32"/>
    <integrator type="path"><integer name="max_depth" value="2"/></integrator>
    {
        _sensor(
            '<integer name="width" value="$resx"/><integer name="height" value="$resy"/>',
            "2, 2.2, 3.2",
            "0, 0, 0",
            spp="2",
        )
    }
    <shape type="ply"><string name="filename" value="Crate_01.ply"/></shape>
    <shape type="rectangle" id="ground"><transform name="to_world"><scale value="4"/>
        <rotate x="1" angle="-90"/><translate y="-0.5"/></transform></shape>
    <emitter type="point" id="sun"><point name="position" x="1" y="3" z="1"/>
        <rgb name="intensity" value="10"/></emitter>
    {extra_light}
    </scene>"""
    p = tmp / "ground.xml"
    p.write_text(textwrap.dedent(xml))
    return p


def fifty(tmp: Path, n: int = 50) -> tuple[Path, list[str]]:
    """``n`` unnamed PLY cubes on a grid (``Brick_<k>.ply``); returns the scene and the stems."""
    shapes, stems = [], []
    for k in range(n):
        stem = f"Brick_01_02_{k:03d}"
        x, z = (k % 10) * 0.6 - 2.7, (k // 10) * 0.6 - 1.2
        write_ply(tmp / f"{stem}.ply", CUBE_V * 0.5 + [x, 0, z], CUBE_F)
        shapes.append(f'<shape type="ply"><string name="filename" value="{stem}.ply"/></shape>')
        stems.append(stem)
    xml = f"""<scene version="3.0.0">
    <default name="width" value="48"/>
    <integrator type="direct"/>
    {
        _sensor(
            '<integer name="width" value="$width"/><integer name="height" value="32"/>',
            "0, 4, 4",
            "0, 0, 0",
            spp="1",
        )
    }
    {"".join(shapes)}
    <emitter type="constant"/>
    </scene>"""
    p = tmp / "fifty.xml"
    p.write_text(textwrap.dedent(xml))
    return p, stems

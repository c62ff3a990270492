"""Helpers shared by the tests (scene snippets, running the CLI in a fresh interpreter)."""

from __future__ import annotations

import os
import re
import subprocess
import sys
import textwrap
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
SCENES = ROOT / "scenes_xml"


def scene_xml(
    body: str,
    width: int = 32,
    height: int = 24,
    fov: float = 40.0,
    integrator: str = '<integrator type="npr_gbuffer"/>',
    origin: str = "0, 0, 0",
    target: str = "0, 0, 1",
    spp: int = 1,
    rfilter: str = "box",
) -> str:
    """A small scene: a perspective camera at ``origin`` looking at ``target`` plus ``body``."""
    return textwrap.dedent(f"""\
        <scene version="3.0.0">
            {integrator}
            <sensor type="perspective">
                <float name="fov" value="{fov}"/>
                <transform name="to_world">
                    <lookat origin="{origin}" target="{target}" up="0, 1, 0"/>
                </transform>
                <sampler type="independent"><integer name="sample_count" value="{spp}"/></sampler>
                <film type="hdrfilm">
                    <integer name="width" value="{width}"/>
                    <integer name="height" value="{height}"/>
                    <rfilter type="{rfilter}"/>
                </film>
            </sensor>
            {body}
        </scene>""")


def run_cli(*args: str, env: dict | None = None, cwd: Path | None = None):
    """Run ``mi-npr`` in a fresh interpreter (as a user would); returns CompletedProcess."""
    e = dict(os.environ)
    if env:
        e.update(env)
    return subprocess.run(
        [sys.executable, "-m", "mi_npr.cli", *args],
        capture_output=True,
        text=True,
        env=e,
        cwd=cwd or ROOT,
        timeout=600,
        check=False,
    )


def sun_only(style: str, directory: Path) -> Path:
    """``scenes_xml/foliage_<style>.xml`` lit by its sun alone, one sample through each pixel
    centre (stratified, no jitter): deterministic shading, no sky sampling noise, no blending at
    pixel edges, shadows included. Written to ``directory``; returns its path."""
    text = (SCENES / f"foliage_{style}.xml").read_text()
    text = re.sub(r'<emitter type="constant".*?</emitter>', "", text, flags=re.S)
    text = text.replace(
        '<sampler type="independent">',
        '<sampler type="stratified"><boolean name="jitter" value="false"/>',
    )
    text = text.replace('value="meshes/', f'value="{SCENES}/meshes/')
    path = Path(directory) / f"{style}_sun_only.xml"
    path.write_text(text)
    return path

"""The paper's and the thesis's scenes, installed with mi-npr as ``mi_npr.data``.

The files are this folder (``scenes_xml/`` in the source tree), shipped in the wheel as package
data, so the quick start works after ``pip install`` alone::

    mi-npr render scene1 -o out           # a name that is no file resolves to a bundled scene
    mi_npr.render(mi_npr.data.path("scene3"), width=64, height=48)

Meshes and shared parts are found relative to each XML file, as Mitsuba does.
"""

from __future__ import annotations

import os
from pathlib import Path

FOLDER = Path(__file__).resolve().parent


def names() -> list[str]:
    """The bundled scenes' names (file stems): ``cornell_box``, ``scene1``, ..."""
    return sorted(p.stem for p in FOLDER.glob("*.xml"))


def path(name: str) -> Path:
    """The bundled scene ``name`` (with or without ``.xml``); a ``KeyError`` lists the names."""
    stem = name[:-4] if name.endswith(".xml") else name
    p = FOLDER / f"{stem}.xml"
    if os.sep in stem or "/" in stem or not p.is_file():
        raise KeyError(f"no bundled scene {name!r} (bundled: {', '.join(names())})")
    return p


def resolve(scene: str) -> str:
    """``scene`` itself when it is a file (or names a folder), else the bundled scene of that
    name when there is one, else ``scene`` unchanged (its loader reports the missing file)."""
    if os.path.exists(scene) or os.sep in scene or "/" in scene:
        return scene
    try:
        return str(path(scene))
    except KeyError:
        return scene

"""Shared fixtures: every test imports mi_npr (which picks LLVM and the variant) first."""

from __future__ import annotations

import os
from pathlib import Path

import pytest

os.environ.setdefault("MI_NPR_QUICK", "1")

import mi_npr

from .helpers import SCENES, scene_xml

#: The suite's variant: ``llvm_ad_rgb`` (CI), or ``$MI_NPR_VARIANT`` (``cuda_ad_rgb`` for the GPU
#: run recorded in the README).
VARIANT = os.environ.get("MI_NPR_VARIANT") or "llvm_ad_rgb"


@pytest.fixture(autouse=True)
def _default_variant():
    """Each test starts and ends in the suite's variant, whatever it switched to."""
    mi_npr.set_variant(VARIANT)
    yield
    mi_npr.set_variant(VARIANT)


@pytest.fixture
def scenes() -> Path:
    return SCENES


@pytest.fixture
def write_scene(tmp_path):
    """Write ``scene_xml(...)`` to a file and return its path."""

    def _write(body: str, name: str = "scene.xml", **kw) -> Path:
        p = tmp_path / name
        p.write_text(scene_xml(body, **kw))
        return p

    return _write

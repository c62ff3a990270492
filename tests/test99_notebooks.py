"""Every notebook in notebooks/ runs top to bottom (at low resolution: MI_NPR_QUICK=1)."""

from __future__ import annotations

import os

import nbformat
import pytest
from nbclient import NotebookClient

from .helpers import ROOT

NOTEBOOKS = sorted((ROOT / "notebooks").glob("*.ipynb"))


@pytest.mark.parametrize("path", NOTEBOOKS, ids=[p.name for p in NOTEBOOKS])
def test01_notebook_runs(path, monkeypatch):
    monkeypatch.setenv("MI_NPR_QUICK", "1")
    monkeypatch.setenv("MPLBACKEND", "Agg")
    nb = nbformat.read(path, as_version=4)
    client = NotebookClient(
        nb, timeout=600, kernel_name="python3", resources={"metadata": {"path": str(path.parent)}}
    )
    client.execute()
    errors = [
        o
        for c in nb.cells
        if c.cell_type == "code"
        for o in c.get("outputs", [])
        if o.get("output_type") == "error"
    ]
    assert not errors


def test02_there_are_notebooks():
    assert NOTEBOOKS and all(os.path.getsize(p) > 0 for p in NOTEBOOKS)

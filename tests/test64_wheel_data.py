"""The wheel ships the scenes (``mi_npr.data``) and the LLVM start-up hook; installed from it
(not editable), ``mi-npr render scene1`` works with no source tree, and so does Mitsuba's own
import order."""

from __future__ import annotations

import os
import subprocess
import sys
import sysconfig
import zipfile
from pathlib import Path

import pytest

import mi_npr

from .helpers import ROOT, SCENES


@pytest.fixture(scope="module")
def wheel(tmp_path_factory) -> Path:
    out = tmp_path_factory.mktemp("wheel")
    r = subprocess.run(
        [sys.executable, "-m", "pip", "wheel", "--quiet", "--no-deps", "-w", str(out), str(ROOT)],
        capture_output=True,
        text=True,
        timeout=600,
        check=False,
    )
    assert r.returncode == 0, r.stderr[-2000:]
    (whl,) = out.glob("mi_npr-*.whl")
    return whl


def test01_the_wheel_holds_every_scene_and_the_hook(wheel):
    names = set(zipfile.ZipFile(wheel).namelist())
    for p in SCENES.rglob("*"):
        if p.is_file() and p.suffix in (".xml", ".ply", ".json"):
            assert f"mi_npr/data/{p.relative_to(SCENES).as_posix()}" in names, p
    assert {"mi_npr_llvm.pth", "mi_npr_llvm_hook.py", "mi_npr/data/__init__.py"} <= names


def test02_bundled_names_resolve():
    assert {"scene1", "scene2", "scene3", "scene4", "fig9_sphere_cube"} <= set(mi_npr.data.names())
    assert mi_npr.data.path("scene1") == mi_npr.data.path("scene1.xml")
    assert mi_npr.data.resolve("scene1") == str(mi_npr.data.path("scene1"))
    assert mi_npr.data.resolve("no_such_scene") == "no_such_scene"
    assert mi_npr.data.resolve("dir/scene1") == "dir/scene1"  # a path is never looked up
    with pytest.raises(KeyError, match="bundled: cornell_box"):
        mi_npr.data.path("nope")


def test03_installed_from_the_wheel(wheel, tmp_path):
    venv = tmp_path / "venv"
    subprocess.run([sys.executable, "-m", "venv", "--without-pip", str(venv)], check=True)
    py = venv / "bin" / "python"
    site = Path(
        subprocess.run(
            [str(py), "-c", "import sysconfig; print(sysconfig.get_paths()['purelib'])"],
            capture_output=True,
            text=True,
            check=True,
        ).stdout.strip()
    )
    with zipfile.ZipFile(wheel) as z:  # what pip would put in site-packages
        z.extractall(site)
    # the dependencies come from this environment's site-packages, as a plain path (its .pth
    # files, including the editable mi-npr's, are not read from there)
    (site / "zz_deps.pth").write_text(sysconfig.get_paths()["purelib"] + "\n")
    env = {k: v for k, v in os.environ.items() if not k.startswith(("DRJIT_", "MI_NPR_LLVM"))}
    work = tmp_path / "elsewhere"
    work.mkdir()
    code = (
        "import os, sys; import mitsuba as mi; mi.set_variant('llvm_ad_rgb'); import mi_npr; "
        "print(mi_npr.__file__); print(os.environ.get('MI_NPR_LLVM_HOOK')); "
        "sys.argv = ['mi-npr', 'render', 'scene1', '-o', 'out', '-D', 'width=32', "
        "'-D', 'height=24', '--spp', '1', '--no-progress']; "
        "from mi_npr.cli import main; sys.exit(main())"
    )
    r = subprocess.run(
        [str(py), "-c", code], capture_output=True, text=True, env=env, cwd=work, timeout=300
    )
    assert r.returncode == 0, (r.stdout + r.stderr)[-2000:]
    where, hook = r.stdout.splitlines()[:2]
    assert where.startswith(str(site))  # the installed copy, not the source tree
    assert hook != "None"  # the .pth hook chose LLVM before mi_npr was imported
    assert (work / "out" / "scene1.exr").is_file() and (work / "out" / "scene1.png").is_file()

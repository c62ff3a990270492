"""Mitsuba's own import order: ``import mitsuba`` finds a usable LLVM through mi-npr's ``.pth``
start-up hook, without ``import mi_npr`` first, on a machine whose system LLVM is too old."""

from __future__ import annotations

import os
import subprocess
import sys
import sysconfig
from pathlib import Path

import pytest

import mi_npr_llvm_hook as hook
from mi_npr import _llvm

from .helpers import ROOT

OLD_SYSTEM = sorted(Path("/usr/lib/x86_64-linux-gnu").glob("libLLVM-1[4-6]*.so*"))

# Mitsuba's order: the variant first, a kernel, and mi_npr only at the end.
ORDER = """
import os, sys
import mitsuba as mi
mi.set_variant("llvm_ad_rgb")
import drjit as dr
x = dr.minimum(mi.Float([1, 2, 3]), mi.Float([3, 2, 1]))
print("KERNEL", x.numpy().tolist())
print("MI_NPR_BEFORE", "mi_npr" in sys.modules)
print("PATH", os.environ.get("DRJIT_LIBLLVM_PATH"))
print("MARK", os.environ.get("MI_NPR_LLVM_HOOK"))
import mi_npr
print("IMPORTED", mi_npr.__version__)
"""


def _child(code: str, **env_updates: str) -> subprocess.CompletedProcess:
    env = {k: v for k, v in os.environ.items() if k not in (hook.ENV, hook.MARK, hook.OFF)}
    env.update(env_updates)
    return subprocess.run(
        [sys.executable, "-c", code],
        capture_output=True,
        text=True,
        env=env,
        timeout=300,
        check=False,
        cwd=ROOT,
    )


def _fields(out: str) -> dict[str, str]:
    return dict(ln.split(" ", 1) for ln in out.splitlines() if " " in ln)


def test01_the_pth_file_is_installed_next_to_the_hook():
    site = Path(sysconfig.get_paths()["purelib"])
    pth = site / "mi_npr_llvm.pth"
    assert pth.is_file(), f"{pth} missing: reinstall mi-npr (pip install -e .)"
    assert pth.read_text().strip() == "import mi_npr_llvm_hook; mi_npr_llvm_hook.install()"


def test02_mitsuba_order_on_the_system_llvm():
    r = _child(ORDER)
    assert r.returncode == 0, r.stderr[-2000:]
    f = _fields(r.stdout)
    assert f["KERNEL"] == "[1.0, 2.0, 1.0]"
    assert f["MI_NPR_BEFORE"] == "False"  # nobody but the hook chose
    assert f["MARK"] == f["PATH"] != "None"
    assert (_llvm.version_from_name(f["PATH"]) or 0) >= _llvm.MIN_VERSION
    assert f["PATH"] not in {str(p) for p in OLD_SYSTEM}
    assert f["IMPORTED"] == __import__("mi_npr").__version__


def test03_the_hook_only_acts_on_import_drjit():
    code = "import os, sys; import json; print('PATH', os.environ.get('DRJIT_LIBLLVM_PATH'))"
    assert _fields(_child(code).stdout)["PATH"] == "None"


def test04_the_users_choice_wins():
    wheel = [p for p in _llvm.wheel_libraries() if _llvm.inspect(p, "t").usable]
    chosen = wheel[0] if wheel else __import__("mi_npr").LLVM.chosen.path
    r = _child(ORDER, DRJIT_LIBLLVM_PATH=chosen)
    assert r.returncode == 0, r.stderr[-2000:]
    f = _fields(r.stdout)
    assert f["PATH"] == chosen and f["MARK"] == "None"


def test05_switched_off_it_does_nothing():
    code = "import os, drjit; print('PATH', os.environ.get('DRJIT_LIBLLVM_PATH'))"
    assert _fields(_child(code, MI_NPR_NO_LLVM_HOOK="1").stdout)["PATH"] == "None"


def test06_never_raises(monkeypatch):
    def broken():
        raise RuntimeError("no metadata")

    monkeypatch.delenv(hook.ENV, raising=False)
    monkeypatch.setattr(hook, "_select_module", broken)
    assert hook.choose() is None
    monkeypatch.setattr(hook.sys, "meta_path", None)  # even a broken interpreter state
    hook.install()


def test07_mitsuba_command(tmp_path):
    exe = Path(sys.executable).with_name("mitsuba")
    if not exe.exists():
        pytest.skip("no mitsuba command next to this interpreter")
    scene = tmp_path / "s.xml"
    scene.write_text(
        '<scene version="3.0.0"><integrator type="direct"/><sensor type="perspective">'
        '<film type="hdrfilm"><integer name="width" value="8"/><integer name="height" value="6"/>'
        '</film></sensor><shape type="sphere"><point name="center" x="0" y="0" z="5"/></shape>'
        '<emitter type="constant"/></scene>'
    )
    env = {k: v for k, v in os.environ.items() if k not in (hook.ENV, hook.MARK, hook.OFF)}
    r = subprocess.run(
        [str(exe), "-m", "llvm_ad_rgb", "-o", str(tmp_path / "s.exr"), str(scene)],
        capture_output=True,
        text=True,
        env=env,
        timeout=300,
        check=False,
    )
    assert r.returncode == 0, (r.stdout + r.stderr)[-2000:]
    assert (tmp_path / "s.exr").stat().st_size > 0

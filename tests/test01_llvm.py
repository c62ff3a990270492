"""LLVM selection: a usable libLLVM or a clear error, never a process abort."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
from pathlib import Path

import pytest

from mi_npr import _llvm

from .helpers import ROOT, run_cli

OLD_DEBIAN = sorted(Path("/usr/lib/x86_64-linux-gnu").glob("libLLVM-1[4-6].so*"))


def _import_in_child(env_updates: dict[str, str]) -> subprocess.CompletedProcess:
    env = dict(os.environ)
    env.update(env_updates)
    code = "import mi_npr, mitsuba as mi; print('VARIANT', mi.variant())"
    return subprocess.run(
        [sys.executable, "-c", code],
        capture_output=True,
        text=True,
        env=env,
        timeout=300,
        check=False,
        cwd=ROOT,
    )


@pytest.mark.parametrize(
    ("path", "version"),
    [
        ("/usr/lib/x86_64-linux-gnu/libLLVM-15.so.1", 15),
        ("/usr/lib/x86_64-linux-gnu/libLLVM-14.0.6.so.1", 14),
        ("/venv/lib/libLLVM.so.23.1", 23),
        ("/usr/lib/llvm-19/lib/libLLVM.so", 19),
        ("/opt/homebrew/opt/llvm@18/lib/libLLVM.dylib", 18),
        ("/some/where/libLLVM.so", None),
    ],
)
def test01_version_from_name(path, version):
    assert _llvm.version_from_name(path) == version


def test02_the_process_uses_a_new_enough_llvm():
    chosen = __import__("mi_npr").LLVM.chosen
    assert chosen is not None and chosen.usable
    assert chosen.version >= _llvm.MIN_VERSION
    maps = Path("/proc/self/maps").read_text() if Path("/proc/self/maps").exists() else ""
    loaded = {ln.split()[-1] for ln in maps.splitlines() if "libLLVM" in ln}
    for lib in loaded:
        assert (_llvm.version_from_name(lib) or 99) >= _llvm.MIN_VERSION, lib


def test03_bogus_user_path_is_a_clear_error_not_a_signal():
    res = _import_in_child({"DRJIT_LIBLLVM_PATH": "/nonexistent/libLLVM-99.so"})
    assert res.returncode == 1, res  # an exception, not a signal (negative return code)
    assert "DRJIT_LIBLLVM_PATH=/nonexistent/libLLVM-99.so is not usable" in res.stderr
    assert "file does not exist" in res.stderr
    assert "karellen-llvm-core" in res.stderr  # says how to fix it


def test04_cli_reports_bogus_llvm_in_one_line():
    res = run_cli("render", "x.xml", "-o", "out", env={"DRJIT_LIBLLVM_PATH": "/nope/libLLVM.so"})
    assert res.returncode == 1
    assert res.stderr.count("\n") == 1 and "Traceback" not in res.stderr
    assert res.stderr.startswith("mi-npr: error: DRJIT_LIBLLVM_PATH=/nope/libLLVM.so")


@pytest.mark.skipif(not OLD_DEBIAN, reason="no Debian LLVM 14-16 on this machine")
def test05_old_system_llvm_is_refused_before_it_can_abort():
    old = str(OLD_DEBIAN[0])
    res = _import_in_child({"DRJIT_LIBLLVM_PATH": old})
    assert res.returncode == 1, res
    assert res.returncode != -signal.SIGABRT
    assert "too old" in res.stderr and "needs LLVM >= 17" in res.stderr


ELF = b"\x7fELF"  # the first bytes of a Linux shared library


def test06_garbage_library_is_probed_in_a_child(tmp_path):
    fake = tmp_path / "libLLVM.so"
    fake.write_bytes(ELF + b" but not a real library")
    c = _llvm.inspect(str(fake), "test")
    assert not c.usable and "cannot be loaded" in c.problem
    fake_old = tmp_path / "libLLVM-12.so"
    fake_old.write_bytes(ELF)
    c = _llvm.inspect(str(fake_old), "test")
    assert c.version == 12 and "too old" in c.problem
    # A name that promises a good version proves nothing: the file is checked first.
    for junk in (b"not an ELF file", b""):
        fake_new = tmp_path / "libLLVM-19.so"
        fake_new.write_bytes(junk)
        c = _llvm.inspect(str(fake_new), "test")
        assert not c.usable and c.problem == "is not a shared library"


def test07_selection_order(monkeypatch, tmp_path):
    wheel = tmp_path / "wheel" / "libLLVM.so.23.1"
    system_new = tmp_path / "llvm-19" / "libLLVM-19.so"
    system_old = tmp_path / "libLLVM-15.so"
    for p in (wheel, system_new, system_old):
        p.parent.mkdir(parents=True, exist_ok=True)
        p.write_bytes(ELF)
    monkeypatch.delenv("DRJIT_LIBLLVM_PATH", raising=False)
    monkeypatch.setattr(_llvm, "wheel_libraries", lambda: [str(wheel)])
    monkeypatch.setattr(_llvm, "system_libraries", lambda: [str(system_new), str(system_old)])
    assert _llvm.select().chosen.path == str(wheel)
    monkeypatch.setattr(_llvm, "wheel_libraries", lambda: [])
    assert _llvm.select().chosen.path == str(system_new)
    monkeypatch.setattr(_llvm, "system_libraries", lambda: [str(system_old)])
    sel = _llvm.select()
    assert sel.chosen is None and "LLVM 15" in str(_llvm._error(sel))
    # The user's variable always wins, even over a newer wheel.
    monkeypatch.setenv("DRJIT_LIBLLVM_PATH", str(system_new))
    monkeypatch.setattr(_llvm, "wheel_libraries", lambda: [str(wheel)])
    assert _llvm.select().chosen.source == "DRJIT_LIBLLVM_PATH"


def test08_scalar_variant_without_llvm_switches_the_backend_off(monkeypatch):
    monkeypatch.setattr(_llvm, "LAST_SELECTION", _llvm.LAST_SELECTION)  # restored afterwards
    monkeypatch.delenv("DRJIT_LIBLLVM_PATH", raising=False)
    monkeypatch.setenv("MI_NPR_VARIANT", "scalar_rgb")
    monkeypatch.setattr(_llvm, "wheel_libraries", lambda: [])
    monkeypatch.setattr(_llvm, "system_libraries", lambda: ["/usr/lib/libLLVM-15.so"])
    monkeypatch.setattr(sys, "modules", {k: v for k, v in sys.modules.items() if k != "drjit"})
    monkeypatch.setattr(_llvm, "inspect", lambda p, s: _llvm.Candidate(p, s, 15, "too old"))
    sel = _llvm.configure()
    assert sel.disabled and "nonexistent" in os.environ["DRJIT_LIBLLVM_PATH"]
    monkeypatch.setenv("MI_NPR_VARIANT", "llvm_ad_rgb")
    monkeypatch.delenv("DRJIT_LIBLLVM_PATH")
    with pytest.raises(_llvm.LLVMNotFoundError, match="no usable libLLVM"):
        _llvm.configure()


def test09_cli_reports_startup_problems_in_one_line(tmp_path):
    junk = tmp_path / "libLLVM-19.so"  # the name says 19; the content is no library
    junk.write_bytes(b"junk")
    for env, words in (
        ({"MI_NPR_VARIANT": "bogus"}, "variant 'bogus' is not available"),
        ({"DRJIT_LIBLLVM_PATH": str(junk)}, "is not a shared library"),
    ):
        res = run_cli("info", "x.exr", env=env)
        assert res.returncode == 1, res
        assert res.stderr.count("\n") == 1 and "Traceback" not in res.stderr, res.stderr
        assert words in res.stderr


def test10_cli_variant_option_is_known_before_import():
    # The command's --variant decides the variant at import (and whether LLVM is needed),
    # whatever MI_NPR_VARIANT says.
    assert _llvm.cli_process() is False
    res = run_cli("--variant", "scalar_rgb", "info", "x.exr", env={"MI_NPR_VARIANT": "bogus"})
    assert res.returncode == 1 and "x.exr: no such file" in res.stderr, res.stderr

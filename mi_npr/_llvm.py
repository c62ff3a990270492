"""Where libLLVM comes from, decided *before* ``import drjit``.

Dr.Jit 1.5 loads ``libLLVM`` when it is imported and needs LLVM >= 17: with the LLVM 14-16 that
Debian ships, the first kernel that uses ``fminimum`` **aborts the whole process** (no exception).
So this module picks the library and exports ``DRJIT_LIBLLVM_PATH`` before Dr.Jit is imported:

1. the user's ``DRJIT_LIBLLVM_PATH``, when set (it always wins; an unusable one is an error),
2. the ``libLLVM`` shipped by the ``karellen-llvm-core`` wheel that mi-npr depends on,
3. a system ``libLLVM`` >= 17 (``/usr/lib/llvm-*/``, ``/usr/lib/<triplet>/``, ``ldconfig -p``).

The version is read from the file name (``libLLVM-19.so``, ``libLLVM.so.23.1``, ``llvm-19/lib``)
after resolving symlinks; only when the name says nothing is the library opened, in a *separate*
process, to call ``LLVMGetVersion`` (LLVM >= 16), so a broken library can never take this
process down.

When nothing usable exists, :class:`LLVMNotFoundError` says what was found and how to fix it,
unless the user asked for a variant that needs no LLVM (``MI_NPR_VARIANT=scalar_rgb`` or
``cuda_ad_rgb``): then Dr.Jit's LLVM backend is switched off safely instead.
"""

from __future__ import annotations

import glob
import os
import re
import subprocess
import sys
from dataclasses import dataclass, field

MIN_VERSION = 17
ENV = "DRJIT_LIBLLVM_PATH"
WHEEL = "karellen-llvm-core"

_FIX = (
    "Fix: `pip install karellen-llvm-core` (LLVM 23 as a wheel, mi-npr's default), or "
    "`apt-get install libllvm19`, or set DRJIT_LIBLLVM_PATH to a libLLVM >= "
    f"{MIN_VERSION} shared library."
)


class LLVMNotFoundError(ImportError):
    """No libLLVM that Dr.Jit 1.5 can use was found (or the user's choice is unusable)."""


@dataclass(frozen=True)
class Candidate:
    """One libLLVM file and what is known of it."""

    path: str
    source: str  # "DRJIT_LIBLLVM_PATH", "karellen-llvm-core wheel", "system"
    version: int | None = None
    problem: str | None = None

    @property
    def usable(self) -> bool:
        return self.problem is None and self.version is not None and self.version >= MIN_VERSION

    def describe(self) -> str:
        ver = f"LLVM {self.version}" if self.version is not None else "unknown version"
        why = f": {self.problem}" if self.problem else ""
        return f"{self.path} ({self.source}, {ver}){why}"


@dataclass
class Selection:
    """The outcome of :func:`configure`: the library chosen and everything that was looked at."""

    chosen: Candidate | None
    considered: list[Candidate] = field(default_factory=list)
    disabled: bool = False  # True when the LLVM backend was switched off on purpose
    note: str = ""


_VERSION_PATTERNS = (
    re.compile(r"libLLVM-(\d+)"),  # libLLVM-19.so, libLLVM-14.0.6.so.1
    re.compile(r"libLLVM\.so\.(\d+)"),  # libLLVM.so.23.1
    re.compile(r"libLLVM\.(\d+)\.dylib"),
    re.compile(r"llvm-(\d+)/"),  # /usr/lib/llvm-19/lib/libLLVM.so
    re.compile(r"llvm@(\d+)/"),  # Homebrew
)


def version_from_name(path: str) -> int | None:
    """LLVM major version read from a library's path (and its symlink target), or ``None``."""
    for p in (os.path.realpath(path), path):
        base = os.path.basename(p)
        for pat in _VERSION_PATTERNS[:3]:
            m = pat.search(base)
            if m:
                return int(m.group(1))
        for pat in _VERSION_PATTERNS[3:]:
            m = pat.search(p)
            if m:
                return int(m.group(1))
    return None


_PROBE = r"""
import ctypes, sys
try:
    lib = ctypes.CDLL(sys.argv[1])
except OSError as e:
    print("LOADERR", str(e).replace("\n", " ")); sys.exit(0)
f = getattr(lib, "LLVMGetVersion", None)
if f is None:
    print("NOVERSION"); sys.exit(0)
a, b, c = ctypes.c_uint(), ctypes.c_uint(), ctypes.c_uint()
f(ctypes.byref(a), ctypes.byref(b), ctypes.byref(c))
print("VERSION", a.value)
"""


def probe_version(path: str, timeout: float = 30.0) -> tuple[int | None, str | None]:
    """Open ``path`` in a child process and ask it for its version: ``(version, problem)``."""
    try:
        out = subprocess.run(
            [sys.executable, "-c", _PROBE, path],
            capture_output=True,
            text=True,
            timeout=timeout,
            check=False,
        )
    except (OSError, subprocess.TimeoutExpired) as e:
        return None, f"could not probe it ({e})"
    line = (out.stdout.strip().splitlines() or [""])[-1]
    if line.startswith("VERSION"):
        return int(line.split()[1]), None
    if line == "NOVERSION":
        # LLVMGetVersion appeared in LLVM 16: anything without it is older.
        return None, "not a libLLVM >= 16 (no LLVMGetVersion symbol)"
    if line.startswith("LOADERR"):
        return None, "cannot be loaded: " + line[len("LOADERR ") :]
    return None, f"probe failed (exit code {out.returncode})"


#: First bytes of a shared library: ELF (Linux), Mach-O 64/32-bit and universal (macOS).
_LIBRARY_MAGIC = (b"\x7fELF", b"\xcf\xfa\xed\xfe", b"\xce\xfa\xed\xfe", b"\xca\xfe\xba\xbe")


def inspect(path: str, source: str) -> Candidate:
    """Describe one library file: exists? a shared library? which version? usable?"""
    if not os.path.exists(path):
        return Candidate(path, source, None, "file does not exist")
    if os.path.isdir(path):
        return Candidate(path, source, None, "is a directory, not a shared library")
    try:
        with open(path, "rb") as f:
            head = f.read(4)
    except OSError as e:
        return Candidate(path, source, None, f"cannot be read ({e.strerror})")
    if head not in _LIBRARY_MAGIC:  # a name such as libLLVM-19.so proves nothing by itself
        return Candidate(path, source, None, "is not a shared library")
    version = version_from_name(path)
    problem = None
    if version is None:
        version, problem = probe_version(path)
    if problem is None and version is not None and version < MIN_VERSION:
        problem = f"too old: Dr.Jit 1.5 needs LLVM >= {MIN_VERSION} (older ones abort the process)"
    return Candidate(path, source, version, problem)


def wheel_libraries() -> list[str]:
    """libLLVM files installed by the ``karellen-llvm-core`` wheel (newest first)."""
    # Where the wheel puts it in a virtual environment or a plain install: a glob, so the common
    # case does not pay for importing importlib.metadata; the wheel's file list when that finds no
    # recent enough library (--user, --target installs).
    found = glob.glob(os.path.join(sys.prefix, "lib", "libLLVM*.so*"))
    if not any((version_from_name(p) or 0) >= MIN_VERSION for p in found):
        try:  # imported here: importlib.metadata slows every start, and the glob usually finds it
            from importlib import metadata

            dist = metadata.distribution(WHEEL)
            for f in dist.files or ():
                name = os.path.basename(str(f))
                if name.startswith("libLLVM") and ".so" in name:
                    found.append(str(dist.locate_file(f)))
        except Exception:  # not installed, or metadata unreadable
            pass
    found = [os.path.realpath(p) for p in found if os.path.exists(p)]
    return sorted(set(found), key=lambda p: (version_from_name(p) or 0, p), reverse=True)


_SYSTEM_GLOBS = (
    "/usr/lib/llvm-*/lib/libLLVM*.so*",
    "/usr/lib/*-linux-gnu/libLLVM*.so*",
    "/usr/lib64/libLLVM*.so*",
    "/usr/lib/libLLVM*.so*",
    "/usr/local/lib/libLLVM*.so*",
    "/opt/homebrew/opt/llvm*/lib/libLLVM*.dylib",
    "/usr/local/opt/llvm*/lib/libLLVM*.dylib",
)


def system_libraries() -> list[str]:
    """System libLLVM files, newest version first (one path per real file)."""
    paths: list[str] = []
    for pattern in _SYSTEM_GLOBS:
        paths.extend(glob.glob(pattern))
    try:
        out = subprocess.run(
            ["ldconfig", "-p"], capture_output=True, text=True, timeout=10, check=False
        ).stdout
        paths.extend(m.group(1) for m in re.finditer(r"=>\s*(\S*libLLVM\S*)", out))
    except (OSError, subprocess.TimeoutExpired):
        pass
    real: dict[str, str] = {}
    for p in paths:
        if os.path.isfile(p):
            real.setdefault(os.path.realpath(p), p)
    return sorted(real, key=lambda p: (version_from_name(p) or 0, p), reverse=True)


def _loaded_llvm() -> list[str]:
    """libLLVM files mapped into this process (Linux only; empty elsewhere)."""
    try:
        with open("/proc/self/maps") as f:
            return sorted({ln.split()[-1] for ln in f if "libLLVM" in ln and "/" in ln})
    except OSError:
        return []


def requested_variant() -> str:
    """The variant asked for: ``mi-npr --variant NAME`` in the command, else ``$MI_NPR_VARIANT``,
    else ``llvm_ad_rgb``. (The command's option is read here because ``import mi_npr`` must
    know it before Dr.Jit is imported, before the command line is parsed.)"""
    if cli_process():
        args = sys.argv[1:]
        for i, a in enumerate(args):
            if a == "--variant" and i + 1 < len(args):
                return args[i + 1]
            if a.startswith("--variant="):
                return a.split("=", 1)[1]
    return os.environ.get("MI_NPR_VARIANT") or "llvm_ad_rgb"


def _wants_llvm_variant() -> bool:
    return requested_variant().startswith("llvm")


def select() -> Selection:
    """Find the library to use without changing anything (see the module docstring)."""
    user = os.environ.get(ENV)
    if user:
        c = inspect(user, ENV)
        return Selection(c if c.usable else None, [c])
    considered: list[Candidate] = []
    for path in wheel_libraries():
        c = inspect(path, f"{WHEEL} wheel")
        considered.append(c)
        if c.usable:
            return Selection(c, considered)
    for path in system_libraries():
        c = inspect(path, "system")
        considered.append(c)
        if c.usable:
            return Selection(c, considered)
    return Selection(None, considered)


def _error(sel: Selection) -> LLVMNotFoundError:
    if sel.considered and sel.considered[0].source == ENV:
        c = sel.considered[0]
        msg = (
            f"mi-npr: {ENV}={c.path} is not usable: {c.problem or 'unknown version'}. "
            f"Unset {ENV} to let mi-npr find one, or point it to a libLLVM >= {MIN_VERSION}. "
            + _FIX
        )
    elif sel.considered:
        found = "; ".join(c.describe() for c in sel.considered)
        msg = f"mi-npr: no usable libLLVM (Dr.Jit 1.5 needs >= {MIN_VERSION}). Found: {found}. "
        msg += _FIX
    else:
        msg = f"mi-npr: no libLLVM found (Dr.Jit 1.5 needs >= {MIN_VERSION}). " + _FIX
    return LLVMNotFoundError(msg)


LAST_SELECTION: Selection | None = None


def cli_process() -> bool:
    """True when this process is the ``mi-npr`` command (which reports import errors itself)."""
    argv = getattr(sys, "orig_argv", sys.argv)
    return os.path.basename(sys.argv[0]) == "mi-npr" or "mi_npr.cli" in argv


def configure() -> Selection:
    """Choose libLLVM and export ``DRJIT_LIBLLVM_PATH``; must run before ``import drjit``.

    Raises :class:`LLVMNotFoundError` when no usable library exists and an LLVM variant is wanted.
    """
    global LAST_SELECTION
    LAST_SELECTION = _configure()
    return LAST_SELECTION


def _configure() -> Selection:
    if "drjit" in sys.modules:
        # Too late to choose: check what Dr.Jit already loaded, so an old one cannot abort later.
        loaded = _loaded_llvm()
        cands = [inspect(p, "already loaded by drjit") for p in loaded]
        bad = [c for c in cands if not c.usable]
        if bad and _wants_llvm_variant():
            raise LLVMNotFoundError(
                "mi-npr: drjit was imported before mi_npr and loaded "
                + "; ".join(c.describe() for c in bad)
                + f". Import mi_npr first (it picks a usable LLVM), or set {ENV}. "
                + _FIX
            )
        return Selection(cands[0] if cands else None, cands, note="drjit imported first")
    sel = select()
    if sel.chosen is not None:
        os.environ[ENV] = sel.chosen.path
        return sel
    if sel.considered and sel.considered[0].source == ENV:
        raise _error(sel)
    if sys.platform.startswith("linux") and _wants_llvm_variant():
        raise _error(sel)
    if sys.platform.startswith("linux"):
        # A scalar or CUDA variant was asked for: keep Dr.Jit from loading an old LLVM at all.
        os.environ[ENV] = os.path.join(os.sep, "nonexistent", "mi-npr-llvm-disabled", "libLLVM.so")
        sel.disabled = True
        sel.note = str(_error(sel))
    return sel


__all__ = [
    "ENV",
    "MIN_VERSION",
    "Candidate",
    "LLVMNotFoundError",
    "Selection",
    "cli_process",
    "configure",
    "inspect",
    "probe_version",
    "requested_variant",
    "select",
    "version_from_name",
]

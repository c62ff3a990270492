"""Memory: estimate what a render needs before it starts, against what the process may use.

A film too large for memory would kill the process (SIGSEGV inside Dr.Jit or numpy), so
:func:`check_render` runs first (one call at the start of every render) and raises
:class:`~mi_npr.errors.MemoryLimitError`, naming the size needed and the figure it exceeds.

The estimate, per render of a ``W x H`` film with ``spp`` samples per pixel:

- ``W * H * PIXEL_BYTES``: the exact G-buffer pass (rays, intersections, the layers as Dr.Jit
  arrays and their numpy copies), the beauty's film and the layers the integrators add. Measured:
  ~110 bytes per pixel of peak growth for ``npr_gbuffer`` with a ``path`` beauty on
  ``scenes_xml/scene1.xml`` at 640x480 and 1280x960; the budget is 160 (post-passes, EXR copy).
- ``W * H * spp * SAMPLE_BYTES``: the beauty's samples. With Dr.Jit's symbolic loops (the
  default) a path tracer keeps its per-sample state in registers and only the sample index is
  materialised (4 bytes); in wavefront mode (symbolic loops off) every sample's state lives in
  memory (budget 256 bytes). When this term alone would cross the bound, the beauty is
  rendered in passes (several ``integrator.render`` calls with different seeds, averaged by
  their sample counts): :func:`check_render` returns how many.

The bound is ``--max-memory`` (``set_max_memory``, or ``$MI_NPR_MAX_MEMORY``) when given, else
what is available: ``MemAvailable`` of ``/proc/meminfo``. Under an address-space limit
(``RLIMIT_AS``, ``ulimit -v``), that limit less what the process has mapped already bounds both:
the smaller figure wins, as the kernel refuses what lies beyond the limit whatever
``--max-memory`` says (a render past it dies of SIGSEGV inside Dr.Jit).
"""

from __future__ import annotations

import ctypes
import math
import os
import re
import resource
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

from .errors import MemoryLimitError, ParameterError
from .params import check_arg, entry

# Besides the estimate: the C library's side of memory (glibc's malloc_trim and arenas).

#: glibc's ``mallopt`` parameter for the most arenas (``M_ARENA_MAX``).
M_ARENA_MAX = -8


def _libc() -> Any:
    return ctypes.CDLL(None)


def release_freed_memory() -> None:
    """Hand the pages of freed arrays back to the system, where the C library allows it
    (glibc's ``malloc_trim``; elsewhere nothing). glibc keeps freed blocks between live ones
    resident, so without it a phase's temporaries of a few MB each (the strokes' topology
    makes hundreds) would stay in the process's memory after the phase."""
    try:
        _libc().malloc_trim(0)
    except (AttributeError, OSError, TypeError):  # not glibc
        pass


def share_malloc_arena() -> None:
    """Make the threads of this process allocate from one glibc arena (``mallopt(M_ARENA_MAX,
    1)``; elsewhere nothing), for the processes mi-npr runs itself (the command, a batch's
    workers), not for the library inside another program. glibc gives a thread that allocates
    while another does an arena of its own, whose pages stay with it: the strokes' helper
    threads (the intersection search beside the beauty and its pool) left 20-50 MB more
    resident on the tutorials' Lego model than one arena does, at the same speed (their
    allocations are few and large)."""
    try:
        _libc().mallopt(M_ARENA_MAX, 1)
    except (AttributeError, OSError, TypeError):  # not glibc
        pass


#: Bytes per pixel of a render besides the beauty's samples (see the module docstring).
PIXEL_BYTES = 160
#: Bytes per beauty sample with symbolic loops (the sample index) and in wavefront mode.
SAMPLE_BYTES_SYMBOLIC = 4
SAMPLE_BYTES_WAVEFRONT = 256
#: The environment variable that carries ``--max-memory`` (to batch workers too).
ENV = "MI_NPR_MAX_MEMORY"

_UNITS = {"": 1, "K": 1 << 10, "M": 1 << 20, "G": 1 << 30, "T": 1 << 40}
_max_memory: int | None = None


def parse_size(text: str | int) -> int:
    """``"4G"``, ``"512M"``, ``"1.5GiB"``, ``"2e9"`` or an int (bytes) as a number of bytes;
    units are binary (K = 1024). A bad text is a :class:`ParameterError`."""
    if isinstance(text, int) and not isinstance(text, bool):
        n: float = text
    else:
        m = re.fullmatch(r"\s*([0-9.eE+]+)\s*([kKmMgGtT]?)(?:i?[bB])?\s*", str(text))
        try:
            n = float(m[1]) * _UNITS[m[2].upper()] if m else math.nan
        except ValueError:
            n = math.nan
    if not (math.isfinite(n) and 1 <= n < 1 << 60):
        raise ParameterError(f"max memory {text!r}: expected a size such as 4G, 512M or 2e9")
    return int(n)


def set_max_memory(size: str | int | None) -> None:
    """Set the bound for this process (``None``: back to what is available)."""
    global _max_memory
    _max_memory = None if size is None else parse_size(size)


def _gib(n: float) -> str:
    return f"{n / (1 << 30):.3g} GiB" if n >= 1 << 28 else f"{n / (1 << 20):.3g} MiB"


def _meminfo_available() -> int | None:
    try:
        with open("/proc/meminfo", encoding="ascii") as f:
            for line in f:
                if line.startswith("MemAvailable:"):
                    return int(line.split()[1]) * 1024
    except (OSError, ValueError, IndexError):
        pass
    return None


def _mapped() -> int:
    """Bytes of address space this process has mapped (VmSize)."""
    try:
        with open("/proc/self/status", encoding="ascii") as f:
            for line in f:
                if line.startswith("VmSize:"):
                    return int(line.split()[1]) * 1024
    except (OSError, ValueError, IndexError):
        pass
    return 0


def available() -> tuple[int | None, str]:
    """The bound in bytes and where it comes from (``None``: nothing known, no check)."""
    figures: list[tuple[int, str]] = []
    env = os.environ.get(ENV)
    if _max_memory is not None:
        figures.append((_max_memory, "--max-memory"))
    elif env:
        figures.append((parse_size(env), f"${ENV}"))
    else:
        avail = _meminfo_available()
        if avail is not None:
            figures.append((avail, "available memory (MemAvailable)"))
    soft, _ = resource.getrlimit(resource.RLIMIT_AS)
    if soft != resource.RLIM_INFINITY:
        figures.append((max(soft - _mapped(), 0), "the address-space limit (RLIMIT_AS)"))
    if not figures:
        return None, "unknown"
    return min(figures)


@dataclass(frozen=True)
class Estimate:
    """Bytes a render needs: ``fixed`` (pixels) and ``samples`` (the beauty's samples)."""

    width: int
    height: int
    spp: int
    fixed: int
    samples: int

    @property
    def total(self) -> int:
        return self.fixed + self.samples


def estimate(width: int, height: int, spp: int, beauty: bool = True) -> Estimate:
    """What a ``width x height`` render with ``spp`` beauty samples per pixel needs."""
    # Imported here, like every Dr.Jit import of this module: the command line reads
    # --max-memory (parse_size) before it knows that Dr.Jit can start.
    import drjit as dr

    pixels = int(width) * int(height)
    symbolic = bool(dr.flag(dr.JitFlag.SymbolicLoops))
    per_sample = SAMPLE_BYTES_SYMBOLIC if symbolic else SAMPLE_BYTES_WAVEFRONT
    samples = pixels * max(int(spp), 1) * per_sample if beauty else 0
    return Estimate(int(width), int(height), int(spp), pixels * PIXEL_BYTES, samples)


def plan(est: Estimate, bound: int | None, figure: str) -> int:
    """The number of beauty passes that keeps ``est`` under ``bound`` (1: no split), or
    :class:`MemoryLimitError` naming the size and the figure when nothing does."""
    if bound is None or est.total <= bound:
        return 1
    size = f"{est.width} x {est.height}"
    if est.fixed < bound and est.spp > 1:
        passes = math.ceil(est.samples / (bound - est.fixed))
        if passes <= est.spp:
            return passes
    raise MemoryLimitError(
        f"a {size} render at {est.spp} spp needs about {_gib(est.total)}, more than "
        f"{_gib(bound)} ({figure}): lower the resolution, or raise the bound with --max-memory"
    )


def check_render(sensor: object, beauty: object | None, spp: int | None, seed: int = 0) -> int:
    """The checks at the start of a render of ``sensor``'s film: ``seed`` against the validation
    table (``spp`` was checked by :func:`mi_npr.session.check_spp`), then memory. Returns the
    number of beauty passes to use (1 almost always), or raises :class:`ParameterError` /
    :class:`MemoryLimitError`."""
    from .session import RENDER_PARAMS  # imported here: session imports Mitsuba (estimate)

    check_arg("render", entry(RENDER_PARAMS, "seed"), seed)
    film = sensor.film()  # type: ignore[attr-defined]
    w, h = (int(v) for v in film.crop_size())
    n = spp if spp else int(sensor.sampler().sample_count())  # type: ignore[attr-defined]
    bound, figure = available()
    return plan(estimate(w, h, n, beauty is not None), bound, figure)


def pass_counts(spp: int, passes: int) -> list[int]:
    """``spp`` split into ``passes`` sample counts that differ by at most one."""
    base, extra = divmod(spp, passes)
    return [base + (i < extra) for i in range(passes)]


def render_passes(
    integrator: Any,
    scene: Any,
    sensor: Any,
    spp: int,
    seed: int,
    passes: int = 1,
    on_pass: Callable[[int], Any] | None = None,
    first: tuple[Any, int] | None = None,
) -> Any:
    """``integrator.render(scene, sensor, seed, spp)``, or with ``passes > 1`` the mean of that
    many renders of fewer samples with different seeds (weighted by their sample counts): the
    same estimate of the image, in a fraction of the memory (see :func:`check_render`) or with
    a progress bar (``on_pass(samples)`` after each pass, :func:`mi_npr.render.beauty_layers`).

    ``first = (image, n)``: a render of ``n`` of the ``spp`` samples made already with ``seed``
    (the progress bar's time probe); it counts as the first pass, and the passes that render the
    other ``spp - n`` samples take seeds other than ``seed``."""
    if passes <= 1 and first is None:
        return integrator.render(scene, sensor, seed=seed, spp=spp, develop=True, evaluate=True)
    import drjit as dr  # imported here: see estimate
    import mitsuba as mi

    total = spp or int(sensor.sampler().sample_count())
    acc, rest, shift = None, total, 0
    if first is not None:
        img, n = first
        acc, rest, shift = mi.TensorXf64(img) * n, total - n, 1
    for i, n in enumerate(pass_counts(rest, min(passes, rest)) if rest > 0 else []):
        s = (seed * (passes + shift) + i + shift) & 0xFFFFFFFF  # distinct, within uint32
        img = integrator.render(scene, sensor, seed=s, spp=n, develop=True, evaluate=True)
        a = mi.TensorXf64(img) * n  # accumulated in float64, in Dr.Jit
        acc = a if acc is None else acc + a
        dr.eval(acc)
        if on_pass is not None:
            on_pass(n)
    return mi.TensorXf(acc / total)


#: Bytes per pixel of every frame a gif holds until it is written (the RGB frame, Pillow's copy
#: and its palette image).
GIF_BYTES = 8


def check_path(width: int, height: int, frames: int, gifs: int = 0) -> None:
    """The memory check of a camera path of ``frames`` frames of ``width x height``, before its
    first frame renders (each frame's render is checked by :func:`check_render`): the frames go
    to disk as they are rendered and are read back one pair at a time for the coherence
    measure (``2 * PIXEL_BYTES`` per pixel), except the ``gifs`` videos, which hold every frame
    (:data:`GIF_BYTES` per pixel each). :class:`MemoryLimitError` over the bound."""
    pixels = int(width) * int(height)
    need = 2 * pixels * PIXEL_BYTES + int(gifs) * int(frames) * pixels * GIF_BYTES
    bound, figure = available()
    if bound is not None and need > bound:
        what = f" with {gifs} gif{'s' * (gifs > 1)}" if gifs else ""
        raise MemoryLimitError(
            f"a path of {frames} frames of {width} x {height}{what} needs about {_gib(need)}, "
            f"more than {_gib(bound)} ({figure}): write an mp4, lower the resolution, or "
            "raise the bound with --max-memory"
        )


def check_images(width: int, height: int, images: int, what: str) -> None:
    """The memory check of a pass that holds ``images`` images of ``width x height`` pixels at
    once (best-view's batched ID buffers): :class:`MemoryLimitError` over the bound."""
    need = int(width) * int(height) * int(images) * PIXEL_BYTES
    bound, figure = available()
    if bound is not None and need > bound:
        raise MemoryLimitError(
            f"{images} {what} of {width} x {height} need about {_gib(need)}, more than "
            f"{_gib(bound)} ({figure}): lower the resolution, or raise the bound with --max-memory"
        )

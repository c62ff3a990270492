"""The files of a camera path beside its frames: the videos, ``mp4`` (H.264 through
``imageio-ffmpeg``'s own ffmpeg binary) or ``gif`` (Pillow), and the temporal-coherence
measure (``coherence.json`` and its plot ``coherence.png``), written through temporary files
like every other output."""

from __future__ import annotations

import contextlib
import itertools
import json
import os
import subprocess
import tempfile
from collections.abc import Iterable, Iterator
from pathlib import Path

import numpy as np
from PIL import Image

from ..coherence import figure
from ..errors import OutputError, ParameterError, as_path, shown
from ._atomic import atomic_output
from .png import to_rgb8
from .text import write_text

#: The video formats ``mi-npr path --video`` writes.
FORMATS = ("mp4", "gif")


def check_format(fmt: str) -> str:
    """``fmt`` if it is one of :data:`FORMATS`, else a :class:`ParameterError`."""
    if not isinstance(fmt, str) or fmt not in FORMATS:
        raise ParameterError(f"video format {shown(fmt)}: expected one of {', '.join(FORMATS)}")
    return fmt


def frame_image(image: np.ndarray) -> np.ndarray:
    """A linear float (H, W, 3) picture as the sRGB uint8 frame of a video."""
    a = np.asarray(image) if isinstance(image, np.ndarray) else None
    if a is None or a.ndim != 3 or a.shape[2] < 3 or a.dtype.kind not in "fiu":
        raise ParameterError(f"image = {shown(image)}: expected an (H, W, 3) array of numbers")
    return to_rgb8(a[..., :3])


def _even(a: np.ndarray) -> np.ndarray:
    """H.264 in yuv420p needs even sides: repeat the last row/column where odd."""
    h, w = a.shape[:2]
    return np.pad(a, ((0, h % 2), (0, w % 2), (0, 0)), mode="edge")


def write_video(path: str | os.PathLike[str], frames: Iterable[np.ndarray], fps: int = 24) -> Path:
    """Write uint8 (H, W, 3) ``frames`` as ``path`` (its suffix ``.mp4`` or ``.gif`` picks the
    format). ``mp4`` needs the ``imageio-ffmpeg`` package (a dependency of mi-npr); its frames
    are streamed to ffmpeg one at a time (``frames`` may be a generator reading them from
    disk), while a ``gif`` holds them all (Pillow's encoder needs every frame)."""
    target = as_path(path, "output file")
    fmt = check_format(target.suffix.lstrip("."))
    if isinstance(fps, bool) or not isinstance(fps, int) or not 1 <= fps <= 240:
        raise ParameterError(f"fps = {fps!r}: must be in [1, 240]")
    it = iter(frames)
    first = next(it, None)
    if first is None:
        raise ParameterError(f"{target}: no frames")
    images = (np.ascontiguousarray(f, np.uint8) for f in itertools.chain([first], it))
    with atomic_output(target) as tmp:
        if fmt == "gif":
            pics = [Image.fromarray(a) for a in images]
            pics[0].save(
                tmp,
                format="GIF",
                save_all=True,
                append_images=pics[1:],
                duration=round(1000 / fps),
                loop=0,
            )
        else:
            _write_mp4(tmp, (_even(a) for a in images), fps, target)
    return target


def _write_mp4(tmp: str, images: Iterator[np.ndarray], fps: int, target: Path) -> None:
    try:  # imported here: only an mp4 needs it, and its import looks for an ffmpeg binary
        import imageio_ffmpeg
    except ImportError:
        raise OutputError(f"{target}: mp4 needs the imageio-ffmpeg package") from None
    first = next(images)
    h, w = first.shape[:2]
    cmd = [
        imageio_ffmpeg.get_ffmpeg_exe(), "-y", "-loglevel", "error",
        "-f", "rawvideo", "-pix_fmt", "rgb24", "-s", f"{w}x{h}", "-r", str(fps), "-i", "-",
        "-an", "-vcodec", "libx264", "-pix_fmt", "yuv420p", "-f", "mp4", tmp,
    ]  # fmt: skip
    with tempfile.TemporaryFile() as err:
        proc = subprocess.Popen(cmd, stdin=subprocess.PIPE, stdout=subprocess.DEVNULL, stderr=err)
        assert proc.stdin is not None
        try:
            for a in itertools.chain([first], images):
                if a.shape[:2] != (h, w):
                    raise ParameterError(f"{target}: frames of {a.shape[1]} x {a.shape[0]} "
                                         f"and {w} x {h}")  # fmt: skip
                proc.stdin.write(a.tobytes())
        except BrokenPipeError:
            pass  # ffmpeg stopped: its message follows
        except BaseException:
            proc.kill()
            raise
        finally:
            with contextlib.suppress(BrokenPipeError):
                proc.stdin.close()
            proc.wait()
        if proc.returncode != 0:
            err.seek(0)
            msg = err.read().decode(errors="replace").strip().splitlines()
            raise OutputError(f"{target}: ffmpeg failed ({msg[-1] if msg else proc.returncode})")


def write_coherence(
    coherence: dict, outdir: str | os.PathLike[str], curves: dict | None = None
) -> list[Path]:
    """``coherence.json`` (``coherence``, plus any other ``curves``: name -> a
    :func:`mi_npr.coherence.popping` result) and, with matplotlib (the ``plots`` extra), its
    plot ``coherence.png``; without matplotlib the plot is skipped. Returns the paths."""

    out = as_path(outdir, "output directory")
    data = dict(coherence)
    if curves:
        data["variants"] = curves
    files = [write_text(out / "coherence.json", json.dumps(data, indent=1))]
    fig = figure({"path": coherence, **(curves or {})})
    if fig is not None:
        target = out / "coherence.png"
        with atomic_output(target) as tmp:
            fig.savefig(tmp, format="png", dpi=100)
        import matplotlib.pyplot as plt  # imported here: optional (the plots extra)

        plt.close(fig)
        files.append(target)
    return files

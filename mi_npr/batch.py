"""Running one job per input (scene, EXR) with a progress bar, where one failure does not stop the
others: what the CLI's multi-scene commands share. Errors become one-line messages."""

from __future__ import annotations

import sys
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from .errors import NprError, ParameterError, one_line


@dataclass
class JobResult:
    """What one job produced, or why it failed."""

    item: str
    outputs: list[Path] = field(default_factory=list)
    error: str | None = None
    seconds: float = 0.0

    @property
    def ok(self) -> bool:
        return self.error is None


def parse_define(text: str) -> tuple[str, str]:
    """``"name=value"`` -> ``(name, value)``; :class:`ParameterError` if malformed."""
    name, sep, value = text.partition("=")
    name = name.strip()
    if not sep:
        raise ParameterError(f"-D {text!r}: expected name=value")
    if not name or not name.replace("_", "a").isalnum():
        raise ParameterError(f"-D {text!r}: {name!r} is not a valid parameter name")
    return name, value


def check_unique_stems(paths: Sequence[str]) -> None:
    """Two inputs with the same file stem would overwrite each other's outputs."""
    seen: dict[str, str] = {}
    for p in paths:
        stem = Path(p).stem
        if stem in seen and seen[stem] != p:
            raise ParameterError(f"{seen[stem]} and {p} would both write outputs named {stem!r}")
        seen[stem] = p


def run_jobs(
    items: Sequence[str],
    job: Callable[[str], list[Path]],
    progress: bool = True,
    traceback: bool = False,
    desc: str = "rendering",
    on_result: Callable[[JobResult], tuple[str, bool]] | None = None,
) -> list[JobResult]:
    """Run ``job`` on every item; a failing item is recorded and the next one runs.

    ``on_result(result) -> (line, is_error)``: a line printed as soon as that item is done
    (stderr for errors, stdout otherwise), above the progress bar when there is one."""
    results: list[JobResult] = []
    bar: Any = None
    if progress and len(items) > 1:
        from tqdm import tqdm

        bar = tqdm(total=len(items), desc=desc, unit="scene", leave=True)
    for item in items:
        if bar is not None:
            bar.set_postfix_str(Path(item).name)
        t0 = time.perf_counter()
        res = JobResult(item)
        try:
            res.outputs = job(item)
        except NprError as e:  # one line; name the input when the message does not
            res.error = str(e) if item in str(e) else f"{item}: {e}"
        except Exception as e:
            if traceback:
                raise
            res.error = f"{item}: internal error: {type(e).__name__}: {one_line(e)}"
        res.seconds = time.perf_counter() - t0
        results.append(res)
        if on_result is not None:
            line, is_error = on_result(res)
            stream = sys.stderr if is_error else sys.stdout
            if bar is not None:
                bar.write(line, file=stream)
            else:
                print(line, file=stream, flush=True)
        if bar is not None:
            bar.update(1)
    if bar is not None:
        bar.close()
    return results

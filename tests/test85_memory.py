"""A render's memory is estimated before it starts (mi_npr.memory); over the bound a
clear one-line error names the size and the figure, never a signal death; ``--max-memory``
changes the bound; a beauty whose samples alone cross it is rendered in passes."""

from __future__ import annotations

import os
import subprocess
import sys
import textwrap
import weakref

import numpy as np
import pytest

import mi_npr
from mi_npr import memory

from .helpers import ROOT, run_cli, scene_xml

BALL = '<shape type="sphere" id="ball"><point name="center" x="0" y="0" z="4"/></shape>'

LIMITED = textwrap.dedent("""\
    import resource, sys
    limit = int(sys.argv[1])
    resource.setrlimit(resource.RLIMIT_AS, (limit, limit))
    from mi_npr.cli import main
    sys.exit(main(sys.argv[2:]))
""")


def _limited(*args, limit=3 << 30):
    # On LLVM: CUDA's driver alone maps more address space than these limits (the GPU run of the
    # suite sets MI_NPR_VARIANT=cuda_ad_rgb).
    env = {**os.environ, "MI_NPR_VARIANT": "llvm_ad_rgb"}
    return subprocess.run(
        [sys.executable, "-c", LIMITED, str(limit), *args],
        env=env,
        capture_output=True,
        text=True,
        cwd=ROOT,
        timeout=300,
        check=False,
    )


def test01_address_space_limit_is_a_clear_error_not_a_signal(tmp_path):
    scene = tmp_path / "ball.xml"
    scene.write_text(scene_xml(BALL, width=8192, height=8192))
    r = _limited("render", str(scene), "-o", str(tmp_path / "out"), "--no-progress")
    assert r.returncode == 1, (r.returncode, r.stderr[-2000:])  # never -11 / 139
    lines = r.stderr.strip().splitlines()
    assert len(lines) == 1 and "8192 x 8192" in lines[0] and "RLIMIT_AS" in lines[0]
    assert "GiB" in lines[0] and "--max-memory" in lines[0]
    assert not list((tmp_path / "out").iterdir())


def test02_max_memory_flag(tmp_path):
    scene = tmp_path / "ball.xml"
    scene.write_text(scene_xml(BALL, width=64, height=48))
    r = run_cli("render", str(scene), "-o", str(tmp_path / "o"), "--max-memory", "100K")
    assert r.returncode == 1
    assert "64 x 48" in r.stderr and "(--max-memory)" in r.stderr
    ok = run_cli("render", str(scene), "-o", str(tmp_path / "o"), "--max-memory", "1G")
    assert ok.returncode == 0, ok.stderr
    bad = run_cli("render", str(scene), "-o", str(tmp_path / "o"), "--max-memory", "lots")
    assert bad.returncode == 2 and "argument --max-memory" in bad.stderr


@pytest.mark.parametrize(
    ("text", "size"), [("4G", 4 << 30), ("512M", 512 << 20), ("1.5GiB", 3 << 29), ("2e9", 2e9)]
)
def test03_parse_size(text, size):
    assert memory.parse_size(text) == size


@pytest.mark.parametrize("text", ["", "G", "-1G", "nan", "inf", "1e30", "4X", "abc"])
def test04_parse_size_refuses(text):
    with pytest.raises(mi_npr.ParameterError, match="max memory"):
        memory.parse_size(text)


def test05_plan():
    est = memory.estimate(100, 100, 64)
    assert est.fixed == 100 * 100 * memory.PIXEL_BYTES
    assert memory.plan(est, None, "unknown") == 1
    assert memory.plan(est, est.total, "x") == 1
    # samples alone cross the bound: passes, each under it
    bound = est.fixed + est.samples // 3
    n = memory.plan(est, bound, "x")
    assert est.fixed + est.samples / n <= bound < est.fixed + est.samples / (n - 1)
    with pytest.raises(mi_npr.MemoryLimitError, match=r"100 x 100 render at 64 spp"):
        memory.plan(est, est.fixed // 2, "the figure")
    assert memory.pass_counts(10, 3) == [4, 3, 3] and sum(memory.pass_counts(64, 7)) == 64


def test06_beauty_in_passes_is_the_same_image(tmp_path, monkeypatch):
    """A constant environment seen by a path tracer: every sample is the constant, so the mean
    of the passes must equal it exactly; the passes really happened (two renders)."""
    xml = scene_xml(
        '<emitter type="constant"><rgb name="radiance" value="0.25, 0.5, 0.75"/></emitter>',
        width=32,
        height=24,
        integrator='<integrator type="npr_gbuffer"><integrator type="path"/></integrator>',
        spp=8,
    )
    path = tmp_path / "env.xml"
    path.write_text(xml)
    one = mi_npr.render(path)
    est = memory.estimate(32, 24, 8)
    memory.set_max_memory(est.fixed + est.samples // 2 + 1)
    calls = []
    real = memory.render_passes

    def spy(*a, **k):
        calls.append(a[-1] if len(a) > 5 else k.get("passes", 1))
        return real(*a, **k)

    monkeypatch.setattr(sys.modules["mi_npr.render"], "render_passes", spy)
    try:
        split = mi_npr.render(path)
    finally:
        memory.set_max_memory(None)
    assert calls == [2]
    for k in "RGB":
        np.testing.assert_allclose(split[k], one.numpy(k), rtol=1e-6)
    np.testing.assert_allclose(split["R"], 0.25, rtol=1e-6)


def test07_spp_and_seed_are_checked_from_the_table(tmp_path):
    path = tmp_path / "ball.xml"
    path.write_text(scene_xml(BALL))
    for kw, name in (
        ({"spp": 2**32 - 1}, "spp"),
        ({"seed": -1}, "seed"),
        ({"seed": 2**32}, "seed"),
    ):
        with pytest.raises(mi_npr.ParameterError, match=f"'{name}'"):
            mi_npr.render(path, **kw)


def test08_best_view_id_buffers_are_checked(tmp_path):
    scene = tmp_path / "ball.xml"
    scene.write_text(scene_xml(BALL))
    r = run_cli(
        "best-view", str(scene), "--measure", "pb", "-o", str(tmp_path / "o"),
        "--res", "20000", "--max-memory", "2G",
    )  # fmt: skip
    assert r.returncode == 1 and "12 ID buffers of 20000 x 15000" in r.stderr, r.stderr
    assert "(--max-memory)" in r.stderr


def test09_max_memory_does_not_lift_an_address_space_limit(tmp_path):
    """--max-memory 1T under a 3 GiB ulimit -v: the smaller bound wins, a clean refusal."""
    scene = tmp_path / "ball.xml"
    scene.write_text(scene_xml(BALL, width=8192, height=8192))
    r = _limited("render", str(scene), "-o", str(tmp_path / "out"), "--no-progress",
                 "--max-memory", "1T")  # fmt: skip
    assert r.returncode == 1, (r.returncode, r.stderr[-2000:])  # never -11 / 139
    lines = r.stderr.strip().splitlines()
    assert len(lines) == 1 and "8192 x 8192" in lines[0] and "RLIMIT_AS" in lines[0]


def test10_a_path_checks_its_memory_before_rendering_and_streams_its_frames(tmp_path):
    from mi_npr import camera as C
    from mi_npr import paths as P

    scene = str(ROOT / "scenes_xml" / "scene3.xml")
    cams = C.orbit(scene, 3, 20.0)
    out = tmp_path / "gif"
    memory.set_max_memory("2M")
    try:  # 3 frames of 320 x 240 in a gif: ~2 x 12 MiB of window, over 2 MiB: before any frame
        with pytest.raises(mi_npr.MemoryLimitError, match=r"a path of 3 frames of 320 x 240"):
            P.render_frames(scene, cams, out, resolution=(320, 240), spp=1, video="gif")
    finally:
        memory.set_max_memory(None)
    assert not any(out.glob("frame_*"))
    # The frames of a rendered path are read back as they are used, not kept.
    r = P.render_frames(scene, C.orbit(scene, 6, 30.0), tmp_path / "p", ["lines"],
                        resolution=(24, 18), spp=1, video="mp4")  # fmt: skip
    assert isinstance(r.gbuffers, P.FrameFiles) and len(r.gbuffers) == 6
    assert (tmp_path / "p" / "beauty.mp4").stat().st_size > 0
    # The measure goes through them once, in order, holding a pair (and the one being read).
    alive: set[int] = set()
    most = [0]

    def watched():
        for i, gb in enumerate(r.gbuffers):
            alive.add(i)
            weakref.finalize(gb, alive.discard, i)
            most[0] = max(most[0], len(alive))
            yield gb

    again = mi_npr.coherence.popping(watched(), layer="lines.V")
    assert most[0] <= 3 and again["frames"] == 6
    assert again["per_frame"] == r.coherence["per_frame"]  # the same measure as the path's


def test11_one_malloc_arena_for_the_command(monkeypatch):
    """``share_malloc_arena`` asks glibc for one arena (``mallopt(M_ARENA_MAX, 1)``), does
    nothing where the C library has no ``mallopt``, and the command asks for it first."""
    calls = []

    class Glibc:
        def mallopt(self, param, value):
            calls.append((param, value))
            return 1

    monkeypatch.setattr(memory, "_libc", Glibc)
    memory.share_malloc_arena()
    assert calls == [(-8, 1)]
    monkeypatch.setattr(memory, "_libc", object)  # no mallopt: not glibc
    memory.share_malloc_arena()
    import mi_npr.cli

    monkeypatch.setattr(mi_npr.cli, "share_malloc_arena", lambda: calls.append("cli"))
    with pytest.raises(SystemExit):
        mi_npr.cli.main(["--version"])
    assert calls[-1] == "cli"
    # a library call in another program's process leaves its malloc alone
    from mi_npr import batch

    assert not batch._on_dask_worker()

"""The thesis's line chain in Dr.Jit against the same chain with OpenCV, same inputs, same run.

The chain (what ``npr_lines`` runs, with ID edges on): depth normalisation over the frame's finite
range -> selective dilation 3x3 (eqs. 5.3-5.4) -> signed depth contours (eq. 5.1) -> isolated-pixel
removal (eq. 5.2) -> max with 1-px object-ID edges. Ours is
``mi_npr.kernels.lines(gb, id_edges=True, crease_angle=0)`` (Dr.Jit, on the active variant's
backend: LLVM, or CUDA with ``MI_NPR_VARIANT=cuda_ad_rgb``). The anchor is the same chain with
OpenCV where it has the operation
(``cv2.minMaxLoc``, ``cv2.blur``, ``cv2.dilate``, ``cv2.erode``, ``cv2.boxFilter``) and numpy for
the rest (the neighbour count of eq. 5.4 has no OpenCV primitive). Both start from the same numpy
``Z`` and ``object_id.V`` layers: ``scene3.xml``'s G-buffer rendered at 640x480 and 3840x2160.

warm: median (and minimum) of ``--repeat`` runs after one warm-up, in this process, the two cases
alternating run by run (so both see the same load on a shared machine), both on
``--threads`` threads (``dr.set_thread_count``, ``cv2.setNumThreads``), ``dr.sync_thread()``
before the timer stops.
cold: the first run in a fresh process with an empty Dr.Jit kernel cache (compilation included).
memory: in that fresh process, the peak resident set size during the first run minus the resident
set size before it (Linux: the high-water mark is reset through /proc/self/clear_refs), and
Dr.Jit's own allocation watermark.

    python benchmarks/bench_kernels.py [--quick] [--repeat N] [--threads N] [--out DIR]

Prints the ratios ours / OpenCV (< 1 means faster) and writes ``bench_kernels.json``.
"""

from __future__ import annotations

import argparse
import json
import statistics
import sys
import tempfile
import time
from pathlib import Path

import _common
import numpy as np

HERE = Path(__file__).resolve().parent
SCENE = HERE.parent / "scenes_xml" / "scene3.xml"
SIZES = [(640, 480), (3840, 2160)]
CASES = ["mi_npr", "opencv"]
TARGETS = {"warm_ms_640x480": 3.0, "ratio_warm_3840x2160": 1.0, "peak_mb_3840x2160": 1024.0}


def opencv_lines(Z: np.ndarray, ids: np.ndarray, c=40.0, t=1.0, t0=0.5) -> np.ndarray:
    """The anchor: the chain of ``mi_npr.kernels.lines(..., id_edges=True, crease_angle=0)``
    with OpenCV (its depth range as the chain's: ``far`` at least ``4 near``, background 2)."""
    import cv2

    box = np.ones((3, 3), np.uint8)
    rep = cv2.BORDER_REPLICATE
    finite = np.isfinite(Z)
    lo, hi, _, _ = cv2.minMaxLoc(np.where(finite, Z, 0).astype(np.float32), finite.view(np.uint8))
    lo, hi = np.float32(lo), np.float32(max(hi, lo + 3.0 * max(lo, 0.0)))
    span = max(hi * np.float32(0.5) - lo * np.float32(0.5), np.float32(1.1754944e-38))
    D = np.clip((Z * np.float32(0.5) - lo * np.float32(0.5)) / span, 0, 1).astype(np.float32)
    D[~finite] = 2.0
    # Selective dilation on R = 1 - D (eqs. 5.3-5.4).
    R = 1.0 - D
    mean = cv2.blur(R, (3, 3), borderType=rep)
    pad = cv2.copyMakeBorder(R, 1, 1, 1, 1, rep)
    h, w = R.shape
    n_above = np.zeros((h, w), np.uint8)
    for dy in range(3):
        for dx in range(3):
            if (dy, dx) != (1, 1):
                n_above += pad[dy : dy + h, dx : dx + w] > mean
    D = 1.0 - np.where(n_above > 4, cv2.dilate(R, box, borderType=rep), R)
    # Eq. 5.1: the farthest neighbour's term is the maximum.
    p = np.clip((cv2.dilate(D, box, borderType=rep) - D) * np.float32(c) - np.float32(t), 0, 1)
    # Eq. 5.2: count of the 3x3 block above t0, zero outside.
    above = (p > t0).astype(np.float32)
    count = cv2.boxFilter(above, -1, (3, 3), normalize=False, borderType=cv2.BORDER_CONSTANT)
    p = np.where(count >= 3, p, 0.0)
    # Object-ID edges, 1 px: a 4-neighbour of another id, on this pixel's side: the
    # near side of a step above t / c in the pre-filtered depth, else the larger id.
    step = np.float32(t / c)
    f, Dp = np.pad(ids, 1, mode="edge"), np.pad(D, 1, mode="edge")
    edge = np.zeros((h, w), bool)
    for dy, dx in ((-1, 0), (0, -1), (0, 1), (1, 0)):
        q_id = f[1 + dy : 1 + dy + h, 1 + dx : 1 + dx + w]
        dz = Dp[1 + dy : 1 + dy + h, 1 + dx : 1 + dx + w] - D
        edge |= (q_id != ids) & ((dz > step) | ((np.abs(dz) <= step) & (ids > q_id)))
    return np.where(edge, np.float32(1.0), p).astype(np.float32)


def _setup(case: str, data: Path, w: int, h: int, threads: int):
    """A zero-argument function that runs the chain once and waits for the result."""
    Z = np.load(data / f"Z_{w}x{h}.npy")
    ids = np.load(data / f"id_{w}x{h}.npy")
    if case == "opencv":
        import cv2

        cv2.setNumThreads(threads)
        return lambda: opencv_lines(Z, ids)
    import mi_npr

    dr = mi_npr.dr
    dr.set_thread_count(threads)
    gb = {"Z": Z, "object_id.V": ids}

    def run():
        out = mi_npr.kernels.lines(gb, id_edges=True, crease_angle=0)
        dr.sync_thread()
        return out

    return run


def _status_kb(key: str) -> int:
    for line in Path("/proc/self/status").read_text().splitlines():
        if line.startswith(key + ":"):
            return int(line.split()[1])
    raise KeyError(key)


def _reset_peak_rss() -> int:
    """Reset the kernel's high-water mark of this process's RSS (Linux >= 4.0); current RSS."""
    Path("/proc/self/clear_refs").write_text("5")
    return _status_kb("VmRSS")


def _cold_child(case: str, data: str, w: int, h: int, threads: int) -> None:
    fn = _setup(case, Path(data), w, h, threads)
    if case == "mi_npr":
        import drjit as dr

        dr.detail.malloc_clear_statistics()
    base = _reset_peak_rss()
    t0 = time.perf_counter()
    fn()
    ms = (time.perf_counter() - t0) * 1e3
    peak = _status_kb("VmHWM")
    res = {"cold_ms": ms, "peak_growth_mb": (peak - base) / 1024, "peak_rss_mb": peak / 1024}
    if case == "mi_npr":
        res["drjit_watermark_mb"] = dr.detail.malloc_watermark(dr.JitBackend.LLVM) / 2**20
    print(json.dumps(res))


def measure_cold(case: str, data: Path, w: int, h: int, threads: int) -> dict:
    return _common.cold_run(__file__, case, data, w, h, "--threads", threads)


def measure_warm(data: Path, w: int, h: int, threads: int, repeat: int) -> dict:
    """Warm timings of every case, interleaved run by run so that both see the same load."""
    fns = {case: _setup(case, data, w, h, threads) for case in CASES}
    times: dict[str, list[float]] = {case: [] for case in CASES}
    for fn in fns.values():
        fn()
    for _ in range(repeat):
        for case, fn in fns.items():
            time.sleep(0.02)
            t0 = time.perf_counter()
            fn()
            times[case].append((time.perf_counter() - t0) * 1e3)
    return {
        case: {"warm_ms": statistics.median(ts), "warm_min_ms": min(ts)}
        for case, ts in times.items()
    }


def render_inputs(data: Path, sizes: list[tuple[int, int]]) -> dict:
    """scene3's Z and object_id at each size (headlight G-buffer pass, no beauty integrator)."""
    import mi_npr

    agree = {}
    for w, h in sizes:
        scene = mi_npr.load_scene(SCENE, width=w, height=h, spp=1)
        gb = mi_npr.render_gbuffer(scene)
        np.save(data / f"Z_{w}x{h}.npy", gb["Z"])
        np.save(data / f"id_{w}x{h}.npy", gb["object_id.V"])
        ours = np.asarray(mi_npr.kernels.lines(gb, id_edges=True, crease_angle=0))
        anchor = opencv_lines(gb["Z"], gb["object_id.V"])
        agree[f"{w}x{h}"] = {
            "max_abs_diff": float(np.abs(ours - anchor).max()),
            "pixels_differing": int(np.count_nonzero(np.abs(ours - anchor) > 1e-5)),
            "line_pixels": int(np.count_nonzero(ours)),
        }
    return agree


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=15)
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--quick", action="store_true", help="640x480 only, 5 repeats")
    ap.add_argument("--out", type=Path, default=HERE / "results")
    ap.add_argument("--cold-child", nargs=4, help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.cold_child:
        case, data, w, h = args.cold_child
        _cold_child(case, data, int(w), int(h), args.threads)
        return 0

    sizes = SIZES[:1] if args.quick else SIZES
    repeat = 5 if args.quick else args.repeat
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        data = Path(tmp)
        agree = render_inputs(data, sizes)
        for w, h in sizes:
            res: dict = {"width": w, "height": h, "agreement": agree[f"{w}x{h}"]}
            warm = measure_warm(data, w, h, args.threads, repeat)
            for case in CASES:
                res[case] = {**warm[case], **measure_cold(case, data, w, h, args.threads)}
            for mode in ("warm_ms", "cold_ms"):
                res[f"ratio_{mode[:4]}_vs_opencv"] = res["mi_npr"][mode] / res["opencv"][mode]
            rows.append(res)
            print(f"\n{w}x{h}, {args.threads} threads (ms; ratio = mi_npr / opencv, < 1 is faster)")
            print(f"  {'case':<10}{'warm':>10}{'(min)':>10}{'cold':>10}{'peak +MB':>10}")
            for case in CASES:
                r = res[case]
                print(
                    f"  {case:<10}{r['warm_ms']:>10.2f}{r['warm_min_ms']:>10.2f}"
                    f"{r['cold_ms']:>10.1f}{r['peak_growth_mb']:>10.1f}"
                )
            print(
                f"  {'ratio':<10}{res['ratio_warm_vs_opencv']:>10.2f}{'':>10}"
                f"{res['ratio_cold_vs_opencv']:>10.2f}"
            )
            a = res["agreement"]
            print(
                f"  outputs agree: max |diff| {a['max_abs_diff']:.2g}, "
                f"{a['pixels_differing']} of {a['line_pixels']} line pixels differ"
            )
    targets = {"warm_ms_640x480": rows[0]["mi_npr"]["warm_ms"]}
    if len(rows) > 1:
        targets["ratio_warm_3840x2160"] = rows[1]["ratio_warm_vs_opencv"]
        targets["peak_mb_3840x2160"] = rows[1]["mi_npr"]["peak_growth_mb"]
    print("\ntargets:")
    for k, v in targets.items():
        verdict = "ok" if v <= TARGETS[k] else "MISSED"
        print(f"  {k:<24}{v:>10.2f}  (target <= {TARGETS[k]:g}) {verdict}")
    path = _common.write_report(
        "bench_kernels",
        args.out,
        scene=str(SCENE.relative_to(_common.ROOT)),
        chain="normalize -> selective dilation 3x3 -> eq. 5.1 (c=40, t=1) -> eq. 5.2 (t0=0.5) "
        "-> ID edges",
        threads=args.threads,
        repeat=repeat,
        targets={k: {"value": v, "target": TARGETS[k]} for k, v in targets.items()},
        results=rows,
    )
    print(f"\nwrote {path}")
    return 0


if __name__ == "__main__":
    sys.exit(main())

"""Cryptomatte 1.2: read back with a decoder written here from the specification (its own
MurmurHash3, checked on published test vectors), masks against the exact object ids where a
pixel is wholly one object, coverage summing to 1 where the scene covers a pixel, and the
film-filter splatting against a brute-force loop."""

from __future__ import annotations

import json
import os
import struct
import subprocess
import sys

import numpy as np
import OpenEXR
import pytest

import mi_npr
from mi_npr import cryptomatte as C
from mi_npr import layers as L
from mi_npr.io import read_exr

from .helpers import ROOT, SCENES, run_cli, scene_xml


# ----------------------------------------------------------------- the decoder, from the spec
def mm3(data: bytes, seed: int = 0) -> int:
    """MurmurHash3_x86_32 written from the reference C (blocks, tail, fmix32)."""

    def rotl(x: int, r: int) -> int:
        return ((x << r) | (x >> (32 - r))) & 0xFFFFFFFF

    h = seed
    nblocks = len(data) // 4
    for i in range(nblocks):
        k = int.from_bytes(data[4 * i : 4 * i + 4], "little")
        k = rotl((k * 0xCC9E2D51) & 0xFFFFFFFF, 15) * 0x1B873593 & 0xFFFFFFFF
        h = (rotl(h ^ k, 13) * 5 + 0xE6546B64) & 0xFFFFFFFF
    tail = data[4 * nblocks :]
    k = 0
    for j in reversed(range(len(tail))):  # the reference's switch falls through 3, 2, 1
        k ^= tail[j] << (8 * j)
    if tail:
        h ^= rotl((k * 0xCC9E2D51) & 0xFFFFFFFF, 15) * 0x1B873593 & 0xFFFFFFFF
    h ^= len(data)
    for shift, mul in ((16, 0x85EBCA6B), (13, 0xC2B2AE35)):
        h = ((h ^ (h >> shift)) * mul) & 0xFFFFFFFF
    return h ^ (h >> 16)


@pytest.mark.parametrize(
    ("data", "seed", "expected"),
    [
        (b"", 0, 0),
        (b"", 1, 0x514E28B7),
        (b"", 0xFFFFFFFF, 0x81F16F39),
        (b"\0\0\0\0", 0, 0x2362F9DE),
        (b"hello", 0, 0x248BFA47),
        (b"The quick brown fox jumps over the lazy dog", 0, 0x2E4FF723),
    ],
)
def test01_murmurhash3_test_vectors(data, seed, expected):
    assert mm3(data, seed) == expected
    assert C.murmurhash3_32(data, seed) == expected


def spec_id(name: str) -> float:
    """The specification's name -> float id (flip bit 23 of a 0 or 255 exponent)."""
    h = mm3(name.encode())
    if (h >> 23) & 0xFF in (0, 0xFF):
        h ^= 1 << 23
    return struct.unpack("<f", struct.pack("<I", h))[0]


def test02_ids_and_tails():
    names = ["", "a", "ab", "abc", "abcd", "ünï", *(f"obj{i}" for i in range(200))]
    for n in names:
        assert C.murmurhash3_32(n) == mm3(n.encode())
        f = np.float32(C.name_id(n))
        assert f.view(np.uint32) == np.float32(spec_id(n)).view(np.uint32)
        assert np.isfinite(f) and (f == 0 or abs(f) >= np.finfo(np.float32).tiny)
    # a name whose hash has exponent 255 (a NaN as raw bits) gets a normal float id
    special = next(f"n{i}" for i in range(100000) if (mm3(f"n{i}".encode()) >> 23) & 0xFF == 255)
    assert np.isfinite(C.name_id(special))


def decode(path) -> tuple[dict, dict]:
    """{layer name: (manifest {name: float id}, ranks [(id, coverage) (H, W) arrays])}."""
    with OpenEXR.File(str(path), separate_channels=True) as f:
        header = dict(f.header())
        chans = {k: np.array(v.pixels) for k, v in f.channels().items()}
    out = {}
    for key, value in header.items():
        if not (key.startswith("cryptomatte/") and key.endswith("/name")):
            continue
        prefix = key[: -len("name")]
        layer_key = key.split("/")[1]
        assert layer_key == f"{mm3(value.encode()):08x}"[:7]  # the key is the name's hash
        assert header[prefix + "hash"] == "MurmurHash3_32"
        assert header[prefix + "conversion"] == "uint32_to_float32"
        manifest = {
            n: struct.unpack(">f", bytes.fromhex(h))[0]
            for n, h in json.loads(header[prefix + "manifest"]).items()
        }
        for n, v in manifest.items():
            assert np.float32(v).view(np.uint32) == np.float32(spec_id(n)).view(np.uint32)
        ranks = []
        i = 0
        while f"{value}{i:02d}.R" in chans:
            base = f"{value}{i:02d}."
            ranks.append((chans[base + "R"], chans[base + "G"]))
            ranks.append((chans[base + "B"], chans[base + "A"]))
            i += 1
        out[value] = (manifest, ranks)
    return out, chans


def matte(ranks, id_value: float) -> np.ndarray:
    m = np.zeros(ranks[0][0].shape, np.float64)
    for ids, cov in ranks:
        m += np.where(ids.view(np.uint32) == np.float32(id_value).view(np.uint32), cov, 0.0)
    return m


SPHERES = """
    <bsdf type="diffuse" id="red"><rgb name="reflectance" value="0.8, 0.1, 0.1"/></bsdf>
    <shape type="sphere" id="left"><point name="center" x="-0.7" y="0" z="4"/>
        <float name="radius" value="0.6"/><ref id="red"/></shape>
    <shape type="sphere" id="right"><point name="center" x="0.7" y="0.1" z="4"/>
        <float name="radius" value="0.6"/><ref id="red"/></shape>
    <shape type="sphere" id="small"><point name="center" x="0" y="-0.6" z="3"/>
        <float name="radius" value="0.25"/></shape>
    <shape type="rectangle" id="wall"><transform name="to_world"><scale value="1.2"/>
        <translate x="0" y="0.9" z="6"/></transform></shape>
"""


@pytest.fixture(scope="module", params=["gaussian", "box"])
def written(request, tmp_path_factory):
    d = tmp_path_factory.mktemp("crypto")
    xml = d / "s.xml"
    xml.write_text(scene_xml(SPHERES, width=48, height=36, spp=8, rfilter=request.param))
    r = run_cli("render", str(xml), "-o", str(d), "--cryptomatte", "--no-progress")
    assert r.returncode == 0, r.stderr
    gb = mi_npr.io.read_exr(d / "s.exr")
    return gb, decode(d / "s.exr"), request.param


def test03_layers_metadata_and_manifest(written):
    gb, (crypto, _), _ = written
    assert set(crypto) == {"CryptoObject", "CryptoMaterial"}
    manifest, ranks = crypto["CryptoObject"]
    assert set(manifest) == set(gb.objects.values())
    assert len(ranks) == 6
    mats, _ = crypto["CryptoMaterial"]
    # shared referenced BSDF -> one material; unnamed nested ones named after their shape
    assert set(mats) == {"red", "small.bsdf", "wall.bsdf"}
    assert L.meaning("CryptoObject01.A") == "Cryptomatte CryptoObject: coverage of rank 3"
    assert L.meaning("CryptoMaterial00.B").endswith("id (name hash as float) of rank 1")
    assert L.meaning("CryptoObjectXY.R") == ""


def test04_masks_match_exact_ids_where_a_pixel_is_one_object(written):
    gb, (crypto, _), rfilter = written
    manifest, ranks = crypto["CryptoObject"]
    ids = gb.numpy(L.OBJECT_ID).astype(np.int64)
    r = 3 if rfilter == "gaussian" else 1  # reach of the filter, plus a pixel for thin parts
    pad = np.pad(ids, r, mode="edge")
    h, w = ids.shape
    window = np.stack(
        [pad[dy : dy + h, dx : dx + w] for dy in range(2 * r + 1) for dx in range(2 * r + 1)]
    )
    pure = np.all(window == ids, axis=0)
    assert pure.sum() > 0.3 * ids.size
    fractional = 0
    for oid, name in gb.objects.items():
        m = matte(ranks, manifest[name])
        inside = pure & (ids == oid)
        outside = pure & (ids != oid)
        assert inside.any(), name
        np.testing.assert_allclose(m[inside], 1.0, atol=1e-6)
        np.testing.assert_allclose(m[outside], 0.0, atol=1e-6)
        fractional += int(((m > 0.02) & (m < 0.98)).sum())
    assert fractional > 20  # anti-aliased edges, not pixel-centre ids


def test05_coverage_sums_to_one_where_covered_and_is_ranked(written):
    gb, (crypto, _), _ = written
    for layer in ("CryptoObject", "CryptoMaterial"):
        _, ranks = crypto[layer]
        covs = np.stack([c for _, c in ranks]).astype(np.float64)
        assert np.all(covs >= 0) and np.all(np.diff(covs, axis=0) <= 1e-7)  # sorted
        total = covs.sum(axis=0)
        assert total.max() <= 1 + 1e-5
        ids = gb.numpy(L.OBJECT_ID)
        pad = np.pad(ids, 3, mode="edge")
        h, w = ids.shape
        covered = np.ones_like(ids, bool)
        for dy in range(7):
            for dx in range(7):
                covered &= pad[dy : dy + h, dx : dx + w] > 0
        np.testing.assert_allclose(total[covered], 1.0, atol=1e-5)
        assert np.all(total[ids == 0] < 1.0 - 1e-3) or not (ids == 0).any()


# ----------------------------------------------------------------- splatting vs brute force
def brute_coverage(xs, ys, ids, n, w, h, f, radius):
    acc = np.zeros((h, w, n + 1))
    for x, y, i in zip(xs, ys, ids, strict=True):
        for qy in range(h):
            for qx in range(w):
                dx, dy = x - (qx + 0.5), y - (qy + 0.5)
                if abs(dx) < radius and abs(dy) < radius:
                    acc[qy, qx, i] += max(f(dx), 0.0) * max(f(dy), 0.0)
    tot = acc.sum(axis=2, keepdims=True)
    return np.divide(acc, tot, out=np.zeros_like(acc), where=tot > 0).reshape(h * w, n + 1)


def random_samples(kind: str, w: int, h: int, spp: int, n: int, seed: int):
    """A reconstruction filter ``kind``, its weight as a Python function, and ``spp`` random
    samples in every pixel of a ``w x h`` film with random ids 0..n."""
    import mitsuba as mi

    rf = mi.load_dict({"type": kind})
    rng = np.random.default_rng(seed)
    pix = np.repeat(np.arange(w * h), spp)
    xs = (pix % w) + rng.random(pix.size)
    ys = (pix // w) + rng.random(pix.size)
    ids = rng.integers(0, n + 1, size=pix.size)

    def f(d):
        return float(np.asarray(rf.eval(mi.Float(np.float32(d)))).ravel()[0])

    return rf, f, xs, ys, ids


@pytest.mark.parametrize("kind", ["box", "gaussian", "tent"])
@pytest.mark.parametrize(("w", "h"), [(1, 1), (5, 3)])
def test06_splatting_against_a_brute_force_loop(kind, w, h):
    n = 3
    rf, f, xs, ys, ids = random_samples(kind, w, h, 5, n, 7)
    ref = brute_coverage(xs, ys, ids, n, w, h, f, rf.radius())
    got = C.coverage(xs.astype(np.float32), ys.astype(np.float32), ids, n, w, h, rf)
    np.testing.assert_allclose(got, ref, atol=2e-6)
    np.testing.assert_allclose(got.sum(axis=1), 1.0, atol=1e-6)


@pytest.mark.parametrize("kind", ["box", "gaussian"])
@pytest.mark.parametrize(("w", "h", "first", "rows"), [(5, 7, 2, 3), (4, 6, 0, 1), (3, 5, 4, 1)])
def test06b_a_band_of_rows_against_the_brute_force_loop(kind, w, h, first, rows):
    """One band of rows (``first`` to ``first + rows``) from samples of every row, some on
    the far side of its edges: the brute force's rows, and only the nonzero cells kept."""
    import mitsuba as mi

    n = 3
    rf, f, xs, ys, ids = random_samples(kind, w, h, 4, n, 11)
    ref = brute_coverage(xs, ys, ids, n, w, h, f, rf.radius())[first * w : (first + rows) * w]
    acc = mi.Float(np.zeros(rows * w * (n + 1), np.float32))
    C._accumulate(acc, xs.astype(np.float32), ys.astype(np.float32), ids, n, w, rows, rf, first)
    pixel, col, share = C._shares(acc, first * w, rows * w, n)
    assert np.all(share > 0) and np.all(pixel >= first * w)
    got = np.zeros_like(ref)
    got[pixel - first * w, col] = share
    np.testing.assert_allclose(got, ref, atol=2e-6)


@pytest.mark.parametrize("kind", ["box", "gaussian", "tent"])
@pytest.mark.parametrize(("group", "shuffle"), [(4, False), (3, False), (4, True), (7, False)])
def test06d_grouped_samples_against_the_brute_force_loop(kind, group, shuffle):
    """Samples taken ``group`` at a time (a pixel's, summed in one thread, as the render
    passes them): the brute force's coverage whether the groups are a pixel's samples (4 per
    pixel), straddle pixels (3, 7: groups that do not divide the samples either), or are
    shuffled (almost every sample on its own), on a 5 x 3 film and a band of it."""
    import mitsuba as mi

    n, w, h = 3, 5, 3
    rf, f, xs, ys, ids = random_samples(kind, w, h, 4, n, 13)
    ids[::4] = 2  # most pixels' first sample and some others share an id
    ids[1::4] = 2
    if shuffle:
        order = np.random.default_rng(5).permutation(len(xs))
        xs, ys, ids = xs[order], ys[order], ids[order]
    ref = brute_coverage(xs, ys, ids, n, w, h, f, rf.radius())
    for first, rows in ((0, h), (1, 1)):
        acc = mi.Float(np.zeros(rows * w * (n + 1), np.float32))
        C._accumulate(
            acc, xs.astype(np.float32), ys.astype(np.float32), ids, n, w, rows, rf, first, group
        )
        pixel, col, share = C._shares(acc, first * w, rows * w, n)
        got = np.zeros((rows * w, n + 1))
        got[pixel - first * w, col] = share
        # float32 positions and sums against float64: a few ulps of the shares
        np.testing.assert_allclose(got, ref[first * w : (first + rows) * w], atol=5e-6)


def test06c_bands_estimate_the_same_coverage(monkeypatch):
    """The film ranked in bands of 4 rows (each from its own samples and its neighbours'
    edge rows) agrees with one band: the same top id wherever one band is certain, every
    covered pixel's coverage summing to 1 across the bands' edges, within the noise of 64
    samples elsewhere."""
    scene = mi_npr.load_scene(SCENES / "scene1.xml", width=48, height=36)
    one, _ = C.cryptomatte(scene, spp=64, seed=3)
    n = len(mi_npr.object_table(scene).names)
    monkeypatch.setattr(C, "BAND_CELLS", 48 * (n + 1) * 4)
    banded, _ = C.cryptomatte(scene, spp=64, seed=3)
    assert one.keys() == banded.keys()
    sure = one["CryptoObject00.G"] == 1.0
    assert sure.mean() > 0.5
    np.testing.assert_array_equal(one["CryptoObject00.R"][sure], banded["CryptoObject00.R"][sure])
    ranks = [f"CryptoObject0{i}.{c}" for i in range(3) for c in "GA"]
    totals = [sum(x[r] for r in ranks) for x in (one, banded)]
    covered = np.abs(totals[0] - 1.0) < 1e-6  # the scene covers every sample reaching these
    assert covered.mean() > 0.9
    np.testing.assert_allclose(totals[1][covered], 1.0, atol=1e-6)
    assert np.abs(one["CryptoObject00.G"] - banded["CryptoObject00.G"]).max() < 0.35
    assert not np.array_equal(one["CryptoObject00.G"], banded["CryptoObject00.G"])


# ----------------------------------------------------------------- the integrator parameter
def test07_integrator_parameter(write_scene):
    import mitsuba as mi

    path = write_scene(
        SPHERES,
        integrator='<integrator type="npr_gbuffer"><boolean name="cryptomatte" value="true"/>'
        "</integrator>",
        width=16,
        height=12,
    )
    scene = mi_npr.load_scene(path)
    names = scene.integrator().aov_names()
    assert names[-24:] == C.aov_names() and names[-24] == "CryptoObject00.R"
    img = np.asarray(mi.render(scene))
    assert img.shape == (12, 16, 3 + len(names))
    gb = mi_npr.render(path)
    for name in C.aov_names():
        np.testing.assert_array_equal(img[..., 3 + names.index(name)], gb.numpy(name))
    assert any(k.startswith("cryptomatte/") for k in gb.metadata)
    with pytest.raises(mi_npr.SceneError, match="cryptomatte"):
        mi_npr.load_scene(
            write_scene(
                SPHERES,
                name="bad.xml",
                integrator='<integrator type="npr_gbuffer"><string name="cryptomatte" '
                'value="maybe"/></integrator>',
            )
        )


def test08_bad_levels_is_a_clear_error(write_scene):
    scene = mi_npr.load_scene(write_scene(SPHERES))
    with pytest.raises(mi_npr.ParameterError, match="levels"):
        C.cryptomatte(scene, levels=0)


CRYPTO_LIMITED = """\
import resource, sys
limit = int(sys.argv[1])
resource.setrlimit(resource.RLIMIT_AS, (limit, limit))
from mi_npr.cli import main
sys.exit(main(sys.argv[2:]))
"""


def test10_samples_in_passes_under_an_address_space_limit(tmp_path):
    """Twenty million coverage samples (320 x 240 at 256 spp) under a 2 GiB address-space limit:
    cast in passes of about a million, the render finishes (at once, they took more than 1 GB
    and the process died of SIGSEGV under this limit)."""
    scene = tmp_path / "ball.xml"
    body = '<shape type="sphere" id="ball"><point name="center" x="0" y="0" z="4"/></shape>'
    scene.write_text(scene_xml(body, width=320, height=240, spp=256))
    argv = ["render", str(scene), "-o", str(tmp_path / "o"), "--cryptomatte", "--no-progress"]
    env = {**os.environ, "MI_NPR_VARIANT": "llvm_ad_rgb"}  # CUDA's driver maps more than this
    r = subprocess.run(
        [sys.executable, "-c", CRYPTO_LIMITED, str(2 << 30), *argv],
        env=env, capture_output=True, text=True, cwd=ROOT, timeout=300, check=False,
    )  # fmt: skip
    assert r.returncode == 0, (r.returncode, r.stderr[-2000:])
    gb = read_exr(tmp_path / "o" / "ball.exr")
    cov = gb.numpy("CryptoObject00.G")
    assert cov.max() == pytest.approx(1.0) and (cov > 0).any()


def test11_passes_estimate_the_same_coverage(monkeypatch):
    """Coverage from passes of a few samples per pixel (other random numbers, the same
    estimator) agrees with one pass: the same top id everywhere it is certain, and coverage
    within the noise of 64 samples elsewhere."""
    scene = mi_npr.load_scene(SCENES / "scene1.xml", width=48, height=36)
    one, _ = C.cryptomatte(scene, spp=64, seed=3)
    monkeypatch.setattr(C, "SAMPLES_PER_PASS", 48 * 36 * 5)  # 13 passes of <= 5 spp
    many, _ = C.cryptomatte(scene, spp=64, seed=3)
    sure = one["CryptoObject00.G"] == 1.0
    assert sure.mean() > 0.5
    np.testing.assert_array_equal(one["CryptoObject00.R"][sure], many["CryptoObject00.R"][sure])
    assert np.abs(one["CryptoObject00.G"] - many["CryptoObject00.G"]).max() < 0.35
    assert not np.array_equal(one["CryptoObject00.G"], many["CryptoObject00.G"])


def test12_too_many_names_is_refused_before_the_render(tmp_path, monkeypatch):
    monkeypatch.setattr(C, "_MAX_CELLS", 10)
    calls = []
    render_module = sys.modules["mi_npr.render"]  # mi_npr.render is also the function
    monkeypatch.setattr(render_module, "gbuffer_layers", lambda *a, **k: calls.append(1))
    with pytest.raises(mi_npr.ParameterError, match="too many to rank"):
        mi_npr.render_layers(SCENES / "scene1.xml", ["cryptomatte"], resolution=(16, 12), spp=1)
    assert not calls


def test13_coverage_refuses_a_dense_table_past_the_bound(monkeypatch):
    """:func:`coverage` holds the whole (pixels x names) table at once: past ``_MAX_CELLS``
    it is a clear error before anything is allocated (the banded render holds a row)."""
    import mitsuba as mi

    monkeypatch.setattr(C, "_MAX_CELLS", 5 * 3 * 4 - 1)
    xs = ys = np.full(1, 0.5, np.float32)
    with pytest.raises(mi_npr.ParameterError, match="5x3 pixels x 4 names is too many"):
        C.coverage(xs, ys, np.zeros(1, np.uint32), 3, 5, 3, mi.load_dict({"type": "box"}))
    monkeypatch.setattr(C, "_MAX_CELLS", 5 * 3 * 4)
    assert C.coverage(
        xs, ys, np.zeros(1, np.uint32), 3, 5, 3, mi.load_dict({"type": "box"})
    ).shape == (15, 4)

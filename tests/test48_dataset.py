"""``mi-npr dataset`` (:mod:`mi_npr.dataset`): meshes written here (an off-centre box as PLY, a
tetrahedron as OBJ text, a sphere as STL) rendered from random views; the files of every view,
the manifest rows, the normalisation against the closed-form framing distance, bad meshes
reported and skipped, resume, and the random views' seed."""

from __future__ import annotations

import json
import math
import os

import mitsuba as mi
import numpy as np
import pytest

from mi_npr import dataset as D
from mi_npr import views as V
from mi_npr.errors import InputError, ParameterError
from mi_npr.io import read_exr
from mi_npr.meshes import box, uv_sphere, write_ply

from .helpers import run_cli

#: The box: sides 2, 1, 3 centred at (5, -2, 7); normalised, its corners lie on the unit sphere.
SIZE, CENTRE = (2.0, 1.0, 3.0), (5.0, -2.0, 7.0)
TET = "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nf 1 3 2\nf 1 2 4\nf 1 4 3\nf 2 3 4\n"
PX = 48
#: Distance from which a 40 degree camera sees the unit sphere with the 10% margin, written out.
DISTANCE = 1.1 / math.sin(math.radians(20.0))
KINDS = ("exr", "png", "lines.png", "lines.svg", "strokes.svg", "strokes.json")


def _meshes(folder):
    folder.mkdir()
    write_ply(folder / "box.ply", *box(SIZE, CENTRE))
    (folder / "tet.obj").write_text(TET)
    trimesh = pytest.importorskip("trimesh")
    V_, F_ = uv_sphere(12, 8)
    trimesh.Trimesh(V_, F_).export(folder / "ball.stl")
    trimesh.Trimesh(*box((1.0, 2.0, 3.0))).export(folder / "brick.glb")
    bad = folder / "bad"
    bad.mkdir()
    write_ply(bad / "nofaces.ply", *box()[:1], np.zeros((0, 3), np.uint32))
    (bad / "nan.obj").write_text("v 0 0 0\nv 1 0 0\nv nan 1 0\nf 1 2 3\n")
    (bad / "garbage.ply").write_bytes(b"this is no mesh\x00\x01")
    (bad / "empty.obj").write_text("")
    (bad / "scenes.obj").write_text(TET)  # a good mesh whose outputs would mix with OUT/scenes
    return folder


@pytest.fixture(scope="module")
def made(tmp_path_factory):
    root = tmp_path_factory.mktemp("dataset")
    meshes = _meshes(root / "meshes")
    out = root / "out"
    rows = D.make_dataset(
        [meshes], out, "random:2", seed=3, width=PX, height=PX, spp=1, workers=0, progress=False
    )
    return out, rows


def _views(rows, stem):
    return [r for r in rows if r["view"] is not None and r["mesh"].endswith(stem)]


def test01_every_view_has_its_files_and_manifest_row(made):
    out, rows = made
    good = [r for r in rows if r["view"] is not None]
    assert len(good) == 4 * 2
    assert {r["status"] for r in good} == {"done"}
    for r in good:
        for kind in KINDS:
            assert (out / r["files"][kind]).is_file(), (r["mesh"], kind)
        assert set(r["camera"]) >= {"origin", "target", "up", "fov"}
        assert (out / r["scene"]).is_file()
    assert {r["triangles"] for r in _views(rows, "box.ply")} == {12}
    assert {r["triangles"] for r in _views(rows, "tet.obj")} == {4}
    assert (out / "meshes" / "ball.ply").is_file()  # the STL and the GLB, converted
    assert {r["triangles"] for r in _views(rows, "brick.glb")} == {12}
    assert _views(rows, "brick.glb")[0]["normalisation"]["scale"] == pytest.approx(
        1 / math.sqrt(0.25 + 1 + 2.25)
    )
    on_disk = [json.loads(line) for line in (out / D.INDEX).read_text().splitlines()]
    assert on_disk == rows


def test02_normalised_box_is_framed_at_the_closed_form_distance(made):
    out, rows = made
    s = np.array(SIZE) / 2
    corners = np.array([[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)]) * s
    corners /= np.linalg.norm(s)  # the unit bounding sphere
    pixel = 2 * DISTANCE * math.tan(math.radians(20.0)) / PX  # a pixel's width at the centre
    for r in _views(rows, "box.ply"):
        origin = np.array(r["camera"]["origin"])
        assert np.linalg.norm(origin) == pytest.approx(DISTANCE, rel=1e-5)
        assert np.allclose(r["camera"]["target"], 0.0, atol=1e-6)
        d = origin / np.linalg.norm(origin)
        gb = read_exr(out / r["files"]["exr"])
        z = gb.numpy("Z")
        ids = gb.numpy("object_id.V")
        hit = np.isfinite(z)
        assert np.array_equal(hit, ids > 0)
        # the nearest point of a convex box is its corner nearest the camera, depth D - max(v.d)
        nearest = DISTANCE - float(np.max(corners @ d))
        assert nearest - 1e-4 <= z[hit].min() <= nearest + 2 * pixel
        assert z[hit].max() <= DISTANCE + 1.0
        border = np.concatenate([ids[0], ids[-1], ids[:, 0], ids[:, -1]])
        assert not border.any()  # the unit sphere fits the image, so does the box


def test03_bad_meshes_are_rows_with_their_reason(made):
    _, rows = made
    skipped = {r["mesh"].rsplit("/", 1)[-1]: r for r in rows if r["status"] == "skipped"}
    assert set(skipped) == {"nofaces.ply", "nan.obj", "garbage.ply", "empty.obj", "scenes.obj"}
    assert "rename" in skipped["scenes.obj"]["error"]
    assert "0 faces" in skipped["nofaces.ply"]["error"]
    assert "NaN" in skipped["nan.obj"]["error"]
    assert "unreadable" in skipped["garbage.ply"]["error"]
    assert "no vertices" in skipped["empty.obj"]["error"]
    for name, r in skipped.items():
        assert r["view"] is None and name in r["error"]


def test04_resume_skips_the_views_done(made, tmp_path):
    out, rows = made
    log = (out / "manifest.jsonl").read_text()
    times = {p: p.stat().st_mtime_ns for p in out.rglob("*.exr")}
    again = D.make_dataset(
        [out.parent / "meshes"],
        out,
        "random:2",
        seed=3,
        width=PX,
        height=PX,
        spp=1,
        workers=0,
        resume=True,
        progress=False,
    )
    assert (out / "manifest.jsonl").read_text() == log  # no job ran
    assert {p: p.stat().st_mtime_ns for p in out.rglob("*.exr")} == times
    assert again == rows


def test05_random_views_follow_their_seed(made):
    _, rows = made
    origins = np.array([r["camera"]["origin"] for r in _views(rows, "tet.obj")])
    # uniform directions by the seed: normalised standard normals of PCG64(3), drawn here
    rng = np.random.Generator(np.random.PCG64(3))
    g = rng.standard_normal((2, 3))
    assert np.allclose(origins / DISTANCE, g / np.linalg.norm(g, axis=1, keepdims=True), atol=1e-6)
    assert np.array_equal(V.random_directions(5, 3), V.random_directions(5, 3))
    assert not np.allclose(V.random_directions(5, 3), V.random_directions(5, 4))
    assert V.parse_views("random:4:9").option == "9"
    with pytest.raises(ParameterError, match="random:4:x"):
        V.parse_views("random:4:x")


def test06_inputs_refused_in_one_line(tmp_path):
    with pytest.raises(InputError, match="no such file"):
        D.make_dataset([tmp_path / "nothing.obj"], tmp_path / "o", workers=0)
    with pytest.raises(InputError, match="matches no file"):
        D.make_dataset([str(tmp_path / "*.stl")], tmp_path / "o", workers=0)
    (tmp_path / "a").mkdir()
    (tmp_path / "b").mkdir()
    (tmp_path / "a" / "m.obj").write_text(TET)
    (tmp_path / "b" / "m.obj").write_text(TET)
    with pytest.raises(ParameterError, match="'m'"):
        D.make_dataset([tmp_path / "a", tmp_path / "b"], tmp_path / "o", workers=0)


def test07_command(tmp_path):
    (tmp_path / "tet.obj").write_text(TET)
    (tmp_path / "bad.obj").write_text("v 0 0 0\n")
    out = tmp_path / "out"
    r = run_cli(
        "dataset",
        str(tmp_path / "*.obj"),
        "-o",
        str(out),
        "--views",
        "sphere:2",
        "--width",
        "24",
        "--height",
        "24",
        "--spp",
        "1",
        "--lines",
        "--workers",
        "0",
        "--no-progress",
    )
    assert r.returncode == 0, r.stderr
    assert "2 of 2 views done, 1 meshes skipped" in r.stdout
    assert "bad.obj: 0 faces" in r.stderr
    rows = [json.loads(line) for line in (out / D.INDEX).read_text().splitlines()]
    done = [x for x in rows if x["status"] == "done"]
    assert [x["view"] for x in done] == ["sphere_000", "sphere_001"]
    assert "strokes.json" not in done[0]["files"] and "lines.png" in done[0]["files"]
    r = run_cli("dataset", str(tmp_path / "tet.obj"), "-o", str(out), "--views", "best:x")
    assert r.returncode == 1 and r.stderr.count("\n") == 1 and "best:x" in r.stderr


def test08_parquet_rows_are_the_manifest_rows(made):
    pq = pytest.importorskip("pyarrow.parquet")
    out, rows = made
    table = pq.read_table(out / D.PARQUET)
    assert table.column("view").to_pylist() == [r["view"] for r in rows]
    files = [None if f is None else json.loads(f) for f in table.column("files").to_pylist()]
    assert files == [r.get("files") for r in rows]


def test09_local_cluster(tmp_path):
    (tmp_path / "tet.obj").write_text(TET)
    rows = D.make_dataset(
        [tmp_path / "tet.obj"],
        tmp_path / "out",
        "orbit:2",
        drawings=("lines",),
        width=24,
        height=24,
        spp=1,
        workers=1,
        threads_per_worker=1,
        progress=False,
    )
    assert [(r["view"], r["status"]) for r in rows] == [
        ("orbit_000", "done"),
        ("orbit_001", "done"),
    ]
    assert all((tmp_path / "out" / r["files"]["lines.png"]).is_file() for r in rows)


def test10_out_inside_the_folder_searched(tmp_path):
    trimesh = pytest.importorskip("trimesh")
    trimesh.Trimesh(*box()).export(tmp_path / "cube.stl")
    kw = {"width": 16, "height": 16, "spp": 1, "workers": 0, "progress": False}
    first = D.make_dataset([tmp_path], tmp_path / "out", "orbit:1", drawings=("lines",), **kw)
    assert (tmp_path / "out" / "meshes" / "cube.ply").is_file()
    # OUT/meshes/cube.ply is no input: no clash of stems, the same one mesh again
    again = D.make_dataset([tmp_path], tmp_path / "out", "orbit:1", drawings=("lines",), **kw)
    assert [r["mesh"] for r in again] == [r["mesh"] for r in first] == [str(tmp_path / "cube.stl")]


# -- many views in one launch -------------------------------------------------------------


def _sensors(scene_path, spec, res):
    from mi_npr.camera import sensor_for
    from mi_npr.session import SceneSession

    s = SceneSession.open(scene_path, resolution=res)
    return s, [
        sensor_for(c, s.sensor) for _, c in V.cameras(V.parse_views(spec), s.scene, s.sensor)
    ]


#: Dr.Jit's LLVM kernels give the same bits for a view alone or among others; CUDA's compiler
#: may contract a multiply-add differently in the two kernels (the last bit of a float).
EXACT = mi.variant().startswith("llvm")


def _same(a: np.ndarray, b: np.ndarray, name: str) -> None:
    if EXACT or not np.issubdtype(a.dtype, np.floating):
        assert a.dtype == b.dtype and a.tobytes() == b.tobytes(), name
    else:
        assert a.dtype == b.dtype, name
        np.testing.assert_allclose(a, b, rtol=1e-5, atol=1e-6, err_msg=name)


@pytest.mark.parametrize(
    ("scene", "spec", "res"),
    [
        ("scenes_xml/scene1.xml", "orbit:3", (40, 30)),
        ("scenes_xml/scene2.xml", "sphere:4", (33, 17)),
    ],
)
def test11_views_in_one_launch_equal_the_views_one_by_one(scene, spec, res):
    """Every layer of every view of :func:`render_views` is bit for bit the layer of the pass
    of that view alone (the reference: ``render_gbuffer`` on the view's own sensor)."""
    from mi_npr.render import render_gbuffer, render_views
    from mi_npr.session import SceneSession

    s, sensors = _sensors(scene, spec, res)
    many = render_views(s, sensors)
    assert len(many) == len(sensors)
    for gb, sensor in zip(many, sensors, strict=True):
        one = render_gbuffer(SceneSession(s.scene, sensor, s.source))
        assert gb.names == one.names and gb.objects == one.objects
        assert gb.metadata == one.metadata and gb.camera == one.camera
        for name in one.names:
            _same(gb.numpy(name), one.numpy(name), name)
        assert (one.object_id > 0).any()  # the views see something


def test12_views_in_one_launch_with_the_beauty():
    from mi_npr.render import render_gbuffer, render_views
    from mi_npr.session import SceneSession

    s, sensors = _sensors("scenes_xml/scene1.xml", "orbit:2", (24, 16))
    integrator = s.scene.integrator()
    many = render_views(s, sensors, integrator, spp=2, seed=5)
    lit = False
    for gb, sensor in zip(many, sensors, strict=True):
        one = render_gbuffer(
            SceneSession(s.scene, sensor, s.source), beauty=integrator, spp=2, seed=5
        )
        for name in one.names:
            a, b = gb.numpy(name), one.numpy(name)
            if name in ("R", "G", "B"):  # Mitsuba's own render: its film adds samples in the
                # order its threads take them, so two renders differ in the last bits
                assert np.allclose(a, b, rtol=1e-5, atol=1e-6), name
                lit = lit or bool(np.abs(a).max() > 0)
            else:
                assert a.tobytes() == b.tobytes(), name
        assert gb.metadata["mi_npr/beauty"] != "headlight"
    assert lit  # a beauty, not black


def test13_views_that_differ_by_more_than_their_pose_are_refused():
    from mi_npr.camera import Camera, sensor_for
    from mi_npr.render import render_views

    s, sensors = _sensors("scenes_xml/scene1.xml", "orbit:2", (24, 16))
    cam = Camera((0.0, 1.0, 5.0), (0.0, 0.0, 0.0), (0.0, 1.0, 0.0), 30.0)  # another fov
    with pytest.raises(ParameterError, match="one film size, field of view"):
        render_views(s, [*sensors, sensor_for(cam, s.sensor)])
    assert render_views(s, []) == []


def test14_dataset_files_do_not_depend_on_views_per_launch(tmp_path):
    """One view per launch and three: the same files, byte for byte except the EXR's
    compression of equal layers (compared layer by layer), and the same manifest rows."""
    meshes = tmp_path / "m"
    meshes.mkdir()
    write_ply(meshes / "box.ply", *box(SIZE, CENTRE))
    (meshes / "tet.obj").write_text(TET)
    kw = {"width": 32, "height": 24, "workers": 0, "progress": False, "drawings": ("lines",)}
    runs = {
        k: D.make_dataset(
            [meshes], tmp_path / f"k{k}", "random:4", seed=1, views_per_launch=k, **kw
        )
        for k in (1, 3)
    }
    strip = ("job", "seconds", "finished", "worker")
    for a, b in zip(runs[1], runs[3], strict=True):
        assert {k: v for k, v in a.items() if k not in strip} == {
            k: v for k, v in b.items() if k not in strip
        }
        assert a["status"] == "done" and set(a["files"]) >= {"exr", "png", "lines.png", "lines.svg"}
        for kind, name in a["files"].items():
            one, three = tmp_path / "k1" / name, tmp_path / "k3" / b["files"][kind]
            if kind == "exr":
                g1, g3 = read_exr(one), read_exr(three)
                assert g1.names == g3.names
                for layer in g1.names:
                    _same(g1.numpy(layer), g3.numpy(layer), layer)
                assert g1.metadata["mi_npr/beauty"] == "headlight"  # no beauty unless asked
            elif EXACT:  # the SVG's title names its scene, in its own OUT
                here = str(tmp_path / "k3").encode()
                assert one.read_bytes().replace(str(tmp_path / "k1").encode(), here) == (
                    three.read_bytes()
                ), kind


#: The tetrahedron with a fin: a fifth triangle on the edge from (1, 0, 0) to (0, 1, 0), which
#: two of the tetrahedron's faces share already: one edge of three triangles.
FIN = TET + "v 1 1 1\nf 2 3 5\n"


@pytest.mark.parametrize("rule", ["warn", "skip"])
def test15_non_manifold_meshes_warn_or_skip(tmp_path, made, rule):
    (tmp_path / "fin.obj").write_text(FIN)
    (tmp_path / "tet.obj").write_text(TET)
    kw = {"width": 16, "height": 16, "workers": 0, "progress": False, "drawings": ("lines",)}
    rows = D.make_dataset([tmp_path], tmp_path / "out", "orbit:2", non_manifold=rule, **kw)
    fin = [r for r in rows if r["mesh"].endswith("fin.obj")]
    tet = [r for r in rows if r["mesh"].endswith("tet.obj")]
    why = "fin.obj: non-manifold: 1 edge shared by more than two triangles"
    assert [r["status"] for r in tet] == ["done", "done"]
    assert all(r["warning"] is None for r in tet)
    if rule == "warn":  # rendered, every row says so
        assert [(r["status"], r["warning"].endswith(why)) for r in fin] == [("done", True)] * 2
    else:
        assert [(r["status"], r["view"]) for r in fin] == [("skipped", None)]
        assert fin[0]["error"].endswith(why)
    _, fixture = made  # closed meshes, an STL's repeated corners among them: no warning
    assert all(r.get("warning") is None for r in fixture if r["status"] == "done")
    with pytest.raises(ParameterError, match="non_manifold"):
        D.make_dataset([tmp_path / "tet.obj"], tmp_path / "o", non_manifold="drop", **kw)


def _rss_mb() -> float:
    for line in open("/proc/self/status"):
        if line.startswith("VmRSS:"):
            return int(line.split()[1]) / 1024
    raise AssertionError("no VmRSS in /proc/self/status")


@pytest.mark.skipif(not os.path.exists("/proc/self/status"), reason="reads Linux's /proc")
def test16_memory_and_kernels_stay_flat_over_many_jobs(tmp_path):
    """120 jobs in this process: 10 meshes of different sizes, 12 views each. From the fourth
    mesh on, the resident set grows by less than 10% (the caches are bounded: scenes, the launch
    of views, Dr.Jit's kernels) and almost no kernel is new: a kernel that baked in a view's or
    a mesh's values (a literal camera axis did) is a kernel of its own for every one of them,
    kept in Dr.Jit's cache for good."""
    import drjit as dr

    from mi_npr import batch

    kw = {"width": 16, "height": 16, "workers": 0, "progress": False, "drawings": ("lines",)}
    rss, new_kernels, seen = [], [], set()
    dr.set_flag(dr.JitFlag.KernelHistory, True)
    try:
        for m in range(10):
            folder = tmp_path / f"m{m}"
            folder.mkdir()
            V_, F_ = uv_sphere(6 + 3 * m, 4 + 2 * m)
            write_ply(folder / f"mesh{m}.ply", V_ * (1.0 + 0.2 * m), F_)
            dr.kernel_history()  # clears it
            rows = D.make_dataset([folder], tmp_path / "out", "random:12", seed=m, **kw)
            assert [r["status"] for r in rows] == ["done"] * 12
            hashes = {str(k["hash"]) for k in dr.kernel_history() if "hash" in k}
            new_kernels.append(len(hashes - seen))  # in memory or on disk, a kernel of its own
            seen |= hashes
            rss.append(_rss_mb())
    finally:
        dr.set_flag(dr.JitFlag.KernelHistory, False)
    assert max(rss[3:]) < 1.1 * rss[3], rss
    # A few a mesh, never one a view (12 views would make 12): Mitsuba's vertex normals bake the
    # vertex count in, and a virtual call's kernel bakes in the registry's id range, which grows
    # while the scene cache fills (SCENE_CACHE scenes alive) and then only moves as ids are reused.
    settled = batch.SCENE_CACHE + 1
    assert max(new_kernels[settled:]) <= 5, new_kernels
    assert len(batch._LAUNCH["views"]) < 12 and len(batch._SCENES) <= batch.SCENE_CACHE


def test17_an_stl_keeps_its_creases(tmp_path):
    """An STL is faceted: shaded with face normals, a box's visible faces have one normal each
    (axis-aligned: the normalisation only moves and scales it), and the lines drawing has its
    inner edges (creases), which smooth vertex normals would round off."""
    trimesh = pytest.importorskip("trimesh")
    trimesh.Trimesh(*box(SIZE, CENTRE)).export(tmp_path / "cube.stl")
    rows = D.make_dataset(
        [tmp_path / "cube.stl"],
        tmp_path / "o",
        "sphere:1",
        width=48,
        height=48,
        workers=0,
        progress=False,
        drawings=("lines",),
    )
    row = rows[0]
    assert row["status"] == "done"
    gb = read_exr(tmp_path / "o" / row["files"]["exr"])
    inside = gb.object_id > 0
    n = gb.normals[inside]
    assert inside.sum() > 100 and np.all(np.abs(n).max(axis=1) > 0.999)
    # ink inside the box's outline: its inner edges (the silhouette alone would leave none)
    from PIL import Image

    ink = 1 - np.asarray(Image.open(tmp_path / "o" / row["files"]["lines.png"]).convert("L")) / 255
    from scipy.ndimage import binary_erosion

    core = binary_erosion(inside, iterations=3)
    assert ink[core].max() > 0.5


def test_no_image_under_the_svg_without_a_beauty(made, tmp_path):
    """Without a beauty the lines' SVG holds strokes only; with one, the beauty is embedded."""
    out, rows = made
    row = next(r for r in rows if r["view"] is not None and r["status"] == "done")
    text = (out / row["files"]["lines.svg"]).read_text()
    assert "<image" not in text and "<path" in text
    mesh = tmp_path / "tet.obj"
    mesh.write_text(TET)
    got = D.make_dataset([mesh], tmp_path / "o", "random:1", width=24, height=24, spp=1,
                         workers=0, progress=False, beauty=True)  # fmt: skip
    assert "<image" in (tmp_path / "o" / got[0]["files"]["lines.svg"]).read_text()


def test_a_failed_write_is_a_failed_row_and_is_retried(tmp_path, monkeypatch):
    """The files are written by the batch's writer thread: a write that fails there leaves no
    file of the view, its row says why, and a retry renders and writes the view again."""
    import mi_npr.io

    mesh = tmp_path / "tet.obj"
    mesh.write_text(TET)
    real, failed = mi_npr.io.write_png, set()

    def flaky(path, *a, **k):  # random_001_lines.png fails once in each OUT
        if os.path.basename(path) == "random_001_lines.png" and path not in failed:
            failed.add(path)
            raise mi_npr.errors.OutputError(f"{path}: cannot write (disk full)")
        return real(path, *a, **k)

    monkeypatch.setattr(mi_npr.io, "write_png", flaky)
    kw = dict(width=24, height=24, spp=1, workers=0, progress=False, drawings=("lines",))
    rows = D.make_dataset([mesh], tmp_path / "a", "random:3", **kw)
    assert [r["status"] for r in rows] == ["done", "failed", "done"]
    assert "random_001_lines.png: cannot write (disk full)" in rows[1]["error"]
    assert not list((tmp_path / "a" / "tet").glob("random_001*"))
    assert not [p for p in (tmp_path / "a" / "tet").iterdir() if p.name.startswith(".")]
    rows = D.make_dataset([mesh], tmp_path / "b", "random:3", retries=1, **kw)
    assert [r["status"] for r in rows] == ["done"] * 3
    manifest = [json.loads(x) for x in (tmp_path / "b" / "manifest.jsonl").read_text().splitlines()]
    assert sorted((m["job"], m["attempt"]) for m in manifest) == [
        ("tet/random_000", 1), ("tet/random_001", 2), ("tet/random_002", 1)
    ]  # fmt: skip
    assert (tmp_path / "b" / "tet" / "random_001_lines.png").is_file()
    resumed = D.make_dataset([mesh], tmp_path / "b", "random:3", resume=True, **kw)
    assert [r["status"] for r in resumed] == ["done"] * 3
    assert len((tmp_path / "b" / "manifest.jsonl").read_text().splitlines()) == 3  # none redone


def test_output_sets_and_sweeps_are_per_thread(tmp_path):
    """A file written in another thread while this thread holds an output set open is renamed
    at once (it is no part of this thread's set), and a sweep of its folder leaves the other
    thread's live temporary file alone."""
    import threading

    from mi_npr.io._atomic import atomic_output, clean_stale, output_set

    inside, release, seen = threading.Event(), threading.Event(), []

    def other():
        with atomic_output(tmp_path / "b.txt") as tmp:
            open(tmp, "w").write("b")
            seen.append(tmp)
            inside.set()
            release.wait(10)

    with output_set():
        with atomic_output(tmp_path / "a.txt") as tmp:
            open(tmp, "w").write("a")
        t = threading.Thread(target=other)
        t.start()
        assert inside.wait(10)
        assert clean_stale(tmp_path) == [] and os.path.exists(seen[0])
        release.set()
        t.join()
        assert (tmp_path / "b.txt").read_text() == "b"  # renamed by its own thread
        assert not (tmp_path / "a.txt").exists()  # this set's file waits for the set's end
    assert (tmp_path / "a.txt").read_text() == "a"

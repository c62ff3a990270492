"""Regenerate the pictures of the README and the docs: python docs/make_figures.py (test extra)."""

from __future__ import annotations

import os
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np

import mi_npr

ROOT = Path(__file__).resolve().parents[1]
OUT = ROOT / "docs" / "images"


def _figure(
    panels: list,
    name: str,
    shape: tuple[int, int],
    size: tuple[float, float],
    dpi: int,
    suptitle: str | None = None,
) -> Path:
    """Save ``panels`` ((image, title) or (image, title, imshow options)) as a grid."""
    fig, ax = plt.subplots(*shape, figsize=size)
    for a, (img, title, *kw) in zip(np.ravel(ax), panels, strict=True):
        a.imshow(img, **(kw[0] if kw else {}))
        a.set_title(title)
        a.axis("off")
    if suptitle:
        fig.suptitle(suptitle)
    fig.tight_layout()
    path = OUT / name
    fig.savefig(path, dpi=dpi, bbox_inches="tight")
    plt.close(fig)
    return path


def gbuffer_panel() -> Path:
    gb = mi_npr.render(ROOT / "scenes_xml" / "scene1.xml", width=320, height=240, spp=64)
    z = np.where(np.isfinite(gb["Z"]), gb["Z"], np.nan)
    panels = [
        (mi_npr.io.to_rgb8(gb.beauty), "R G B (nested path tracer)", {}),
        (z, "Z", {"cmap": "magma_r"}),
        (np.clip(gb.normals * 0.5 + 0.5, 0, 1), "N.X N.Y N.Z", {}),
        (gb["object_id.V"], "object_id.V", {"cmap": "tab10", "interpolation": "nearest"}),
        (gb["prim_id.V"] % 7, "prim_id (mod 7)", {"cmap": "viridis", "interpolation": "nearest"}),
        (np.clip(np.abs(gb.positions) / 4, 0, 1), "|P.X P.Y P.Z| / 4", {}),
    ]
    return _figure(panels, "gbuffer_scene1.png", (2, 3), (12, 6.2), 80)


def lines_panel() -> Path:
    path_xml = ROOT / "scenes_xml" / "scene4.xml"
    gb = mi_npr.render(path_xml, width=640, height=480, spp=64, integrator="npr_lines")
    depth = np.asarray(mi_npr.kernels.lines(gb, id_edges=False, crease_angle=0.0))
    gray = {"cmap": "gray", "vmin": 0, "vmax": 1}
    panels = [
        (mi_npr.io.to_rgb8(gb.beauty), "R G B (npr_lines, defaults)"),
        (1.0 - depth, "depth contours only (eq. 5.1)", gray),
        (1.0 - gb["lines.V"], "lines (defaults: + boundaries + creases, 3x3 AA)", gray),
    ]
    return _figure(panels, "lines_scene4.png", (1, 3), (15, 4.3), 100)


def contours_panel() -> Path:
    """The paper's Fig. 10: apparent contours in red over scenes 1 and 3."""
    panels = []
    for name in ("scene1", "scene3"):
        gb, _ = mi_npr.render_contours(
            ROOT / "scenes_xml" / f"{name}.xml", width=320, height=240, spp=64
        )
        panels.append((mi_npr.io.to_rgb8(gb.beauty), f"mi-npr contours scenes_xml/{name}.xml"))
    return _figure(panels, "contours_scenes.png", (1, 2), (12, 5.0), 80)


def raytree_panel() -> Path:
    panels = []
    for name in ("scene1.xml", "raytree_mirror_glass.xml"):
        gb = mi_npr.render_raytree(ROOT / "scenes_xml" / name, width=400, height=300, spp=64)
        panels.append((mi_npr.io.to_rgb8(gb.beauty), name))
    title = "ray-tree edges: real red, reflection blue, refraction green, shadow gray"
    return _figure(panels, "raytree_edges.png", (1, 2), (11, 4.4), 72, title)


def foliage_panel() -> Path:
    """The four foliage styles (thesis Fig. 4.8) and the N layer at abstraction 0 and 1."""
    styles = ["small_leaves", "large_leaves", "van_gogh", "childrens_book"]
    res = 420
    crop = np.s_[int(0.08 * res) : int(0.62 * res), int(0.14 * res) : int(0.86 * res)]
    panels = []
    for name in styles:
        gb = mi_npr.render(ROOT / "scenes_xml" / f"foliage_{name}.xml", width=res, height=res)
        panels.append((mi_npr.io.to_rgb8(gb.beauty)[crop], name))
    for a in (0.0, 1.0):
        gb = mi_npr.render(
            ROOT / "scenes_xml" / "foliage_large_leaves.xml", width=res, height=res, abstraction=a
        )
        leaf = (gb["leaf_id.V"] > 0)[..., None]
        panels.append((np.where(leaf, gb.normals * 0.5 + 0.5, 1.0)[crop], f"N, abstraction {a:g}"))
    return _figure(panels, "foliage_styles.png", (1, len(panels)), (3.0 * len(panels), 2.6), 80)


def overview_panel() -> Path:
    """What ``make demo`` makes of scene 1: depth lines, apparent contours, ray-tree edges."""
    path_xml = ROOT / "scenes_xml" / "scene1.xml"
    size = {"width": 400, "height": 300, "spp": 64}
    lines = mi_npr.render(path_xml, integrator="npr_lines", **size)
    contours, _ = mi_npr.render_contours(path_xml, **size)
    edges = mi_npr.render_raytree(path_xml, **size)
    panels = [
        (mi_npr.io.to_rgb8(lines.beauty), "npr_lines: depth contours (eqs. 5.1-5.4)"),
        (mi_npr.io.to_rgb8(contours.beauty), "npr_contours: apparent contours of real objects"),
        (mi_npr.io.to_rgb8(edges.beauty), "npr_raytree: real / reflection / refraction / shadow"),
    ]
    return _figure(panels, "overview_scene1.png", (1, 3), (15, 3.9), 80)


def _browser_screenshot(svg: Path, png: Path, size: tuple[int, int]) -> np.ndarray:
    """``svg`` as a headless Chromium renders it (``apt-get install chromium``)."""
    import shutil
    import subprocess

    from PIL import Image

    exe = shutil.which("chromium") or shutil.which("chromium-browser") or shutil.which("chrome")
    if exe is None:
        raise SystemExit("the svg figure needs a headless browser: apt-get install chromium")
    subprocess.run(
        [
            exe,
            "--headless",
            "--no-sandbox",
            "--disable-gpu",
            "--hide-scrollbars",
            f"--window-size={size[0]},{size[1]}",
            f"--screenshot={png}",
            svg.as_uri(),
        ],
        check=True,
        capture_output=True,
        timeout=120,
    )
    return np.asarray(Image.open(png).convert("RGB"))


def svg_panel() -> Path:
    """The SVG of ``mi-npr contours`` on scene 1 as a browser shows it, and a zoom on one sphere's
    edge: the path's vertices on the true outline against the old pixel-centre chain."""
    import re
    import tempfile

    w, h = 320, 240
    gb, contours, paths, _ = mi_npr.render_vector_contours(
        ROOT / "scenes_xml" / "scene1.xml", width=w, height=h, spp=64
    )
    beauty = mi_npr.compose.raw_beauty(gb)
    full = mi_npr.io.svg_document(paths, w, h, beauty=beauty)
    full = full.replace(f'width="{w}" height="{h}" viewBox', 'width="640" height="480" viewBox')
    # the zoom: 24 x 18 pixels on the left sphere's upper-left rim, thin strokes, with the
    # pixel-centre chain of the same contour in blue for comparison
    left = next(c for c in contours if c.name == "sphere_left")
    old = mi_npr.io.svg_document([left], w, h, color=(0.0, 0.2, 1.0), stroke_width=0.06)
    old_layer = old[old.index('<g id="contours"') : old.rindex("</svg>")]
    old_layer = old_layer.replace('id="contours"', 'id="pixel-centres"', 1)
    old_layer = re.sub(r'id="sphere_left"', 'id="sphere_left-pixels"', old_layer)
    zoom = mi_npr.io.svg_document(paths, w, h, beauty=beauty, stroke_width=0.08)
    zoom = zoom.replace("</svg>", old_layer + "</svg>")
    x0, y0 = int(left.points[:, 0].min()) + 2, int(left.points[:, 1].min()) + 4
    zoom = zoom.replace(
        f'width="{w}" height="{h}" viewBox="0 0 {w} {h}"',
        f'width="640" height="480" viewBox="{x0} {y0} 24 18"',
    )
    with tempfile.TemporaryDirectory() as tmp:
        shots = []
        for name, text in (("full", full), ("zoom", zoom)):
            svg = Path(tmp) / f"{name}.svg"
            svg.write_text(text)
            shots.append(_browser_screenshot(svg, Path(tmp) / f"{name}.png", (640, 480)))
    panels = [
        (shots[0], "scene1_contours.svg in Chromium (vector paths over the embedded beauty)"),
        (shots[1], "zoom: red, the sphere's and the wall's paths; blue, pixel centres"),
    ]
    return _figure(panels, "svg_scene1.png", (1, 2), (13, 5.1), 80)


#: Mitsuba's tutorial scenes (github.com/mitsuba-renderer/mitsuba-tutorials, scenes/): not part
#: of this repository; the figure below is committed and skipped where they are absent (CI).
PUBLIC = Path(os.environ.get("MI_NPR_PUBLIC_SCENES", "/work/public/tutorials/scenes"))


def selection_panel() -> Path | None:
    """A real scene (the tutorials' 439-mesh Lego loader) with --id-mode and --only."""
    path_xml = PUBLIC / "lego" / "scene.xml"
    if not path_xml.is_file():
        print(f"skipped selection figure: {path_xml} not found (set MI_NPR_PUBLIC_SCENES)")
        return None
    size = {"resolution": (480, 300), "spp": 32}
    runs = [
        ({"id_mode": "shape"}, "--contours (every mesh: 439 objects)"),
        ({"id_mode": "material"}, "--contours --id-mode material (one per BSDF)"),
        (
            {"only": "Gear*,Technic*", "ignore": "TechnicBush*"},
            "--contours --only 'Gear*' --only 'Technic*' --ignore 'TechnicBush*'",
        ),
    ]
    panels = []
    for params, title in runs:
        r = mi_npr.pipeline.render_layers(path_xml, ["contours"], params, **size)
        panels.append((mi_npr.io.to_rgb8(r.pictures["contours"])[40:270, 60:440], title))
    return _figure(panels, "selection_lego.png", (1, 3), (16, 3.6), 80)


def fit_camera_panel() -> Path:
    """The camera from a sketch on scene 3: the drawing (from a camera 14 degrees around and 8%
    nearer), the lines from the start and from the fitted camera over it."""
    from mi_npr.ad import Pinhole, soft_lines
    from mi_npr.ad.fit import camera_error, fit_camera
    from mi_npr.camera import Camera, rotate

    w, h = 160, 120
    scene = mi_npr.load_scene(ROOT / "scenes_xml" / "scene3.xml", width=w, height=h, spp=1)
    start = mi_npr.camera_of(scene.sensors()[0])
    t = np.array([0.0, 0.55, 0.6])
    o = t + rotate(np.subtract(start.origin, t), [0.3, 1.0, 0.1], np.radians(14.0)) * 0.92
    hidden = Camera(tuple(o), tuple(t), (0.0, 1.0, 0.0), start.fov)

    def lines(c: Camera) -> np.ndarray:
        cam = Pinhole.look_at(c.origin, c.target, c.up, c.fov)
        return np.clip(np.asarray(soft_lines(scene, cam, (w, h), n=2, sigma=0.7)), 0, 1)

    drawing = lines(hidden)
    fit = fit_camera(scene, drawing, iterations=150)
    deg, dist = camera_error(fit.camera, hidden)

    def overlay(b: np.ndarray) -> np.ndarray:  # red: the drawing only, blue: the lines only
        a = drawing
        return np.stack([1 - b, 1 - a - b + a * b, 1 - a], -1).clip(0, 1)

    panels = [
        (1 - drawing, "the drawing (hidden camera)", {"cmap": "gray", "vmin": 0, "vmax": 1}),
        (overlay(lines(start)), "before: the scene's sensor"),
        (
            overlay(lines(fit.camera)),
            f"after {len(fit.loss)} steps: {deg:.3f} deg, {100 * dist:.3f}%",
        ),
    ]
    return _figure(panels, "fit_camera_scene3.png", (1, 3), (13, 3.6), 80)


def fit_shape_panel() -> Path:
    """Fitting a shape on scene 3: the drawing with the front-left box turned 12 degrees and
    scaled by 1.1, the lines before and after the box's rotation and scale are fitted."""
    from mi_npr.ad import soft_lines
    from mi_npr.ad.fit import fit_shape

    w, h = 160, 120
    path = ROOT / "scenes_xml" / "scene3.xml"
    scene = mi_npr.load_scene(path, width=w, height=h, spp=1)
    table = mi_npr.object_table(scene)
    name = "box_front_left"
    shape = next(s for oid, s in table.shapes.items() if table.names[oid] == name)
    mi = mi_npr.mi
    params = mi.traverse(scene)
    key = f"{shape.id()}.vertex_positions" if shape.is_mesh() else f"{shape.id()}.to_world"
    original = mi.Float(params[key]) if shape.is_mesh() else mi.Transform4f(params[key])
    bb = shape.bbox()
    c = [float(v) for v in np.asarray((bb.min + bb.max) * 0.5).ravel()]
    change = (
        mi.ScalarTransform4f().translate(c)
        @ mi.ScalarTransform4f().rotate([0, 1, 0], 12.0).scale(1.1)
        @ mi.ScalarTransform4f().translate([-v for v in c])
    )
    if shape.is_mesh():
        P = mi.Transform4f(change) @ mi_npr.dr.unravel(mi.Point3f, original)
        params[key] = mi_npr.dr.ravel(P)
    else:
        params[key] = mi.Transform4f(change) @ original
    params.update()
    drawing = np.clip(np.asarray(soft_lines(scene, n=2, sigma=0.7)), 0, 1)
    params[key] = original
    params.update()
    before = np.clip(np.asarray(soft_lines(scene, n=2, sigma=0.7)), 0, 1)
    fit = fit_shape(scene, drawing, name, params="rotation,scale", iterations=120)
    after = np.clip(np.asarray(soft_lines(scene, n=2, sigma=0.7)), 0, 1)

    def overlay(b: np.ndarray) -> np.ndarray:  # red: the drawing only, blue: the lines only
        a = drawing
        return np.stack([1 - b, 1 - a - b + a * b, 1 - a], -1).clip(0, 1)

    title = f"after: {fit.rotation[1]:.2f} deg about y, scale {fit.scale:.3f}"
    panels = [
        (1 - drawing, f"the drawing ({name} turned 12 deg, x1.1)", {"cmap": "gray"}),
        (overlay(before), "before: the scene as loaded"),
        (overlay(after), title),
    ]
    return _figure(panels, "fit_shape_scene3.png", (1, 3), (13, 3.6), 80)


def dataset_panel() -> Path:
    """A contact sheet of ``mi-npr dataset``: four meshes (rows: a bumpy sphere, a torus, a
    12-sided ring, the foliage scene's tree), the line drawings of four ``sphere:4`` views at
    256x256, then the depth and the normals of the first view."""
    import tempfile

    import trimesh

    from mi_npr.dataset import make_dataset
    from mi_npr.meshes import uv_sphere, write_ply

    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp) / "meshes"
        folder.mkdir()
        V, F = uv_sphere(100, 51)
        V = V * (1 + 0.1 * np.sin(6 * V[:, :1]) * np.sin(6 * V[:, 1:2]) * np.sin(6 * V[:, 2:]))
        write_ply(folder / "a_bumpy.ply", V.astype(np.float32), F)
        torus = trimesh.creation.torus(major_radius=1.0, minor_radius=0.35)
        torus.export(folder / "b_torus.stl")
        ring = trimesh.creation.annulus(r_min=0.55, r_max=1.0, height=0.5, sections=12)
        ring.export(folder / "c_ring.stl")
        tree = ROOT / "scenes_xml" / "meshes" / "foliage_tree_wood.ply"
        (folder / "d_tree.ply").write_bytes(tree.read_bytes())
        out = Path(tmp) / "out"
        rows = make_dataset(
            [folder], out, "sphere:4", drawings=("lines",), workers=0, progress=False
        )
        panels = []
        for mesh in sorted({r["mesh"] for r in rows}):
            views = [r for r in rows if r["mesh"] == mesh]
            stem = Path(mesh).stem.split("_", 1)[1]
            for r in views:
                lines = plt.imread(out / r["files"]["lines.png"])
                panels.append((lines, f"{stem} {r['view'][-3:]}"))
            gb = mi_npr.io.read_exr(out / views[0]["files"]["exr"])
            z = np.where(np.isfinite(gb["Z"]), gb["Z"], np.nan)
            panels.append((z, f"{stem} 000: Z", {"cmap": "magma_r"}))
            n = np.where(gb.object_id[..., None] > 0, gb.normals * 0.5 + 0.5, 1.0)
            panels.append((np.clip(n, 0, 1), f"{stem} 000: N"))
    return _figure(panels, "dataset_contact_sheet.png", (4, 6), (15, 10.4), 64)


def strokes_lego_panel() -> Path | None:
    """The tutorials' Lego model in the ``technical`` style (hidden lines dashed) and the
    ``illustration`` style, 640x480 (needs ``$MI_NPR_TUTORIALS``, a mitsuba-tutorials clone)."""
    from mi_npr.io.strokes import strokes_on_paper
    from mi_npr.scene import object_table
    from mi_npr.strokes.drawing import STROKES_PARAMS, draw_strokes

    root = os.environ.get("MI_NPR_TUTORIALS")
    if not root:
        print("strokes_lego: set MI_NPR_TUTORIALS to a mitsuba-tutorials clone")
        return None
    scene = mi_npr.load_scene(Path(root) / "scenes/lego/scene.xml", width=640, height=480)
    sensor, table = scene.sensors()[0], object_table(scene)
    panels = []
    for style, title in (
        ("technical", "technical: hidden lines dashed (max_qi 1)"),
        ("illustration", "illustration: widths by depth, tapered, no hidden lines"),
    ):
        params = {p.name: p.default for p in STROKES_PARAMS} | {"style": style}
        d = draw_strokes(scene, sensor, table, params)
        panels.append((mi_npr.io.to_rgb8(strokes_on_paper(d)), title))
    return _figure(panels, "strokes_lego.png", (1, 2), (16, 6.2), 80)


def strokes_cameras_panel() -> Path | None:
    """Strokes (``technical`` style) of mitsuba-data's documentation scenes seen through a thin
    lens and an orthographic camera, an open cylinder, and two spheres sunk into a box and
    through each other (intersection strokes of shapes that are not meshes), 320x240 (needs
    ``$MI_NPR_DATA``, a mitsuba-data clone)."""
    import tempfile

    from mi_npr.io.strokes import strokes_on_paper
    from mi_npr.scene import SEARCH_PATH_ENV, object_table
    from mi_npr.strokes.drawing import STROKES_PARAMS, draw_strokes

    root = os.environ.get("MI_NPR_DATA")
    if not root:
        print("strokes_cameras: set MI_NPR_DATA to a mitsuba-data clone")
        return None
    docs = Path(root) / "docs" / "scenes"
    common = Path(root) / "common"
    os.environ[SEARCH_PATH_ENV] = os.pathsep.join(map(str, (common, common / "meshes", docs)))
    spheres = Path(tempfile.mkdtemp()) / "spheres.xml"
    spheres.write_text(
        '<scene version="3.0.0"><sensor type="perspective"><float name="fov" value="35"/>'
        '<transform name="to_world"><lookat origin="0.8, 3.2, 8" target="0.4, -0.4, 0" '
        'up="0, 1, 0"/></transform><film type="hdrfilm"><integer name="width" value="320"/>'
        '<integer name="height" value="240"/></film></sensor>'
        '<shape type="sphere"><point name="center" value="0, 0, 0"/>'
        '<float name="radius" value="0.8"/></shape>'
        '<shape type="sphere"><point name="center" value="1.1, 0.1, 0.2"/>'
        '<float name="radius" value="0.6"/></shape>'
        '<shape type="cube"><transform name="to_world"><scale x="2" y="0.4" z="1.5"/>'
        '<translate x="0.4" y="-0.8"/></transform></shape></scene>'
    )
    panels = []
    for path, title in (
        (docs / "sensor_thinlens.xml", "thin lens (sensor_thinlens.xml)"),
        (docs / "sensor_orthographic.xml", "orthographic (sensor_orthographic.xml)"),
        (docs / "shape_cylinder_twosided.xml", "open cylinder (shape_cylinder_twosided.xml)"),
        (spheres, "spheres sunk into a box: intersection strokes"),
    ):
        scene = mi_npr.load_scene(path, width=320, height=240, spp=4)
        params = {p.name: p.default for p in STROKES_PARAMS} | {"style": "technical"}
        d = draw_strokes(scene, scene.sensors()[0], object_table(scene), params)
        panels.append((mi_npr.io.to_rgb8(strokes_on_paper(d)), title))
    return _figure(panels, "strokes_cameras.png", (1, 4), (18, 3.9), 80)


PANELS = {
    "overview": overview_panel,
    "gbuffer": gbuffer_panel,
    "lines": lines_panel,
    "contours": contours_panel,
    "raytree": raytree_panel,
    "foliage": foliage_panel,
    "svg": svg_panel,
    "selection": selection_panel,
    "fit_camera": fit_camera_panel,
    "fit_shape": fit_shape_panel,
    "dataset": dataset_panel,
    "strokes_lego": strokes_lego_panel,
    "strokes_cameras": strokes_cameras_panel,
}

if __name__ == "__main__":
    import sys

    OUT.mkdir(parents=True, exist_ok=True)
    for name in sys.argv[1:] or PANELS:  # python docs/make_figures.py [gbuffer lines foliage]
        print(PANELS[name]())

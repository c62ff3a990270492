"""Line drawings against Blender Freestyle: the same camera, the same meshes, the same run.

Two procedural scenes, written as OBJ files that both Mitsuba and Blender load (public scenes
cannot be fetched here): ``room``, a Cornell-box-like room of one-sided walls with a tall and a
short box, and ``lego``, a 20 x 20 grid of 400 "lego-like" pieces (bricks with cylindrical
studs, square frames with a hole, round pillars; turned by assorted angles) on a base plate.

Freestyle (Blender, headless, Cycles with every object a holdout on a transparent film, so the
alpha channel is the strokes alone): silhouette + border + crease at 134 degrees, 1 px lines.
Ours: ``npr_lines``'s defaults (depth contours, ID edges, creases at 134 degrees, ``line_aa``
3) through :func:`mi_npr.antialias.antialiased_lines`, and the aliased chain (``line_aa = 1``).

Measures, on ink masks (coverage > 0.5) at 640 x 480:

- found: the share of Freestyle's ink pixels with one of ours within 1.5 px;
- on Freestyle: the share of our ink pixels with one of Freestyle's within 1.5 px;
- ink width: ink pixels per pixel of the skeleton (``skimage.morphology.skeletonize``);
- line time: ours, the chain alone (``line_aa = 1``) and with the 3 x 3 supersampled tracing
  (warm median of ``--repeat`` runs); Freestyle's, the sum of its own stage timers (mesh
  cleaning, WEdge building, feature lines, view map, stroke generation and rendering, printed
  with ``--debug-freestyle``) in the second of two renders; Blender's render time with Freestyle
  minus without is stored too.

Set-up: Blender comes from Debian's ``blender`` package; the benchmark tries
``apt-get install -y blender`` when ``blender`` is not on the PATH and skips cleanly (a message,
exit code 0, a JSON that says why) where it is missing or fails.

    python benchmarks/bench_drawing.py [--quick] [--repeat N] [--out DIR]

Writes ``bench_drawing.json`` and, beside it, ``bench_drawing_<scene>.png`` (Freestyle | ours).
"""

from __future__ import annotations

import argparse
import json
import math
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import _common
import numpy as np

HERE = Path(__file__).resolve().parent
W, H = 640, 480
GOALS = {"found": 0.95, "on_freestyle": 0.95, "ink_width_px": 1.6, "time_ratio": 0.01}

# ------------------------------------------------------------------ meshes


class Mesh:
    """Triangles with shared vertices (creases need shared edges), oriented by hints."""

    def __init__(self, name: str) -> None:
        self.name, self.v, self.f = name, [], []

    def vert(self, p) -> int:
        self.v.append(tuple(float(c) for c in p))
        return len(self.v) - 1

    def poly(self, idx: list[int], outward) -> None:
        """A planar polygon (fan-triangulated about its centroid when it has > 4 corners),
        wound so that its normal points along ``outward``."""
        pts = np.array([self.v[i] for i in idx])
        n = np.cross(pts[1] - pts[0], pts[2] - pts[0])
        if np.dot(n, outward) < 0:
            idx = idx[::-1]
        if len(idx) <= 4:
            self.f.append((idx[0], idx[1], idx[2]))
            if len(idx) == 4:
                self.f.append((idx[0], idx[2], idx[3]))
            return
        c = self.vert(pts.mean(axis=0))
        for a, b in zip(idx, idx[1:] + idx[:1], strict=True):
            self.f.append((c, a, b))


def _turn(p, centre, angle):
    x, z = p[0] - centre[0], p[2] - centre[2]
    c, s = math.cos(angle), math.sin(angle)
    return (centre[0] + c * x + s * z, p[1], centre[2] - s * x + c * z)


def add_prism(m: Mesh, ring: list, y0: float, y1: float, centre, angle: float = 0.0) -> None:
    """A vertical prism over the convex polygon ``ring`` ((x, z) pairs, any order around)."""
    lo = [m.vert(_turn((x, y0, z), centre, angle)) for x, z in ring]
    hi = [m.vert(_turn((x, y1, z), centre, angle)) for x, z in ring]
    m.poly(hi, (0, 1, 0))
    m.poly(lo, (0, -1, 0))
    k = len(ring)
    cx, cz = np.mean([p[0] for p in ring]), np.mean([p[1] for p in ring])
    for i in range(k):
        j = (i + 1) % k
        mx, mz = (ring[i][0] + ring[j][0]) / 2 - cx, (ring[i][1] + ring[j][1]) / 2 - cz
        out = _turn((mx + centre[0], 0, mz + centre[2]), centre, angle)
        m.poly([lo[i], lo[j], hi[j], hi[i]], (out[0] - centre[0], 0, out[2] - centre[2]))


def square(cx, cz, half):
    return [
        (cx - half, cz - half),
        (cx + half, cz - half),
        (cx + half, cz + half),
        (cx - half, cz + half),
    ]


def circle(cx, cz, r, seg):
    return [
        (cx + r * math.cos(2 * math.pi * k / seg), cz + r * math.sin(2 * math.pi * k / seg))
        for k in range(seg)
    ]


def add_frame(m: Mesh, cx, cz, half, hole, y0, y1, angle) -> None:
    """A square block with a square hole through it (one connected mesh)."""
    c = (cx, 0, cz)
    o = [m.vert(_turn((x, y, z), c, angle)) for y in (y0, y1) for x, z in square(cx, cz, half)]
    i = [m.vert(_turn((x, y, z), c, angle)) for y in (y0, y1) for x, z in square(cx, cz, hole)]
    for k in range(4):
        j = (k + 1) % 4
        m.poly([o[4 + k], o[4 + j], i[4 + j], i[4 + k]], (0, 1, 0))  # top ring
        m.poly([o[k], o[j], i[j], i[k]], (0, -1, 0))  # bottom ring
        p = np.array(m.v[o[k]]) + np.array(m.v[o[j]]) - 2 * np.array(c)
        m.poly([o[k], o[j], o[4 + j], o[4 + k]], (p[0], 0, p[2]))  # outer side
        m.poly([i[k], i[j], i[4 + j], i[4 + k]], (-p[0], 0, -p[2]))  # inner side, into the hole


def room_scene() -> tuple[list[Mesh], dict]:
    """A Cornell-box-like room: five one-sided walls (open at the front) and two boxes."""
    walls = {
        "floor": ([(-1, 0, -1), (1, 0, -1), (1, 0, 1), (-1, 0, 1)], (0, 1, 0)),
        "ceiling": ([(-1, 2, -1), (1, 2, -1), (1, 2, 1), (-1, 2, 1)], (0, -1, 0)),
        "back": ([(-1, 0, -1), (1, 0, -1), (1, 2, -1), (-1, 2, -1)], (0, 0, 1)),
        "left": ([(-1, 0, -1), (-1, 0, 1), (-1, 2, 1), (-1, 2, -1)], (1, 0, 0)),
        "right": ([(1, 0, -1), (1, 0, 1), (1, 2, 1), (1, 2, -1)], (-1, 0, 0)),
    }
    meshes = []
    for name, (pts, n) in walls.items():
        m = Mesh(name)
        m.poly([m.vert(p) for p in pts], n)
        meshes.append(m)
    tall, short = Mesh("tall_box"), Mesh("short_box")
    add_prism(tall, square(-0.35, -0.3, 0.3), 0.0, 1.2, (-0.35, 0, -0.3), math.radians(17))
    add_prism(short, square(0.35, 0.35, 0.3), 0.0, 0.6, (0.35, 0, 0.35), math.radians(-18))
    meshes += [tall, short]
    camera = {"origin": (0, 1, 3.9), "target": (0, 1, 0), "up": (0, 1, 0), "fov": 40.0}
    return meshes, camera


def lego_scene(n: int = 20) -> tuple[list[Mesh], dict]:
    """A base plate and an n x n grid of pieces: bricks with 4 studs, frames with a hole, round
    pillars, each turned by an assorted angle about the vertical."""
    plate = Mesh("plate")
    half = n / 2 + 0.5
    add_prism(plate, square(0, 0, half), -0.2, 0.0, (0, 0, 0))
    meshes = [plate]
    for i in range(n):
        for j in range(n):
            cx, cz = i - n / 2 + 0.5, j - n / 2 + 0.5
            angle = math.radians((i * 13 + j * 29) % 90)
            m = Mesh(f"piece_{i:02d}_{j:02d}")
            kind = (i * 7 + j * 3) % 3
            if kind == 0:
                top = 0.4 if (i + j) % 2 else 0.8
                add_prism(m, square(cx, cz, 0.4), 0.0, top, (cx, 0, cz), angle)
                for sx in (-0.2, 0.2):
                    for sz in (-0.2, 0.2):
                        add_prism(
                            m,
                            circle(cx + sx, cz + sz, 0.11, 12),
                            top,
                            top + 0.12,
                            (cx, 0, cz),
                            angle,
                        )
            elif kind == 1:
                add_frame(m, cx, cz, 0.4, 0.2, 0.0, 0.35, angle)
            else:
                add_prism(m, circle(cx, cz, 0.33, 16), 0.0, 0.6, (cx, 0, cz))
            meshes.append(m)
    camera = {"origin": (13.0, 11.0, 15.0), "target": (0, -0.5, 0), "up": (0, 1, 0), "fov": 42.0}
    return meshes, camera


def write_obj(path: Path, meshes: list[Mesh]) -> Path:
    """One OBJ with an ``o`` group per mesh (Blender makes one object of each)."""
    lines, base = [], 1
    for m in meshes:
        lines.append(f"o {m.name}")
        lines += [f"v {x:.6f} {y:.6f} {z:.6f}" for x, y, z in m.v]
        lines += [f"f {a + base} {b + base} {c + base}" for a, b, c in m.f]
        base += len(m.v)
    path.write_text("\n".join(lines) + "\n")
    return path


# ------------------------------------------------------------------ Blender / Freestyle

#: Blender's side of every Freestyle comparison (this one and ``bench_strokes.py``): the OBJ of
#: ``cfg["obj"]`` with holdout materials on a transparent film, the camera of ``cfg`` (Mitsuba's
#: lookat as a matrix, horizontal fov, clip planes), Cycles at 1 sample, and one lineset of
#: visible silhouette, border and crease lines (``cfg["crease"]`` degrees), 1 px black.
FREESTYLE_SCENE = r"""
import json, math, sys, time
import addon_utils, bpy
from mathutils import Matrix

cfg = json.loads(open(sys.argv[sys.argv.index("--") + 1]).read())
bpy.ops.wm.read_factory_settings(use_empty=True)
scene = bpy.context.scene
bpy.ops.wm.obj_import(filepath=cfg["obj"], forward_axis="Y", up_axis="Z")
holdout = bpy.data.materials.new("holdout")
holdout.use_nodes = True
nodes = holdout.node_tree.nodes
nodes.clear()
out = nodes.new("ShaderNodeOutputMaterial")
hold = nodes.new("ShaderNodeHoldout")
holdout.node_tree.links.new(hold.outputs[0], out.inputs[0])
for ob in scene.objects:
    if ob.type == "MESH":
        ob.data.materials.clear()
        ob.data.materials.append(holdout)
cam_data = bpy.data.cameras.new("cam")
cam_data.sensor_fit = "HORIZONTAL"
cam_data.angle = math.radians(cfg["fov"])
cam_data.clip_start, cam_data.clip_end = cfg.get("near", 0.01), cfg.get("far", 1000.0)
cam = bpy.data.objects.new("cam", cam_data)
scene.collection.objects.link(cam)
cam.matrix_world = Matrix(cfg["matrix"])
scene.camera = cam
r = scene.render
r.engine = "CYCLES"
scene.cycles.samples = 1
scene.cycles.use_denoising = False
scene.cycles.device = "CPU"
r.resolution_x, r.resolution_y, r.resolution_percentage = cfg["w"], cfg["h"], 100
r.film_transparent = True
r.threads_mode = "FIXED"
r.threads = cfg["threads"]
r.image_settings.file_format = "PNG"
r.image_settings.color_mode = "RGBA"
r.line_thickness_mode = "ABSOLUTE"
r.line_thickness = 1.0
vl = scene.view_layers[0]
fs = vl.freestyle_settings
fs.crease_angle = math.radians(cfg.get("crease", 134.0))
fs.use_culling = False
for ls in list(fs.linesets):
    fs.linesets.remove(ls)
ls = fs.linesets.new("lines")
ls.select_by_visibility, ls.visibility = True, "VISIBLE"
ls.select_by_edge_types = True
for flag in ("silhouette", "border", "crease"):
    setattr(ls, "select_" + flag, True)
for flag in ("external_contour", "contour", "suggestive_contour", "ridge_valley",
             "material_boundary", "edge_mark"):
    setattr(ls, "select_" + flag, False)
ls.linestyle.thickness = 1.0
ls.linestyle.color = (0.0, 0.0, 0.0)
"""

BLENDER_SCRIPT = (
    FREESTYLE_SCENE
    + r"""
times = {}
for use in (False, True, False, True):  # the second pair: caches and kernels warm
    r.use_freestyle = use
    r.filepath = cfg["png"] if use else cfg["png"] + ".plain.png"
    t0 = time.perf_counter()
    bpy.ops.render.render(write_still=True)
    times["with" if use else "without"] = time.perf_counter() - t0
json.dump(times, open(cfg["times"], "w"))
"""
)


def blender_available(allow_install: bool) -> tuple[str | None, str]:
    """The blender binary, installing Debian's package if needed: (path or None, why not)."""
    exe = shutil.which("blender")
    if exe or not allow_install:
        return exe, "" if exe else "blender is not installed"
    try:
        subprocess.run(
            ["apt-get", "install", "-y", "blender"], capture_output=True, check=True, timeout=900
        )
    except (OSError, subprocess.SubprocessError) as e:
        return None, f"apt-get install -y blender failed: {type(e).__name__}"
    exe = shutil.which("blender")
    return exe, "" if exe else "apt-get installed no blender binary"


def camera_matrix(cam: dict) -> list[list[float]]:
    """Blender's camera-to-world matrix for Mitsuba's ``lookat`` (Mitsuba: +z forward, +x left,
    +y up; Blender: -z forward, +x right, +y up)."""
    o, t, u = (np.asarray(cam[k], np.float64) for k in ("origin", "target", "up"))
    d = (t - o) / np.linalg.norm(t - o)
    left = np.cross(u, d)
    left /= np.linalg.norm(left)
    up = np.cross(d, left)
    m = np.eye(4)
    m[:3, 0], m[:3, 1], m[:3, 2], m[:3, 3] = -left, up, -d, o
    return m.tolist()


def freestyle(exe: str, obj: Path, cam: dict, work: Path, threads: int) -> tuple[np.ndarray, dict]:
    """Freestyle's stroke coverage (H, W) in [0, 1] and Blender's render times (s)."""
    from PIL import Image

    script, cfg = work / "freestyle.py", work / "freestyle.json"
    script.write_text(BLENDER_SCRIPT)
    png, times = work / "freestyle.png", work / "times.json"
    cfg.write_text(
        json.dumps(
            {
                "obj": str(obj),
                "fov": cam["fov"],
                "matrix": camera_matrix(cam),
                "w": W,
                "h": H,
                "png": str(png),
                "times": str(times),
                "threads": threads,
            }
        )
    )
    cmd = [exe, "-b", "--factory-startup", "--debug-freestyle", "--python", str(script)]
    proc = subprocess.run([*cmd, "--", str(cfg)], capture_output=True, text=True, timeout=1800)
    if proc.returncode != 0 or not png.exists():
        tail = (proc.stdout + proc.stderr).strip().splitlines()[-5:]
        raise RuntimeError("blender failed: " + " | ".join(tail))
    alpha = np.asarray(Image.open(png).convert("RGBA"), np.float32)[..., 3] / 255.0
    out = json.loads(times.read_text())
    out["stages"] = freestyle_stages(proc.stdout)
    return alpha, out


#: Freestyle's own timers (seconds) printed with --debug-freestyle, one per stage.
STAGES = (
    "Mesh cleaning",
    "WEdge building",
    "Feature lines",
    "ViewMap building",
    "Strokes generation",
    "Stroke rendering",
)


def freestyle_stages(log: str) -> dict[str, float]:
    """The stage times of the *last* Freestyle render in ``log`` (seconds)."""
    stages: dict[str, float] = {}
    for line in log.splitlines():
        key, _, value = line.partition(":")
        if key.strip() in STAGES:
            try:
                stages[key.strip()] = float(value.split()[0])
            except (ValueError, IndexError):
                pass
    return stages


# ------------------------------------------------------------------ ours and the measures


def mitsuba_xml(meshes: list[Mesh], cam: dict, work: Path) -> Path:
    shapes = []
    for m in meshes:
        path = write_obj(work / f"{m.name}.obj", [m])
        shapes.append(
            f'<shape type="obj" id="{m.name}"><string name="filename" value="{path}"/>'
            '<boolean name="face_normals" value="true"/></shape>'
        )
    o, t, u = (", ".join(f"{v:g}" for v in cam[k]) for k in ("origin", "target", "up"))
    xml = f"""<scene version="3.0.0">
    <integrator type="npr_gbuffer"/>
    <sensor type="perspective">
        <float name="fov" value="{cam["fov"]}"/><string name="fov_axis" value="x"/>
        <float name="near_clip" value="0.01"/><float name="far_clip" value="1000"/>
        <transform name="to_world"><lookat origin="{o}" target="{t}" up="{u}"/></transform>
        <sampler type="independent"><integer name="sample_count" value="1"/></sampler>
        <film type="hdrfilm"><integer name="width" value="{W}"/><integer name="height" value="{H}"/>
            <rfilter type="box"/></film>
    </sensor>
    {"".join(shapes)}
</scene>"""
    path = work / "scene.xml"
    path.write_text(xml)
    return path


def ours(xml: Path, repeat: int) -> dict:
    """Our drawings (line_aa 3 and 1) and their warm median times in ms."""
    import mi_npr
    from mi_npr.antialias import antialiased_lines

    dr = mi_npr.dr
    scene = mi_npr.load_scene(xml)
    sensor = scene.sensors()[0]
    gb = mi_npr.render(scene)
    out, times = {}, {}
    for n in (3, 1):

        def run(n=n):
            ink = antialiased_lines(scene, sensor, gb, n)
            dr.sync_thread()
            return ink

        out[n] = np.asarray(run(), np.float32)
        samples = []
        for _ in range(repeat):
            t0 = time.perf_counter()
            run()
            samples.append((time.perf_counter() - t0) * 1e3)
        times[n] = statistics.median(samples)
    return {"ink": out, "ms": times, "objects": len(gb.objects)}


def measures(ref: np.ndarray, mine: np.ndarray) -> dict:
    from scipy.ndimage import distance_transform_edt
    from skimage.morphology import skeletonize

    f, o = ref > 0.5, mine > 0.5
    to_o = distance_transform_edt(~o) if o.any() else np.full(o.shape, np.inf)
    to_f = distance_transform_edt(~f) if f.any() else np.full(f.shape, np.inf)

    def width(mask):
        skel = skeletonize(mask).sum()
        return float(mask.sum() / skel) if skel else None

    return {
        "found": float((to_o[f] <= 1.5).mean()) if f.any() else None,
        "on_freestyle": float((to_f[o] <= 1.5).mean()) if o.any() else None,
        "ink_width_px": width(o),
        "freestyle_ink_width_px": width(f),
        "ink_pixels": int(o.sum()),
        "freestyle_ink_pixels": int(f.sum()),
    }


def side_by_side(path: Path, ref: np.ndarray, mine: np.ndarray) -> None:
    from PIL import Image

    gap = np.ones((ref.shape[0], 8), np.float32)
    img = np.concatenate([1 - ref, gap, 1 - np.clip(mine, 0, 1)], axis=1)
    Image.fromarray((img * 255 + 0.5).astype(np.uint8)).save(path)


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=5)
    ap.add_argument("--quick", action="store_true", help="the room only, 3 repeats")
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--no-install", action="store_true", help="do not try apt-get")
    ap.add_argument("--out", type=Path, default=HERE / "results")
    args = ap.parse_args()
    exe, why = blender_available(not args.no_install)
    if exe is None:
        print(f"bench_drawing: skipped: {why}")
        _common.write_report("bench_drawing", args.out, skipped=why)
        return 0
    version = subprocess.run([exe, "--version"], capture_output=True, text=True).stdout.split("\n")[
        0
    ]
    cases = {"room": room_scene} if args.quick else {"room": room_scene, "lego": lego_scene}
    results = {}
    args.out.mkdir(parents=True, exist_ok=True)
    for name, make in cases.items():
        meshes, cam = make()
        with tempfile.TemporaryDirectory() as tmp:
            work = Path(tmp)
            obj = write_obj(work / f"{name}.obj", meshes)
            try:
                ref, blender_s = freestyle(exe, obj, cam, work, args.threads)
            except (RuntimeError, subprocess.SubprocessError) as e:
                print(f"bench_drawing: {name}: skipped: {e}")
                results[name] = {"skipped": str(e)}
                continue
            mine = ours(mitsuba_xml(meshes, cam, work), 3 if args.quick else args.repeat)
        # Freestyle's line time: its own stage timers; the render-time difference is noisier.
        fs_ms = sum(blender_s["stages"].values()) * 1e3
        diff_ms = (blender_s["with"] - blender_s["without"]) * 1e3
        print(
            f"{name}: Blender render {blender_s['without']:.2f} s, with Freestyle "
            f"{blender_s['with']:.2f} s; Freestyle's stages {fs_ms:.0f} ms"
        )
        row = {"meshes": len(meshes), "objects_in_view_table": mine["objects"]}
        for n, label in ((3, "ours_aa3"), (1, "ours_aa1")):
            row[label] = {**measures(ref, mine["ink"][n]), "line_ms": mine["ms"][n]}
            row[label]["time_ratio"] = round(mine["ms"][n] / fs_ms, 5) if fs_ms > 0 else None
        row["freestyle"] = {
            "render_s_with": blender_s["with"],
            "render_s_without": blender_s["without"],
            "render_difference_ms": diff_ms,
            "stages_s": blender_s["stages"],
            "line_ms": fs_ms,
        }
        results[name] = row
        side_by_side(args.out / f"bench_drawing_{name}.png", ref, mine["ink"][3])
        for label in ("ours_aa3", "ours_aa1"):
            r = row[label]
            print(
                f"{name:5s} {label}: found {r['found']:.3f}, on Freestyle {r['on_freestyle']:.3f}, "
                f"width {r['ink_width_px']:.2f} px (Freestyle {r['freestyle_ink_width_px']:.2f}), "
                f"lines {r['line_ms']:.1f} ms vs Freestyle {fs_ms:.0f} ms "
                f"(ratio {r['time_ratio']})"
            )
    path = _common.write_report(
        "bench_drawing",
        args.out,
        blender=version,
        resolution=[W, H],
        goals=GOALS,
        threads=args.threads,
        scenes=results,
    )
    print(f"wrote {path}")
    return 0


if __name__ == "__main__":
    sys.exit(main())

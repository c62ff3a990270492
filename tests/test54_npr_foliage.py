"""The npr_foliage BSDF: normal mixing n = normalize((1 - a) n_leaf + a n_hlp) in the shading
and in the G-buffer's N layer, closed forms on one leaf, and the issue's finite-difference check
on a whole tree."""

from __future__ import annotations

import json
import textwrap

import drjit as dr
import numpy as np
import pytest

import mi_npr
from mi_npr import foliage as fo
from mi_npr import layers as L
from mi_npr.errors import SceneError
from mi_npr.foliage.styles import write_foliage_scene

mi = mi_npr.mi
ALBEDO, E = 0.5, 3.0


def field_from_json(path) -> callable:
    """The documented field, re-implemented from the JSON file: sum_i w exp(-q_i / 2)."""
    d = json.loads(open(path).read())
    blobs = [
        (np.array(h["center"]), np.array(h["radii"]), np.array(h["axes"]), h["weight"])
        for h in d["hlps"]
    ]

    def F(P: np.ndarray) -> np.ndarray:
        total = np.zeros(len(P))
        for c, r, a, w in blobs:
            total += w * np.exp(-0.5 * np.sum(((P - c) @ a.T / r) ** 2, axis=1))
        return total

    return F


def fd_normal(F, P: np.ndarray, eps: float = 1e-5) -> np.ndarray:
    g = np.stack([(F(P + eps * e) - F(P - eps * e)) / (2 * eps) for e in np.eye(3)], axis=1)
    return -g / np.linalg.norm(g, axis=1, keepdims=True)


def one_leaf_scene(
    tmp_path, a: float, extra: str = "", light: str = "0, 0, -1", bsdf: str | None = None
) -> str:
    """A 1.6-wide square leaf at z = 1 facing the camera (at z = 4), a unit-sphere HLP at the
    origin, a directional light, pixel-centre samples (stratified, no jitter)."""
    h = fo.HLPSet([[0, 0, 0]], [[1, 1, 1]], [np.eye(3)], [1.0])
    h.save(tmp_path / "one.json")
    leaf = fo.Plant.from_points([[0, 0, 1]], [[0, 0, 1]], sizes=1.6, axes=[[1, 0, 0]], areas=2.56)
    leaf.save(tmp_path / "one.ply")
    return textwrap.dedent(f"""\
        <scene version="3.0.0">
            <integrator type="direct"/>
            <sensor type="perspective">
                <float name="fov" value="40"/>
                <transform name="to_world"><lookat origin="0, 0, 4" target="0, 0, 0" up="0, 1, 0"/></transform>
                <sampler type="stratified"><integer name="sample_count" value="1"/>
                    <boolean name="jitter" value="false"/></sampler>
                <film type="hdrfilm"><integer name="width" value="33"/><integer name="height" value="33"/>
                    <rfilter type="box"/></film>
            </sensor>
            <shape type="npr_leaves" id="leaf">
                <string name="plant" value="one.ply"/>
                <string name="hlps" value="one.json"/>
                <float name="leaf_size" value="1.6"/>
                <string name="placement" value="leaves"/>
                <string name="orientation" value="leaf"/>
                <bsdf type="npr_foliage">
                    {bsdf or '<string name="hlps" value="one.json"/>'}
                    <float name="abstraction" value="{a}"/>
                    {extra}
                    <bsdf type="diffuse"><rgb name="reflectance" value="{ALBEDO}"/></bsdf>
                </bsdf>
            </shape>
            <emitter type="directional">
                <vector name="direction" value="{light}"/>
                <rgb name="irradiance" value="{E}"/>
            </emitter>
        </scene>""")  # noqa: E501


def render_one_leaf(tmp_path, a, **kw):
    p = tmp_path / f"leaf_{a}.xml"
    p.write_text(one_leaf_scene(tmp_path, a, **kw))
    return mi_npr.render(p)


@pytest.mark.parametrize("a", [0.0, 0.3, 1.0])
def test01_one_leaf_closed_form(tmp_path, a):
    """The leaf's normal is +z, the HLP normal at P is P / |P|: N and the Lambert shading of the
    mixed normal (light from the camera side, along -z) are known in closed form."""
    gb = render_one_leaf(tmp_path, a)
    leaf = gb.object_id == 1
    assert leaf.sum() > 100
    P = gb.stack(L.P)[leaf].astype(np.float64)
    n_hlp = P / np.linalg.norm(P, axis=1, keepdims=True)
    mixed = (1 - a) * np.array([0, 0, 1.0]) + a * n_hlp
    mixed /= np.linalg.norm(mixed, axis=1, keepdims=True)
    np.testing.assert_allclose(gb.normals[leaf], mixed, atol=1e-5)
    expected = ALBEDO / np.pi * E * np.maximum(mixed[:, 2], 0.0)
    np.testing.assert_allclose(gb.beauty[leaf][:, 0], expected, rtol=1e-4, atol=1e-6)
    assert np.all(gb.beauty[~leaf] == 0) and np.all(gb.normals[~leaf] == 0)


def test02_two_sided_and_bands(tmp_path):
    # Light from behind the leaf (outer side = +z faces the camera): Lambert on the mixed normal
    # sees no light, whichever face the camera sees.
    gb = render_one_leaf(tmp_path, 0.0, light="0, 0, 1")
    assert np.all(gb.beauty == 0)
    # bands = 3: the cosine factor is quantized to ceil(3 cos) / 3.
    light = np.array([0.6, 0.0, -0.8])
    gb = render_one_leaf(
        tmp_path, 1.0, extra='<integer name="bands" value="3"/>', light="0.6, 0, -0.8"
    )
    leaf = gb.object_id == 1
    cos = np.maximum(gb.normals[leaf] @ -light, 0.0)
    expected = ALBEDO / np.pi * E * np.ceil(cos * 3) / 3
    np.testing.assert_allclose(gb.beauty[leaf][:, 0], expected, rtol=1e-4, atol=1e-6)
    assert len(np.unique(np.round(gb.beauty[leaf][:, 0], 5))) <= 4  # flat tones


def test03_bsdf_interface_is_consistent(tmp_path):
    """eval, pdf, eval_pdf and sample agree with each other (diffuse nested BSDF), from both
    sides of the leaf."""
    p = tmp_path / "s.xml"
    p.write_text(one_leaf_scene(tmp_path, 0.6))
    scene = mi_npr.load_scene(p)
    bsdf = scene.shapes()[0].bsdf()
    n = 64
    rng = np.random.default_rng(54)
    for z in (4.0, -4.0):  # the front and the back of the leaf
        o = np.stack([rng.uniform(-0.5, 0.5, n), rng.uniform(-0.5, 0.5, n), np.full(n, z)])
        ray = mi.Ray3f(mi.Point3f(o.astype(np.float32)), mi.Vector3f(0, 0, -float(np.sign(z))))
        si = scene.ray_intersect(ray)
        assert np.all(np.asarray(si.is_valid()))
        ctx = mi.BSDFContext()
        bs, weight = bsdf.sample(ctx, si, mi.Float(rng.random(n)), mi.Point2f(rng.random((2, n))))
        value = bsdf.eval(ctx, si, bs.wo)
        pdf = bsdf.pdf(ctx, si, bs.wo)
        ok = np.asarray(pdf) > 1e-3
        np.testing.assert_allclose(np.asarray(bs.pdf)[ok], np.asarray(pdf)[ok], rtol=1e-4)
        w = np.asarray(dr.ravel(weight)).reshape(n, 3)[ok, 0]
        v = np.asarray(dr.ravel(value)).reshape(n, 3)[ok, 0]
        np.testing.assert_allclose(w, v / np.asarray(pdf)[ok], rtol=1e-4)
        v2, pdf2 = bsdf.eval_pdf(ctx, si, bs.wo)
        np.testing.assert_allclose(
            np.asarray(dr.ravel(v2)).reshape(n, 3)[:, 0],
            np.asarray(dr.ravel(value)).reshape(n, 3)[:, 0],
            rtol=1e-6,
        )
        np.testing.assert_allclose(np.asarray(pdf2), np.asarray(pdf), rtol=1e-6)
        # The sampled directions leave on the outer side of the mixed normal.
        wo = np.asarray(dr.ravel(si.to_world(bs.wo))).reshape(n, 3)
        n_mix = np.asarray(dr.ravel(bsdf.npr_shading_normal(si))).reshape(n, 3)
        assert np.all(np.sum(wo * n_mix, axis=1) >= -1e-6)
    np.testing.assert_allclose(np.asarray(dr.ravel(bsdf.eval_diffuse_reflectance(si))), ALBEDO)
    assert "abstraction=0.6" in str(bsdf)
    assert "nested.reflectance.value" in mi.traverse(bsdf).keys()  # the material stays editable


@pytest.fixture(scope="module")
def tree_scenes(tmp_path_factory):
    d = tmp_path_factory.mktemp("tree")
    plant = fo.procedural_tree(seed=7, n_leaves=300)
    hlps = fo.build_hlps(plant, k=6, seed=0)
    for style in ("small_leaves", "van_gogh"):
        write_foliage_scene(d / f"{style}.xml", plant, style, hlps=hlps, assets="tree")
    return d


@pytest.mark.parametrize("style", ["small_leaves", "van_gogh"])
def test04_N_is_the_field_gradient_at_abstraction_1(tree_scenes, style):
    """The issue's check: with abstraction = 1 the N layer at every leaf pixel equals the field's
    normalised (outward, i.e. negative) gradient, by finite differences here, to 1e-3."""
    gb = mi_npr.render(tree_scenes / f"{style}.xml", width=64, height=64, spp=1, abstraction=1.0)
    leaf = gb.object_id == gb.find_object("leaves")
    assert leaf.sum() > 100
    F = field_from_json(tree_scenes / "tree_hlps.json")
    ref = fd_normal(F, gb.stack(L.P)[leaf].astype(np.float64))
    np.testing.assert_allclose(gb.normals[leaf], ref, atol=1e-3)
    wood = gb.object_id == gb.find_object("wood")
    # The wood keeps its own normals: they are not the field's.
    cos = np.sum(gb.normals[wood] * fd_normal(F, gb.stack(L.P)[wood].astype(np.float64)), axis=1)
    assert np.any(np.abs(np.abs(cos) - 1) > 0.1)


def test05_N_is_the_leaf_normal_at_abstraction_0_and_mixes_between(tree_scenes):
    """abstraction = 0: the hit triangle's geometric normal (turned to the HLP surface's outer
    side); 0.5: the normalised mean of the two."""
    path = tree_scenes / "small_leaves.xml"
    scene = mi_npr.load_scene(path, width=64, height=64, spp=1, abstraction=0.0)
    gb0 = mi_npr.render(scene)
    leaf = gb0.object_id == gb0.find_object("leaves")
    mesh = next(s for s in scene.shapes() if s.id() == "leaves")
    params = mi.traverse(mesh)
    V = np.asarray(params["vertex_positions"], np.float64).reshape(-1, 3)
    Fc = np.asarray(params["faces"]).reshape(-1, 3)
    tri = Fc[gb0.numpy("prim_id.V")[leaf]]
    n_geo = np.cross(V[tri[:, 1]] - V[tri[:, 0]], V[tri[:, 2]] - V[tri[:, 0]])
    n_geo /= np.linalg.norm(n_geo, axis=1, keepdims=True)
    F = field_from_json(tree_scenes / "tree_hlps.json")
    P = gb0.stack(L.P)[leaf].astype(np.float64)
    n_hlp = fd_normal(F, P)
    n_leaf = n_geo * np.sign(np.sum(n_geo * n_hlp, axis=1))[:, None]
    np.testing.assert_allclose(gb0.normals[leaf], n_leaf, atol=1e-4)
    gb5 = mi_npr.render(path, width=64, height=64, spp=1, abstraction=0.5)
    np.testing.assert_array_equal(gb5.object_id, gb0.object_id)  # same leaves
    half = n_leaf + n_hlp
    half /= np.linalg.norm(half, axis=1, keepdims=True)
    np.testing.assert_allclose(gb5.normals[leaf], half, atol=1e-3)
    # Other shapes keep their own normals.
    wood = gb0.object_id == gb0.find_object("wood")
    # (Bit for bit on LLVM; CUDA compiles the two renders' kernels to different instruction
    # orders, an ulp apart.)
    np.testing.assert_allclose(gb0.normals[wood], gb5.normals[wood], rtol=0, atol=2.5e-7)


def test06_path_integrator_and_mi_render(tree_scenes):
    scene = mi_npr.load_scene(
        tree_scenes / "van_gogh.xml", width=32, height=32, spp=4, beauty="path", abstraction=0.5
    )
    img = np.asarray(mi.render(scene))[..., :3]
    assert np.isfinite(img).all() and img.max() > 0


def test07_parameter_errors(tmp_path):
    hlps = '<string name="hlps" value="one.json"/>'
    cases = [
        ({"a": 1.5}, "abstraction"),
        ({"extra": '<float name="abstractoin" value="0.5"/>'}, "unknown parameter 'abstractoin'"),
        ({"bsdf": "<!-- no hlps -->"}, "'hlps'"),
        ({"bsdf": '<string name="hlps" value="none.json"/>'}, "none.json: no such file"),
        ({"extra": '<integer name="bands" value="-1"/>'}, "bands"),
        ({"extra": f"{hlps}"}, "hlps"),
        ({"extra": '<bsdf type="diffuse"/>'}, "at most one nested"),
    ]
    for i, (kw, match) in enumerate(cases):
        p = tmp_path / f"bad{i}.xml"
        p.write_text(one_leaf_scene(tmp_path, **{"a": 0.5, **kw}))
        with pytest.raises(SceneError, match=match):
            mi_npr.load_scene(p)


def test08_any_bsdf_can_define_the_N_layer(write_scene):
    """The G-buffer hook is generic: a BSDF with npr_shading_normal(si, active) sets N on the
    pixels of the shapes that use it, and only there."""

    class Tilted(mi.BSDF):
        def __init__(self, props):
            super().__init__(props)
            self.m_flags = int(mi.BSDFFlags.DiffuseReflection)

        def npr_shading_normal(self, si, active=True):
            return dr.normalize(si.n + mi.Vector3f(0, 1, 0))

        def eval(self, ctx, si, wo, active=True):
            return mi.Color3f(0.0)

        def pdf(self, ctx, si, wo, active=True):
            return mi.Float(0.0)

        def sample(self, ctx, si, s1, s2, active=True):
            return mi.BSDFSample3f(), mi.Color3f(0.0)

    mi.register_bsdf("test54_tilted", lambda props: Tilted(props))
    body = (
        '<shape type="sphere" id="ball"><point name="center" x="0.6" y="0" z="4"/>'
        '<bsdf type="test54_tilted"/></shape>'
        '<shape type="sphere" id="plain"><point name="center" x="-0.6" y="0" z="4"/>'
        '<float name="radius" value="0.5"/></shape>'
    )
    gb = mi_npr.render(write_scene(body))
    ball, plain = gb.object_id == 1, gb.object_id == 2
    P = gb.stack(L.P)
    n = P[ball] - [0.6, 0, 4]
    n /= np.linalg.norm(n, axis=1, keepdims=True)
    tilted = n + np.array([0.0, 1.0, 0.0])
    np.testing.assert_allclose(
        gb.normals[ball], tilted / np.linalg.norm(tilted, axis=1)[:, None], atol=1e-5
    )
    m = (P[plain] - [-0.6, 0, 4]) / 0.5
    np.testing.assert_allclose(gb.normals[plain], m, atol=1e-5)

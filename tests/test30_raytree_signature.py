"""Ray-tree signature strings, the 64-bit node keys and hash, and the light numbering: pure
functions checked against references written here (a parser, a numpy MurmurHash3 fmix64)."""

from __future__ import annotations

import random
import re

import numpy as np
import pytest

import mi_npr
from mi_npr.raytree import format_signature, light_table
from mi_npr.raytree.signature import light_marks, object_letters
from mi_npr.raytree.tracer import check_max_depth, mix64, node_key

MASK64 = (1 << 64) - 1


# ----------------------------------------------------------------------------- references
def fmix64_ref(h: int) -> int:
    """MurmurHash3's fmix64, Python integers (the published constants)."""
    h ^= h >> 33
    h = (h * 0xFF51AFD7ED558CCD) & MASK64
    h ^= h >> 33
    h = (h * 0xC4CEB9FE1A85EC53) & MASK64
    return h ^ (h >> 33)


def node_key_ref(pos: int, obj: int, words) -> int:
    h = fmix64_ref((pos << 32) | obj)
    for i, w in enumerate(words):
        h = fmix64_ref(h ^ ((w + (i + 1) * 0x9E3779B97F4A7C15) & MASK64))
    return h


def tree_hash_ref(tree: dict) -> int:
    return fmix64_ref(sum(node_key_ref(p, o, w) for p, (o, w) in tree.items()) & MASK64)


TOKEN = re.compile(r"(\d+)?([A-Z]|\{\d+\})((?:L(?:[1-9]|\{\d+\}))*)")


def parse_ref(s: str) -> dict:
    """The grammar of mi_npr.raytree.signature, parsed back into {pos: (obj, light numbers)}."""
    out, i = {}, 0
    while i < len(s):
        m = TOKEN.match(s, i)
        assert m, f"cannot parse {s[i:]!r} in {s!r}"
        pos = int(m.group(1)) if m.group(1) else 1
        o = m.group(2)
        obj = ord(o) - ord("A") + 1 if len(o) == 1 else int(o[1:-1])
        lights = [int(x.strip("{}")) for x in re.findall(r"L([1-9]|\{\d+\})", m.group(3))]
        out[pos] = (obj, tuple(lights))
        i = m.end()
    return out


def random_tree(rng: random.Random, max_depth: int, n_obj: int, n_lights: int) -> dict:
    words = (n_lights + 31) // 32 or 1
    tree: dict = {}

    def grow(p: int, d: int) -> None:
        mask = [0] * words
        for k in range(n_lights):
            if rng.random() < 0.4:
                mask[k // 32] |= 1 << (k % 32)
        tree[p] = (rng.randint(1, n_obj), tuple(mask))
        for c in (2 * p, 2 * p + 1):
            if d + 1 < max_depth and rng.random() < 0.5:
                grow(c, d + 1)

    grow(1, 0)
    return tree


def lights_of(words) -> tuple[int, ...]:
    return tuple(32 * i + b + 1 for i, w in enumerate(words) for b in range(32) if (w >> b) & 1)


# ----------------------------------------------------------------------------- strings
def test01_the_papers_examples():
    # Fig. 5, tree a: C at the root, its reflection B sees light 1, B's reflection A.
    a = {1: (3, (0,)), 2: (2, (1,)), 4: (1, (0,))}
    assert format_signature(a) == "4A2BL1C"
    # Tree b: the same chain along refraction rays (the caption's "7A3BL1" + its root).
    b = {1: (3, (0,)), 3: (2, (1,)), 7: (1, (0,))}
    assert format_signature(b) == "7A3BL1C"


def test02_small_cases():
    assert format_signature({}) == ""  # a ray that hits nothing
    assert format_signature({1: (1, (0,))}) == "A"
    assert format_signature({1: (26, (0b101,))}) == "ZL1L3"
    # reflection subtree before refraction subtree before the node itself; node 5 is the
    # refraction child of node 2. "L12B" is light 1 then node 2: lights above 9 take braces.
    t = {1: (1, (0,)), 2: (2, (0,)), 3: (3, (0,)), 5: (4, (1,))}
    assert format_signature(t) == "5DL12B3CA"
    assert parse_ref("5DL12B3CA") == {1: (1, ()), 2: (2, ()), 3: (3, ()), 5: (4, (1,))}
    with pytest.raises(mi_npr.ParameterError, match="root"):
        format_signature({2: (1, (0,))})


def test03_big_ids_and_many_lights():
    assert object_letters(1) == "A" and object_letters(26) == "Z" and object_letters(27) == "{27}"
    with pytest.raises(mi_npr.ParameterError):
        object_letters(0)
    assert light_marks((1 << 8 | 1 << 9, 1)) == "L9L{10}L{33}"
    # object L (12) next to light marks and positions stays readable
    t = {1: (12, (1,)), 2: (12, (0,)), 4: (12, (1 << 11,))}
    assert format_signature(t) == "4LL{12}2LLL1"
    assert parse_ref("4LL{12}2LLL1") == {1: (12, (1,)), 2: (12, ()), 4: (12, (12,))}


@pytest.mark.parametrize(("n_obj", "n_lights"), [(3, 1), (30, 12), (200, 40)])
def test04_strings_are_injective_random_trees(n_obj, n_lights):
    """Parsing a string gives its tree back, so equal strings mean equal trees."""
    rng = random.Random(n_obj)
    seen: dict[str, dict] = {}
    for _ in range(400):
        tree = random_tree(rng, 4, n_obj, n_lights)
        s = format_signature(tree)
        expected = {p: (o, lights_of(w)) for p, (o, w) in tree.items()}
        assert parse_ref(s) == expected, s
        if s in seen:
            assert seen[s] == tree
        seen[s] = tree


# ----------------------------------------------------------------------------- hashing
def test05_mix64_and_node_keys_match_the_reference():
    mi, dr = mi_npr.mi, mi_npr.dr
    rng = np.random.default_rng(5)
    vals = [0, 1, 2**32 - 1, 2**63, MASK64, *map(int, rng.integers(0, 2**63, 20))]
    got = mix64(mi.UInt64(np.array(vals, dtype=np.uint64))).numpy()
    assert [int(v) for v in got] == [fmix64_ref(v) for v in vals]
    assert fmix64_ref(0) == 0  # the empty tree hashes to 0
    pos = rng.integers(1, 2**10, 50).astype(np.uint32)
    obj = rng.integers(0, 300, 50).astype(np.uint32)
    w = rng.integers(0, 2**32, (50, 2), dtype=np.uint64).astype(np.uint32)
    keys = node_key(mi.UInt32(pos), mi.UInt32(obj), [mi.UInt32(w[:, 0]), mi.UInt32(w[:, 1])])
    ref = [
        node_key_ref(int(p), int(o), [int(a), int(b)])
        for p, o, (a, b) in zip(pos, obj, w, strict=True)
    ]
    assert [int(k) for k in keys.numpy()] == ref
    assert dr.width(keys) == 50


def test06_tree_hashes_of_random_trees_do_not_collide():
    rng = random.Random(6)
    trees = [random_tree(rng, 4, 5, 2) for _ in range(3000)]
    by_string: dict[str, int] = {}
    for t in trees:
        h = tree_hash_ref(t)
        s = format_signature(t)
        assert by_string.setdefault(s, h) == h
    hashes = set(by_string.values())
    assert len(hashes) == len(by_string)  # different strings, different hashes


def test07_max_depth_is_checked():
    assert check_max_depth(1) == 1 and check_max_depth(31) == 31
    for bad in (0, -1, 32, 2.5, "3", True):
        with pytest.raises(mi_npr.ParameterError, match="max_depth"):
            check_max_depth(bad)


# ----------------------------------------------------------------------------- lights
LIGHTS = [
    '<emitter type="point" id="zeta"><point name="position" x="0" y="3" z="0"/></emitter>',
    '<emitter type="directional"><vector name="direction" x="0" y="-1" z="1"/></emitter>',
    '<emitter type="constant" id="alpha"/>',
    '<shape type="rectangle" id="lamp"><transform name="to_world"><translate z="9"/>'
    '</transform><emitter type="area"/></shape>',
    '<emitter type="spot" id="mid"><transform name="to_world"><lookat origin="0,2,0" '
    'target="0,0,4"/></transform></emitter>',
]


def test08_lights_are_numbered_by_name_whatever_the_xml_order(write_scene):
    tables = []
    for order in (LIGHTS, LIGHTS[::-1], LIGHTS[2:] + LIGHTS[:2]):
        scene = mi_npr.load_scene(write_scene("".join(order)))
        lt = light_table(scene, mi_npr.object_table(scene))
        tables.append((lt.names, lt.kinds, lt.shape_ids))
    assert tables[0] == tables[1] == tables[2]
    names, kinds, shape_ids = tables[0]
    assert list(names.values()) == sorted(names.values())
    assert names[1] == "alpha" and kinds[1] == "environment"
    assert names[2].startswith("directionalemitter_") and kinds[2] == "direction"
    assert names[3] == "lamp.emitter" and kinds[3] == "area" and shape_ids[3] == 1
    assert names[4] == "mid" and kinds[4] == "position"
    assert names[5] == "zeta" and kinds[5] == "position"


def test09_light_masks_take_words_of_32(write_scene):
    many = "".join(
        f'<emitter type="point" id="p{i:02d}"><point name="position" x="{i}" y="3" z="0"/>'
        "</emitter>"
        for i in range(33)
    )
    scene = mi_npr.load_scene(write_scene(many))
    lt = light_table(scene, mi_npr.object_table(scene))
    assert len(lt) == 33 and lt.words == 2
    scene0 = mi_npr.load_scene(write_scene('<shape type="sphere"/>'))
    assert light_table(scene0, mi_npr.object_table(scene0)).words == 1

"""Camera paths as data (orbit, through, explore) and their JSON format."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from mi_npr import ParameterError
from mi_npr import camera as C
from mi_npr import paths as P

from .helpers import SCENES

SCENE3 = str(SCENES / "scene3.xml")


def _deg(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Angles in degrees between rows of unit vectors (the test's own reference)."""
    a = a / np.linalg.norm(a, axis=-1, keepdims=True)
    b = b / np.linalg.norm(b, axis=-1, keepdims=True)
    return np.degrees(np.arccos(np.clip(np.sum(a * b, axis=-1), -1, 1)))


def _circle_keys(n: int = 4, r: float = 5.0, h: float = 1.0) -> list[C.Camera]:
    return [
        C.Camera(
            (r * math.cos(2 * math.pi * k / n), h, r * math.sin(2 * math.pi * k / n)),
            (0, 0, 0),
            (0, 1, 0),
            40 + 5 * k,
            k / (n - 1),
        )
        for k in range(n)
    ]


def test01_through_passes_through_its_keyframes():
    keys = _circle_keys()
    for frames in (4, 5, 37, 40):
        path = P.through(keys, frames)
        assert len(path) == frames
        at = [round(k * (frames - 1) / (len(keys) - 1)) for k in range(len(keys))]
        for k, f in zip(keys, at, strict=True):
            np.testing.assert_allclose(path[f].origin, k.origin, atol=1e-9)
            np.testing.assert_allclose(path[f].target, k.target, atol=1e-9)
            d = k.forward
            up = np.array(k.up) - np.dot(k.up, d) * d  # the key's up, orthogonal to the view
            np.testing.assert_allclose(path[f].up, up / np.linalg.norm(up), atol=1e-9)
            assert path[f].fov == pytest.approx(k.fov) and path[f].time == pytest.approx(k.time)


def test02_through_has_bounded_angular_speed_and_no_flips():
    keys = _circle_keys()  # 90 degrees between keys
    frames = 37  # 12 frames per key interval: 7.5 degrees per frame on average
    path = P.through(keys, frames)
    Og = np.array([c.origin for c in path])
    speed = _deg(Og[1:] * [1, 0, 1], Og[:-1] * [1, 0, 1])  # angle about the y axis
    assert speed.max() <= 1.2 * 7.5 and speed.min() >= 0.7 * 7.5  # chords vs the circle
    D = np.array([c.forward for c in path])
    assert _deg(D[1:], D[:-1]).max() <= 1.2 * 7.5
    U = np.array([c.up for c in path])
    assert np.all(np.sum(U[1:] * U[:-1], axis=1) > 0.9)  # up never flips
    np.testing.assert_allclose(np.sum(U * D, axis=1), 0, atol=1e-9)  # up is orthogonal to view


def test03_through_looking_along_up_does_not_flip():
    keys = [
        C.Camera((0, 5, 0.5), (0, 0, 0), (0, 1, 0), 40),
        C.Camera((0.5, 5, 0), (0, 0, 0), (0, 1, 0), 40),
        C.Camera((0, 5, -0.5), (0, 0, 0), (0, 1, 0), 40),
    ]
    path = P.through(keys, 21)
    U = np.array([c.up for c in path])
    assert np.all(np.sum(U[1:] * U[:-1], axis=1) > 0.5)


def test04_orbit_keeps_distance_and_starts_at_the_scene_camera():
    import mitsuba as mi

    path = C.orbit(SCENE3, 12)
    scene = mi.load_file(SCENE3)
    M = np.asarray(scene.sensors()[0].world_transform().matrix, np.float64).reshape(4, 4)
    np.testing.assert_allclose(path[0].origin, M[:3, 3], atol=1e-5)
    T = np.array(path[0].target)
    r = np.linalg.norm(np.array([c.origin for c in path]) - T, axis=1)
    np.testing.assert_allclose(r, r[0], rtol=1e-9)
    Og = np.array([c.origin for c in path]) - T
    steps = _deg(Og[1:] * [1, 0, 1], Og[:-1] * [1, 0, 1])
    np.testing.assert_allclose(steps, 30.0, atol=1e-6)  # 360 / 12, y is up in scene 3


def test05_explore_bounds_speed_and_turning():
    ex = P.explore(SCENE3, 40, "entropy", max_speed=5.0, max_turn=10.0, result=True)
    R = np.array([c.origin for c in ex.cameras]) - np.array(ex.cameras[0].target)
    R /= np.linalg.norm(R, axis=1, keepdims=True)
    speed = _deg(R[1:], R[:-1])
    assert speed.max() <= 5.0 + 1e-6 and speed.sum() > 5.0
    # heading change: the tangent of the motion, parallel moved by rotating about R[i-1] x R[i]
    turns = []
    for i in range(1, len(R) - 1):
        m0, m1 = R[i] - R[i - 1], R[i + 1] - R[i]
        if np.linalg.norm(m0) < 1e-9 or np.linalg.norm(m1) < 1e-9:
            continue
        t0 = m0 - np.dot(m0, R[i]) * R[i]
        t1 = m1 - np.dot(m1, R[i]) * R[i]
        turns.append(_deg(t0[None], t1[None])[0])
    assert max(turns) <= 10.0 + 1.0  # chord tangents: within a degree of the exact heading
    # the view turns as fast as the camera moves (it looks at the centre)
    D = np.array([c.forward for c in ex.cameras])
    assert _deg(D[1:], D[:-1]).max() <= 5.0 + 1e-6
    assert np.all(R @ np.array([0, 1, 0]) >= -1e-9)  # stays on the allowed side of up


def test06_explore_sees_better_views_than_an_orbit():
    frames = 24
    ex = P.explore(SCENE3, frames, "entropy")
    orb = C.orbit(SCENE3, frames)
    q_ex = P.path_qualities(SCENE3, ex, "entropy")
    q_orb = P.path_qualities(SCENE3, orb, "entropy")
    assert q_ex.mean() > q_orb.mean()


def test07_json_round_trip_and_errors(tmp_path):
    keys = _circle_keys()
    back = C.from_json(C.to_json(keys))
    assert back == keys
    data = json.loads(C.to_json(keys))
    assert set(data[0]) == {"origin", "target", "up", "fov", "time"}
    f = tmp_path / "c.json"
    f.write_text(json.dumps([{k: v for k, v in d.items() if k != "time"} for d in data]))
    read = C.read_cameras(f)
    assert [c.time for c in read] == pytest.approx([0, 1 / 3, 2 / 3, 1])
    for bad, what in (
        ("nope", "not a JSON file"),
        ("[]", "non-empty"),
        ('[{"origin": [0,0,0], "target": [0,0,0], "up": [0,1,0], "fov": 40}]', "same point"),
        ('[{"origin": [0,0,0], "target": [0,0,1], "up": [0,0,1], "fov": 40}]', "along the view"),
        ('[{"origin": [0,0,0], "target": [0,0,1], "up": [0,1,0], "fov": 200}]', "fov"),
        ('[{"origin": [0,"x",0], "target": [0,0,1], "up": [0,1,0], "fov": 40}]', "origin"),
        ('[{"origin": "123", "target": [0,0,1], "up": [0,1,0], "fov": 40}]', "origin"),
    ):
        with pytest.raises(ParameterError, match=what):
            C.from_json(bad, "keys.json")
    with pytest.raises(ParameterError, match=r"missing\.json"):
        C.read_cameras(tmp_path / "missing.json")


@pytest.mark.parametrize("frames", [0, -1, 10**9, 2.5, True, "3"])
def test08_bad_frame_counts(frames):
    with pytest.raises(ParameterError, match="frames"):
        P.through(_circle_keys(), frames)


def test09_explore_bad_arguments():
    with pytest.raises(ParameterError, match="max_speed"):
        P.explore(SCENE3, 4, max_speed=0)
    with pytest.raises(ParameterError, match="max_turn"):
        P.explore(SCENE3, 4, max_turn=float("nan"))
    with pytest.raises(ParameterError, match="measure"):
        P.explore(SCENE3, 4, measure="beauty")

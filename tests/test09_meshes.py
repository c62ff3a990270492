"""Mesh generators and PLY I/O."""

from __future__ import annotations

import numpy as np
import pytest

from mi_npr import InputError
from mi_npr.meshes import box, merge, read_ply, uv_sphere, write_ply


def _outward(V, F):
    tri = V[F]
    n = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    return np.einsum("ij,ij->i", n, tri.mean(axis=1) - V.mean(axis=0)) > 0


def test01_uv_sphere_counts_and_winding():
    V, F = uv_sphere(36, 30)
    assert V.shape == (1046, 3) and F.shape == (2088, 3)  # the paper's 2088 faces
    np.testing.assert_allclose(np.linalg.norm(V, axis=1), 1.0, rtol=1e-6)
    assert _outward(V, F).all()
    # Closed: every edge is shared by exactly two faces.
    e = np.sort(np.concatenate([F[:, [0, 1]], F[:, [1, 2]], F[:, [2, 0]]]), axis=1)
    _, counts = np.unique(e, axis=0, return_counts=True)
    assert (counts == 2).all()


def test02_box_is_closed_and_outward():
    V, F = box((1, 2, 3), center=(1, 0, 0))
    assert V.shape == (8, 3) and F.shape == (12, 3) and _outward(V, F).all()
    np.testing.assert_allclose(V.min(0), [0.5, -1, -1.5])


def test03_ply_round_trip_binary(tmp_path):
    V, F = merge(uv_sphere(8, 6), box(0.3))
    path = write_ply(tmp_path / "m.ply", V, F)
    V2, F2, extra = read_ply(path)
    np.testing.assert_array_equal(V2, V)
    np.testing.assert_array_equal(F2, F)
    assert extra == {}


def test04_ascii_ply_with_quads_and_normals(tmp_path):
    text = """ply
format ascii 1.0
element vertex 4
property float x
property float y
property float z
property float nx
property float ny
property float nz
element face 1
property list uchar int vertex_indices
end_header
0 0 0 0 0 1
1 0 0 0 0 1
1 1 0 0 0 1
0 1 0 0 0 1
4 0 1 2 3
"""
    p = tmp_path / "q.ply"
    p.write_text(text)
    V, F, extra = read_ply(p)
    assert V.shape == (4, 3)
    np.testing.assert_array_equal(F, [[0, 1, 2], [0, 2, 3]])
    np.testing.assert_array_equal(extra["nz"], [1, 1, 1, 1])


def test05_bad_files(tmp_path):
    with pytest.raises(InputError, match="no such file"):
        read_ply(tmp_path / "nope.ply")
    (tmp_path / "x.ply").write_text("hello")
    with pytest.raises(InputError, match="not a PLY"):
        read_ply(tmp_path / "x.ply")
    with pytest.raises(ValueError, match="does not exist"):
        write_ply(tmp_path / "y.ply", np.zeros((1, 3)), np.array([[0, 1, 2]]))


def _binary_ply(path, header_faces: str, face_records: bytes, truncate: int = 0):
    V = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]], np.float32)
    head = (
        "ply\nformat binary_little_endian 1.0\nelement vertex 4\n"
        "property float x\nproperty float y\nproperty float z\n"
        f"{header_faces}end_header\n"
    ).encode()
    data = head + V.tobytes() + face_records
    path.write_bytes(data[: len(data) - truncate])
    return path


def test06_binary_faces_with_colours_and_polygons(tmp_path):
    # Per-face scalar properties (colours) beside the index list, as exporters write them.
    header = (
        "element face 2\nproperty list uchar int vertex_indices\n"
        "property uchar red\nproperty uchar green\nproperty uchar blue\n"
    )
    tri = np.dtype([("n", "u1"), ("i", "<i4", 3), ("rgb", "u1", 3)])
    recs = np.array([(3, (0, 1, 2), (255, 0, 0)), (3, (0, 2, 3), (0, 255, 0))], tri).tobytes()
    V, F, _ = read_ply(_binary_ply(tmp_path / "c.ply", header, recs))
    assert V.shape == (4, 3)
    np.testing.assert_array_equal(F, [[0, 1, 2], [0, 2, 3]])
    # A quad with a colour: record by record, triangulated.
    quad = np.dtype([("n", "u1"), ("i", "<i4", 4), ("rgb", "u1", 3)])
    header1 = header.replace("element face 2", "element face 1")
    rec = np.array([(4, (0, 1, 2, 3), (1, 2, 3))], quad).tobytes()
    _, F, _ = read_ply(_binary_ply(tmp_path / "q.ply", header1, rec))
    np.testing.assert_array_equal(F, [[0, 1, 2], [0, 2, 3]])
    with pytest.raises(InputError, match=r"t\.ply: malformed PLY"):
        read_ply(_binary_ply(tmp_path / "t.ply", header1, rec, truncate=5))


def test07_truncated_or_malformed_text_files_name_the_file(tmp_path):
    head = "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\n"
    head += "property float z\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n"
    cases = {
        "short.ply": head + "0 0 0\n1 0 0\n",  # the file ends early
        "count.ply": head.replace("vertex 3", "vertex x") + "0 0 0\n",
        "word.ply": head + "0 0 zero\n1 0 0\n0 1 0\n3 0 1 2\n",
    }
    for name, text in cases.items():
        (tmp_path / name).write_text(text)
        with pytest.raises(InputError, match=rf"{name.replace('.', '[.]')}: malformed PLY"):
            read_ply(tmp_path / name)


def test08_mixed_polygons_in_face_order_and_big_endian(tmp_path):
    # A triangle, a pentagon, a two-vertex "face" (no triangle) and a quad, each fanned around its
    # first vertex, in file order (written out by hand).
    faces = [[4, 0, 1], [0, 1, 2, 3, 4], [1, 2], [5, 3, 2, 1]]
    expected = [[4, 0, 1], [0, 1, 2], [0, 2, 3], [0, 3, 4], [5, 3, 2], [5, 2, 1]]
    V = np.arange(18, dtype=">f8").reshape(6, 3)
    head = (
        "ply\nformat binary_big_endian 1.0\nelement vertex 6\n"
        "property double x\nproperty double y\nproperty double z\nproperty double nx\n"
        f"element face {len(faces)}\nproperty list uchar short vertex_index\nend_header\n"
    )
    vrec = np.concatenate([V, V[:, :1] * 10], axis=1).astype(">f8").tobytes()
    frec = b"".join(bytes([len(f)]) + np.asarray(f, ">i2").tobytes() for f in faces)
    p = tmp_path / "be.ply"
    p.write_bytes(head.encode() + vrec + frec)
    V2, F, extra = read_ply(p)
    np.testing.assert_array_equal(V2, V.astype(np.float32))
    np.testing.assert_array_equal(F, expected)
    np.testing.assert_array_equal(extra["nx"], V[:, 0] * 10)
    # The same faces as ASCII.
    text = "ply\nformat ascii 1.0\nelement vertex 6\nproperty float x\nproperty float y\n"
    text += "property float z\nelement face 4\nproperty list uchar int vertex_indices\nend_header\n"
    text += "".join(" ".join(map(str, v)) + "\n" for v in V.tolist())
    text += "".join(f"{len(f)} {' '.join(map(str, f))}\n" for f in faces)
    (tmp_path / "a.ply").write_text(text)
    np.testing.assert_array_equal(read_ply(tmp_path / "a.ply")[1], expected)

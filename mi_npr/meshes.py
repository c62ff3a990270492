"""Small triangle meshes in numpy: generators used by the scenes and tests, and PLY I/O.

A mesh is ``(V, F)``: ``V`` float32 (n, 3) vertex positions, ``F`` uint32 (m, 3) triangles with
counter-clockwise winding seen from outside. :func:`write_ply` writes binary little-endian PLY
(what Mitsuba's ``ply`` plugin loads fastest); :func:`read_ply` reads binary and ASCII PLY with
triangle or polygon faces (polygons are fanned into triangles).
"""

from __future__ import annotations

import os
import sys
from pathlib import Path

import numpy as np

from .errors import InputError, check_input_file
from .io._atomic import atomic_output


def uv_sphere(n_lon: int = 36, n_lat: int = 30, radius: float = 1.0) -> tuple[np.ndarray, ...]:
    """A latitude-longitude sphere: ``(n_lat - 1) * n_lon + 2`` vertices, ``2 n_lon (n_lat - 1)``
    triangles (36 x 30 gives 1046 vertices and 2088 faces, the paper's Fig. 9 sphere)."""
    if n_lon < 3 or n_lat < 2:
        raise ValueError("uv_sphere needs n_lon >= 3 and n_lat >= 2")
    theta = np.pi * np.arange(1, n_lat) / n_lat  # polar angles of the rings
    phi = 2 * np.pi * np.arange(n_lon) / n_lon
    st, ct = np.sin(theta)[:, None], np.cos(theta)[:, None]
    ring = np.stack(
        [st * np.cos(phi)[None], ct * np.ones_like(phi)[None], st * np.sin(phi)[None]], axis=-1
    ).reshape(-1, 3)
    V = np.concatenate([[[0.0, 1.0, 0.0]], ring, [[0.0, -1.0, 0.0]]]) * radius
    top, bottom = 0, len(V) - 1
    faces = []
    for j in range(n_lon):
        j1 = (j + 1) % n_lon
        faces.append((top, 1 + j1, 1 + j))
        for i in range(n_lat - 2):
            a, b = 1 + i * n_lon + j, 1 + i * n_lon + j1
            c, d = a + n_lon, b + n_lon
            faces.append((a, b, d))
            faces.append((a, d, c))
        last = 1 + (n_lat - 2) * n_lon
        faces.append((last + j, last + j1, bottom))
    return V.astype(np.float32), np.asarray(faces, dtype=np.uint32)


def box(size: float | tuple[float, float, float] = 1.0, center=(0.0, 0.0, 0.0)):
    """An axis-aligned box as 8 vertices and 12 outward-facing triangles."""
    s = np.broadcast_to(np.asarray(size, dtype=np.float64), (3,)) / 2
    c = np.asarray(center, dtype=np.float64)
    corners = np.array([[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)], float)
    V = corners * s + c
    quads = [(0, 1, 3, 2), (4, 6, 7, 5), (0, 4, 5, 1), (2, 3, 7, 6), (0, 2, 6, 4), (1, 5, 7, 3)]
    F = []
    for a, b, cc, d in quads:
        F += [(a, b, cc), (a, cc, d)]
    return V.astype(np.float32), np.asarray(F, dtype=np.uint32)


def merge(*meshes: tuple[np.ndarray, np.ndarray]) -> tuple[np.ndarray, np.ndarray]:
    """Concatenate meshes into one (the parts stay separate connected components)."""
    Vs, Fs, off = [], [], 0
    for V, F in meshes:
        Vs.append(np.asarray(V, np.float32))
        Fs.append(np.asarray(F, np.uint32) + off)
        off += len(V)
    return np.concatenate(Vs), np.concatenate(Fs)


def weld(V: np.ndarray) -> np.ndarray:
    """Index of each vertex among the distinct positions of ``V`` ((n, 3) -> (n,) int64)."""
    if len(V) == 0:
        return np.zeros(0, np.int64)
    _, inverse = np.unique(np.asarray(V), axis=0, return_inverse=True)
    return inverse.reshape(-1).astype(np.int64)


def face_components(F: np.ndarray, V: np.ndarray | None = None) -> np.ndarray:
    """Connected component of each face ((m, 3) -> (m,) int64), numbered 0.. by lowest face.

    Faces sharing a vertex are connected; with ``V`` given, vertices are first welded by position
    (PLY files duplicate seam vertices: a sphere would fall apart into strips without it).
    Label propagation with pointer jumping (numpy, no per-face Python loop).
    """
    F = np.asarray(F, np.int64).reshape(-1, 3)
    if len(F) == 0:
        return np.zeros(0, np.int64)
    if V is not None:
        F = weld(V)[F]
    n = int(F.max()) + 1
    lab = np.arange(n, dtype=np.int64)
    while True:
        m = lab[F].min(axis=1)
        new = lab.copy()
        for j in range(3):
            np.minimum.at(new, F[:, j], m)
        while True:  # pointer jumping: follow labels to their roots
            nxt = new[new]
            if np.array_equal(nxt, new):
                break
            new = nxt
        if np.array_equal(new, lab):
            break
        lab = new
    face_lab = lab[F[:, 0]]
    _, first, inverse = np.unique(face_lab, return_index=True, return_inverse=True)
    rank = np.empty(len(first), np.int64)
    rank[np.argsort(first, kind="stable")] = np.arange(len(first))
    return rank[inverse.reshape(-1)]


def write_ply(
    path: str | os.PathLike[str],
    V: np.ndarray,
    F: np.ndarray,
    vertex_attrs: dict[str, np.ndarray] | None = None,
) -> Path:
    """Binary little-endian PLY with float vertices and uint8-counted uint32 triangle lists.

    ``vertex_attrs`` adds float per-vertex properties after ``x y z`` (``{"nx": (n,) array, ...}``;
    :func:`read_ply` returns them in its ``extra`` dict). ``F`` may have no rows (a point set).
    """
    V = np.ascontiguousarray(V, dtype="<f4")
    F = np.ascontiguousarray(F, dtype="<u4")
    if V.ndim != 2 or V.shape[1] != 3 or F.ndim != 2 or F.shape[1] != 3:
        raise ValueError(f"write_ply: expected V (n, 3) and F (m, 3), got {V.shape}, {F.shape}")
    if F.size and F.max() >= len(V):
        raise ValueError("write_ply: a face refers to a vertex that does not exist")
    attrs = {k: np.asarray(a, dtype="<f4").reshape(-1) for k, a in (vertex_attrs or {}).items()}
    for k, a in attrs.items():
        if len(a) != len(V) or not k.isidentifier() or k in ("x", "y", "z"):
            raise ValueError(f"write_ply: vertex attribute {k!r} is misnamed or not one per vertex")
    props = "".join(f"property float {k}\n" for k in ("x", "y", "z", *attrs))
    header = (
        "ply\nformat binary_little_endian 1.0\ncomment written by mi-npr\n"
        f"element vertex {len(V)}\n{props}"
        f"element face {len(F)}\nproperty list uchar uint vertex_indices\nend_header\n"
    )
    vrec = np.empty(len(V), dtype=[(k, "<f4") for k in ("x", "y", "z", *attrs)])
    vrec["x"], vrec["y"], vrec["z"] = V[:, 0], V[:, 1], V[:, 2]
    for k, a in attrs.items():
        vrec[k] = a
    rec = np.empty(len(F), dtype=[("n", "u1"), ("i", "<u4", (3,))])
    rec["n"], rec["i"] = 3, F
    target = Path(path)
    with atomic_output(target) as tmp, open(tmp, "wb") as f:
        f.write(header.encode("ascii"))
        f.write(vrec.tobytes())
        f.write(rec.tobytes())
    return target


_PLY_TYPES = {
    "char": "i1", "int8": "i1", "uchar": "u1", "uint8": "u1", "short": "i2", "int16": "i2",
    "ushort": "u2", "uint16": "u2", "int": "i4", "int32": "i4", "uint": "u4", "uint32": "u4",
    "float": "f4", "float32": "f4", "double": "f8", "float64": "f8",
}  # fmt: skip


def read_ply(path: str | os.PathLike[str]) -> tuple[np.ndarray, np.ndarray, dict]:
    """``(V, F, extra)``: positions, triangles and any other per-vertex properties by name
    (``nx ny nz`` normals, ...)."""
    p = Path(path)
    check_input_file(p)
    data = p.read_bytes()
    end = data.find(b"end_header")
    if not data.startswith(b"ply") or end < 0:
        raise InputError(f"{p}: not a PLY file")
    body_start = data.find(b"\n", end) + 1
    lines = data[:end].decode("ascii", "replace").splitlines()
    fmt, elements = None, []
    try:
        for ln in lines:
            t = ln.split()
            if not t:
                continue
            if t[0] == "format":
                fmt = t[1]
            elif t[0] == "element":
                elements.append([t[1], int(t[2]), []])
                if elements[-1][1] < 0:
                    raise ValueError(f"element {t[1]!r} has a negative count")
            elif t[0] == "property" and elements:
                elements[-1][2].append(t[1:])
    except (ValueError, IndexError) as e:
        raise InputError(f"{p}: malformed PLY header ({e})") from None
    if fmt not in ("ascii", "binary_little_endian", "binary_big_endian"):
        raise InputError(f"{p}: unsupported PLY format {fmt!r}")
    try:
        if fmt == "ascii":
            return _read_ascii(data[body_start:].decode("ascii"), elements)
        return _read_binary(data, body_start, elements, "<" if "little" in fmt else ">")
    except StopIteration:
        raise InputError(f"{p}: malformed PLY (the file ends before its last element)") from None
    except (ValueError, IndexError, KeyError, UnicodeDecodeError) as e:
        raise InputError(f"{p}: malformed PLY ({e})") from None


def _vertices(props: dict[str, np.ndarray]) -> tuple[np.ndarray, dict]:
    V = np.stack([props["x"], props["y"], props["z"]], axis=-1).astype(np.float32)
    extra = {k: v for k, v in props.items() if k not in ("x", "y", "z")}
    return V, extra


def _triangulate(polys: list[np.ndarray]) -> np.ndarray:
    tris = []
    for poly in polys:
        for k in range(1, len(poly) - 1):
            tris.append((poly[0], poly[k], poly[k + 1]))
    return np.asarray(tris, dtype=np.uint32).reshape(-1, 3)


def _read_ascii(text: str, elements: list) -> tuple[np.ndarray, np.ndarray, dict]:
    tokens = iter(text.split())
    vprops: dict[str, list] = {}
    polys: list[np.ndarray] = []
    for name, count, props in elements:
        for _ in range(count):
            for prop in props:
                if prop[0] == "list":
                    n = int(next(tokens))
                    vals = np.array([int(next(tokens)) for _ in range(n)], dtype=np.int64)
                    if name == "face":
                        polys.append(vals)
                else:
                    v = float(next(tokens))
                    if name == "vertex":
                        vprops.setdefault(prop[1], []).append(v)
    V, extra = _vertices({k: np.asarray(v) for k, v in vprops.items()})
    return V, _triangulate(polys), extra


def _read_binary(data: bytes, pos: int, elements: list, bo: str):
    vprops: dict[str, np.ndarray] = {}
    F = np.zeros((0, 3), np.uint32)
    for name, count, props in elements:
        for pr in props:
            for t in pr[1:-1] if pr[0] == "list" else pr[:1]:
                if t not in _PLY_TYPES:
                    raise ValueError(f"unknown property type {t!r}")
        lists = [j for j, pr in enumerate(props) if pr[0] == "list"]
        # Fast path: one structured read when every list holds 3 items (triangles), whatever
        # scalar properties (colours, ...) come with them.
        fields = []
        for j, pr in enumerate(props):
            if pr[0] == "list":
                fields.append((f"_n{j}", bo + _PLY_TYPES[pr[1]]))
                fields.append((f"_l{j}", bo + _PLY_TYPES[pr[2]], 3))
            else:
                fields.append((f"_s{j}", bo + _PLY_TYPES[pr[0]]))
        dt = np.dtype(fields)
        arr = None
        if pos + dt.itemsize * count <= len(data):
            arr = np.frombuffer(data, dtype=dt, count=count, offset=pos)
            if not all(np.all(arr[f"_n{j}"] == 3) for j in lists):
                arr = None
        if arr is not None:
            pos += dt.itemsize * count
            scalars = {props[j][1]: arr[f"_s{j}"] for j in range(len(props)) if j not in lists}
            polys = arr[f"_l{lists[0]}"] if lists else None  # (count, 3) triangles
        else:  # record by record: polygons of any size
            if not lists:
                raise ValueError(f"element {name!r}: the file ends early")
            cols: dict[int, list] = {j: [] for j in range(len(props)) if j not in lists}
            polys = []
            for _ in range(count):
                for j, pr in enumerate(props):
                    if pr[0] == "list":
                        ct, it = np.dtype(bo + _PLY_TYPES[pr[1]]), np.dtype(bo + _PLY_TYPES[pr[2]])
                        n = int(np.frombuffer(data, ct, 1, pos)[0])
                        pos += ct.itemsize
                        items = np.frombuffer(data, it, n, pos).astype(np.int64)
                        pos += it.itemsize * n
                        if j == lists[0]:
                            polys.append(items)
                    else:
                        t = np.dtype(bo + _PLY_TYPES[pr[0]])
                        cols[j].append(np.frombuffer(data, t, 1, pos)[0])
                        pos += t.itemsize
            scalars = {props[j][1]: np.asarray(v) for j, v in cols.items()}
        if name == "vertex":
            vprops = {k: np.asarray(v, np.float64) for k, v in scalars.items()}
        elif name == "face" and polys is not None:  # the first list: the vertex indices
            F = polys.astype(np.uint32) if isinstance(polys, np.ndarray) else _triangulate(polys)
    V, extra = _vertices(vprops)
    return V, F, extra


if __name__ == "__main__":  # pragma: no cover - regenerates the scene meshes
    out = Path(sys.argv[1] if len(sys.argv) > 1 else "scenes_xml/meshes")
    sphere = uv_sphere(36, 30, 1.0)
    cube = box(0.4)
    write_ply(out / "sphere_with_cube.ply", *merge(sphere, cube))
    write_ply(out / "uv_sphere.ply", *sphere)

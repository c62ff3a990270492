"""A batch view that is not worth looking at says so:
an orbit around a room of one-sided walls sees their backs, black; the manifest row carries a
one-line warning and the command prints it, while views inside the room carry none."""

from __future__ import annotations

import json

import mi_npr
from mi_npr import cli

from .public_style import room


def test01_a_view_of_the_walls_backs_warns(tmp_path, capsys):
    path = room(tmp_path)
    outside = tmp_path / "outside.json"
    outside.write_text(
        json.dumps(
            [
                {"id": "inside", "origin": [0, 0.2, 0.5], "target": [0, 0, -1], "fov": 60},
                {"id": "outside", "origin": [0, 0, -12], "target": [0, 0, 0], "fov": 60},
            ]
        )
    )
    rows = mi_npr.batch.run(
        [path], str(outside), out=tmp_path / "out", width=32, height=24, spp=2, workers=0,
        progress=False,
    )  # fmt: skip
    by_view = {r["view"]: r for r in rows}
    assert all(r["status"] == "done" for r in rows)
    assert by_view["inside"]["warning"] is None
    warning = by_view["outside"]["warning"]
    assert "outside" in warning and ("background" in warning or "luminance" in warning)
    assert "\n" not in warning
    argv = ["batch", str(path), "-o", str(tmp_path / "cli"), "--views", str(outside)]
    assert cli.main([*argv, "--width", "32", "--height", "24", "--spp", "2", "--workers", "0",
                     "--no-progress"]) == 0  # fmt: skip
    err = capsys.readouterr().err
    assert err.count("mi-npr: warning:") == 1 and "outside" in err

"""Control characters in names (object ids, metadata, paths) are escaped wherever they
reach a terminal: an escape sequence in a shape id must not set the terminal's title or colours,
and a newline must not split the listing."""

from __future__ import annotations

import json

import numpy as np

import mi_npr
from mi_npr.errors import for_terminal

from .helpers import run_cli

EVIL = "ball\x1b]0;pwned\x07\x1b[31mred\nfake: line\u202e"


def test01_helper():
    assert for_terminal("plain name é") == "plain name é"
    out = for_terminal(EVIL)
    assert out.isprintable() and "\\x1b" in out and "\\n" in out and "\\u202e" in out


def test02_info_escapes_names(tmp_path):
    ids = np.zeros((4, 5), np.uint32)
    ids[1:3, 1:3] = 1
    gb = mi_npr.GBuffer(
        {"Z": np.ones((4, 5), np.float32), "object_id": ids},
        objects={1: EVIL},
        metadata={"mi_npr/note": "x\x1b[2Jy"},
    )
    path = mi_npr.io.write_exr(tmp_path / "evil.exr", gb)
    r = run_cli("info", str(path))
    assert r.returncode == 0, r.stderr
    assert "\x1b" not in r.stdout and "\x07" not in r.stdout and "\u202e" not in r.stdout
    assert "  1: " + for_terminal(EVIL) in r.stdout.splitlines()  # one line, escaped
    assert not any(line.startswith("fake: line") for line in r.stdout.splitlines())
    j = run_cli("info", str(path), "--json")
    assert json.loads(j.stdout)["objects"]["1"] == EVIL  # JSON keeps the name exactly


def test03_errors_escape_paths(tmp_path):
    r = run_cli("info", str(tmp_path / "no\x1b[31mfile.exr"))
    assert r.returncode == 1 and "\x1b" not in r.stderr and "\\x1b[31m" in r.stderr

"""The documentation's own Sphinx extensions (``docs/_ext``): the CLI reference generated from
``mi_npr.cli.build_parser()`` and the benchmark tables generated from ``benchmarks/results``.

The references are argparse's own records of a parser (its option strings and choices) and
hand-made parsers and JSON whose tables are written out here."""

from __future__ import annotations

import argparse
import importlib.util
import json
import sys
from pathlib import Path
from types import ModuleType

import pytest
from docutils import nodes

ROOT = Path(__file__).resolve().parents[1]


def _load(name: str) -> ModuleType:
    if str(ROOT / "docs/_ext") not in sys.path:  # as docs/conf.py: the extensions' own helpers
        sys.path.insert(0, str(ROOT / "docs/_ext"))
    spec = importlib.util.spec_from_file_location(
        f"_docs_ext_{name}", ROOT / "docs/_ext" / f"{name}.py"
    )
    assert spec is not None and spec.loader is not None
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


cli_ref = _load("cli_reference")
bench = _load("bench_tables")


def _rows(tree: list[nodes.Node]) -> list[list[str]]:
    """The body rows of every table in ``tree``, as cell texts."""
    out = []
    for node in tree:
        for tbody in node.findall(nodes.tbody):
            for row in tbody.findall(nodes.row):
                out.append([entry.astext() for entry in row.findall(nodes.entry)])
    return out


def _toy_parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="toy")
    p.add_argument("scenes", nargs="+", metavar="SCENE.xml", help="scenes")
    p.add_argument("-o", "--output", required=True, metavar="OUT", help="where")
    p.add_argument("--n", type=int, default=3, help="count, %(default)s by default")
    p.add_argument("--only", action="append", metavar="GLOB", help="objects")
    p.add_argument("--fast", action="store_true", help="hurry")
    p.add_argument("--measure", choices=["pb", "entropy"], metavar="M", help="which")
    p.add_argument("--mode", choices=["a", "b"], default="a", help="mode")
    return p


def test_toy_parser_rows():
    rows = {r[0]: r[1:] for r in _rows(cli_ref.parser_nodes(_toy_parser(), None))}
    assert rows == {
        "SCENE.xml": ["SCENE.xml [SCENE.xml ...]", "", "scenes"],
        "-o, --output": ["OUT", "required", "where"],
        "--n": ["N (int)", "3", "count, 3 by default"],
        "--only": ["GLOB", "", "objects (repeatable)"],
        "--fast": ["", "", "hurry"],
        "--measure": ["M one of pb, entropy", "", "which"],
        "--mode": ["{a,b}", "a", "mode"],
    }


def test_usage_is_argparse_usage():
    text = cli_ref.usage(_toy_parser())
    assert text.startswith("usage: toy [-h] -o OUT")
    assert "SCENE.xml [SCENE.xml ...]" in text


def test_every_command_and_flag_of_mi_npr_is_documented():
    from mi_npr.cli import build_parser

    parser = build_parser()
    subs = cli_ref.subcommands(parser)
    action = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
    assert [name for name, _, _ in subs] == list(action.choices)
    for name, summary, sub in subs:
        assert summary, f"{name} has no help line"
        flags = {f for row in _rows(cli_ref.parser_nodes(sub, name)) for f in row[0].split(", ")}
        expected = {s for s in sub._option_string_actions if s not in ("-h", "--help")}
        expected |= {a.metavar or a.dest for a in sub._get_positional_actions()}
        assert flags == expected, name
    render = next(sub for name, _, sub in subs if name == "render")
    rows = {r[0]: r[1:] for r in _rows(cli_ref.parser_nodes(render, "render"))}
    assert rows["-o, --output"][1] == "required"
    assert rows["--svg-image"][1] == "embed"
    assert rows["--seed"][0] == "N (int)"  # the type of mi_npr.scene.RENDER_PARAMS' seed


@pytest.mark.parametrize(
    ("value", "text"),
    [
        (None, "–"),
        (True, "yes"),
        (12000, "12,000"),
        (1234.6, "1,235"),
        (28.17170900016, "28.2"),
        (0.04735677, "0.0474"),
        (0.0, "0"),
        ([640, 480], "640, 480"),
        ("scene1", "scene1"),
    ],
)
def test_fmt(value, text):
    assert bench.fmt(value) == text


def test_records_as_columns_and_as_rows():
    data = {
        "results": [
            {"width": 640, "height": 480, "ours": {"warm_ms": 1.5}, "ratio": 0.5},
            {"width": 1920, "height": 1080, "ours": {"warm_ms": 9.0}, "ratio": 0.25},
        ],
        "targets": {f"t{i}": {"value": i, "target": 1} for i in range(3)},
    }
    recs, rest = bench.records(data["results"])
    assert rest == {}
    table = bench.record_table(recs)
    header = [e.astext() for e in next(table.findall(nodes.thead)).findall(nodes.entry)]
    assert header == ["", "640x480", "1920x1080"]  # 2 records, 2 fields: a column per record
    assert _rows([table]) == [["ours.warm_ms", "1.5", "9"], ["ratio", "0.5", "0.25"]]
    table = bench.record_table(bench.records(data["targets"])[0])
    header = [e.astext() for e in next(table.findall(nodes.thead)).findall(nodes.entry)]
    assert header == ["", "value", "target"]  # 3 records, 2 fields: a row per record
    assert _rows([table]) == [["t0", "0", "1"], ["t1", "1", "1"], ["t2", "2", "1"]]


def test_every_recorded_result_renders_with_its_machine():
    files = sorted((ROOT / "benchmarks/results").glob("*.json"))
    assert files
    for path in files:
        data = json.loads(path.read_text())
        out = bench.results_nodes(data)
        assert out[0].astext().startswith(f"Recorded {data['date'].replace('T', ' ')} on ")
        assert data["machine"]["cpu"] in out[0].astext()
        assert any(isinstance(n, nodes.table) for n in out), path.name

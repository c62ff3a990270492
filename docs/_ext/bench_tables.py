"""Sphinx directives that turn ``benchmarks/results/*.json`` into tables at build time.

- ``.. bench-machines::`` -- one row per results file: when and on which machine it ran.
- ``.. bench-results:: bench_gbuffer`` -- that file: a line naming the machine, then its
  settings and its measurements as tables.

The benchmarks write JSON of different shapes, so the tables are made from the shape, not from
a schema: scalars and lists of scalars are settings; a dict of scalars is a two-column table;
several records (a list of dicts, or a dict whose values are dicts) are one table with a column
per record or per field, whichever way has fewer columns; deeper nesting becomes dotted names
(``rays.stage_ms.refine``). A file that does not exist yet is a sentence saying how to make it.
The directory is the ``bench_results_dir`` setting of ``conf.py``.
"""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any

from doc_tables import table
from docutils import nodes
from sphinx.application import Sphinx
from sphinx.util.docutils import SphinxDirective

#: The fields every benchmark writes about the run itself (shown in the machine line).
META = ("benchmark", "date", "machine", "mi_npr", "variant", "llvm")


def fmt(value: Any) -> str:
    """A measured value for a table: 3 significant digits, whole numbers as they are."""
    if value is None:
        return "–"
    if isinstance(value, bool):
        return "yes" if value else "no"
    if isinstance(value, int):
        return f"{value:,}"
    if isinstance(value, float):
        if not math.isfinite(value):
            return str(value)
        if value == 0:
            return "0"
        if abs(value) >= 1000:
            return f"{value:,.0f}"
        return f"{value:.3g}"
    if isinstance(value, list):
        return ", ".join(fmt(v) for v in value)
    return str(value)


def is_scalar(value: Any) -> bool:
    return not isinstance(value, (dict, list)) or (
        isinstance(value, list) and all(not isinstance(v, (dict, list)) for v in value)
    )


def flatten(value: Any, prefix: str = "") -> list[tuple[str, Any]]:
    """``(dotted name, scalar)`` pairs of a nested dict, in its order."""
    if is_scalar(value):
        return [(prefix, value)]
    items = value.items() if isinstance(value, dict) else enumerate(value)
    out: list[tuple[str, Any]] = []
    for k, v in items:
        out += flatten(v, f"{prefix}.{k}" if prefix else str(k))
    return out


def _label(i: int, record: dict[str, Any]) -> tuple[str, set[str]]:
    """A column title for the i-th record of a list, and the fields it uses up."""
    if "scene" in record and is_scalar(record["scene"]):
        return str(record["scene"]), {"scene"}
    if "width" in record and "height" in record:
        return f"{record['width']}x{record['height']}", {"width", "height"}
    return f"#{i}", set()


def records(value: Any) -> tuple[list[tuple[str, dict]], dict[str, Any]] | None:
    """``value`` as named records (and its scalar leftovers), if it has two or more."""
    if isinstance(value, list) and value and all(isinstance(v, dict) for v in value):
        out = []
        for i, r in enumerate(value):
            name, used = _label(i, r)
            out.append((name, {k: v for k, v in r.items() if k not in used}))
        return out, {}
    if isinstance(value, dict):
        recs = [(str(k), v) for k, v in value.items() if isinstance(v, dict)]
        rest = {k: v for k, v in value.items() if not isinstance(v, dict)}
        if len(recs) >= 2:
            return recs, rest
    return None


def _table(header: list[str], rows: list[list[str]], first_literal: bool = True) -> nodes.table:
    cells = [
        [
            nodes.literal(t, t) if (j == 0 and first_literal) else nodes.Text(t)
            for j, t in enumerate(r)
        ]
        for r in rows
    ]
    widths = [3 if i == 0 else 2 for i in range(len(header))]
    return table(header, cells, widths, "bench")


def record_table(recs: list[tuple[str, dict]]) -> nodes.table:
    """One table of several records: a column per record, or per field when there are fewer
    fields than records."""
    flat = [(name, dict(flatten(r))) for name, r in recs]
    fields = list(dict.fromkeys(k for _, f in flat for k in f))
    if len(fields) < len(flat):  # fields as columns, records as rows
        rows = [[name, *(fmt(f.get(k)) for k in fields)] for name, f in flat]
        return _table(["", *fields], rows)
    rows = [[k, *(fmt(f.get(k)) for _, f in flat)] for k in fields]
    return _table(["", *(name for name, _ in flat)], rows)


def pairs_table(items: list[tuple[str, Any]]) -> nodes.table:
    return _table(["", "value"], [[k, fmt(v)] for k, v in items])


def machine_line(data: dict[str, Any]) -> str:
    """When, where and with what a results file was made, in one sentence."""
    m = data.get("machine") or {}
    parts = []
    if m.get("cpu"):
        cores = f", {m['cpu_count']} cores" if m.get("cpu_count") else ""
        parts.append(f"{m['cpu']}{cores}")
    if m.get("python"):
        parts.append(f"Python {m['python']}")
    if data.get("variant"):
        parts.append(f"variant {data['variant']}")
    llvm = str(data.get("llvm") or "")
    if "(" in llvm:  # the path is the machine's; what matters is which LLVM
        parts.append(llvm[llvm.index("(") + 1 : llvm.rindex(")")])
    if data.get("mi_npr"):
        parts.append(f"mi-npr {data['mi_npr']}")
    date = str(data.get("date", "an unknown date")).replace("T", " ")
    return f"Recorded {date} on {'; '.join(parts) or 'an unrecorded machine'}."


def results_nodes(data: dict[str, Any]) -> list[nodes.Node]:
    out: list[nodes.Node] = [nodes.paragraph(text=machine_line(data))]
    settings = [(k, v) for k, v in data.items() if k not in META and is_scalar(v)]
    if settings:
        out += [nodes.rubric(text="settings"), pairs_table(settings)]
    for key, value in data.items():
        if key in META or is_scalar(value):
            continue
        out.append(nodes.rubric(text=key))
        found = records(value)
        if found is None:
            out.append(pairs_table(flatten(value)))
            continue
        recs, rest = found
        out.append(record_table(recs))
        if rest:
            out.append(pairs_table(flatten(rest)))
    return out


class BenchResults(SphinxDirective):
    """``.. bench-results:: NAME``: the tables of ``<bench_results_dir>/NAME.json``."""

    required_arguments = 1
    has_content = False

    def run(self) -> list[nodes.Node]:
        name = self.arguments[0]
        path = Path(self.config.bench_results_dir) / f"{name}.json"
        self.env.note_dependency(str(path))
        if not path.is_file():
            text = f"No results recorded yet: python benchmarks/{name}.py writes {path.name}."
            return [nodes.paragraph(text=text)]
        return results_nodes(json.loads(path.read_text()))


class BenchMachines(SphinxDirective):
    """``.. bench-machines::``: one row per results file (date, CPU, cores, Python, variant)."""

    has_content = False

    def run(self) -> list[nodes.Node]:
        rows = []
        for path in sorted(Path(self.config.bench_results_dir).glob("*.json")):
            self.env.note_dependency(str(path))
            d = json.loads(path.read_text())
            m = d.get("machine") or {}
            rows.append(
                [
                    path.stem,
                    str(d.get("date", "")).replace("T", " "),
                    str(m.get("cpu", "")),
                    fmt(m.get("cpu_count")),
                    str(m.get("python", "")),
                    str(d.get("variant", "")),
                ]
            )
        if not rows:
            return [nodes.paragraph(text="No results recorded yet: run make bench.")]
        return [_table(["results file", "date", "CPU", "cores", "Python", "variant"], rows)]


def setup(app: Sphinx) -> dict[str, Any]:
    app.add_config_value("bench_results_dir", "", "env")
    app.add_directive("bench-results", BenchResults)
    app.add_directive("bench-machines", BenchMachines)
    return {"version": "1", "parallel_read_safe": True, "parallel_write_safe": True}

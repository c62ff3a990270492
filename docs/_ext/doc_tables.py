"""The one docutils table builder of the documentation's extensions (CLI flags, benchmarks)."""

from __future__ import annotations

from docutils import nodes


def table(
    header: list[str], rows: list[list[nodes.Node]], widths: list[int], css: str
) -> nodes.table:
    """A left-aligned table of ``rows`` (one node per cell) under ``header``, columns of
    relative ``widths``, with the CSS class ``css``."""
    out = nodes.table(classes=[css], align="left")
    tgroup = nodes.tgroup(cols=len(header))
    out += tgroup
    for w in widths:
        tgroup += nodes.colspec(colwidth=w)
    thead = nodes.thead()
    tgroup += thead
    row = nodes.row()
    for h in header:
        row += nodes.entry("", nodes.paragraph(text=h))
    thead += row
    tbody = nodes.tbody()
    tgroup += tbody
    for cells in rows:
        row = nodes.row()
        for cell in cells:
            row += nodes.entry("", nodes.paragraph("", "", cell))
        tbody += row
    return out

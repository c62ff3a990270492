"""Sphinx directive ``.. cli-reference::``: the ``mi-npr`` command, read from its parser.

It calls :func:`mi_npr.cli.build_parser` (the parser the command itself runs) and writes, for
the program and for every subcommand, its description, its usage line and one table per
argument group: flag, value (metavar and type), default, help. Nothing is written by hand, so
the page cannot drift from ``mi-npr --help``. The global options are a section labelled
``cli-global``, each subcommand one labelled ``cli-<command>`` (``:ref:`cli-render```).

argparse has no public API to walk a parser; like argparse's own help formatter this reads
``_action_groups``, ``_group_actions`` and the sub-parsers action's ``_choices_actions``.
"""

from __future__ import annotations

import argparse
from typing import Any

from doc_tables import table
from docutils import nodes
from sphinx.application import Sphinx
from sphinx.util.docutils import SphinxDirective

#: Width of the usage lines (argparse otherwise follows the terminal's).
USAGE_WIDTH = 80


def _formatter(parser: argparse.ArgumentParser) -> argparse.HelpFormatter:
    return argparse.HelpFormatter(parser.prog, width=USAGE_WIDTH)


def usage(parser: argparse.ArgumentParser) -> str:
    """``parser``'s usage line, as ``--help`` prints it (at :data:`USAGE_WIDTH` columns)."""
    fmt = _formatter(parser)
    fmt.add_usage(parser.usage, parser._actions, parser._mutually_exclusive_groups)
    return fmt.format_help().strip()


def _type_name(action: argparse.Action, command: str | None) -> str:
    """The Python type of a flag's value: a builtin ``type=``, else the type of the library
    parameter the flag was built from (``mi_npr.cli`` keeps the table entry on its parser as
    ``type.param``); an RGB colour is ``rgb``."""
    if action.type in (int, float, str):
        return action.type.__name__
    p = getattr(action.type, "param", None)
    if p is None or not isinstance(p.type, type):
        return ""
    return "rgb" if p.type is tuple else p.type.__name__


def value_text(
    parser: argparse.ArgumentParser, action: argparse.Action, command: str | None
) -> str:
    """What follows the flag: its metavar as argparse prints it (``N``, ``SCENE.xml
    [SCENE.xml ...]``), the type, and the choices; empty for a switch."""
    fmt = _formatter(parser)
    if action.option_strings:
        metavar = fmt._format_args(action, fmt._get_default_metavar_for_optional(action))
    else:
        metavar = fmt._format_args(action, fmt._get_default_metavar_for_positional(action))
    if action.nargs == 0:
        return ""
    parts = [metavar]
    tname = _type_name(action, command)
    if tname:
        parts.append(f"({tname})")
    if action.choices is not None and action.metavar is not None:
        parts.append("one of " + ", ".join(map(str, action.choices)))
    return " ".join(parts)


def default_text(action: argparse.Action) -> str:
    """The default as a user reads it: empty where there is none (``None``, a switch that is
    off, an empty list of a repeatable flag), ``required`` for a required option."""
    if action.required and action.option_strings:
        return "required"
    d = action.default
    if d is None or d is argparse.SUPPRESS or d is False or d == []:
        return ""
    if action.nargs == 0:  # store_const and friends: the default is internal
        return ""
    return str(d)


def help_text(parser: argparse.ArgumentParser, action: argparse.Action) -> str:
    """The help string with argparse's ``%(default)s``-style fields filled in, plus
    ``repeatable`` for an ``append`` flag."""
    if not action.help:
        text = ""
    else:
        text = _formatter(parser)._expand_help(action)
    if isinstance(action, argparse._AppendAction) and "repeatable" not in text:
        text = f"{text} (repeatable)" if text else "repeatable"
    return text


def argument_groups(
    parser: argparse.ArgumentParser,
) -> list[tuple[str, list[argparse.Action]]]:
    """``(title, actions)`` of every argument group with something to show, ``--help`` and the
    sub-parsers action left out."""
    groups = []
    for group in parser._action_groups:
        actions = [
            a
            for a in group._group_actions
            if a.help is not argparse.SUPPRESS
            and not isinstance(a, (argparse._HelpAction, argparse._SubParsersAction))
        ]
        if actions:
            groups.append((group.title or "arguments", actions))
    return groups


def subcommands(parser: argparse.ArgumentParser) -> list[tuple[str, str, argparse.ArgumentParser]]:
    """``(name, one-line help, parser)`` of each subcommand, in the order they were added."""
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            helps = {a.dest: a.help or "" for a in action._choices_actions}
            return [(name, helps.get(name, ""), p) for name, p in action.choices.items()]
    return []


def _literal(text: str) -> nodes.Node:
    return nodes.literal(text, text) if text else nodes.Text("")


def _table(rows: list[list[nodes.Node]], header: list[str], widths: list[int]) -> nodes.table:
    return table(header, rows, widths, "cli-flags")


def parser_nodes(parser: argparse.ArgumentParser, command: str | None) -> list[nodes.Node]:
    """Usage and one table per argument group of ``parser``."""
    out: list[nodes.Node] = [nodes.literal_block(text=usage(parser), language="text")]
    for title, actions in argument_groups(parser):
        rows = []
        for a in actions:
            flag = ", ".join(a.option_strings) if a.option_strings else (a.metavar or a.dest)
            rows.append(
                [
                    _literal(str(flag)),
                    _literal(value_text(parser, a, command)),
                    _literal(default_text(a)),
                    nodes.Text(help_text(parser, a)),
                ]
            )
        out.append(nodes.rubric(text=title))
        out.append(_table(rows, ["flag", "value", "default", "meaning"], [18, 18, 10, 54]))
    return out


class CliReference(SphinxDirective):
    """``.. cli-reference::`` (no arguments): the whole command tree of ``mi-npr``."""

    has_content = False
    required_arguments = 0

    def run(self) -> list[nodes.Node]:
        import mi_npr.cli
        from mi_npr.cli import build_parser

        # Rebuild this page when the command changes (a module now, a package later).
        self.env.note_dependency(mi_npr.cli.__file__)
        parser = build_parser()
        out = [self._section("cli-global", f"{parser.prog} (global options)", parser, None, "")]
        for name, summary, sub in subcommands(parser):
            title = f"{parser.prog} {name}"
            out.append(self._section(f"cli-{name}", title, sub, name, summary))
        return out

    def _section(
        self,
        label: str,
        title: str,
        parser: argparse.ArgumentParser,
        command: str | None,
        summary: str,
    ) -> nodes.section:
        """A section labelled ``label``: description, usage and flag tables of ``parser``."""
        section = nodes.section(ids=[label], names=[label])
        section += nodes.title(text=title)
        text = parser.description or summary
        if text:
            section += nodes.paragraph(text=text[:1].upper() + text[1:])
        section += parser_nodes(parser, command)
        self.state.document.note_explicit_target(section)
        return section


def setup(app: Sphinx) -> dict[str, Any]:
    app.add_directive("cli-reference", CliReference)
    return {"version": "1", "parallel_read_safe": True, "parallel_write_safe": True}

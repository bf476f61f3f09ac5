"""The command-line reference, read from planarcal's own parser (never written twice).

``.. planarcal-cli::`` (in a Markdown page: inside an ``{eval-rst}`` fence) becomes one
section for ``planarcal`` and one per command, each with its usage, its description and its
options as Sphinx ``option`` entries, so a page links an option with
``{option}`planarcal calibrate --lens```` and a command with ``cli.md#planarcal-calibrate``.
Help texts are argparse's plain text: every mark in them is escaped, never read as markup.
"""

from __future__ import annotations

import argparse
import string
from typing import Any

from docutils import nodes
from docutils.statemachine import StringList
from sphinx.application import Sphinx
from sphinx.util.docutils import SphinxDirective

from planarcal.cli import build_parser

# Every mark reStructuredText could read as markup (a line starting "- " is a list item).
_MARKUP = set(string.punctuation)


def escaped(text: str) -> str:
    """`text` as reStructuredText that shows exactly it: a backslash before every mark."""
    return "".join("\\" + ch if ch in _MARKUP else ch for ch in text)


def command_parsers(parser: argparse.ArgumentParser) -> dict[str, argparse.ArgumentParser]:
    """Each command's parser, filled: planarcal's command parsers get their arguments when
    their help is first formatted, as `planarcal COMMAND --help` does."""
    commands: dict[str, argparse.ArgumentParser] = {}
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            for name, command in action.choices.items():
                command.format_help()
                commands[name] = command
    return commands


def command_lines(parser: argparse.ArgumentParser) -> dict[str, str]:
    """Each command's one line from the top-level `--help`."""
    lines: dict[str, str] = {}
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            for choice in action._choices_actions:
                lines[choice.dest] = choice.help or ""
    return lines


def option_signature(action: argparse.Action, formatter: argparse.HelpFormatter) -> str:
    """`-o OUTPUT, --output OUTPUT` or `image`: the option's names as `--help` lists them."""
    return formatter._format_action_invocation(action)


def _help_text(action: argparse.Action, parser: argparse.ArgumentParser) -> str:
    if not action.help or action.help == argparse.SUPPRESS:
        return ""
    formatter = parser._get_formatter()
    return formatter._expand_help(action)


def _usage(parser: argparse.ArgumentParser) -> str:
    return parser.format_usage().strip().removeprefix("usage: ")


def _literal_block(text: str) -> list[str]:
    return [".. code-block:: text", "", *("   " + line for line in text.splitlines()), ""]


def _paragraphs(text: str, indent: str = "") -> list[str]:
    """argparse's description: paragraphs separated by blank lines, each line escaped."""
    return [indent + escaped(line.strip()) if line.strip() else "" for line in text.splitlines()]


def _options(parser: argparse.ArgumentParser, program: str) -> list[str]:
    """The parser's options by group (argparse's own groups and their titles)."""
    lines = [f".. program:: {program}", ""]
    formatter = parser._get_formatter()
    for group in parser._action_groups:
        # The commands are the table above the options, not an option.
        actions = [
            a
            for a in group._group_actions
            if a.help != argparse.SUPPRESS and not isinstance(a, argparse._SubParsersAction)
        ]
        if not actions:
            continue
        lines += [f".. rubric:: {escaped(group.title or 'options')}", ""]
        if group.description:
            lines += [*_paragraphs(group.description), ""]
        for action in actions:
            lines += [f".. option:: {option_signature(action, formatter)}", ""]
            help_text = _help_text(action, parser)
            if help_text:
                lines += [*_paragraphs(help_text, indent="   "), ""]
    return lines


def reference_sections(parser: argparse.ArgumentParser) -> list[tuple[str, str, list[str]]]:
    """The reference as (label, title, reStructuredText body): planarcal, then each command."""
    program = parser.prog
    body = [*_literal_block(_usage(parser)), *_paragraphs(parser.description or ""), ""]
    body += [".. list-table::", "   :header-rows: 1", "", "   * - command", "     - what it does"]
    for name, line in command_lines(parser).items():
        body += [f"   * - :ref:`{program} {name} <{program}-{name}>`", f"     - {escaped(line)}"]
    sections = [(program, program, [*body, "", *_options(parser, program)])]
    for name, command in command_parsers(parser).items():
        body = [*_literal_block(_usage(command)), *_paragraphs(command.description or ""), ""]
        sections.append(
            (f"{program}-{name}", command.prog, [*body, *_options(command, command.prog)])
        )
    return sections


class CliReference(SphinxDirective):
    """``.. planarcal-cli::``: the sections of the command-line reference, each labelled
    (``planarcal``, ``planarcal-calibrate``, ...) so a page links it by its anchor."""

    has_content = False

    def run(self) -> list[nodes.Node]:
        source = self.get_source_info()[0]
        sections: list[nodes.Node] = []
        for label, title, body in reference_sections(build_parser()):
            section = nodes.section(ids=[label], names=[label])
            section += nodes.title(title, title)
            self.state.nested_parse(StringList(body, source=source), self.content_offset, section)
            self.state.document.note_explicit_target(section)
            sections.append(section)
        return sections


def setup(app: Sphinx) -> dict[str, Any]:
    app.add_directive("planarcal-cli", CliReference)
    return {"parallel_read_safe": True, "parallel_write_safe": True}

"""The documentation site builds strictly (a broken link or reference fails it), and its
generated reference pages say what the code says: every command's options as the parser has
them, the API's functions with their docstrings."""

from __future__ import annotations

import argparse
import html
import re
import subprocess
import sys
from pathlib import Path

import pytest

import planarcal
from planarcal.cli import build_parser

DOCS = Path(__file__).resolve().parents[2] / "docs"


@pytest.fixture(scope="module")
def site(tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("site")
    # -W -n: any warning, a reference that finds no target included, fails the build.
    strict = ["-W", "-n", "--keep-going", "-q", "-b", "html", "-d", str(out / ".doctrees")]
    build = subprocess.run(
        [sys.executable, "-m", "sphinx", *strict, str(DOCS), str(out)],
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert build.returncode == 0, f"the strict build failed:\n{build.stderr}"
    return out


def plain(text: str) -> str:
    """Text as a page shows it, for comparing: no tags, entities, typographic quotes or
    headings' link marks (the pilcrow), and runs of white space as one space."""
    text = html.unescape(re.sub(r"<[^>]+>", "", text))
    text = text.translate(str.maketrans("\u2018\u2019\u201c\u201d\u00b6", "''\"\" "))
    return " ".join(text.split())


def command_section(page: str, name: str) -> str:
    start = page.index(f'<section id="planarcal-{name}">')
    end = page.find('<section id="planarcal-', start + 1)
    return page[start : end if end != -1 else len(page)]


def documented_actions(parser: argparse.ArgumentParser) -> list[argparse.Action]:
    return [
        a
        for a in parser._actions
        if a.help != argparse.SUPPRESS and not isinstance(a, argparse._SubParsersAction)
    ]


def test_cli_reference_has_every_command_and_option_as_the_parser_does(site: Path) -> None:
    page = (site / "reference" / "cli.html").read_text(encoding="utf-8")
    parser = build_parser()
    commands = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
    assert set(commands.choices) >= {"calibrate", "locate", "run", "register", "board", "live"}
    for name, command in commands.choices.items():
        help_text = command.format_help()  # fills the command's arguments, as --help does
        section = command_section(page, name)
        text = plain(section)
        usage = help_text.split("\n\n", 1)[0].removeprefix("usage: ")
        assert plain(usage) in text, name
        assert plain(command.description or "") in text, name
        actions = documented_actions(command)
        # One entry per option, no more: the page lists what the parser has.
        assert section.count('<dt class="sig sig-object std" id="cmdoption-') == len(actions)
        formatter = command._get_formatter()
        for action in actions:
            for word in action.option_strings or [str(action.metavar or action.dest)]:
                assert re.search(rf"(^|\s){re.escape(word)}(\s|,|$)", text), (name, word)
            if action.help:
                assert plain(formatter._expand_help(action)) in text, (name, action.dest)


def test_api_reference_documents_find_homography_with_its_docstring(site: Path) -> None:
    page = (site / "reference" / "api-homography.html").read_text(encoding="utf-8")
    assert 'id="planarcal.findHomography"' in page
    doc = planarcal.findHomography.__doc__
    assert doc is not None
    first_paragraph = doc.split("\n\n", 1)[0].replace("``", "")
    assert plain(first_paragraph) in plain(page)


def test_api_reference_documents_every_public_name(site: Path) -> None:
    pages = "".join(p.read_text(encoding="utf-8") for p in (site / "reference").glob("api*.html"))
    anchors = set(re.findall(r'id="(planarcal\.[\w.]+)"', pages))
    # The method constants are cv2's numbers, listed in a sentence; the version is a string.
    listed = {name for name in planarcal.__all__ if name.isupper()} | {"__version__"}
    missing = [
        name
        for name in sorted(set(planarcal.__all__) - listed)
        if f"planarcal.{name}" not in anchors and f"planarcal.errors.{name}" not in anchors
    ]
    assert missing == []

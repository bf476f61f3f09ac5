"""The README is the front page: short, its commands the ones CI runs, its links alive.

Sphinx's strict build checks the site's links; the README is not part of the site (it is read
on the forge), so its links and commands are checked here.
"""

from __future__ import annotations

import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
README = ROOT / "README.md"

# Inline links and images: [text](target) and ![alt](target).
LINK = re.compile(r"\]\(([^)\s]+)\)")


def readme() -> str:
    return README.read_text(encoding="utf-8")


def fenced_commands() -> list[str]:
    """The lines of the README's ```bash blocks."""
    blocks = re.findall(r"```bash\n(.*?)```", readme(), flags=re.DOTALL)
    return [line.strip() for block in blocks for line in block.splitlines() if line.strip()]


def ci_lines(name: str) -> list[str]:
    return [line.strip() for line in (ROOT / ".ci" / name).read_text().splitlines()]


def test_readme_is_a_front_page() -> None:
    lines = readme().splitlines()
    assert len(lines) <= 250, f"README.md has {len(lines)} lines; the rest belongs in docs/"


def test_the_test_command_is_the_one_ci_runs_word_for_word() -> None:
    commands = fenced_commands()
    test_command = next(c for c in commands if "pytest" in c)
    assert (
        test_command
        == 'pip install ".[test]" && python -m pytest && cargo test --workspace --locked'
    )
    assert any(line.startswith(test_command + " ||") for line in ci_lines("run"))


def test_the_install_command_runs_the_demo() -> None:
    assert "pip install . && planarcal demo" in fenced_commands()


def test_the_wheel_command_is_the_one_ci_builds_with() -> None:
    build = next(c for c in fenced_commands() if c.startswith('pip install "maturin'))
    assert any(line.startswith(build + " ||") for line in ci_lines("wheel"))


@pytest.mark.parametrize("target", sorted(set(LINK.findall(README.read_text(encoding="utf-8")))))
def test_every_local_link_names_a_file_and_heading_that_exist(target: str) -> None:
    if re.match(r"[a-z]+://", target):
        return
    path, _, anchor = target.partition("#")
    file = ROOT / path
    assert file.is_file(), f"README links {target}, but {path} does not exist"
    if anchor:
        # MyST's and the forge's slugs: lower case, punctuation dropped, spaces as hyphens.
        headings = re.findall(r"^#+ (.+)$", file.read_text(encoding="utf-8"), flags=re.MULTILINE)
        slugs = {re.sub(r"[^\w\- ]", "", h.strip().lower()).replace(" ", "-") for h in headings}
        assert anchor in slugs, f"README links {target}, but {path} has no such heading"

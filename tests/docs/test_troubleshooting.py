"""The troubleshooting page: its hand-written part explains every error class a user can
meet, and its generated catalogue (docs/_ext/error_catalogue.py) finds every raise site,
with messages that match what the code really raises and records that point at real lines."""

from __future__ import annotations

import importlib.util
import json
import re
import sys
from collections.abc import Iterable
from pathlib import Path
from types import ModuleType
from typing import Any

import numpy as np
import pytest

import planarcal
import planarcal.errors
import planarcal.live.output_spec
from planarcal.calib.calibration import Calibration
from planarcal.errors import (
    CalibrationFileError,
    DegenerateError,
    FrameSizeError,
    OutputError,
    PointAtInfinityError,
)

REPO = Path(__file__).resolve().parents[2]
PACKAGE = REPO / "python" / "planarcal"
PAGE = REPO / "docs" / "guides" / "troubleshooting.md"
DIRECTIVE = "```{error-catalogue}"


def _load_catalogue() -> ModuleType:
    """docs/_ext/error_catalogue.py, imported from its path (docs/_ext is no package)."""
    path = REPO / "docs" / "_ext" / "error_catalogue.py"
    spec = importlib.util.spec_from_file_location("error_catalogue", path)
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = module  # dataclasses look their module up by name
    spec.loader.exec_module(module)
    return module


catalogue = _load_catalogue()


@pytest.fixture(scope="module")
def sites() -> list[Any]:
    found: list[Any] = catalogue.raise_sites(PACKAGE)
    return found


@pytest.fixture(scope="module")
def rust_sites() -> list[Any]:
    rust = REPO / "rust"
    found: list[Any] = catalogue.core_messages(rust) + catalogue.binding_messages(rust)
    return found


def _hand_written() -> str:
    text = PAGE.read_text(encoding="utf-8")
    assert text.count(DIRECTIVE) == 1, "the page shows the generated catalogue once"
    return text.split(DIRECTIVE)[0]


def _public_classes() -> list[str]:
    """planarcal.errors' classes, and their subclasses elsewhere in the package."""
    found = catalogue.error_classes(PACKAGE)
    names = set(planarcal.errors.__all__) | {n for n in found if not n.startswith("_")}
    return sorted(names)


def _matches(message: str, templates: Iterable[str]) -> bool:
    """Whether ``message`` is one of ``templates`` with its placeholders filled in."""
    for template in templates:
        parts = re.split(r"\{[^{}]*\}", template)
        pattern = ".*?".join(re.escape(p) for p in parts)
        if re.fullmatch(pattern, message, flags=re.S):
            return True
    return False


def _templates(sites: Iterable[Any], error: str) -> list[str]:
    return [s.message for s in sites if s.error == error]


# -- (a) the hand-written part -------------------------------------------------------------


def test_every_error_class_is_explained_before_the_catalogue() -> None:
    text = _hand_written()
    classes = _public_classes()
    assert "CameraError" in classes and "LineFormatError" in classes  # both kinds found
    missing = [name for name in classes if not re.search(rf"\b{name}\b", text)]
    assert not missing, f"troubleshooting.md does not explain {missing}"


def test_the_exit_statuses_are_the_command_lines() -> None:
    # The page's table holds the statuses cli.py documents (its docstring and INTERRUPTED).
    from planarcal import cli  # noqa: PLC0415 (the CLI module only for its constants)

    text = _hand_written()
    table = re.findall(r"^\| *(\d+) *\|", text, flags=re.M)
    assert table == ["0", "1", "2", str(cli.INTERRUPTED)]
    assert cli.__doc__ is not None and "2 for a malformed command line" in cli.__doc__


# -- (b) the walker finds what a plain search finds, and real messages -------------------


def test_every_plain_raise_of_a_planarcal_class_is_a_site(sites: list[Any]) -> None:
    classes = set(catalogue.error_classes(PACKAGE))
    plain: set[tuple[str, int, str]] = set()
    for path in PACKAGE.rglob("*.py"):
        for number, line in enumerate(path.read_text(encoding="utf-8").splitlines(), 1):
            for name in re.findall(r"\braise\s+(\w+)\(", line):
                if name in classes:
                    plain.add((str(path), number, name))
    found = {(str(s.path), s.line, s.error) for s in sites}
    assert len(plain) > 500  # the search itself works
    assert not plain - found, sorted(plain - found)[:5]
    assert len([s for s in sites if s.raised]) >= len(plain)


@pytest.mark.parametrize(
    ("error", "message", "module"),
    [
        (
            "MissingDependencyError",
            "the report's figures need matplotlib, which is not installed: "
            "pip install 'planarcal[report]'",
            "planarcal.report.figure",
        ),
        ("LineFormatError", "the template format needs a template (--template)", None),
        ("StateError", "a Tracker can be iterated once", "planarcal.live.tracker"),
        # Raised through the caller's class (arguments.real(..., exc=...)).
        ("IntrinsicsError", "{name} must be finite, got {value}", "planarcal.arguments"),
        ("ImageError", "{name} must be finite, got {value}", "planarcal.arguments"),
        # Raised as type(e) of the BoardNotFoundError caught.
        (
            "BoardNotFoundError",
            "{placement_label(k, name)}: {e}",
            "planarcal.calib.placement_set",
        ),
    ],
)
def test_a_known_message_is_listed_with_its_class(
    sites: list[Any], error: str, message: str, module: str | None
) -> None:
    hits = [s for s in sites if s.error == error and s.message == message]
    assert hits, _templates(sites, error)[:10]
    assert module is None or module in {s.module for s in hits}


def test_real_messages_match_their_class_templates(
    sites: list[Any], rust_sites: list[Any], tmp_path: Path
) -> None:
    """Errors raised for real carry a message the catalogue lists under their class."""
    raised: list[BaseException] = []
    for call in (
        lambda: planarcal.live.output_spec.parse_network_spec("tcp://host"),
        lambda: planarcal.estimate_homography([[0, 0], [1, 0], [2, 0], [3, 0]], [[0, 0]] * 4),
        lambda: planarcal.transform_points(
            np.array([[1, 0, 0], [0, 1, 0], [0.01, 0, 1.0]]), [[0.0, 0.0], [-100.0, 0.0]]
        ),
        lambda: _calibration_of_version(tmp_path, 99),
        lambda: _calibration().check_image_size((640, 480)),
    ):
        with pytest.raises(planarcal.Error) as info:
            call()
        raised.append(info.value)
    kinds = [type(e) for e in raised]
    assert kinds == [
        OutputError,
        DegenerateError,
        PointAtInfinityError,
        CalibrationFileError,
        FrameSizeError,
    ]
    every = sites + rust_sites
    for e in raised:
        templates = _templates(every, type(e).__name__)
        assert _matches(str(e), templates), (str(e), templates[:8])
    assert not _matches("no such message", _templates(every, "OutputError"))


def _calibration() -> Calibration:
    world = np.array([[0, 0], [100, 0], [100, 80], [0, 80], [50, 40], [20, 60]], float)
    return Calibration(world, world * 2.0 + 10.0, lens="none", image_size=(320, 240))


def _calibration_of_version(directory: Path, version: int) -> None:
    path = directory / "calib.json"
    _calibration().save(path)
    data = json.loads(path.read_text())
    data["version"] = version
    path.write_text(json.dumps(data))
    Calibration.load(path)


# -- (c) the records point at real files and lines -----------------------------------------


def test_every_record_points_at_its_raise(sites: list[Any], rust_sites: list[Any]) -> None:
    reasons = catalogue.refusal_reasons(PACKAGE)
    assert len(reasons) > 10
    # A message said by a helper (a constant, a function returning it) is elsewhere.
    source = "\n".join(p.read_text(encoding="utf-8") for p in PACKAGE.rglob("*.py"))
    for site in [*sites, *rust_sites, *reasons]:
        lines = site.path.read_text(encoding="utf-8").splitlines()
        assert 1 <= site.line <= len(lines), site
        # The message is written at the call, or a little before it (message = f"...").
        near = "\n".join(lines[max(0, site.line - 15) : site.line + 12])
        words = re.findall(r"[A-Za-z]{5,}", re.sub(r"\{[^{}]*\}", " ", site.message))
        inlined = site.path.suffix == ".py" and all(w in source for w in words)
        assert not words or any(w in near for w in words) or inlined, (site, near)
        if site.path.suffix == ".py":
            relative = site.path.relative_to(PACKAGE).with_suffix("")
            assert site.module.split(".")[1:] == [p for p in relative.parts if p != "__init__"], (
                site
            )
            callee = lines[site.line - 1]
            assert site.error.split(".")[-1] in callee or re.search(r"\w+\)?\(", callee), site


def test_the_catalogue_groups_every_class_once(sites: list[Any]) -> None:
    groups = catalogue.by_error(sites)
    assert list(groups)[-2:] == list(catalogue.ARGPARSE_ERRORS)
    for error, group in groups.items():
        messages = [s.message for s in group]
        assert len(messages) == len(set(messages)), error
    assert sum(len(g) for g in groups.values()) > 600


def test_the_walker_resolves_classes_chosen_at_run_time(tmp_path: Path) -> None:
    package = tmp_path / "pkg"
    package.mkdir()
    (package / "errors.py").write_text(
        "class Error(Exception): ...\n"
        "class FooError(Error, ValueError): ...\n"
        "class BarError(FooError): ...\n"
    )
    (package / "work.py").write_text(
        "from pkg.errors import BarError, FooError as Foo\n"
        "HINT = 'try again'\n"
        "def check(value, exc=Foo):\n"
        "    raise exc(f'value {value!r} is bad')\n"
        "def use(v):\n"
        "    check(v, exc=BarError)\n"
        "    try:\n"
        "        check(v)\n"
        "    except BarError as e:\n"
        "        raise type(e)(f'while using: {e}') from None\n"
        "    raise Foo(HINT)\n"
        "def other():\n"
        "    raise ValueError('not ours')\n"
    )
    found = {(s.error, s.message, s.line) for s in catalogue.raise_sites(package)}
    assert found == {
        ("FooError", "value {value} is bad", 4),
        ("BarError", "value {value} is bad", 4),
        ("BarError", "while using: {e}", 10),
        ("FooError", "try again", 11),
    }
    foreign = catalogue.foreign_raises(package)
    assert [(path.name, line, name) for path, line, name in foreign] == [
        ("work.py", 13, "ValueError")
    ]

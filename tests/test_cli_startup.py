"""Start-up: `import planarcal`, `planarcal --help` and `planarcal --version` load no numpy,
OpenCV, SciPy or matplotlib (each command loads what it needs when it runs), while every
public name of the package still imports (lazily) as before. The time it saves is measured
in benches/bench_startup.py."""

from __future__ import annotations

import ast
import importlib.metadata
import json
import re
import subprocess
import sys
from pathlib import Path

import pytest

import planarcal
from test_cli import _run

HEAVY = ("numpy", "cv2", "scipy", "matplotlib", "planarcal.errors", "planarcal.calib")


def _modules_after(code: str) -> list[str]:
    """The modules a fresh interpreter holds after running `code`."""
    script = f"{code}\nimport json, sys\nprint(json.dumps(sorted(sys.modules)))"
    result = subprocess.run(
        [sys.executable, "-c", script], capture_output=True, text=True, timeout=120, check=False
    )
    assert result.returncode == 0, result.stderr
    loaded: list[str] = json.loads(result.stdout.splitlines()[-1])
    return loaded


def _heavy(loaded: list[str]) -> list[str]:
    return [m for m in loaded if any(m == h or m.startswith(h + ".") for h in HEAVY)]


@pytest.mark.parametrize(
    "code",
    [
        "import planarcal",
        "import planarcal.cli",
        "from planarcal.cli import main\ntry:\n    main(['--help'])\nexcept SystemExit:\n    pass",
        "from planarcal.cli import main\ntry:\n    main(['--version'])\nexcept SystemExit:\n"
        "    pass",
    ],
    ids=["import", "import-cli", "help", "version"],
)
def test_starting_up_loads_nothing_heavy(code: str) -> None:
    assert _heavy(_modules_after(code)) == []


def test_a_command_loads_what_it_needs_when_it_runs() -> None:
    loaded = _modules_after(
        "from planarcal.cli import main\ntry:\n    main(['locate', '--help'])\n"
        "except SystemExit:\n    pass"
    )
    assert "cv2" in loaded and "planarcal.commands.locate" in loaded
    assert "planarcal.commands.calibrate" not in loaded  # only the command asked for


def test_help_and_version_as_a_user_runs_them() -> None:
    result = _run("--version")
    assert result.returncode == 0 and result.stdout == f"planarcal {planarcal.__version__}\n"
    result = _run("--help")
    assert result.returncode == 0
    commands = ("board", "calibrate", "intrinsics", "register", "locate", "run", "live", "demo")
    for command in commands:
        assert f"    {command}" in result.stdout
    # A command's own help lists its arguments, loaded for it.
    for command, option in (("calibrate", "--measured-pitch"), ("register", "--drop-outliers")):
        result = _run(command, "--help")
        assert result.returncode == 0 and option in result.stdout, result.stderr
        assert f"usage: planarcal {command}" in result.stdout


# ------------------------------------------------------------------------------------------
# the lazy exports


def _type_checking_imports() -> dict[str, str]:
    """name -> module of the imports under `if TYPE_CHECKING:` in planarcal/__init__.py."""
    tree = ast.parse(Path(planarcal.__file__).read_text())
    found: dict[str, str] = {}
    for node in tree.body:
        if isinstance(node, ast.If) and ast.unparse(node.test) == "TYPE_CHECKING":
            for stmt in node.body:
                assert isinstance(stmt, ast.ImportFrom) and stmt.module is not None
                for alias in stmt.names:
                    found[alias.asname or alias.name] = stmt.module
    return found


def test_every_public_name_is_exported_lazily_from_its_module() -> None:
    static = _type_checking_imports()
    lazy = {n: m for m, names in planarcal._EXPORTS.items() for n in names}
    assert static == lazy  # what type checkers see is what runs
    assert sorted(planarcal.__all__) == sorted([*lazy, "__version__"])
    for name, module in lazy.items():
        assert getattr(planarcal, name) is getattr(sys.modules[module], name), name
    assert set(planarcal.__all__) <= set(dir(planarcal))
    namespace: dict[str, object] = {}
    exec("from planarcal import *", namespace)
    assert set(planarcal.__all__) <= set(namespace)
    with pytest.raises(AttributeError, match="no attribute 'nothing'"):
        _ = planarcal.nothing


def test_subpackages_still_come_with_the_package() -> None:
    loaded = _modules_after(
        "import planarcal\nassert planarcal.synth.paper_scene\nassert planarcal.robot.RobotFrame"
    )
    assert "planarcal.synth" in loaded


def test_the_version_is_written_in_one_place() -> None:
    """The wheel's metadata and planarcal.__version__ are both the Cargo workspace's."""
    cargo = Path(__file__).parents[1] / "Cargo.toml"
    written = re.search(r'^version = "([^"]+)"', cargo.read_text(), re.M)
    assert written is not None
    assert importlib.metadata.version("planarcal") == planarcal.__version__ == written[1]

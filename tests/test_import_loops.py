"""Layers import downward (STYLE.md): files that import each other in a loop are where a
model came to import its own description. These read every import statement of the package's
source (module level, inside functions, under TYPE_CHECKING: a loop of types is a loop too)
and check that the loops untangled in issue 22 stay untangled, and that the public names the
untangling moved still work."""

from __future__ import annotations

import ast
import functools
from pathlib import Path

import numpy as np
import pytest

import planarcal
from planarcal.camera import CameraIntrinsics
from planarcal.robot import RobotFrame
from planarcal.robot.summary import quality, registration_summary

PACKAGE_DIR = Path(planarcal.__file__).parent


def _module_name(path: Path) -> str:
    parts = path.relative_to(PACKAGE_DIR.parent).with_suffix("").parts
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


@functools.cache
def _modules() -> dict[str, Path]:
    return {_module_name(p): p for p in PACKAGE_DIR.rglob("*.py")}


def _resolve(name: str) -> str | None:
    """The package's module a dotted name is (or lies in): the longest known prefix."""
    parts = name.split(".")
    for k in range(len(parts), 0, -1):
        candidate = ".".join(parts[:k])
        if candidate in _modules():
            return candidate
    return None


@functools.cache
def imports_of(module: str) -> frozenset[str]:
    """Every planarcal module `module`'s file names in an import statement, anywhere in it."""
    path = _modules()[module]
    is_package = path.name == "__init__.py"
    out: set[str] = set()
    for node in ast.walk(ast.parse(path.read_text(), str(path))):
        if isinstance(node, ast.Import):
            names = [alias.name for alias in node.names]
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:
                anchor = module.split(".")
                anchor = anchor if is_package else anchor[:-1]
                anchor = anchor[: len(anchor) - (node.level - 1)]
                base = ".".join([*anchor, base] if base else anchor)
            # "from pkg import name": the submodule pkg.name when there is one, else pkg.
            names = [f"{base}.{alias.name}" for alias in node.names]
        else:
            continue
        for name in names:
            target = _resolve(name)
            if target is not None and target != module:
                out.add(target)
    return frozenset(out)


def reaches(start: str, goal: str) -> list[str] | None:
    """A chain of imports from `start` to `goal` (their files' import statements), or None."""
    seen = {start}
    todo = [[start]]
    while todo:
        chain = todo.pop()
        for nxt in sorted(imports_of(chain[-1])):
            if nxt == goal:
                return [*chain, nxt]
            if nxt not in seen:
                seen.add(nxt)
                todo.append([*chain, nxt])
    return None


def test_the_reader_sees_the_imports_it_should() -> None:
    """The premise: the walker finds the imports of a module's file, and chains of them."""
    assert "planarcal.robot.summary" in imports_of("planarcal.robot.registration")
    assert "planarcal.camera.file_storage" in imports_of("planarcal.camera.intrinsics")
    assert reaches("planarcal.robot.registration", "planarcal.robot.summary") is not None


@pytest.mark.parametrize(
    ("model", "description"),
    [
        ("planarcal.robot.registration", "planarcal.robot.summary"),
        ("planarcal.camera.intrinsics", "planarcal.camera.file_storage"),
    ],
)
def test_a_model_and_its_description_import_one_way(model: str, description: str) -> None:
    """The registration describes itself through robot.summary, the intrinsics read and write
    themselves through camera.file_storage; neither of those imports its model back, not
    even for a type."""
    assert reaches(model, description) is not None
    loop = reaches(description, model)
    assert loop is None, " -> ".join(loop or [])


def test_the_registration_still_describes_itself() -> None:
    """RobotFrame.summary, the name the untangling kept, is robot.summary's text."""
    rng = np.random.default_rng(3)
    plane = rng.uniform(0, 200, (8, 2))
    turn = np.deg2rad(30.0)
    rotation = np.array([[np.cos(turn), -np.sin(turn)], [np.sin(turn), np.cos(turn)]])
    robot = plane @ rotation.T + [400.0, -120.0] + rng.normal(0, 0.02, plane.shape)
    frame = RobotFrame.fit(plane, robot)
    text = frame.summary(lines=list(range(2, 10)))
    assert text == registration_summary(frame, list(range(2, 10)))
    assert frame.rotation_deg is not None and abs(abs(frame.rotation_deg) - 30.0) < 0.1
    assert f"rotation {frame.rotation_deg:.3f} deg" in text
    assert quality(frame) in {"excellent", "good"}


def test_the_intrinsics_still_read_and_write_themselves(tmp_path: Path) -> None:
    """CameraIntrinsics.save_yaml and load_yaml, the names the untangling kept, round-trip
    through camera.file_storage."""
    k = CameraIntrinsics(
        np.array([[900.0, 0.0, 640.0], [0.0, 905.0, 360.0], [0.0, 0.0, 1.0]]),
        np.array([-0.12, 0.03, 0.001, -0.0005, 0.0]),
        (1280, 720),
        rms_px=0.21,
        n_views=3,
        per_view_rms_px=(0.2, 0.22, 0.21),
    )
    for suffix in (".yaml", ".xml", ".json"):
        back = CameraIntrinsics.load_yaml(k.save_yaml(tmp_path / f"k{suffix}"))
        assert np.array_equal(back.matrix, k.matrix)
        assert np.array_equal(back.dist_coeffs, k.dist_coeffs)
        assert back.image_size == k.image_size and back.per_view_rms_px == k.per_view_rms_px

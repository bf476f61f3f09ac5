"""References to a name where it is defined, resolved to where the reference documents it.

The API reference documents each object under the name users import
(``planarcal.findHomography``), while docstrings and type hints name it where it is defined
(``planarcal.homography.opencv.findHomography``) or relative to their own module. Autodoc
links a class's two names (``:canonical:``) but not a function's or a constant's: when a
Python reference finds no target, the object it names is imported and, if the reference
documents that same object, the reference goes there.
"""

from __future__ import annotations

import importlib
import re
from typing import Any

from docutils import nodes
from sphinx.addnodes import pending_xref
from sphinx.application import Sphinx
from sphinx.environment import BuildEnvironment

_MISSING = object()
# Where autodoc says a docstring came from: the object's own dotted name.
_DOCSTRING_OF = re.compile(r"docstring of ([\w.]+)")
# Filled at the first unresolved reference of a build, once every page has been read.
_documented: dict[tuple[int, str], str] = {}


def _imported(path: str) -> object:
    """The object named by the dotted `path` (a module, or attributes of one), or _MISSING."""
    parts = path.split(".")
    for split in range(len(parts), 0, -1):
        try:
            value: object = importlib.import_module(".".join(parts[:split]))
        except ImportError:
            continue
        except Exception:  # a module that fails to import is no target
            return _MISSING
        for attribute in parts[split:]:
            value = getattr(value, attribute, _MISSING)
            if value is _MISSING:
                return _MISSING
        return value
    return _MISSING


def _documented_by_identity(env: BuildEnvironment) -> dict[tuple[int, str], str]:
    """(id of the object, its last name) -> the name the reference documents it under."""
    if not _documented:
        for name, entry in env.get_domain("py").objects.items():  # type: ignore[attr-defined]
            if entry.aliased or not name.startswith("planarcal"):
                continue
            value = _imported(name)
            if value is not _MISSING:
                _documented.setdefault((id(value), name.rsplit(".", 1)[-1]), name)
    return _documented


def _forget(app: Sphinx, env: BuildEnvironment) -> None:
    _documented.clear()


def _resolve(
    app: Sphinx, env: BuildEnvironment, node: pending_xref, contnode: nodes.TextElement
) -> nodes.reference | None:
    if node.get("refdomain") != "py":
        return None
    target: str = node["reftarget"].lstrip(".~")
    module = node.get("py:module")
    klass = node.get("py:class")
    candidates = [target]
    if module:
        candidates += [f"{module}.{target}"] + ([f"{module}.{klass}.{target}"] if klass else [])
    # A name relative to the docstring's own class or module, where it was written.
    source = _DOCSTRING_OF.search(node.source or "")
    if source:
        parts = source.group(1).split(".")
        candidates += [".".join([*parts[:n], target]) for n in range(len(parts), 0, -1)]
    documented = _documented_by_identity(env)
    names = [
        documented.get((id(value), candidate.rsplit(".", 1)[-1]))
        for candidate in candidates
        if (value := _imported(candidate)) is not _MISSING
    ]
    # A type hint's bare name (an alias, ``Coords``) the one documented object of that name
    # (Sphinx 9 finds these itself; 8 looks for a class only).
    if "." not in target:
        same_name = {name for name in documented.values() if name.endswith(f".{target}")}
        names += list(same_name) if len(same_name) == 1 else []
    name = next((n for n in names if n is not None), None)
    if name is None:
        return None
    # "obj": a function named by :class: in a type hint is still that function.
    return env.get_domain("py").resolve_xref(
        env, node["refdoc"], app.builder, "obj", name, node, contnode
    )


def setup(app: Sphinx) -> dict[str, Any]:
    app.connect("env-updated", _forget)
    app.connect("missing-reference", _resolve)
    return {"parallel_read_safe": True, "parallel_write_safe": True}

"""numpy's ``ArrayLike`` shown by its name (conf.py's ``autodoc_type_aliases``) also inside a
union: Sphinx 9 writes an aliased name there by its repr, "TypeAliasForwardRef('...')"
(``ArrayLike | None``), so the alias's repr is made its name."""

from __future__ import annotations

from typing import Any

from sphinx.application import Sphinx
from sphinx.util.inspect import TypeAliasForwardRef


def _name(alias: TypeAliasForwardRef) -> str:
    return alias.name


def setup(app: Sphinx) -> dict[str, Any]:
    TypeAliasForwardRef.__repr__ = _name  # type: ignore[method-assign]
    return {"parallel_read_safe": True, "parallel_write_safe": True}

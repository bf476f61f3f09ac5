"""How the API reference shows types: three corrections to what autodoc writes.

* numpy's ``ArrayLike`` by its name (conf.py's ``autodoc_type_aliases``) also inside a union:
  Sphinx 9 writes an aliased name there by its repr, "TypeAliasForwardRef('...')"
  (``ArrayLike | None``), so the alias's repr is made its name.
* No "Return type: None" under an exception: autodoc leaves ``__init__``'s out for a class,
  not for an exception.
* A private base (``_PointError``) stands for its own bases, which are documented.
"""

from __future__ import annotations

from typing import Any

from docutils import nodes
from sphinx.application import Sphinx
from sphinx.util.inspect import TypeAliasForwardRef


def _name(alias: TypeAliasForwardRef) -> str:
    return alias.name


def _no_return_type_on_exceptions(
    app: Sphinx, domain: str, objtype: str, content: nodes.Element
) -> None:
    if domain != "py" or objtype != "exception":
        return
    for field_list in [n for n in content.children if isinstance(n, nodes.field_list)]:
        for field in [f for f in field_list.children if f[0].astext() == "rtype"]:
            field_list.remove(field)
        if not field_list.children:
            content.remove(field_list)


def _public(bases: list[Any]) -> list[Any]:
    public: list[Any] = []
    for base in bases:
        private = getattr(base, "__name__", "").startswith("_")
        for each in _public(list(base.__bases__)) if private else [base]:
            if each not in public:
                public.append(each)
    return public


def _public_bases(app: Sphinx, name: str, obj: object, options: Any, bases: list[Any]) -> None:
    bases[:] = _public(bases)


def setup(app: Sphinx) -> dict[str, Any]:
    TypeAliasForwardRef.__repr__ = _name  # type: ignore[method-assign]
    app.connect("object-description-transform", _no_return_type_on_exceptions)
    app.connect("autodoc-process-bases", _public_bases)
    return {"parallel_read_safe": True, "parallel_write_safe": True}

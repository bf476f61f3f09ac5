"""planarcal's docstrings as reStructuredText: they are prose with ``literals``, so three
things are adjusted before Sphinx reads them.

* Google-style sections (``Args:``, ``Raises:``) in functions and classes go through napoleon;
  not in properties and attributes, whose first line is prose with a colon ("The frame: ..."),
  which napoleon would read as "type: description".
* ``|x|`` is an absolute value, not a substitution: its bars are escaped (outside literals).
* A constant with no docstring of its own shows none, rather than its type's (``dict``'s).
"""

from __future__ import annotations

import re
from typing import Any

from sphinx.application import Sphinx
from sphinx.ext.napoleon import Config
from sphinx.ext.napoleon.docstring import GoogleDocstring

_NAPOLEON = Config(napoleon_numpy_docstring=False, napoleon_use_rtype=False)
_PROSE_FIRST = ("attribute", "data", "property")
# An inline literal (kept as it is), or a bar outside one.
_LITERAL_OR_BAR = re.compile(r"(``.+?``)|\|")


def _escape_bars(line: str) -> str:
    return _LITERAL_OR_BAR.sub(lambda m: m.group(1) or r"\|", line)


def _is_table_row(line: str) -> bool:
    stripped = line.strip()
    return stripped.startswith(("|", "+")) and stripped.endswith(("|", "+"))


def _adjust(app: Sphinx, what: str, name: str, obj: object, options: Any, lines: list[str]) -> None:
    inherited = type(obj).__doc__
    if what == "data" and inherited and "\n".join(lines).strip() == inherited.strip():
        lines.clear()
        return
    if what not in _PROSE_FIRST:
        google = GoogleDocstring(lines, _NAPOLEON, app, what, name, obj, options)  # type: ignore[arg-type]
        lines[:] = google.lines()
    lines[:] = [line if _is_table_row(line) else _escape_bars(line) for line in lines]


def setup(app: Sphinx) -> dict[str, Any]:
    app.connect("autodoc-process-docstring", _adjust)
    return {"parallel_read_safe": True, "parallel_write_safe": True}

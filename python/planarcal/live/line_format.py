"""How ``planarcal run`` writes a frame as one line: JSON, CSV, or a template of the user's.

A robot controller reads one line per frame. Whatever the format, a frame is ONE line, an
empty frame included (so the controller knows the frame was seen and holds nothing), and a
trigger's answer is that one line. One line per part, the other habit of simple parsers,
would need an end-of-frame marker to tell "no parts" from "not answered yet", and a
trigger's answer would be several lines: one line per frame with a count does not.

``json``
    ``FrameResult.to_json()``: ``{"frame", "t", "coords", "objects": [{"id", "px", "mm",
    "std_mm", "angle_deg"}]}``, objects by ID, ``angle_deg`` null where the part is too
    round for an axis.
``csv``
    ``frame,t,coords,n`` then, for each of the n objects by ID, ``id,x,y,angle,std``, all
    on one line, comma-separated, no quoting (no field contains a comma)::

        17,1764070306.123456,board,2,1,40.1250,40.0100,12.50,0.00310,2,200.0000,60.0000,nan,0.00290

    No header line: rows differ in length, a client that connects mid-stream would never
    see it, and a trigger's answer is one line. The layout above is the contract.
``template``
    the same head (``frame,t,coords,n``) and, per object, the user's template instead of
    ``id,x,y,angle,std``: ``--template "{id},{x:.2f},{y:.2f},{angle:.1f}"`` gives
    ``17,1764070306.123456,board,2,1,40.12,40.01,12.5,2,200.00,60.00,nan``. ``csv`` is
    exactly the template ``{id},{x:.4f},{y:.4f},{angle:.2f},{std:.5f}`` (the JSON line's
    decimals; t to the microsecond).

Template fields (Python format specs apply: ``{x:.2f}``, ``{id:03d}``): frame (int), t
(float, s since the epoch, when the frame was read), coords (str: "board" or "robot", the
frame of reference of x, y and angle), n (int, objects in the frame), id (int, stable while
the part stays in view), x, y (float, mm in that frame), std (float, mm, the 1-sigma
uncertainty of x, y), angle (float, degrees in [-90, 90) in that frame), px, py (float, the
centroid in the image, px), area (float, px^2). A template is checked when it is compiled
(at start-up): an unknown field (``{xx}``) raises ``LineFormatError`` listing the fields, and
so does a field whose rendering could contain the line's separator (a comma) or a line
break, which would shift every later field of the line or split it: the ``,`` grouping
option (``{area:,.0f}`` gives ``1,147``), a comma as the fill character (``{x:,>10}``), the
``c`` type (``{id:c}`` turns ID 44 into a comma), and the ``n`` type (its grouping and
decimal mark follow the locale). Each field is rendered with large, small, negative and
non-finite values of its type to find out.

A part too round for an axis has no angle: ``nan`` in csv and templates (Python's rendering
of NaN under any float spec), null in JSON. A controller's number parser rejects ``nan``
instead of reading it as 0, so a robot never turns a gripper by an angle that does not
exist; a program that handles round parts tests the field for ``nan`` first.

Errors (a trigger that cannot be answered) are lines too: ``{"error": "...", "t": ...}`` in
JSON; ``ERROR,<message>`` in csv and templates (the message with its commas replaced by
semicolons, so the line has two fields). A frame line never starts with ``ERROR``.
"""

from __future__ import annotations

import itertools
import json
import math
import re
import string
import time
from typing import Any, Protocol

import numpy as np

from planarcal.errors import OutputError

__all__ = [
    "CSV_TEMPLATE",
    "FIELDS",
    "FORMATS",
    "LineFormat",
    "LineFormatError",
    "line_format",
]

FORMATS = ("json", "csv", "template")
"""The names ``--format`` accepts."""

CSV_TEMPLATE = "{id},{x:.4f},{y:.4f},{angle:.2f},{std:.5f}"
"""The per-object part of a csv line (the JSON line's decimals: 1e-4 mm, 1e-2 degree)."""

_HEAD_TEMPLATE = "{frame},{t:.6f},{coords},{n}"
"""The start of every csv and template line."""

_FRAME_FIELDS = ("frame", "t", "coords", "n")
_OBJECT_FIELDS = ("id", "x", "y", "std", "angle", "px", "py", "area")
FIELDS = _FRAME_FIELDS + _OBJECT_FIELDS
"""The names a template may use."""

SEPARATOR = ","
"""What separates the fields of a csv or template line."""

LINE_BREAKS = "\n\r\v\f\x1c\x1d\x1e\x85\u2028\u2029"
"""Characters that end a line for some reader (str.splitlines breaks at each of them)."""

_INT_FIELDS = ("frame", "n", "id")
_STR_FIELDS = ("coords",)
# What each field's type is tried with: a separator or a line break in any rendering, or a
# failure, refuses the template (44 and 10 are a comma's and a newline's code points).
_PROBES: dict[str, tuple[Any, ...]] = {
    "int": (0, 7, 10, 13, 44, 1147, -1234567, 2**53),
    "float": (0.0, 1147.0, -1234567.891, 1e21, 1e-7, math.nan, math.inf, -math.inf),
    "str": ("board", "robot"),
}


class LineFormatError(OutputError):
    """A template or format that cannot be used: an unknown field, a format spec that does
    not suit the field's type, a line break, an unknown format name."""


class FrameLike(Protocol):
    """What a line is made from (``planarcal.live.tracker.FrameResult``)."""

    @property
    def index(self) -> int: ...
    @property
    def timestamp(self) -> float: ...
    @property
    def coords(self) -> str: ...
    @property
    def ids(self) -> Any: ...
    @property
    def centroids_px(self) -> Any: ...
    @property
    def world_mm(self) -> Any: ...
    @property
    def std_mm(self) -> Any: ...
    @property
    def areas_px(self) -> Any: ...
    @property
    def angles_deg(self) -> Any: ...

    def to_json(self) -> str: ...


class LineFormat:
    """Turns a frame into its line (``frame``) and a failure into an error line (``error``)
    in one of the formats above; see the module docstring."""

    def __init__(self, name: str, template: str | None = None) -> None:
        if name not in FORMATS:
            raise LineFormatError(f"unknown line format {name!r}: expected one of {FORMATS}")
        if name == "template" and template is None:
            raise LineFormatError("the template format needs a template (--template)")
        if name != "template" and template is not None:
            raise LineFormatError(f"a template goes with the template format, not {name!r}")
        self.name = name
        self.template = CSV_TEMPLATE if name == "csv" else template
        self._head: _Compiled | None = None
        self._object: _Compiled | None = None
        if self.template is not None:
            self._head = _Compiled(_HEAD_TEMPLATE, _FRAME_FIELDS)
            self._object = _Compiled(self.template, FIELDS)
            _check_against_dummy(self)

    def frame(self, result: FrameLike) -> str:
        """The frame's line (no newline)."""
        if self._object is None or self._head is None:
            return result.to_json()
        n = len(result.ids)
        head = {"frame": result.index, "t": result.timestamp, "coords": result.coords, "n": n}
        line = self._head.render_one(head)
        if not n:
            return line
        order = np.argsort(result.ids, kind="stable")
        columns = _columns(result, order, self._object.fields, head, n)
        return line + "," + ",".join(map(self._object.text.format, *columns))

    def error(self, message: str, when: float | None = None) -> str:
        """An error line (no newline) saying `message`."""
        message = " ".join(message.split())  # one line, whatever the message held
        if self.name == "json":
            t = time.time() if when is None else when
            # Compact, like the frame lines; t to the microsecond, like theirs.
            return json.dumps({"error": message, "t": round(t, 6)}, separators=(",", ":"))
        return "ERROR," + message.replace(",", ";")

    def __repr__(self) -> str:
        suffix = f" {self.template!r}" if self.name == "template" else ""
        return f"<LineFormat {self.name}{suffix}>"


def line_format(name: str | None = None, template: str | None = None) -> LineFormat:
    """The LineFormat that ``--format`` and ``--template`` name (no name: json, or template
    when a template is given). Raises LineFormatError at once for a template that would
    fail, or a template given with another format."""
    if name is None:
        name = "json" if template is None else "template"
    return LineFormat(name, template)


MAX_SPEC_NUMBER = 64
"""The largest width or precision a template's field may ask for."""


class _Compiled:
    """A template with named fields turned into a positional one (``{0:.2f}``) and the
    names in that order, so that a row renders with one ``str.format(*values)``."""

    def __init__(self, template: str, allowed: tuple[str, ...]) -> None:
        if not isinstance(template, str) or not template.strip():
            raise LineFormatError("a template must be a non-empty string")
        if any(c in LINE_BREAKS for c in template):
            raise LineFormatError(f"template {template!r}: a line break would split the line")
        fields: list[str] = []
        out: list[str] = []
        try:
            parsed = list(string.Formatter().parse(template))
        except ValueError as e:
            raise LineFormatError(f"template {template!r}: {e}") from None
        for literal, name, spec, conversion in parsed:
            out.append(literal.replace("{", "{{").replace("}", "}}"))
            if name is None:
                continue
            if name not in allowed:
                what = "a positional field {}" if not name else f"unknown field {{{name}}}"
                raise LineFormatError(
                    f"template {template!r}: {what}; the fields are " + ", ".join(allowed)
                )
            if name not in fields:
                fields.append(name)
            if spec and ("{" in spec):
                raise LineFormatError(f"template {template!r}: nested fields are not allowed")
            # A width or precision of millions would build megabytes a part, every frame.
            if spec and any(int(d) > MAX_SPEC_NUMBER for d in re.findall(r"\d+", spec)):
                raise LineFormatError(
                    f"template {template!r}: {{{name}:{spec}}}: widths and precisions go up "
                    f"to {MAX_SPEC_NUMBER}"
                )
            conv = f"!{conversion}" if conversion else ""
            _check_field(template, name, conv, spec or "")
            out.append("{" + str(fields.index(name)) + conv + (f":{spec}" if spec else "") + "}")
        self.source = template
        self.text = "".join(out)
        self.fields = tuple(fields)

    def render_one(self, values: dict[str, Any]) -> str:
        return self.text.format(*(values[f] for f in self.fields))


def _check_field(template: str, name: str, conv: str, spec: str) -> None:
    """Raises LineFormatError naming the field when ``{name<conv>:<spec>}`` can render the
    separator or a line break (or fails) for some value of the field's type. A spec that
    does not suit the type at all is left to the dummy frame's check, which says so."""
    field = "{" + name + conv + (f":{spec}" if spec else "") + "}"
    if spec.endswith("n"):
        raise LineFormatError(
            f"template {template!r}: {field}: the 'n' type follows the locale, whose digit "
            f"grouping or decimal mark may be {SEPARATOR!r}, the separator of the line's "
            "fields; use 'd', 'f' or 'g'"
        )
    kind = "int" if name in _INT_FIELDS else "str" if name in _STR_FIELDS else "float"
    text = "{0" + conv + (f":{spec}" if spec else "") + "}"
    for value in _PROBES[kind]:
        try:
            rendered = text.format(value)
        except (ValueError, TypeError, OverflowError) as e:
            if value == _PROBES[kind][0] and not isinstance(e, OverflowError):
                return  # the spec does not suit the type: the dummy frame's check says so
            raise LineFormatError(
                f"template {template!r}: {field} cannot render {name} = {value!r}: {e}"
            ) from None
        bad = next((c for c in rendered if c == SEPARATOR or c in LINE_BREAKS), None)
        if bad is not None:
            what = (
                "a comma, the separator of the line's fields, so a parser would split it in two"
                if bad == SEPARATOR
                else f"a line break ({bad!r}), which would split the line"
            )
            raise LineFormatError(
                f"template {template!r}: field {name} ({field}) can render {what}: "
                f"{name} = {value!r} gives {rendered!r}; {_advice(spec)}"
            )


_SPEC = re.compile(
    r"(?:(?P<fill>.)?[<>=^])?[-+ ]?z?#?0?\d*(?P<grouping>[,_])?(?:\.\d+)?(?P<type>.)?"
)
"""Python's format spec mini-language, as far as the advice below needs it."""


def _advice(spec: str) -> str:
    """How to mend a field spec that can render a separator or a line break."""
    match = _SPEC.fullmatch(spec)
    parts = [] if match is None else [match["fill"], match["grouping"], match["type"]]
    fill, grouping, kind = parts or [None, None, None]
    if kind == "c":
        return "use the 'd' type for a number"
    if grouping == SEPARATOR:
        return "drop the ',' digit grouping (or use '_')"
    if fill is not None and fill == SEPARATOR:
        return "choose another fill character"
    return "choose another format spec"


def _columns(
    result: FrameLike, order: Any, fields: tuple[str, ...], head: dict[str, Any], n: int
) -> list[Any]:
    """One iterable per field of the template, a value per object (by ID)."""
    columns: list[Any] = []
    for name in fields:
        if name in head:
            columns.append(itertools.repeat(head[name], n))
        elif name == "id":
            columns.append(result.ids[order].tolist())
        elif name == "x":
            columns.append(result.world_mm[order, 0].tolist())
        elif name == "y":
            columns.append(result.world_mm[order, 1].tolist())
        elif name == "std":
            columns.append(result.std_mm[order].tolist())
        elif name == "angle":
            # NaN, never None: a float spec renders it as "nan" (see the module docstring).
            columns.append(result.angles_deg[order].astype(float).tolist())
        elif name == "px":
            columns.append(result.centroids_px[order, 0].tolist())
        elif name == "py":
            columns.append(result.centroids_px[order, 1].tolist())
        else:  # area
            columns.append(result.areas_px[order].tolist())
    return columns


class _Dummy:
    """A frame of two objects, one with an angle and one without, to try a template on."""

    index = 0
    timestamp = 1.0e9
    coords = "board"
    ids = np.array([1, 2], dtype=np.int64)
    centroids_px = np.array([[10.0, 20.0], [30.0, 40.0]])
    world_mm = np.array([[1.0, 2.0], [3.0, 4.0]])
    std_mm = np.array([0.01, 0.02])
    areas_px = np.array([100.0, 200.0])
    angles_deg = np.array([12.5, math.nan])

    def to_json(self) -> str:
        return ""


def _check_against_dummy(fmt: LineFormat) -> None:
    """Renders a dummy frame: a spec that does not suit its field's type (``{coords:.2f}``,
    ``{x:d}``) fails here, at start-up, naming the template and the cause."""
    try:
        line = fmt.frame(_Dummy())
    except (ValueError, TypeError, KeyError, IndexError) as e:
        raise LineFormatError(f"template {fmt.template!r} cannot be rendered: {e}") from None
    if "\n" in line or "\r" in line:
        raise LineFormatError(f"template {fmt.template!r} renders a line break")

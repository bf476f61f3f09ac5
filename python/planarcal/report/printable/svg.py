"""The laid-out page as SVG: ``width``/``height`` in mm and a ``viewBox`` in mm, so one user
unit is one mm; dots are ``<circle>`` elements (exact circles), a board's black squares and
marker cells one ``<path>`` of rectangles (``M x0 y0 H x1 V y1 H x0 Z`` each)."""

from __future__ import annotations

from xml.sax.saxutils import escape, quoteattr

from planarcal.calib.boards import Board
from planarcal.report.printable.layout import Drawing, document_title
from planarcal.report.printable.shapes import Area, Circle, Line, Polygon, fmt

_FONT_FAMILY = "Courier, 'Courier New', 'Liberation Mono', 'DejaVu Sans Mono', monospace"


def svg_bytes(drawing: Drawing, board: Board) -> bytes:
    w, h = drawing.size
    title = f"{document_title(board)}; {drawing.page} {drawing.orientation}"
    out = [
        '<?xml version="1.0" encoding="UTF-8" standalone="no"?>',
        f'<svg xmlns="http://www.w3.org/2000/svg" version="1.1" width="{fmt(w)}mm" '
        f'height="{fmt(h)}mm" viewBox="0 0 {fmt(w)} {fmt(h)}">',
        f"<title>{escape(title)}</title>",
        "<desc>Print at 100% (actual size); one user unit is one millimetre. World point "
        f"(X, Y) of the board is at page ({fmt(drawing.offset[0])} + X, "
        f"{fmt(drawing.offset[1])} + Y).</desc>",
        f'<rect id="page" x="0" y="0" width="{fmt(w)}" height="{fmt(h)}" fill="#ffffff"/>',
    ]
    groups: dict[str, list[str]] = {}
    for shape in drawing.shapes:
        attrs = f'id="{shape.id}" class="{shape.cls}"'
        if isinstance(shape, Circle):
            white = ' fill="#ffffff"' if shape.white else ""
            element = (
                f'<circle {attrs} cx="{fmt(shape.cx)}" cy="{fmt(shape.cy)}" '
                f'r="{fmt(shape.r)}"{white}/>'
            )
        elif isinstance(shape, Area):
            path = " ".join(
                f"M{fmt(x0)} {fmt(y0)}H{fmt(x1)}V{fmt(y1)}H{fmt(x0)}Z"
                for x0, y0, x1, y1 in shape.rects
            )
            element = f'<path {attrs} d="{path}"/>'
        elif isinstance(shape, Line):
            element = (
                f'<line {attrs} x1="{fmt(shape.x1)}" y1="{fmt(shape.y1)}" '
                f'x2="{fmt(shape.x2)}" y2="{fmt(shape.y2)}" '
                f'stroke="#000000" stroke-width="{fmt(shape.width)}" stroke-linecap="butt"/>'
            )
        elif isinstance(shape, Polygon):
            points = " ".join(f"{fmt(x)},{fmt(y)}" for x, y in shape.points)
            element = f'<polygon {attrs} points="{points}"/>'
        else:
            weight = ' font-weight="bold"' if shape.bold else ""
            element = (
                f'<text {attrs} x="{fmt(shape.x)}" y="{fmt(shape.y)}" '
                f'font-size="{fmt(shape.size)}" text-anchor="{shape.anchor}"{weight}>'
                f"{escape(shape.text)}</text>"
            )
        groups.setdefault(shape.group, []).append(element)
    for group, elements in groups.items():
        # Only lines are stroked (each says so); everything else is filled black.
        has_text = any(e.startswith("<text") for e in elements)
        font = f" font-family={quoteattr(_FONT_FAMILY)}" if has_text else ""
        out.append(f'<g id="{group}" fill="#000000" stroke="none"{font}>')
        out += elements
        out.append("</g>")
    out.append("</svg>")
    return ("\n".join(out) + "\n").encode("utf-8")

"""The laid-out page as a one-page PDF, written by hand: the MediaBox is the page in points
(mm * 72 / 25.4); one ``cm`` operator scales the content to mm (72 / 25.4 written to 12
decimals) and flips y; dots are the usual four cubic Bezier arcs, exact at their four
extreme points and within 0.03 % of the radius between them (2 micrometres on a 15 mm dot);
a board's black squares and marker cells are one path of rectangles filled at once.
Text uses the standard Courier fonts (no embedding, widths exactly 0.6 em), and the catalog
asks viewers not to scale when printing (``/PrintScaling /None``)."""

from __future__ import annotations

import math
import zlib

from planarcal.calib.boards import Board
from planarcal.report.printable.layout import Drawing, document_title
from planarcal.report.printable.shapes import Area, Circle, Line, Polygon, fmt

PT_PER_MM = 72.0 / 25.4
"""PDF points per millimetre (a point is 1/72 inch, an inch 25.4 mm)."""


_KAPPA = 4.0 * (math.sqrt(2.0) - 1.0) / 3.0  # Bezier control distance of a quarter circle


def _pdf_string(text: str) -> str:
    escaped = text.replace("\\", "\\\\").replace("(", "\\(").replace(")", "\\)")
    return f"({escaped})"


def _pdf_content(drawing: Drawing) -> bytes:
    h = drawing.size[1]
    k = f"{PT_PER_MM:.12f}"
    ops = [
        "% planarcal board: user units are mm from the top-left corner, y down",
        f"q {k} 0 0 -{k} 0 {fmt(h * PT_PER_MM)} cm",
        "0 g 0 G 0 J 0 j",
    ]
    for shape in drawing.shapes:
        if isinstance(shape, Circle):
            cx, cy, r = shape.cx, shape.cy, shape.r
            c = _KAPPA * r
            f = fmt
            disc = (
                f"{f(cx + r)} {f(cy)} m "
                f"{f(cx + r)} {f(cy + c)} {f(cx + c)} {f(cy + r)} {f(cx)} {f(cy + r)} c "
                f"{f(cx - c)} {f(cy + r)} {f(cx - r)} {f(cy + c)} {f(cx - r)} {f(cy)} c "
                f"{f(cx - r)} {f(cy - c)} {f(cx - c)} {f(cy - r)} {f(cx)} {f(cy - r)} c "
                f"{f(cx + c)} {f(cy - r)} {f(cx + r)} {f(cy - c)} {f(cx + r)} {f(cy)} c h f"
            )
            # A white disc is filled white, then black is the fill again.
            ops.append(f"1 g {disc} 0 g" if shape.white else disc)
        elif isinstance(shape, Area):
            ops += [
                f"{fmt(x0)} {fmt(y0)} m {fmt(x1)} {fmt(y0)} l {fmt(x1)} {fmt(y1)} l "
                f"{fmt(x0)} {fmt(y1)} l h"
                for x0, y0, x1, y1 in shape.rects
            ]
            ops.append("f")
        elif isinstance(shape, Line):
            ops.append(
                f"{fmt(shape.width)} w {fmt(shape.x1)} {fmt(shape.y1)} m "
                f"{fmt(shape.x2)} {fmt(shape.y2)} l S"
            )
        elif isinstance(shape, Polygon):
            (x0, y0), *rest = shape.points
            path = " ".join(f"{fmt(x)} {fmt(y)} l" for x, y in rest)
            ops.append(f"{fmt(x0)} {fmt(y0)} m {path} h f")
        else:
            font = "/F2" if shape.bold else "/F1"
            ops.append(
                f"BT {font} {fmt(shape.size)} Tf 1 0 0 -1 {fmt(shape.pdf_x())} "
                f"{fmt(shape.y)} Tm {_pdf_string(shape.text)} Tj ET"
            )
    ops.append("Q")
    return ("\n".join(ops) + "\n").encode("latin-1")


def pdf_bytes(drawing: Drawing, board: Board) -> bytes:
    w, h = drawing.size
    content = zlib.compress(_pdf_content(drawing), 9)
    title = document_title(board)
    objects: list[bytes] = [
        b"<< /Type /Catalog /Pages 2 0 R "
        b"/ViewerPreferences << /PrintScaling /None /PickTrayByPDFSize true >> >>",
        b"<< /Type /Pages /Kids [3 0 R] /Count 1 >>",
        (
            f"<< /Type /Page /Parent 2 0 R /MediaBox [0 0 {fmt(w * PT_PER_MM)} "
            f"{fmt(h * PT_PER_MM)}] /Resources << /Font << /F1 5 0 R /F2 6 0 R >> >> "
            "/Contents 4 0 R >>"
        ).encode("latin-1"),
        f"<< /Length {len(content)} /Filter /FlateDecode >>\nstream\n".encode("latin-1")
        + content
        + b"\nendstream",
        b"<< /Type /Font /Subtype /Type1 /BaseFont /Courier /Encoding /WinAnsiEncoding >>",
        b"<< /Type /Font /Subtype /Type1 /BaseFont /Courier-Bold /Encoding /WinAnsiEncoding >>",
        f"<< /Title {_pdf_string(title)} /Producer (planarcal) >>".encode("latin-1"),
    ]
    out = bytearray(b"%PDF-1.7\n%\xe2\xe3\xcf\xd3\n")
    offsets = []
    for number, body in enumerate(objects, start=1):
        offsets.append(len(out))
        out += f"{number} 0 obj\n".encode("latin-1") + body + b"\nendobj\n"
    xref = len(out)
    out += f"xref\n0 {len(objects) + 1}\n".encode("latin-1")
    out += b"0000000000 65535 f \n"
    for offset in offsets:
        out += f"{offset:010d} 00000 n \n".encode("latin-1")
    out += (
        f"trailer\n<< /Size {len(objects) + 1} /Root 1 0 R /Info {len(objects)} 0 R >>\n"
        f"startxref\n{xref}\n%%EOF\n"
    ).encode("latin-1")
    return bytes(out)

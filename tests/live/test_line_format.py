"""The line formats of `planarcal run`: JSON as the core writes it, csv and templates parsed
back field by field (objects by ID, a missing angle as nan, an empty frame still a line),
error lines a parser tells from frame lines, and templates refused at compile time with the
list of fields."""

from __future__ import annotations

import json
import math
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from planarcal.errors import OutputError
from planarcal.live.line_format import (
    CSV_TEMPLATE,
    FIELDS,
    LineFormat,
    LineFormatError,
    line_format,
)
from planarcal.live.tracker import FrameResult


def frame(n: int = 3, index: int = 17) -> FrameResult:
    """A frame of `n` objects whose IDs are out of order, the second one without an angle."""
    ids = np.array([5, 2, 9, 7, 1, 3][:n], dtype=np.int64)
    px = np.array([[100.0 + 10 * k, 50.0 + 5 * k] for k in range(n)]).reshape(n, 2)
    mm = np.array([[12.34567 + k, -3.21 * k] for k in range(n)]).reshape(n, 2)
    std = np.array([0.001 * (k + 1) for k in range(n)])
    areas = np.array([400.0 + k for k in range(n)])
    angles = np.array([30.0 - 20 * k for k in range(n)])
    if n > 1:
        angles[1] = np.nan
    return FrameResult(index, 1764070306.5, ids, px, mm, std, areas, angles, "robot")


def objects_by_id(r: FrameResult) -> list[tuple[int, float, float, float, float]]:
    """(id, x, y, angle, std) of each object, by ID."""
    order = np.argsort(r.ids)
    return [
        (
            int(r.ids[k]),
            float(r.world_mm[k, 0]),
            float(r.world_mm[k, 1]),
            float(r.angles_deg[k]),
            float(r.std_mm[k]),
        )
        for k in order
    ]


def test_json_is_the_frames_own_line() -> None:
    r = frame()
    fmt = line_format()
    assert fmt.name == "json" and fmt.frame(r) == r.to_json()
    parsed = json.loads(fmt.frame(r))
    assert parsed["coords"] == "robot" and [o["id"] for o in parsed["objects"]] == [2, 5, 9]
    assert [o["angle_deg"] for o in parsed["objects"]] == [None, 30.0, -10.0]


def test_csv_line_parses_back_to_the_objects_by_id() -> None:
    r = frame()
    line = line_format("csv").frame(r)
    assert "\n" not in line
    fields = line.split(",")
    assert fields[:4] == ["17", "1764070306.500000", "robot", "3"]
    rest = fields[4:]
    assert len(rest) == 3 * 5
    for k, (oid, x, y, angle, std) in enumerate(objects_by_id(r)):
        got = rest[5 * k : 5 * k + 5]
        assert int(got[0]) == oid
        assert float(got[1]) == pytest.approx(x, abs=5e-5)
        assert float(got[2]) == pytest.approx(y, abs=5e-5)
        assert float(got[4]) == pytest.approx(std, abs=5e-6)
        if math.isnan(angle):
            assert got[3] == "nan" and math.isnan(float(got[3]))
        else:
            assert float(got[3]) == pytest.approx(angle, abs=5e-3)


def test_csv_is_the_csv_template_and_an_empty_frame_is_still_a_line() -> None:
    r = frame()
    assert line_format("csv").frame(r) == line_format("template", CSV_TEMPLATE).frame(r)
    empty = frame(0, index=4)
    assert line_format("csv").frame(empty) == "4,1764070306.500000,robot,0"
    assert line_format(template="{id},{x:.2f}").frame(empty) == "4,1764070306.500000,robot,0"


def test_template_renders_each_object_with_its_specs() -> None:
    r = frame(2)
    fmt = line_format(template="{id:03d},{x:.2f},{y:.2f},{angle:.1f},{px:.0f},{coords}")
    assert fmt.name == "template"
    assert fmt.frame(r) == (
        "17,1764070306.500000,robot,2,002,13.35,-3.21,nan,110,robot,005,12.35,-0.00,30.0,100,robot"
    )
    # Every field renders, with and without a spec.
    every = line_format(template=",".join("{" + f + "}" for f in FIELDS))
    assert every.frame(r).count(",") == 3 + 2 * len(FIELDS)


@pytest.mark.parametrize(
    ("template", "message"),
    [
        ("{xx}", r"unknown field \{xx\}; the fields are frame, t, coords, n, id, x, y"),
        ("{}", "a positional field"),
        ("{0}", r"unknown field \{0\}"),
        ("{x.real}", r"unknown field \{x.real\}"),
        ("{coords:.2f}", "cannot be rendered: Unknown format code 'f'"),
        ("{x:d}", "cannot be rendered"),
        ("{x", "expected '}'"),
        ("{x}\n{y}", "line break"),
        ("  ", "non-empty"),
        ("{x:{y}}", "nested"),
        ("{x:>999999999}", r"\{x:>999999999\}: widths and precisions go up to 64"),
        ("{x:.100f}", "widths and precisions go up to 64"),
    ],
)
def test_bad_templates_are_refused_when_compiled(template: str, message: str) -> None:
    with pytest.raises(LineFormatError, match=message) as info:
        line_format(template=template)
    assert isinstance(info.value, OutputError) and isinstance(info.value, ValueError)


@pytest.mark.parametrize(
    ("template", "message"),
    [
        ("{id},{area:,.0f}", r"field area \(\{area:,.0f\}\) can render a comma.*'1,147'.*grouping"),
        ("{id:,d}", r"field id \(\{id:,d\}\) can render a comma"),
        ("{t:,.6f}", r"field t .* can render a comma"),
        ("{x:,>12.3f}", r"field x .*can render a comma.*another fill character"),
        (
            "{coords:,^9}",
            r"field coords .*can render a comma.*: coords = 'board' gives ',,board,,'",
        ),
        ("{id:c}", r"field id \(\{id:c\}\) can render a line break \('\\n'\).*'d' type"),
        ("{x:n}", r"\{x:n\}: the 'n' type follows the locale"),
        ("{id}\x0b{x}", "line break"),
        ("{x:\u2028>9}", "line break"),
    ],
)
def test_templates_that_can_render_the_separator_are_refused_naming_the_field(
    template: str, message: str
) -> None:
    with pytest.raises(LineFormatError, match=message):
        line_format(template=template)


def test_fields_that_cannot_render_the_separator_are_accepted() -> None:
    fmt = line_format(template="{id:03d},{x:+.3f},{area:_.0f},{y:>12.2f},{coords!r},{std:.2e}")
    line = fmt.frame(frame(1))
    assert line.count(",") == 3 + 6  # the head's separators, then the template's own five


def test_run_refuses_a_template_that_can_render_a_comma_at_start_up(tmp_path: Path) -> None:
    # Neither the calibration nor the source exist: the template is refused before both.
    done = subprocess.run(
        [
            sys.executable,
            "-m",
            "planarcal",
            "run",
            "--source",
            str(tmp_path / "none.avi"),
            "--calibration",
            str(tmp_path / "none.json"),
            "--template",
            "{id},{x:.2f},{area:,.0f}",
        ],
        capture_output=True,
        text=True,
        timeout=120,
        check=False,
    )
    assert done.returncode != 0 and done.stdout == ""
    assert "field area ({area:,.0f}) can render a comma" in done.stderr, done.stderr
    assert "none.avi" not in done.stderr and "none.json" not in done.stderr


def test_format_and_template_must_agree() -> None:
    with pytest.raises(LineFormatError, match="goes with the template format, not 'csv'"):
        line_format("csv", "{id}")
    with pytest.raises(LineFormatError, match="needs a template"):
        line_format("template")
    with pytest.raises(LineFormatError, match="unknown line format 'xml'"):
        LineFormat("xml")


def test_error_lines_are_one_line_a_parser_tells_from_a_frame() -> None:
    message = "no frame within 3 s, camera\nlost"
    parsed = json.loads(line_format().error(message, when=12.0))
    assert parsed == {"error": "no frame within 3 s, camera lost", "t": 12.0}
    for fmt in (line_format("csv"), line_format(template="{id}")):
        line = fmt.error(message)
        assert line == "ERROR,no frame within 3 s; camera lost"
        assert line.count(",") == 1 and not fmt.frame(frame()).startswith("ERROR")

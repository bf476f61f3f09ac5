"""A calibration file loads only as what it was saved as (issue 21): an edit by hand is refused
with a CalibrationFileError naming the field (the digest of version 4, and checks that every
value the others determine agrees, which hold even where a digest was recomputed); what loads
can be saved again, byte for byte the same; a deliberate edit is loaded with trust_edits=True.
Real files on disk, real registrations, every leaf of a real file edited."""

from __future__ import annotations

import copy
import json
import math
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from planarcal.calib.board import CircleGridBoard
from planarcal.calib.calibration import Calibration
from planarcal.calib.calibration_file import FILE_VERSION, field_digests
from planarcal.errors import BoardError, CalibrationFileError
from planarcal.synth import paper_data
from test_cli import _run

WORLD = np.array(paper_data.WORLD_MM)
IMAGE = np.array(paper_data.IMAGE_PX)
DATA = Path(__file__).resolve().parents[1] / "robot" / "data"
V2_FILE = DATA / "calibration_v2.json"
V3_FILE = Path(__file__).resolve().parent / "data" / "calibration_v3_registered.json"
"""The paper's 28 points registered by N-point pairs (image px, so plane_std_mm) with z,
saved by the planarcal before the digest (file version 3)."""

PROBE_PX = np.array([[640.0, 360.0], [400.0, 200.0], [900.0, 540.0], [380.5, 170.25]])


def _registered() -> Calibration:
    """The paper's points with board and image size, registered by N-point pairs (image px:
    plane_std_mm) with z to a mirrored, turned robot frame."""
    cal = Calibration(WORLD, IMAGE, board=CircleGridBoard(), image_size=(1280, 720), lens="none")
    points = [0, 13, 20, 27, 6]
    turn = math.radians(-120.0)
    rotation = np.array([[math.cos(turn), -math.sin(turn)], [math.sin(turn), math.cos(turn)]])
    robot = WORLD[points] @ (rotation @ np.diag([1.0, -1.0])).T + [410.0, -230.0]
    robot += np.random.default_rng(3).normal(0.0, 0.05, robot.shape)
    return cal.register(robot, image_px=IMAGE[points], robot_z=[12.0, 12.1, 11.9, 12.05, 12.0])


@pytest.fixture(scope="module")
def registered() -> Calibration:
    return _registered()


@pytest.fixture(scope="module")
def saved(registered: Calibration, tmp_path_factory: pytest.TempPathFactory) -> dict[str, Any]:
    """The registered calibration's file, parsed."""
    path = registered.save(tmp_path_factory.mktemp("saved") / "calib.json")
    data: dict[str, Any] = json.loads(path.read_text())
    return data


def _write(path: Path, data: Any) -> Path:
    path.write_text(json.dumps(data, indent=2))
    return path


def _redigested(data: dict[str, Any]) -> dict[str, Any]:
    """`data` with its digest recomputed: what a careless user's script would write."""
    out = copy.deepcopy(data)
    out["digest"] = {"sha256": field_digests(out)}
    return out


def _meaning(cal: Calibration) -> dict[str, Any]:
    """What a loaded calibration does: maps pixels to the board and the robot with their
    1-sigma, world to image, and what it would save (all of it but when it was made)."""
    board, board_std = cal.image_to_world(PROBE_PX, return_std=True)
    out: dict[str, Any] = {
        "board": board.tolist(),
        "board_std": board_std.tolist(),
        "image": cal.world_to_image(WORLD[::5]).tolist(),
        "file": cal.to_dict(),
    }
    if cal.robot_frame is not None:
        robot, robot_std = cal.image_to_world(PROBE_PX, return_std=True, frame="robot")
        out["robot"], out["robot_std"] = robot.tolist(), robot_std.tolist()
    return out


# -- 1. edits that change what a file means are refused, naming the field ------------------

EDITS: list[tuple[str, Callable[[dict[str, Any]], None], str]] = [
    ("pitch", lambda d: d["board"].update(pitch_mm=20.4), r"board"),
    ("cols", lambda d: d["board"].update(cols=15), r"board"),
    ("rows", lambda d: d["board"].update(rows=11), r"board"),
    ("cols and rows", lambda d: d["board"].update(cols=10, rows=14), r"board"),
    ("dot size", lambda d: d["board"].update(diameter_mm=12.0), r"board"),
    ("world scale", lambda d: d.update(world_scale=[1.02, 1.0]), r"world_scale"),
    ("image size", lambda d: d.update(image_size_px=[1920, 1080]), r"image_size_px"),
    ("image size swapped", lambda d: d.update(image_size_px=[720, 1280]), r"image_size_px"),
    ("plane std", lambda d: d["robot_frame"]["plane_std_mm"].__setitem__(0, 0.5), "robot_frame"),
    ("no robot frame", lambda d: d.pop("robot_frame"), r"robot_frame"),
    ("robot frame null", lambda d: d.update(robot_frame=None), r"robot_frame"),
    ("robot x a string", lambda d: d["robot_frame"]["robot_mm"][1].__setitem__(0, "250"), "robot"),
    ("z a boolean", lambda d: d["robot_frame"]["robot_z_mm"].__setitem__(2, True), "robot_z_mm"),
    ("drop a string", lambda d: d["robot_frame"].update(drop_outliers="false"), "drop_outliers"),
    ("z beyond", lambda d: d["robot_frame"]["robot_z_mm"].__setitem__(0, 1e308), "robot_z_mm"),
    ("residual", lambda d: d["robot_frame"]["residuals_mm"].__setitem__(1, 0.001), "residuals"),
    ("tilt", lambda d: d["robot_frame"]["plane"].update(rms_mm=0.0), r"robot_frame"),
    ("note", lambda d: d.update(lens_note="a fine lens"), r"lens_note"),
    ("created", lambda d: d.update(created="2020-01-01T00:00:00+00:00"), r"created"),
    ("summary", lambda d: d["summary"].update(loo_rms_mm=0.001), r"summary"),
    ("version", lambda d: d.update(version=3), r"digest|version"),
    ("no digest", lambda d: d.pop("digest"), r"digest"),
    ("a field added", lambda d: d.update(comment="mine"), r"comment"),
]


@pytest.mark.parametrize(("edit", "match"), [e[1:] for e in EDITS], ids=[e[0] for e in EDITS])
def test_a_hand_edit_is_refused_naming_the_field(
    saved: dict[str, Any], tmp_path: Path, edit: Callable[[dict[str, Any]], None], match: str
) -> None:
    data = copy.deepcopy(saved)
    edit(data)
    with pytest.raises(CalibrationFileError, match=match):
        Calibration.load(_write(tmp_path / "edited.json", data))


INCONSISTENT: list[tuple[str, Callable[[dict[str, Any]], None], str]] = [
    ("pitch", lambda d: d["board"].update(pitch_mm=20.4), r"world_mm: world point 1 .* board"),
    ("cols and rows", lambda d: d["board"].update(cols=10, rows=14), r"not a dot of the board"),
    ("world scale", lambda d: d.update(world_scale=[1.02, 1.0]), r"scaled by \[1.02, 1.0\]"),
    ("scale huge", lambda d: d.update(world_scale=[1e300, 1.0]), r"on the dot of another point"),
    ("scale tiny", lambda d: d.update(world_scale=[5e-324, 1.0]), r"0 \(0, 0\) mm is not a dot"),
    ("image size cut", lambda d: d.update(image_size_px=[600, 1280]), r"outside the 600 x"),
    ("robot x a string", lambda d: d["robot_frame"]["robot_mm"][1].__setitem__(0, "250"), "mm"),
    (
        "z a boolean",
        lambda d: d["robot_frame"]["robot_z_mm"].__setitem__(2, True),
        r"\[2\] is true",
    ),
    ("drop a string", lambda d: d["robot_frame"].update(drop_outliers="no"), "drop_outliers must"),
    ("reflected", lambda d: d["robot_frame"].update(reflected=0), "reflected must be true"),
    ("z beyond", lambda d: d["robot_frame"]["robot_z_mm"].__setitem__(0, 1e308), r"z_mm\[0\]"),
    (
        "residual",
        lambda d: d["robot_frame"]["residuals_mm"].__setitem__(1, 0.001),
        r"residuals_mm\[1\]",
    ),
    ("tilt", lambda d: d["robot_frame"]["plane"].update(rms_mm=0.0), "robot_frame.plane.rms_mm"),
    ("rotation", lambda d: d["robot_frame"].update(rotation_deg=0.0), "rotation_deg is 0.0"),
    ("solver named", lambda d: d["summary"].update(solver="a33"), "summary.solver"),
    ("deviation", lambda d: d["summary"].update(max_abs_dx_mm=0.5), "summary.max_abs_dx_mm"),
    ("no robot frame", lambda d: d.pop("robot_frame"), "missing the field robot_frame"),
    ("unknown field", lambda d: d["board"].update(colour="red"), "unknown field board.colour"),
]


@pytest.mark.parametrize(
    ("edit", "match"), [e[1:] for e in INCONSISTENT], ids=[e[0] for e in INCONSISTENT]
)
def test_an_inconsistent_file_is_refused_even_with_its_digest_recomputed(
    saved: dict[str, Any], tmp_path: Path, edit: Callable[[dict[str, Any]], None], match: str
) -> None:
    data = copy.deepcopy(saved)
    edit(data)
    path = _write(tmp_path / "edited.json", _redigested(data))
    for trust_edits in (False, True):
        with pytest.raises(CalibrationFileError, match=match):
            Calibration.load(path, trust_edits=trust_edits)


def test_the_refusal_says_how_to_change_a_file(saved: dict[str, Any], tmp_path: Path) -> None:
    data = copy.deepcopy(saved)
    data["image_size_px"] = [1920, 1080]
    with pytest.raises(
        CalibrationFileError,
        match=r"image_size_px is not what the file was saved with \(its digest does not "
        r"match\): edited by hand\? .*planarcal check .* --accept-edits "
        r"\(docs/guides/calibrating.md, Calibration files\)$",
    ):
        Calibration.load(_write(tmp_path / "edited.json", data))
    # The page and the section the refusal points at exist.
    guide = Path(__file__).resolve().parents[2] / "docs" / "guides" / "calibrating.md"
    assert "\n## Calibration files\n" in guide.read_text(encoding="utf-8")


# -- 2. old files -----------------------------------------------------------------------------


def test_files_of_versions_two_and_three_still_load(tmp_path: Path) -> None:
    old = Calibration.load(V2_FILE)
    assert old.lens_model == "k1k2c" and old.robot_frame is None
    v3 = json.loads(V3_FILE.read_text())
    assert v3["version"] == 3 and "digest" not in v3
    cal = Calibration.load(V3_FILE)
    assert cal.robot_frame is not None and cal.robot_frame.plane_std_mm is not None
    assert cal.created == v3["created"]
    again = Calibration.load(cal.save(tmp_path / "v7.json"))
    assert json.loads((tmp_path / "v7.json").read_text())["version"] == FILE_VERSION == 7
    np.testing.assert_array_equal(
        again.image_to_world(PROBE_PX, frame="robot"), cal.image_to_world(PROBE_PX, frame="robot")
    )


OLD_EDITS: list[tuple[str, Callable[[dict[str, Any]], None], str]] = [
    ("no robot frame", lambda d: d.pop("robot_frame"), "missing the field robot_frame"),
    ("pitch", lambda d: d["board"].update(pitch_mm=20.4), "not a dot of the board"),
    ("image size cut", lambda d: d.update(image_size_px=[600, 1280]), "outside the 600"),
    ("robot x a string", lambda d: d["robot_frame"]["robot_mm"][0].__setitem__(1, "1"), "robot"),
    ("z beyond", lambda d: d["robot_frame"]["robot_z_mm"].__setitem__(0, 1e308), "robot_z_mm"),
    ("a digest", lambda d: d.update(digest={"sha256": {}}), "version 3 file has no digest"),
    ("to version 2", lambda d: d.update(version=2), "version 2 file has no robot_frame"),
]


@pytest.mark.parametrize(
    ("edit", "match"), [e[1:] for e in OLD_EDITS], ids=[e[0] for e in OLD_EDITS]
)
def test_an_old_file_keeps_its_checks(
    tmp_path: Path, edit: Callable[[dict[str, Any]], None], match: str
) -> None:
    data = json.loads(V3_FILE.read_text())
    edit(data)
    with pytest.raises(CalibrationFileError, match=match):
        Calibration.load(_write(tmp_path / "old.json", data))


def test_a_lens_is_the_image_size_s(tmp_path: Path) -> None:
    # A radial lens's unit is the image's half-diagonal: another image size is another lens.
    data = json.loads(V2_FILE.read_text())
    data["image_size_px"] = [1281, 720]
    with pytest.raises(CalibrationFileError, match=r"not the frame of image_size_px \[1281, 720\]"):
        Calibration.load(_write(tmp_path / "old.json", data))
    # The refusal shows the file's numbers as the file writes them, not NumPy's repr.
    data["image_size_px"] = [1280, 720]
    data["lens_model"] = data["lens"]["model"] = "k1k2"
    with pytest.raises(CalibrationFileError) as refused:
        Calibration.load(_write(tmp_path / "old.json", data))
    centre = data["lens"]["centre_px"]
    assert f"lens.centre_px [{centre[0]!r}, {centre[1]!r}] are not the frame" in str(refused.value)
    assert "its centre [639.5, 359.5]" in str(refused.value)


def test_a_new_file_read_as_an_old_version_is_refused(
    saved: dict[str, Any], tmp_path: Path
) -> None:
    data = copy.deepcopy(saved)
    data["version"] = 3  # to escape the digest
    with pytest.raises(CalibrationFileError, match="a version 3 file has no digest"):
        Calibration.load(_write(tmp_path / "old.json", data))


# -- 3. what loads can be saved, and a re-save is the same file ----------------------------


def test_a_value_that_loads_can_be_saved(tmp_path: Path) -> None:
    # robot_z_mm 1e308 loaded (its plane's fit overflowed) and could not be saved again.
    data = json.loads(V3_FILE.read_text())
    for key in ("robot_z_mm", "plane_std_mm"):
        for value in (1e308, -1e308, 1e300, 2e9):
            edited = copy.deepcopy(data)
            edited["robot_frame"][key][0] = value
            with pytest.raises(CalibrationFileError, match=rf"robot_frame.{key}\[0\]"):
                Calibration.load(_write(tmp_path / "big.json", edited))
    edited = copy.deepcopy(data)
    edited["robot_frame"]["outlier_mm"] = 1e308
    with pytest.raises(CalibrationFileError, match="outlier_mm"):
        Calibration.load(_write(tmp_path / "big.json", edited))


@pytest.mark.parametrize("kind", ["registered", "lens", "old lens file"])
def test_saving_an_unchanged_calibration_again_writes_the_same_bytes(
    registered: Calibration, tmp_path: Path, kind: str
) -> None:
    if kind == "registered":
        cal = registered
    elif kind == "lens":
        old = Calibration.load(V2_FILE)
        cal = Calibration(
            old.world_points, old.image_points, board=old.board, image_size=(1280, 720)
        )
        assert cal.lens_model == "k1k2c"  # a fitted radial lens, its last digits the fit's
    else:
        cal = Calibration.load(V2_FILE)
    first = cal.save(tmp_path / "first.json").read_bytes()
    assert cal.save(tmp_path / "same.json").read_bytes() == first  # the same object
    loaded = Calibration.load(tmp_path / "first.json")
    assert loaded.save(tmp_path / "second.json").read_bytes() == first
    assert json.loads(first)["created"] == cal.created


def test_a_changed_calibration_is_a_new_one(registered: Calibration) -> None:
    # created is when the calibration was made: a registration makes another one.
    unregistered = registered.with_robot_frame(None)
    assert unregistered.to_dict()["robot_frame"] is None
    assert unregistered.created >= registered.created


# -- 4. a deliberate edit ---------------------------------------------------------------------


def test_trust_edits_loads_a_deliberate_edit_and_save_stamps_it(
    saved: dict[str, Any], tmp_path: Path
) -> None:
    data = copy.deepcopy(saved)
    data["image_size_px"] = [1920, 1080]  # the camera was set to 1080p after calibrating
    data["robot_frame"] = None  # the robot moved: its registration is void
    data["lens_note"] = "checked by hand"
    path = _write(tmp_path / "edited.json", data)
    with pytest.raises(CalibrationFileError, match="edited by hand"):
        Calibration.load(path)
    cal = Calibration.load(path, trust_edits=True)
    assert cal.image_size == (1920, 1080) and cal.robot_frame is None
    assert cal.lens_note == "checked by hand"
    back = Calibration.load(cal.save(tmp_path / "stamped.json"))  # a digest of its own
    assert back.image_size == (1920, 1080) and back.lens_note == "checked by hand"


def test_a_calibration_that_could_not_be_loaded_is_not_saved(tmp_path: Path) -> None:
    # A file's checks hold for what the API saves, so that every saved file loads.
    off = WORLD.copy()
    off[3] += 0.5  # not a dot of the board: refused at once, with no calibration to save
    with pytest.raises(BoardError, match=r"world point 3 .* is not a dot of the board"):
        Calibration(off, IMAGE, board=CircleGridBoard(), image_size=(1280, 720), lens="none")
    cal = Calibration(WORLD, IMAGE, image_size=(300, 200), lens="none")
    with pytest.raises(CalibrationFileError, match=r"image point 4 .* outside the 300 x 200 px"):
        cal.save(tmp_path / "never.json")
    assert not (tmp_path / "never.json").exists()


# -- 5. every leaf of a real file, edited ----------------------------------------------------


def _paths(data: Any, path: tuple[Any, ...] = ()) -> Iterator[tuple[Any, ...]]:
    """Every entry of a JSON document (containers too), the points' thinned out (each of
    their entries takes the same path through the checks)."""
    if path:
        yield path
    if isinstance(data, dict):
        for key, value in data.items():
            yield from _paths(value, (*path, key))
    elif isinstance(data, list):
        step = 7 if path[:1] == ("points",) and len(path) == 2 else 1
        for i in range(0, len(data), step):
            yield from _paths(data[i], (*path, i))


def _variants(value: Any) -> list[Any]:
    """Other values for an entry: of another JSON type, and of its own type but another."""
    removed = _REMOVED
    if isinstance(value, bool):
        return [not value, 1, "true", None, removed]
    if isinstance(value, int | float):
        other = value * 1.01 + 1 if isinstance(value, float) else value + 1
        return [other, -value if value else 1e-3, str(value), True, None, [value], 1e308, removed]
    if isinstance(value, str):
        return [value + "x", "", 1, None, removed]
    if value is None:
        return [0, "null", False, {}, [], removed]
    if isinstance(value, list):
        return [value[:-1] if value else [0], [], {}, "[]", None, removed]
    return [{}, [], None, removed]


_REMOVED = object()
ALIASES = {"homography_world_mm_to_image_px": "homography", "world_mm": "world point"}


def _edited(data: Any, path: tuple[Any, ...], value: Any) -> Any:
    out = copy.deepcopy(data)
    parent = out
    for key in path[:-1]:
        parent = parent[key]
    if value is _REMOVED:
        del parent[path[-1]]
    else:
        parent[path[-1]] = value
    return out


def _names_the_field(message: str, path: tuple[Any, ...]) -> bool:
    names = [p for p in path if isinstance(p, str)]
    return any(n in message or ALIASES.get(n, n) in message for n in names)


def test_every_leaf_edited_is_refused_naming_it_or_means_the_same(
    registered: Calibration, saved: dict[str, Any], tmp_path: Path
) -> None:
    """The fuzz campaign's calibration-file editor, exhaustively: every entry of a real file
    (a registered calibration) replaced by a value of another type, another value of its own
    type, or removed. Each is refused with a CalibrationFileError that names the field, or
    loads as the very same calibration."""
    path = tmp_path / "edited.json"
    original = _meaning(Calibration.load(_write(path, saved)))
    tried = refused = 0
    for where in list(_paths(saved)):
        current: Any = saved
        for key in where:
            current = current[key]
        for value in _variants(current):
            if type(value) is type(current) and value == current:
                continue  # no edit ([] for [])
            tried += 1
            _write(path, _edited(saved, where, value))
            try:
                loaded = Calibration.load(path)
            except CalibrationFileError as e:
                refused += 1
                assert _names_the_field(str(e), where), (where, value, str(e))
                continue
            assert _meaning(loaded) == original, (where, value)
    assert tried > 1000 and refused == tried  # the digest leaves no edit unnoticed


def test_every_leaf_edited_and_trusted_loads_only_what_can_be_saved(
    saved: dict[str, Any], tmp_path: Path
) -> None:
    """The same edits loaded with trust_edits=True (no digest: the consistency checks
    alone): each is refused naming the field, or loads a calibration that saves and loads
    again as itself."""
    path = tmp_path / "edited.json"
    loaded_any = 0
    for where in list(_paths(saved)):
        if where[0] == "points" or where[:2] in {("robot_frame", "plane_mm")}:
            continue  # checked by the residuals and the refit: the test above covers them
        current: Any = saved
        for key in where:
            current = current[key]
        for value in _variants(current):
            _write(path, _edited(saved, where, value))
            try:
                cal = Calibration.load(path, trust_edits=True)
            except CalibrationFileError as e:
                assert _names_the_field(str(e), where), (where, value, str(e))
                continue
            loaded_any += 1
            again = Calibration.load(cal.save(tmp_path / "again.json"))
            assert _meaning(again) == _meaning(cal), (where, value)
    assert loaded_any > 0


def test_planarcal_check_says_what_a_file_holds_and_keeps_a_deliberate_edit(
    saved: dict[str, Any], tmp_path: Path
) -> None:
    path = _write(tmp_path / "calib.json", saved)
    good = _run("check", path)
    assert good.returncode == 0, good.stderr
    assert "consistent and as saved" in good.stdout
    assert "frame: the robot's (rigid registration from 5 touches" in good.stdout
    # The registration removed by hand (the robot moved): refused as it is, kept when the
    # edit is accepted.
    edited = copy.deepcopy(saved)
    edited["robot_frame"] = None
    _write(path, edited)
    refused = _run("check", path)
    assert refused.returncode == 1 and "edited by hand?" in refused.stderr
    assert f"planarcal check '{path}' --accept-edits" in refused.stderr
    kept = _run("check", path, "--accept-edits")
    assert kept.returncode == 0, kept.stderr
    assert "frame: the board's" in kept.stdout and "new digest" in kept.stdout
    assert Calibration.load(path).robot_frame is None
    # An edit the other values contradict is refused even with --accept-edits.
    contradicted = copy.deepcopy(saved)
    contradicted["board"]["pitch_mm"] = 20.4
    _write(path, contradicted)
    before = path.read_bytes()
    still = _run("check", path, "--accept-edits")
    assert still.returncode == 1 and "pitch" in still.stderr and "Traceback" not in still.stderr
    assert path.read_bytes() == before

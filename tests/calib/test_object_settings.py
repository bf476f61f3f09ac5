"""The object-detection settings a calibration carries (issue 24): checked values, saved in
the calibration file (version 7, under its digest), and used by locate_objects, the Tracker,
`planarcal locate` and `planarcal run` unless their own options override them, field by
field. On the paper's rendered scene: 3 bolts (outlines of some 1150 px^2) and 7 nuts (some
640 px^2)."""

from __future__ import annotations

import copy
import json
import re
import subprocess
import sys
from pathlib import Path
from typing import Any

import cv2
import numpy as np
import pytest

from planarcal import synth
from planarcal.calib.calibration import Calibration
from planarcal.calib.calibration_file import FILE_VERSION, calibration_to_dict, field_digests
from planarcal.calib.object_settings import ObjectSettings, detect_options_with
from planarcal.cli import main as cli_main
from planarcal.errors import ArgumentError, CalibrationFileError
from planarcal.live.objects import DetectedObject, detect_objects, locate_objects
from planarcal.live.tracker import Tracker

BOLTS = ObjectSettings(min_area_px=900.0)
"""Settings that keep the bolts only."""
SPLIT_X = 620
"""The image column that parts the scene's objects in two, 20 px or more from any centroid:
5 to its left (2 bolts), 5 to its right (1 bolt)."""


@pytest.fixture(scope="module")
def scene() -> synth.PaperScene:
    return synth.paper_scene(seed=3)


@pytest.fixture(scope="module")
def cal(scene: synth.PaperScene) -> Calibration:
    return Calibration.from_image(scene.calibration.image, synth.PAPER_BOARD)


@pytest.fixture(scope="module")
def everything(scene: synth.PaperScene) -> list[DetectedObject]:
    found = detect_objects(scene.objects.image)
    areas = np.array([o.area_px for o in found])
    assert len(found) == 10 and (areas > 900).sum() == 3  # the scene the tests rely on
    return found


@pytest.fixture(scope="module")
def files(
    scene: synth.PaperScene, cal: Calibration, tmp_path_factory: pytest.TempPathFactory
) -> dict[str, Path]:
    """The objects' image, alone in a folder too (a source for run), and calibration files
    without settings, with BOLTS, and with the left half of the image as their roi."""
    d = tmp_path_factory.mktemp("object_settings")
    (d / "frames").mkdir()
    cv2.imwrite(str(d / "frames" / "objects.png"), scene.objects.image)
    return {
        "image": d / "frames" / "objects.png",
        "frames": d / "frames",
        "plain": cal.save(d / "plain.json"),
        "bolts": cal.with_object_settings(BOLTS).save(d / "bolts.json"),
        "left": cal.with_object_settings(ObjectSettings(roi=(0, 0, SPLIT_X, 720))).save(
            d / "left.json"
        ),
    }


def _left(objects: list[DetectedObject]) -> list[tuple[float, float]]:
    return sorted(o.centroid_px for o in objects if o.centroid_px[0] < SPLIT_X)


def _same_points(got: Any, want: Any) -> None:
    """The same image points in any order (to 1e-3 px: the JSON lines round them)."""
    a, b = np.array(sorted(map(tuple, got))), np.array(sorted(map(tuple, want)))
    assert a.shape == b.shape and len(a)
    np.testing.assert_allclose(a, b, atol=1e-3)


# -- 1. the settings' values --------------------------------------------------------------


@pytest.mark.parametrize(
    ("fields", "match"),
    [
        ({"min_area_px": -1.0}, "min_area_px must be a number >= 0"),
        ({"max_area_px": 0.0}, "max_area_px must be a number > 0"),
        ({"blur_sigma": -0.5}, "blur_sigma must be a number >= 0"),
        ({"min_area_px": float("nan")}, "min_area_px must be finite"),
        ({"max_area_px": float("inf")}, "max_area_px must be finite"),
        ({"blur_sigma": 10**400}, "blur_sigma must be finite"),
        ({"min_area_px": "5"}, "min_area_px must be a number"),
        ({"min_area_px": True}, "min_area_px must be a number"),
        ({"min_area_px": 500.0, "max_area_px": 100.0}, "min_area_px .* is above max_area_px"),
        ({"roi": (0, 0, 10)}, r"roi must be \(x, y, width, height\)"),
        ({"roi": "0,0,1,1"}, r"roi must be \(x, y, width, height\)"),
        ({"roi": (0, 0, 0, 10)}, r"roi\[2\] \(width\) must be from 1"),
        ({"roi": (-1, 0, 10, 10)}, r"roi\[0\] \(x\) must be from 0"),
        ({"roi": (0, 0, 10.5, 10)}, r"roi\[2\] \(width\) must be a whole number"),
        ({"roi": (0, True, 10, 10)}, r"roi\[1\] \(y\) must be a whole number"),
    ],
)
def test_a_value_that_cannot_be_a_setting_is_an_argument_error(
    fields: dict[str, Any], match: str
) -> None:
    with pytest.raises(ArgumentError, match=match) as caught:
        ObjectSettings(**fields)
    assert isinstance(caught.value, ValueError)


def test_settings_are_normalised_and_changed_field_by_field() -> None:
    s = ObjectSettings(min_area_px=900, roi=[1, 2, 30, 40])  # type: ignore[arg-type]
    assert s.min_area_px == 900.0 and isinstance(s.min_area_px, float)
    assert s.roi == (1, 2, 30, 40) and s == ObjectSettings(900.0, None, (1, 2, 30, 40))
    assert s.with_(roi=None, blur_sigma=2) == ObjectSettings(min_area_px=900.0, blur_sigma=2.0)
    assert ObjectSettings().is_default and not s.is_default
    with pytest.raises(ArgumentError, match="unknown object setting 'min_area'"):
        s.with_(min_area=5)
    with pytest.raises(ArgumentError, match="is above max_area_px"):
        s.with_(max_area_px=100)
    assert s.detect_options() == {"min_area_px": 900.0, "roi": (1, 2, 30, 40)}
    assert ObjectSettings().detect_options((1280, 720)) == {}
    with pytest.raises(ArgumentError, match=r"roi \[1, 2, 30, 40\] .* beyond the 20 x 50 px"):
        s.detect_options((20, 50))
    with pytest.raises(ArgumentError, match="blur_sigma 100 px is more than"):
        ObjectSettings(blur_sigma=100).detect_options((64, 48))


def test_overrides_replace_a_setting_of_their_name_and_pass_the_rest() -> None:
    held = ObjectSettings(min_area_px=900.0, roi=(0, 0, 640, 720), blur_sigma=2.0)
    mask = np.ones((720, 1280), bool)
    got = detect_options_with(held, {"min_area_px": None, "max_area_px": 5e3, "mask": mask})
    assert got.pop("mask") is mask
    assert got == {"max_area_px": 5e3, "roi": (0, 0, 640, 720), "blur_sigma": 2.0}
    with pytest.raises(ArgumentError, match=r"min_area_px \(900 px\^2\) is above max_area_px"):
        detect_options_with(held, {"max_area_px": 100.0})


def test_the_dict_form_is_strict_and_names_the_key() -> None:
    s = ObjectSettings(min_area_px=12.5, max_area_px=4000.0, roi=(5, 6, 70, 80), blur_sigma=0.0)
    data = s.to_dict()
    assert data == {
        "min_area_px": 12.5,
        "max_area_px": 4000.0,
        "roi": [5, 6, 70, 80],
        "blur_sigma": 0.0,
    }
    assert ObjectSettings.from_dict(json.loads(json.dumps(data))) == s
    assert ObjectSettings.from_dict({"min_area_px": 3}) == ObjectSettings(min_area_px=3.0)
    for bad, match in [
        ({"min_area": 3}, "unknown object setting 'min_area'"),
        ({"max_area_px": "400"}, "max_area_px must be null or a number, got '400'"),
        ({"blur_sigma": True}, "blur_sigma must be null or a number"),
        ({"roi": [1, 2, 3, 4.0]}, "roi must be null or .x, y, width, height."),
        ({"roi": {"x": 1}}, "roi must be null or"),
        ({"min_area_px": -3}, "min_area_px must be a number >= 0"),
        ([], "must be a JSON object"),
    ]:
        with pytest.raises(ArgumentError, match=match):
            ObjectSettings.from_dict(bad)


# -- 2. the calibration and its file ------------------------------------------------------


def test_a_calibration_carries_settings_its_images_can_take(cal: Calibration) -> None:
    assert cal.object_settings == ObjectSettings()
    held = cal.with_object_settings(BOLTS)
    assert held.object_settings == BOLTS and cal.object_settings == ObjectSettings()
    assert held.created == cal.created  # the same mapping: the same calibration
    np.testing.assert_array_equal(held.H, cal.H)
    # Kept by a registration, by a printer's scale and (scaled) by another frame size.
    assert cal.board is not None
    assert held.rescaled(cal.board.pitch * 1.01).object_settings == BOLTS
    left = cal.with_object_settings(ObjectSettings(roi=(0, 0, 640, 720), blur_sigma=1.0))
    big = left.for_frame_size(2560, 1440)
    assert big.object_settings == ObjectSettings(roi=(0, 0, 1280, 1440), blur_sigma=2.0)
    assert held.for_frame_size(640, 360).object_settings.min_area_px == pytest.approx(900.0 / 4)
    with pytest.raises(ArgumentError, match=r"beyond the 1280 x 720 px image"):
        cal.with_object_settings(ObjectSettings(roi=(640, 0, 641, 720)))
    with pytest.raises(ArgumentError, match="settings must be an ObjectSettings, got dict"):
        cal.with_object_settings({"min_area_px": 5.0})  # type: ignore[arg-type]


def test_the_settings_survive_the_file_and_a_resave_is_the_same_file(
    cal: Calibration, tmp_path: Path
) -> None:
    settings = ObjectSettings(min_area_px=50.0, max_area_px=2e4, roi=(10, 20, 600, 500))
    path = cal.with_object_settings(settings.with_(blur_sigma=1.2)).save(tmp_path / "a.json")
    data = json.loads(path.read_text())
    assert data["version"] == FILE_VERSION == 7
    assert data["object_settings"] == {
        "min_area_px": 50.0,
        "max_area_px": 20000.0,
        "roi": [10, 20, 600, 500],
        "blur_sigma": 1.2,
    }
    assert "object_settings" in data["digest"]["sha256"]
    back = Calibration.load(path)
    assert back.object_settings == settings.with_(blur_sigma=1.2)
    again = back.save(tmp_path / "b.json")
    assert again.read_bytes() == path.read_bytes()


def test_a_version_6_file_loads_with_the_default_settings(cal: Calibration, tmp_path: Path) -> None:
    v6 = calibration_to_dict(cal, version=6)
    assert "object_settings" not in v6 and v6["version"] == 6
    path = tmp_path / "v6.json"
    path.write_text(json.dumps(v6, indent=2) + "\n")
    old = Calibration.load(path)
    assert old.object_settings == ObjectSettings()
    # Saved again, the file changes by its version and the new field only (and their
    # digests).
    v7 = json.loads(old.save(tmp_path / "v7.json").read_text())
    assert v7["object_settings"] == ObjectSettings().to_dict()
    changed = {k for k in v6.keys() | v7.keys() if v6.get(k) != v7.get(k)}
    assert changed == {"version", "object_settings", "digest"}
    d6, d7 = v6["digest"]["sha256"], v7["digest"]["sha256"]
    assert {k for k in d6.keys() | d7.keys() if d6.get(k) != d7.get(k)} == {
        "version",
        "object_settings",
    }
    # A version 6 file that holds settings was edited (its version, to escape the field).
    with_settings = copy.deepcopy(v6)
    with_settings["object_settings"] = BOLTS.to_dict()
    with pytest.raises(CalibrationFileError, match="a version 6 file has no object_settings"):
        Calibration.from_dict(_redigested(with_settings))


def _redigested(data: dict[str, Any]) -> dict[str, Any]:
    data = copy.deepcopy(data)
    data["digest"] = {"sha256": field_digests(data)}
    return data


def test_an_edited_setting_is_refused_unless_accepted(files: dict[str, Path]) -> None:
    data = json.loads(files["bolts"].read_text())
    data["object_settings"]["min_area_px"] = 100.0
    with pytest.raises(
        CalibrationFileError, match="object_settings is not what the file was saved with"
    ):
        Calibration.from_dict(data)
    # Accepted on purpose (planarcal check --accept-edits), the edit is what loads.
    accepted = Calibration.from_dict(data, trust_edits=True)
    assert accepted.object_settings == ObjectSettings(min_area_px=100.0)


@pytest.mark.parametrize(
    ("edit", "match"),
    [
        (lambda s: s.update(min_area_px="900"), "object_settings: min_area_px must be null or a"),
        (lambda s: s.update(max_area_px=-1.0), "object_settings: max_area_px must be a number"),
        (lambda s: s.update(max_area_px=10.0), "min_area_px .* is above max_area_px"),
        (lambda s: s.update(roi=[0, 0, 1281, 720]), r"beyond the 1280 x 720 px image"),
        (lambda s: s.update(roi=[0, 0, 12.0, 7]), "roi must be null or"),
        (lambda s: s.update(blur_sigma=5000.0), "blur_sigma 5000 px is more than"),
        (lambda s: s.update(colour="red"), "unknown object setting 'colour'"),
        (lambda s: s.pop("roi"), "missing the field object_settings.roi"),
    ],
    ids=[
        "string",
        "negative",
        "min above max",
        "roi beyond",
        "roi float",
        "blur",
        "unknown",
        "missing",
    ],
)
def test_a_setting_that_cannot_be_is_refused_even_with_its_digest_recomputed(
    files: dict[str, Path], edit: Any, match: str
) -> None:
    data = json.loads(files["bolts"].read_text())
    edit(data["object_settings"])
    for trust_edits in (False, True):
        with pytest.raises(CalibrationFileError, match=match):
            Calibration.from_dict(_redigested(data), trust_edits=trust_edits)


def test_a_version_7_file_has_its_settings(files: dict[str, Path]) -> None:
    data = json.loads(files["plain"].read_text())
    missing, null = copy.deepcopy(data), copy.deepcopy(data)
    missing.pop("object_settings")
    null["object_settings"] = None
    for edited, match in [
        (missing, "missing the field object_settings"),
        (null, "object_settings must be a JSON object"),
    ]:
        with pytest.raises(CalibrationFileError, match=match):
            Calibration.from_dict(_redigested(edited))


# -- 3. what uses them --------------------------------------------------------------------


def test_locate_uses_the_calibrations_settings(
    scene: synth.PaperScene,
    cal: Calibration,
    files: dict[str, Path],
    everything: list[DetectedObject],
) -> None:
    image = scene.objects.image
    assert len(locate_objects(image, Calibration.load(files["plain"]))) == 10
    bolts = locate_objects(image, Calibration.load(files["bolts"]))
    assert len(bolts) == 3 and all(o.area_px > 900 for o in bolts)
    left = locate_objects(image, Calibration.load(files["left"]))
    assert len(left) == 5
    _same_points([o.centroid_px for o in left], _left(everything))
    # An option given replaces the setting of its name; None is detect_objects' default.
    assert len(locate_objects(image, Calibration.load(files["bolts"]), min_area_px=None)) == 10
    assert len(locate_objects(image, Calibration.load(files["left"]), roi=None)) == 10
    with pytest.raises(ArgumentError, match="is above max_area_px"):
        locate_objects(image, Calibration.load(files["bolts"]), max_area_px=500.0)


def test_detect_objects_takes_the_roi_as_a_mask_of_it(
    scene: synth.PaperScene, everything: list[DetectedObject]
) -> None:
    image = scene.objects.image
    x, y, w, h = 300, 200, 500, 400
    mask = np.zeros(image.shape[:2], np.uint8)
    mask[y : y + h, x : x + w] = 1
    by_roi = detect_objects(image, roi=(x, y, w, h))
    assert 0 < len(by_roi) < len(everything)
    assert [o.centroid_px for o in by_roi] == [
        o.centroid_px for o in detect_objects(image, mask=mask)
    ]
    with pytest.raises(ArgumentError, match=r"roi\[3\] \(height\)"):
        detect_objects(image, roi=(0, 0, 10, 0))


def _tracked(calibration: Calibration, frames: Path, **options: Any) -> list[Any]:
    with Tracker(calibration, frames, detect_options=options or None) as tracker:
        results = list(tracker)
    assert len(results) == 1
    return list(results[0].objects)


def test_the_tracker_uses_the_calibrations_settings(
    files: dict[str, Path], everything: list[DetectedObject]
) -> None:
    bolts = Calibration.load(files["bolts"])
    assert len(_tracked(Calibration.load(files["plain"]), files["frames"])) == 10
    assert len(_tracked(bolts, files["frames"])) == 3
    left = _tracked(Calibration.load(files["left"]), files["frames"])
    _same_points([o.centroid_px for o in left], _left(everything))
    # Overridden field by field: the file's minimum replaced, the rest kept.
    assert len(_tracked(bolts, files["frames"], min_area_px=0.0)) == 10
    assert len(_tracked(bolts, files["frames"], max_area_px=1e5)) == 3
    tracker = Tracker(bolts, files["frames"], detect_options={"blur_sigma": 1.0})
    with tracker:
        assert tracker.detect_options == {"min_area_px": 900.0, "blur_sigma": 1.0}
    with pytest.raises(ArgumentError, match="is above max_area_px"):
        Tracker(bolts, files["frames"], detect_options={"max_area_px": 10.0})
    with pytest.raises(ArgumentError, match="min_area_px must be a number >= 0"):
        Tracker(bolts, files["frames"], detect_options={"min_area_px": -1.0})


# -- 4. the command line ------------------------------------------------------------------


def _cli(*words: str | Path) -> int:
    """planarcal's status for `words`, in this process (argparse's own refusals included)."""
    try:
        return cli_main([str(w) for w in words])
    except SystemExit as e:
        return int(e.code or 0)


def _located(capsys: pytest.CaptureFixture[str], *words: str | Path) -> list[dict[str, Any]]:
    capsys.readouterr()
    assert _cli("locate", *words, "--json") == 0
    objects: list[dict[str, Any]] = json.loads(capsys.readouterr().out)["objects"]
    return objects


def test_locate_on_the_command_line_uses_the_file_and_its_options_override_it(
    files: dict[str, Path], capsys: pytest.CaptureFixture[str], everything: list[DetectedObject]
) -> None:
    image = files["image"]
    assert len(_located(capsys, image, "--calibration", files["plain"])) == 10
    assert len(_located(capsys, image, "--calibration", files["bolts"])) == 3
    assert len(_located(capsys, image, "--calibration", files["bolts"], "--min-area", "0")) == 10
    left = _located(capsys, image, "--calibration", files["left"])
    _same_points([o["image_px"] for o in left], _left(everything))
    whole = _located(capsys, image, "--calibration", files["left"], "--roi", "0,0,1280,720")
    assert len(whole) == 10
    small = _located(capsys, image, "--calibration", files["plain"], "--max-area", "900")
    assert len(small) == 7
    blurred = _located(capsys, image, "--calibration", files["bolts"], "--blur", "2.5")
    assert len(blurred) == 3


@pytest.mark.parametrize(
    ("words", "said"),
    [
        (["--roi", "1,2,3"], "expected X,Y,W,H"),
        (["--roi", "0,0,0,5"], r"roi\[2\] \(width\) must be from 1"),
        (["--roi", "a,b,c,d"], "expected X,Y,W,H"),
        (["--roi", "0,0,1281,720"], "beyond the 1280 x 720 px image"),
        (["--max-area", "0"], "--max-area: must be a positive number"),
        (["--max-area", "nan"], "--max-area: must be a finite number"),
        (["--blur", "-1"], "--blur: must be 0 or more"),
        (["--blur", "5000"], "blur_sigma 5000 px is more than"),
        (["--max-area", "500"], r"is above max_area_px .*object settings: min area 900"),
    ],
)
@pytest.mark.parametrize("command", ["locate", "run"])
def test_bad_detection_options_are_a_malformed_command_line(
    files: dict[str, Path],
    capsys: pytest.CaptureFixture[str],
    tmp_path: Path,
    command: str,
    words: list[str],
    said: str,
) -> None:
    capsys.readouterr()
    where: list[str | Path] = (
        [files["image"]] if command == "locate" else ["--source", files["frames"]]
    )
    out = tmp_path / "lines.jsonl"
    tail: list[str | Path] = [] if command == "locate" else ["-o", out]
    status = _cli(command, *where, "--calibration", files["bolts"], *words, *tail)
    assert status == 2
    assert re.search(said, capsys.readouterr().err)
    assert not out.exists()  # refused before the output was opened


def test_run_uses_the_file_and_its_options_override_it(
    files: dict[str, Path], tmp_path: Path, everything: list[DetectedObject]
) -> None:
    def run(calibration: Path, *words: str) -> list[dict[str, Any]]:
        out = tmp_path / f"{calibration.stem}{len(words)}.jsonl"
        status = _cli(
            "run", "--source", files["frames"], "--calibration", calibration, "-o", out, *words
        )
        assert status == 0
        lines = out.read_text().splitlines()
        assert len(lines) == 1
        objects: list[dict[str, Any]] = json.loads(lines[0])["objects"]
        return objects

    assert len(run(files["plain"])) == 10
    assert len(run(files["bolts"])) == 3
    assert len(run(files["bolts"], "--min-area", "0")) == 10
    assert len(run(files["left"], "--roi", "0,0,1280,720")) == 10
    right_nuts = [o for o in everything if o.area_px <= 900 and o.centroid_px[0] >= SPLIT_X]
    assert len(right_nuts) == 4
    nuts = run(files["plain"], "--max-area", "900", "--roi", f"{SPLIT_X},0,{1280 - SPLIT_X},720")
    _same_points([o["px"] for o in nuts], [o.centroid_px for o in right_nuts])


def test_the_real_command_refuses_a_bad_option_with_status_2(files: dict[str, Path]) -> None:
    result = subprocess.run(
        [sys.executable, "-m", "planarcal", "locate", str(files["image"])]  # noqa: RUF005
        + ["--calibration", str(files["bolts"]), "--max-area", "500"],
        capture_output=True,
        text=True,
        timeout=120,
        check=False,
    )
    assert result.returncode == 2, result.stderr
    assert "min_area_px (900 px^2) is above max_area_px (500 px^2)" in result.stderr

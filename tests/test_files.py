"""planarcal.files.atomic_write, and every writer of planarcal built on it, on real files: the
permissions a new file gets under the umask and those a replaced file keeps; the anonymous
temporary file (Linux's O_TMPFILE) and the named one used where it is refused; temporary files
that dead writers left; failures that leave the old file and nothing else. What a SIGKILL
mid-save leaves is in test_killed_save.py."""

from __future__ import annotations

import contextlib
import errno
import os
import re
import time
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import cv2
import numpy as np
import pytest

from planarcal import synth
from planarcal.calib.board import CircleGridBoard
from planarcal.calib.calibration import Calibration
from planarcal.calib.detect import DetectionDiagnostics, detect_board
from planarcal.camera import CameraIntrinsics
from planarcal.cli import main
from planarcal.files import atomic_write, remove_stale_temporaries, temporary_name_pattern
from planarcal.live.outputs import FileOutput
from planarcal.report import write_detection_failure, write_report
from planarcal.report.printable import write_board

# Any temporary file atomic_write names, whatever its target.
TEMPORARY = re.compile(r"\..+\.[0-9a-f]{12}\.tmp")
ANONYMOUS_FILES = hasattr(os, "O_TMPFILE") and os.path.isdir("/proc/self/fd")


@contextlib.contextmanager
def umask(mask: int) -> Iterator[None]:
    previous = os.umask(mask)
    try:
        yield
    finally:
        os.umask(previous)


def mode(path: Path) -> int:
    return path.stat().st_mode & 0o777


def names(directory: Path) -> list[str]:
    return sorted(p.name for p in directory.iterdir())


@pytest.fixture(params=["anonymous", "named"])
def temporary_kind(request: pytest.FixtureRequest, monkeypatch: pytest.MonkeyPatch) -> str:
    """Each test runs with the anonymous temporary file (where the OS has one) and with the
    named one, as on an OS without O_TMPFILE."""
    kind: str = request.param
    if kind == "named":
        monkeypatch.delattr(os, "O_TMPFILE", raising=False)
    elif not ANONYMOUS_FILES:
        pytest.skip("no O_TMPFILE and /proc/self/fd here")
    return kind


# ------------------------------------------------------------------------------------------
# atomic_write


@pytest.mark.parametrize("mask", [0o022, 0o077, 0o002, 0o000], ids=oct)
def test_a_new_file_gets_what_open_would_give(
    tmp_path: Path, temporary_kind: str, mask: int
) -> None:
    target = tmp_path / "new.json"
    with umask(mask):
        assert atomic_write(target, "{}\n") == target
        with open(tmp_path / "by_open", "w") as f:
            f.write("{}\n")
    assert mode(target) == 0o666 & ~mask == mode(tmp_path / "by_open")
    assert target.read_text() == "{}\n"
    assert names(tmp_path) == ["by_open", "new.json"]


@pytest.mark.parametrize("kept", [0o640, 0o600, 0o644, 0o444, 0o755, 0o666], ids=oct)
def test_a_replaced_file_keeps_its_permissions(
    tmp_path: Path, temporary_kind: str, kept: int
) -> None:
    target = tmp_path / "calib.json"
    target.write_bytes(b"old")
    target.chmod(kept)
    with umask(0o022):
        atomic_write(target, b"new")
    assert mode(target) == kept
    assert target.read_bytes() == b"new"
    # Kept again on the next save, and under another umask.
    with umask(0o077):
        atomic_write(target, b"newer")
    assert mode(target) == kept and target.read_bytes() == b"newer"
    assert names(tmp_path) == ["calib.json"]


def test_a_symlink_replaced_gives_no_permissions_of_its_own(tmp_path: Path) -> None:
    # A symlink's own bits mean nothing; the file it pointed to is not touched.
    pointed_to = tmp_path / "elsewhere.json"
    pointed_to.write_bytes(b"elsewhere")
    pointed_to.chmod(0o600)
    link = tmp_path / "calib.json"
    link.symlink_to(pointed_to)
    with umask(0o022):
        atomic_write(link, b"new")
    assert not link.is_symlink() and link.read_bytes() == b"new" and mode(link) == 0o644
    assert pointed_to.read_bytes() == b"elsewhere" and mode(pointed_to) == 0o600


def test_the_content_is_nameless_until_complete_on_linux(
    tmp_path: Path, temporary_kind: str, monkeypatch: pytest.MonkeyPatch
) -> None:
    """What the directory holds when the content reaches the disk: with O_TMPFILE nothing but
    the old file (a process killed then leaves nothing); without, a temporary file beside it."""
    target = tmp_path / "report.png"
    target.write_bytes(b"old")
    seen_at_fsync: list[list[str]] = []
    real_fsync = os.fsync

    def watching_fsync(fd: int) -> None:
        seen_at_fsync.append(names(tmp_path))
        real_fsync(fd)

    monkeypatch.setattr(os, "fsync", watching_fsync)
    atomic_write(target, b"\x89PNG" + bytes(1000))
    monkeypatch.undo()
    content_synced = seen_at_fsync[0]  # then the directory's, after the rename
    if temporary_kind == "anonymous":
        assert content_synced == ["report.png"]
    else:
        temporary, old = content_synced
        assert temporary_name_pattern(target).fullmatch(temporary) and old == "report.png"
    assert seen_at_fsync[-1] == ["report.png"]
    assert target.read_bytes() == b"\x89PNG" + bytes(1000)


@pytest.mark.parametrize("refusal", [errno.EOPNOTSUPP, errno.EISDIR, errno.EINVAL])
def test_a_filesystem_refusing_anonymous_files_gets_a_named_one(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, refusal: int
) -> None:
    if not ANONYMOUS_FILES:
        pytest.skip("no O_TMPFILE here")
    real_open = os.open
    refused = []

    def refusing_open(path: Any, flags: int, *args: Any, **kwargs: Any) -> int:
        if flags & os.O_TMPFILE == os.O_TMPFILE:
            refused.append(path)
            raise OSError(refusal, os.strerror(refusal))
        return real_open(path, flags, *args, **kwargs)

    monkeypatch.setattr(os, "open", refusing_open)
    target = tmp_path / "calib.json"
    with umask(0o022):
        atomic_write(target, "{}")
    assert refused and target.read_text() == "{}" and mode(target) == 0o644
    assert names(tmp_path) == ["calib.json"]


def test_other_errors_of_the_anonymous_file_are_not_hidden(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    if not ANONYMOUS_FILES:
        pytest.skip("no O_TMPFILE here")
    real_open = os.open

    def full_disk_open(path: Any, flags: int, *args: Any, **kwargs: Any) -> int:
        if flags & os.O_TMPFILE == os.O_TMPFILE:
            raise OSError(errno.EDQUOT, os.strerror(errno.EDQUOT))
        return real_open(path, flags, *args, **kwargs)

    monkeypatch.setattr(os, "open", full_disk_open)
    target = tmp_path / "calib.json"
    target.write_text("old")
    with pytest.raises(OSError, match=r"calib\.json") as caught:
        atomic_write(target, "new")
    assert caught.value.errno == errno.EDQUOT and caught.value.filename == str(target)
    assert target.read_text() == "old" and names(tmp_path) == ["calib.json"]


@pytest.mark.parametrize("failing", ["write", "fsync", "replace"])
def test_a_failed_save_leaves_the_old_file_and_nothing_else(
    tmp_path: Path, temporary_kind: str, monkeypatch: pytest.MonkeyPatch, failing: str
) -> None:
    target = tmp_path / "calib.json"
    target.write_text("old")
    target.chmod(0o640)
    code = {"write": errno.ENOSPC, "fsync": errno.EIO, "replace": errno.EACCES}[failing]

    def fail(*args: Any, **kwargs: Any) -> Any:
        raise OSError(code, os.strerror(code))

    monkeypatch.setattr(os, failing, fail)
    with pytest.raises(OSError, match=r"calib\.json") as caught:
        atomic_write(target, "new " * 100_000)
    monkeypatch.undo()
    assert caught.value.errno == code and caught.value.filename == str(target)
    assert target.read_text() == "old" and mode(target) == 0o640
    assert names(tmp_path) == ["calib.json"]


def test_stale_temporaries_of_the_target_are_removed(tmp_path: Path) -> None:
    target = tmp_path / "calib(1)+.json"  # regular-expression characters in the name

    def leave(name: str, age_s: float, directory: bool = False) -> Path:
        path = tmp_path / name
        if directory:
            path.mkdir()
        else:
            path.write_text("half a file")
        then = time.time() - age_s
        os.utime(path, (then, then))
        return path

    dead = leave(".calib(1)+.json.0123456789ab.tmp", 120)
    dead_too = leave(".calib(1)+.json.ba9876543210.tmp", 61)
    kept = [
        leave(".calib(1)+.json.00112233aabb.tmp", 1),  # a live writer's, perhaps
        leave(".other.json.0123456789ab.tmp", 120),  # another target's
        leave(".calib(1)+.json.0123456789ab.tmp.bak", 120),
        leave("calib(1)+.json.0123456789ab.tmp", 120),  # not hidden: not ours
        leave(".calib(1)+.json.0123456789AB.tmp", 120),  # token_hex is lower case
        leave(".calib(1)+.json.0123456789a.tmp", 120),
        leave(".calib(1)x.json.0123456789ab.tmp", 120),  # "+" is not "any character"
        leave(".calib(1)+.json.abcdefabcdef.tmp", 120, directory=True),
    ]
    atomic_write(target, "{}")
    assert not dead.exists() and not dead_too.exists()
    assert all(p.exists() for p in kept)
    assert target.read_text() == "{}"
    # Called on its own, it says what it removed.
    again = leave(".calib(1)+.json.0123456789ab.tmp", 120)
    assert remove_stale_temporaries(target) == [again]
    assert remove_stale_temporaries(target) == []
    assert remove_stale_temporaries(target, older_than_s=0.0) == [kept[0]]


def test_a_missing_directory_is_named(tmp_path: Path) -> None:
    target = tmp_path / "no" / "calib.json"
    with pytest.raises(FileNotFoundError, match="no directory") as caught:
        atomic_write(target, "{}")
    assert caught.value.filename == str(target)


# ------------------------------------------------------------------------------------------
# every writer of planarcal


@pytest.fixture(scope="module")
def scene() -> synth.PaperScene:
    return synth.paper_scene(seed=0)


@pytest.fixture(scope="module")
def inputs(scene: synth.PaperScene, tmp_path_factory: pytest.TempPathFactory) -> dict[str, Any]:
    """A detected board and its calibration (saved), the objects' image."""
    directory = tmp_path_factory.mktemp("inputs")
    assert scene.calibration.board is not None
    detection = detect_board(scene.calibration.image, scene.calibration.board)
    cal = Calibration.from_detection(detection)
    objects_png = directory / "objects.png"
    cv2.imwrite(str(objects_png), scene.objects.image)
    return {
        "detection": detection,
        "cal": cal,
        "calib_json": cal.save(directory / "calib.json"),
        "objects_png": objects_png,
    }


def writers(scene: synth.PaperScene, inputs: dict[str, Any]) -> dict[str, Callable[[Path], Any]]:
    """Every kind of file planarcal writes, each written into a directory."""
    board = CircleGridBoard(cols=7, rows=5, pitch=20.0, diameter=10.0, origin_marker=True)
    intrinsics = CameraIntrinsics(np.diag([800.0, 800.0, 1.0]), np.zeros(5), (640, 480))
    nothing_seen = DetectionDiagnostics(board=board, image_size=(640, 480), blobs=(), candidates=())

    def write_json_lines(d: Path) -> None:
        with FileOutput(d / "positions.jsonl") as out:
            out.send('{"frame": 0}')

    return {
        "calibration": lambda d: inputs["cal"].save(d / "calib.json"),
        "intrinsics yaml": lambda d: intrinsics.save_yaml(d / "camera.yaml"),
        "intrinsics xml": lambda d: intrinsics.save_yaml(d / "camera.xml"),
        "board svg": lambda d: write_board(board, d / "board.svg"),
        "board pdf": lambda d: write_board(board, d / "board.pdf"),
        "report": lambda d: write_report(
            inputs["cal"],
            d / "report",
            image=scene.calibration.image,
            detection=inputs["detection"],
        ),
        "detection failure": lambda d: write_detection_failure(
            d / "failed", np.full((480, 640), 128, np.uint8), nothing_seen, "no board"
        ),
        "annotated image": lambda d: main(
            [
                "locate",
                str(inputs["objects_png"]),
                "--calibration",
                str(inputs["calib_json"]),
                "--annotate",
                str(d / "annotated.png"),
            ]
        ),
        "json lines": write_json_lines,
    }


EXPECTED_FILES = {
    "calib.json",
    "camera.yaml",
    "camera.xml",
    "board.svg",
    "board.pdf",
    *(f"report/{n}" for n in ("points.csv", "summary.json", "detection.png")),
    *(f"report/{n}.png" for n in ("deviations", "lens", "uncertainty")),
    "failed/detection_failed.png",
    "annotated.png",
    "positions.jsonl",
}


@pytest.mark.parametrize("mask", [0o022, 0o077], ids=oct)
def test_every_writer_gives_the_umasks_permissions_and_renames_complete_files(
    scene: synth.PaperScene,
    inputs: dict[str, Any],
    tmp_path: Path,
    monkeypatch: pytest.MonkeyPatch,
    capsys: pytest.CaptureFixture[str],
    mask: int,
) -> None:
    renamed_into_place: set[Path] = set()
    real_replace = os.replace

    def recording_replace(src: Any, dst: Any, **kwargs: Any) -> None:
        real_replace(src, dst, **kwargs)
        renamed_into_place.add(Path(dst))

    monkeypatch.setattr(os, "replace", recording_replace)
    with umask(mask):
        for write in writers(scene, inputs).values():
            write(tmp_path)
    monkeypatch.undo()
    capsys.readouterr()
    written = {p for p in tmp_path.rglob("*") if p.is_file()}
    assert {p.relative_to(tmp_path).as_posix() for p in written} == EXPECTED_FILES
    for path in written:
        assert mode(path) == 0o666 & ~mask, (path, oct(mode(path)))
        if path.name != "positions.jsonl":  # appended to by design, line by line
            assert path in renamed_into_place, path
    for directory in {p.parent for p in written}:
        assert not [n for n in names(directory) if TEMPORARY.fullmatch(n)]


def test_every_writer_keeps_a_replaced_files_permissions(
    scene: synth.PaperScene,
    inputs: dict[str, Any],
    tmp_path: Path,
    capsys: pytest.CaptureFixture[str],
) -> None:
    all_writers = writers(scene, inputs)
    with umask(0o022):
        for write in all_writers.values():
            write(tmp_path)
        written = sorted(p for p in tmp_path.rglob("*") if p.is_file())
        for path in written:
            path.chmod(0o640)
        before = {p: p.stat().st_ino for p in written}
        for write in all_writers.values():
            write(tmp_path)
    capsys.readouterr()
    for path in written:
        assert mode(path) == 0o640, path
        if path.name != "positions.jsonl":  # the others are new files under the old names
            assert path.stat().st_ino != before[path], path

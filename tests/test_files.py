"""planarcal.files.atomic_write, and every writer of planarcal built on it, on real files: the
permissions a new file gets under the umask and those a replaced file keeps; the anonymous
temporary file (Linux's O_TMPFILE) and the named one used where it is refused; temporary files
that dead writers left; failures that leave the old file and nothing else; symlinks followed
and kept, FIFOs and character devices (/dev/null, /dev/stdout) written as streams, never
replaced, and what cannot be written refused. What a SIGKILL mid-save leaves is in
test_killed_save.py."""

from __future__ import annotations

import contextlib
import errno
import os
import re
import socket
import stat
import subprocess
import sys
import threading
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


def test_a_symlink_keeps_pointing_to_its_target_saved_atomically(
    tmp_path: Path, temporary_kind: str
) -> None:
    # It used to be replaced by a regular file: the link gone, its target left stale.
    elsewhere = tmp_path / "elsewhere"
    elsewhere.mkdir()
    pointed_to = elsewhere / "calib.json"
    pointed_to.write_bytes(b"old")
    pointed_to.chmod(0o600)
    old_inode = pointed_to.stat().st_ino
    link = tmp_path / "calib.json"
    link.symlink_to(Path("elsewhere") / "calib.json")  # relative to the link's directory
    chained = tmp_path / "current.json"
    chained.symlink_to(link.name)
    with umask(0o022):
        assert atomic_write(chained, b"new") == chained
    assert chained.is_symlink() and link.is_symlink()
    assert os.readlink(chained) == "calib.json"
    assert os.readlink(link) == os.path.join("elsewhere", "calib.json")
    # Replaced (a new inode, renamed in), keeping its own permissions.
    assert pointed_to.read_bytes() == b"new" and mode(pointed_to) == 0o600
    assert pointed_to.stat().st_ino != old_inode
    assert names(tmp_path) == ["calib.json", "current.json", "elsewhere"]
    assert names(elsewhere) == ["calib.json"]


def test_a_dangling_symlink_gets_its_target_created(tmp_path: Path, temporary_kind: str) -> None:
    link = tmp_path / "calib.json"
    link.symlink_to(tmp_path / "versions" / "v2.json")
    with pytest.raises(FileNotFoundError, match="no directory") as caught:
        atomic_write(link, "{}")
    assert caught.value.filename == str(link) and link.is_symlink()
    (tmp_path / "versions").mkdir()
    with umask(0o022):
        atomic_write(link, "{}")
    assert link.is_symlink() and link.read_text() == "{}"
    assert mode(tmp_path / "versions" / "v2.json") == 0o644


def test_a_symlink_loop_is_named(tmp_path: Path) -> None:
    (tmp_path / "a").symlink_to("b")
    (tmp_path / "b").symlink_to("a")
    with pytest.raises(OSError, match="cannot write") as caught:
        atomic_write(tmp_path / "a", "{}")
    assert caught.value.errno == errno.ELOOP and caught.value.filename == str(tmp_path / "a")
    assert (tmp_path / "a").is_symlink() and (tmp_path / "b").is_symlink()


@pytest.mark.parametrize("through_link", [False, True], ids=["fifo", "link to a fifo"])
def test_a_fifo_is_written_as_a_stream(tmp_path: Path, through_link: bool) -> None:
    fifo = tmp_path / "pipe"
    os.mkfifo(fifo)
    received: list[bytes] = []

    def read_all() -> None:
        with open(fifo, "rb") as f:
            received.append(f.read())

    reader = threading.Thread(target=read_all, daemon=True)
    reader.start()
    path = tmp_path / "calib.json" if through_link else fifo
    if through_link:
        path.symlink_to(fifo)
    payload = b"x" * 300_000  # more than a pipe holds: the reader drains it meanwhile
    atomic_write(path, payload)
    reader.join(timeout=60)
    assert received == [payload]
    assert stat.S_ISFIFO(os.lstat(fifo).st_mode)
    assert not [n for n in names(tmp_path) if TEMPORARY.fullmatch(n)]


def assert_still_null_device(path: Path, before: os.stat_result) -> None:
    after = os.lstat(path)
    assert stat.S_ISCHR(after.st_mode), path
    assert (after.st_ino, after.st_rdev) == (before.st_ino, before.st_rdev)


def test_a_character_device_is_written_never_replaced(tmp_path: Path) -> None:
    """A null device node made here first: the system's /dev/null is tried only once the
    same write has left a private one a device (the old code replaced it with a file)."""
    if not hasattr(os, "mknod") or os.geteuid() != 0:
        pytest.skip("making a device node needs root")
    private = tmp_path / "null"
    os.mknod(private, 0o666 | stat.S_IFCHR, os.makedev(1, 3))
    before = os.lstat(private)
    atomic_write(private, b"calibration")
    assert_still_null_device(private, before)
    link = tmp_path / "calib.json"
    link.symlink_to(private)
    atomic_write(link, b"calibration")
    assert_still_null_device(private, before)
    assert link.is_symlink()
    system = Path("/dev/null")
    before = os.lstat(system)
    atomic_write(system, b"calibration")
    assert_still_null_device(system, before)
    assert not [n for n in names(Path("/dev")) if TEMPORARY.fullmatch(n)]


@pytest.mark.parametrize("appended", [False, True], ids=[">", ">>"])
def test_dev_stdout_writes_to_the_processs_output(tmp_path: Path, appended: bool) -> None:
    """``-o /dev/stdout`` (a link through /proc to fd 1) writes to whatever fd 1 is: a pipe,
    or a file the shell opened, added to rather than replaced."""
    code = "import sys; from planarcal.files import atomic_write; atomic_write(sys.argv[1], 'new')"
    # A private link first: the system's /dev/stdout is tried only once that one worked (the
    # old code replaced the link with a file).
    private = tmp_path / "stdout"
    private.symlink_to("/proc/self/fd/1")
    for path in (private, Path("/dev/stdout")):
        piped = subprocess.run([sys.executable, "-c", code, path], capture_output=True)
        assert (piped.returncode, piped.stdout) == (0, b"new"), piped.stderr
        assert path.is_symlink()
    private.unlink()
    out = tmp_path / "out.txt"
    out.write_bytes(b"before|")
    with open(out, "ab" if appended else "wb") as f:
        subprocess.run([sys.executable, "-c", code, "/dev/fd/1"], stdout=f, check=True)
    assert out.read_bytes() == (b"before|new" if appended else b"new")
    assert names(tmp_path) == ["out.txt"]


def test_what_cannot_be_written_is_refused_and_left(tmp_path: Path) -> None:
    directory = tmp_path / "report"
    directory.mkdir()
    with pytest.raises(IsADirectoryError, match="a directory") as refused:
        atomic_write(directory, "{}")
    assert refused.value.filename == str(directory) and directory.is_dir()
    sock_path = tmp_path / "sock"
    with socket.socket(socket.AF_UNIX) as sock:
        sock.bind(str(sock_path))
        with pytest.raises(OSError, match="a socket"):
            atomic_write(sock_path, "{}")
    assert stat.S_ISSOCK(os.lstat(sock_path).st_mode)
    if hasattr(os, "mknod") and os.geteuid() == 0:
        disk = tmp_path / "disk"
        os.mknod(disk, 0o600 | stat.S_IFBLK, os.makedev(7, 0))  # a loop device's numbers
        link = tmp_path / "calib.json"
        link.symlink_to(disk)
        with pytest.raises(OSError, match="a block device") as caught:
            atomic_write(link, "{}")
        assert caught.value.filename == str(link)
        assert stat.S_ISBLK(os.lstat(disk).st_mode) and link.is_symlink()


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
    *(f"report/{n}.png" for n in ("deviations", "lens", "uncertainty", "coverage")),
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


def test_a_calibration_saved_to_dev_null_leaves_it_a_device(
    inputs: dict[str, Any], tmp_path: Path
) -> None:
    if not hasattr(os, "mknod") or os.geteuid() != 0:
        pytest.skip("making a device node needs root")
    private = tmp_path / "null"
    os.mknod(private, 0o666 | stat.S_IFCHR, os.makedev(1, 3))
    before = os.lstat(private)
    inputs["cal"].save(private)
    assert_still_null_device(private, before)

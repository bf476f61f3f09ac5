"""The gist of an OpenCV error, for the messages of the IntrinsicsError raised in its place."""

from __future__ import annotations


def last_line(e: BaseException) -> str:
    """The gist of an OpenCV error: its last line (OpenCV's "(-215:...) ..." part). Errors
    raised inside OpenCV's Python bindings can surface as a SystemError whose cause is the
    cv2.error."""
    cause = e.__cause__ if isinstance(e, SystemError) and e.__cause__ is not None else e
    text = str(cause).strip()
    return text.splitlines()[-1].strip() if text else type(cause).__name__

"""A daemon thread that runs a Camera's blocking calls (opening, reading, releasing), so that
the caller can stop waiting after ``timeout_s`` even when OpenCV never returns: a call cannot
be interrupted from Python, but the caller need not stay with it.
"""

from __future__ import annotations

import queue
import threading
from collections.abc import Callable
from typing import Any, Generic, TypeVar, cast

__all__ = ["Worker", "WorkerTimeoutError"]

_T = TypeVar("_T")


class WorkerTimeoutError(Exception):
    """The worker did not finish a call within the caller's timeout."""


class _Job(Generic[_T]):
    """One call for the worker thread, and its outcome."""

    __slots__ = ("done", "error", "fn", "result")

    def __init__(self, fn: Callable[[], _T]) -> None:
        self.fn = fn
        self.done = threading.Event()
        self.result: _T | None = None
        self.error: BaseException | None = None


class Worker:
    """A daemon thread that runs jobs in order. ``call`` waits for a job at most ``timeout``;
    ``stop`` queues a last job and the order to exit, without waiting: a job that hangs keeps
    the thread (never the caller) until it returns, and the last job runs after it."""

    def __init__(self, name: str) -> None:
        self._jobs: queue.SimpleQueue[_Job[Any] | None] = queue.SimpleQueue()
        self.stopped = False
        # The thread references the queue only, never the Camera, so an unclosed Camera can
        # still be collected (its __del__ stops the worker).
        self.thread = threading.Thread(target=Worker._run, args=(self._jobs,), name=name)
        self.thread.daemon = True
        self.thread.start()

    @staticmethod
    def _run(jobs: queue.SimpleQueue[_Job[Any] | None]) -> None:
        while True:
            job = jobs.get()
            if job is None:
                return
            try:
                job.result = job.fn()
            except BaseException as e:  # handed to the caller, who re-raises it
                job.error = e
            finally:
                job.done.set()
            # Hold nothing while waiting for the next job: the last job's function may be a
            # method of the Camera, which must stay collectable.
            del job

    def call(self, fn: Callable[[], _T], timeout: float) -> _T:
        """Run ``fn`` on the worker thread; its result, or its exception re-raised here, or
        ``WorkerTimeoutError`` if it has not finished after ``timeout`` seconds."""
        job = _Job(fn)
        self._jobs.put(job)
        if not job.done.wait(timeout):
            raise WorkerTimeoutError
        if job.error is not None:
            error, job.error = job.error, None  # no reference cycle through the traceback
            raise error
        return cast(_T, job.result)

    def stop(self, last: Callable[[], None] | None = None) -> None:
        """Queue ``last`` (run when every queued job is done) and the order to exit."""
        if self.stopped:
            return
        self.stopped = True
        if last is not None:
            self._jobs.put(_Job(last))
        self._jobs.put(None)

"""The live page's HTTP server: the page, its files and the JSON API (docs/live.md) over a
``LiveSession``, as a Starlette application (served by uvicorn, ``commands/live.py``).

Starlette: a small, well-kept ASGI toolkit (the one FastAPI is built on) with streaming
responses for the image stream and nothing the page does not use; the session's work runs in
its thread pool, never on the event loop. Every request passes ``_Guard`` first: the token
(when one is set) and the body's size."""

from __future__ import annotations

import hmac
import json
from collections.abc import AsyncIterator, Awaitable, Callable
from pathlib import Path
from typing import Any

from starlette.applications import Starlette
from starlette.concurrency import run_in_threadpool
from starlette.requests import Request
from starlette.responses import FileResponse, JSONResponse, Response, StreamingResponse
from starlette.routing import Mount, Route
from starlette.staticfiles import StaticFiles
from starlette.types import ASGIApp, Message, Receive, Scope, Send

from planarcal.errors import ArgumentError, BusyError, NotFoundError, StateError
from planarcal.web.session import LiveSession

STATIC = Path(__file__).parent / "static"
MAX_BODY_BYTES = 2**20
"""The largest request body (a touch CSV of thousands of lines is well under it)."""
DRAIN_BYTES = 16 * MAX_BODY_BYTES
"""A body up to this size is read (and dropped) before the 413 answer; beyond, the answer
comes at once."""
TOKEN_COOKIE = "planarcal_token"
BOUNDARY = "planarcal-frame"
STREAM_WAIT_S = 2.0


class BodyTooLargeError(ArgumentError):
    """A request body over MAX_BODY_BYTES."""


def _status(error: BaseException) -> int:
    """The HTTP status of an error: the request's fault (400, 404, 413) or the state's (409,
    503)."""
    if isinstance(error, BodyTooLargeError):
        return 413
    if isinstance(error, BusyError):
        return 503
    if isinstance(error, StateError):
        return 409
    if isinstance(error, NotFoundError):
        return 404
    if isinstance(error, ValueError | TypeError):
        return 400
    return 500


def _error(error: BaseException) -> JSONResponse:
    status = _status(error)
    text = str(error) if status != 500 else f"internal error ({type(error).__name__}): {error}"
    return JSONResponse({"error": text}, status_code=status)


class _Guard:
    """ASGI middleware: with a token, every request (page, files, API, stream) must carry it:
    ``?token=``, the cookie the page then keeps, or ``Authorization: Bearer``; 401 if not. A
    body is refused with 413 beyond MAX_BODY_BYTES, by its declared length or as it comes."""

    def __init__(self, app: ASGIApp, token: str | None) -> None:
        self.app = app
        self.token = token

    async def __call__(self, scope: Scope, receive: Receive, send: Send) -> None:
        if scope["type"] != "http":
            await self.app(scope, receive, send)
            return
        request = Request(scope)
        if self.token is not None and not self._allowed(request):
            await JSONResponse(
                {"error": "a token is required: open the URL planarcal live printed"}, 401
            )(scope, receive, send)
            return
        length = request.headers.get("content-length")
        if length is not None and (not _whole(length) or int(length) > MAX_BODY_BYTES):
            if _whole(length) and int(length) <= DRAIN_BYTES:
                await _drain(receive)  # a client still sending misses an early answer
            await _error(BodyTooLargeError(f"the body is over {MAX_BODY_BYTES} bytes"))(
                scope, receive, send
            )
            return
        await self.app(scope, _bounded(receive), send)

    def _allowed(self, request: Request) -> bool:
        given = [
            request.query_params.get("token"),
            request.cookies.get(TOKEN_COOKIE),
            request.headers.get("authorization", "").removeprefix("Bearer ").strip() or None,
        ]
        assert self.token is not None
        return any(g is not None and _same(g, self.token) for g in given)


def _same(given: str, token: str) -> bool:
    """Whether ``given`` is the token (in constant time)."""
    return hmac.compare_digest(given.encode(), token.encode())


async def _drain(receive: Receive) -> None:
    """Reads and drops a request's body."""
    while True:
        message = await receive()
        if message["type"] != "http.request" or not message.get("more_body", False):
            return


def _bounded(receive: Receive) -> Receive:
    """``receive`` that stops a chunked body at MAX_BODY_BYTES."""
    seen = 0

    async def inner() -> Message:
        nonlocal seen
        message = await receive()
        if message["type"] == "http.request":
            seen += len(message.get("body", b""))
            if seen > MAX_BODY_BYTES:
                raise BodyTooLargeError(f"the body is over {MAX_BODY_BYTES} bytes")
        return message

    return inner


async def _json_body(request: Request) -> dict[str, Any]:
    """The request's JSON object (an empty body is {})."""
    data = await request.body()
    if not data.strip():
        return {}
    try:
        body = json.loads(data)
    except (UnicodeDecodeError, json.JSONDecodeError) as e:
        raise ArgumentError(f"the body is not JSON: {e}") from None
    if not isinstance(body, dict):
        raise ArgumentError(f"the body must be a JSON object, got {type(body).__name__}")
    return body


def _whole(text: str) -> bool:
    """ASCII digits only (str.isdigit also takes "²", which int() refuses)."""
    return text.isascii() and text.isdigit()


def _index(path: str) -> int:
    """A path's placement or touch number."""
    if not _whole(path) or len(path) > 9:
        raise NotFoundError(f"{path!r} is not a number")
    return int(path)


Handler = Callable[[Request], Awaitable[Response]]


def _guarded(handler: Handler) -> Handler:
    """A handler whose errors become JSON answers with their status (a bad request never
    gets a traceback)."""

    async def inner(request: Request) -> Response:
        try:
            return await handler(request)
        except Exception as e:  # every failure is an answer
            return _error(e)

    return inner


class _Api:
    """The endpoints over one session (docs/live.md)."""

    def __init__(self, session: LiveSession, token: str | None) -> None:
        self.session = session
        self.token = token

    async def page(self, request: Request) -> Response:
        response = FileResponse(STATIC / "index.html", headers={"Cache-Control": "no-store"})
        given = request.query_params.get("token")
        if self.token is not None and given is not None and _same(given, self.token):
            response.set_cookie(TOKEN_COOKIE, given, httponly=True, samesite="strict")
        return response

    async def state(self, request: Request) -> Response:
        return JSONResponse(await run_in_threadpool(self.session.state))

    async def frame(self, request: Request) -> Response:
        got = await run_in_threadpool(self.session.jpeg, 0, STREAM_WAIT_S)
        if got is None:
            raise StateError(f"no frame from {self.session.pump.label}: {self.session.pump.error}")
        return Response(got[1], media_type="image/jpeg", headers={"Cache-Control": "no-store"})

    async def stream(self, request: Request) -> Response:
        async def frames() -> AsyncIterator[bytes]:
            last = 0
            while not await request.is_disconnected():
                got = await run_in_threadpool(self.session.jpeg, last, STREAM_WAIT_S)
                if got is None:
                    if self.session.closed:
                        return
                    continue
                last, data = got
                head = f"--{BOUNDARY}\r\nContent-Type: image/jpeg\r\n"
                yield f"{head}Content-Length: {len(data)}\r\n\r\n".encode() + data + b"\r\n"

        return StreamingResponse(
            frames(),
            media_type=f"multipart/x-mixed-replace; boundary={BOUNDARY}",
            headers={"Cache-Control": "no-store"},
        )

    async def mode(self, request: Request) -> Response:
        body = await _json_body(request)
        await run_in_threadpool(self.session.set_mode, body.get("mode"))
        return await self.state(request)

    async def capture(self, request: Request) -> Response:
        await run_in_threadpool(self.session.capture)
        return await self.state(request)

    async def drop_placement(self, request: Request) -> Response:
        await run_in_threadpool(self.session.drop_placement, _index(request.path_params["index"]))
        return await self.state(request)

    async def placement_png(self, request: Request) -> Response:
        index = _index(request.path_params["index"])
        data = await run_in_threadpool(self.session.placement_png, index)
        return Response(data, media_type="image/png")

    async def diagnostics_png(self, request: Request) -> Response:
        data = await run_in_threadpool(self.session.diagnostics_png)
        return Response(data, media_type="image/png", headers={"Cache-Control": "no-store"})

    async def coverage_png(self, request: Request) -> Response:
        data = self.session.coverage_png
        if data is None:
            raise NotFoundError("no error map yet: capture a placement first")
        return Response(data, media_type="image/png", headers={"Cache-Control": "no-store"})

    async def calibrate(self, request: Request) -> Response:
        body = await _json_body(request)
        limit = body.get("max_error_mm")
        if limit is not None and (
            isinstance(limit, bool) or not isinstance(limit, int | float) or not limit > 0
        ):
            raise ArgumentError(f"max_error_mm must be a number > 0 or null, got {limit!r}")
        await run_in_threadpool(self.session.calibrate, limit)
        return await self.state(request)

    async def figure(self, request: Request) -> Response:
        data = await run_in_threadpool(self.session.figure, request.path_params["name"])
        return Response(data, media_type="image/png", headers={"Cache-Control": "no-store"})

    async def save(self, request: Request) -> Response:
        saved = await run_in_threadpool(self.session.save)
        return JSONResponse({"saved": str(saved)})

    async def calibration_json(self, request: Request) -> Response:
        data = await run_in_threadpool(self.session.calibration_bytes)
        return Response(
            data,
            media_type="application/json",
            headers={"Content-Disposition": 'attachment; filename="calibration.json"'},
        )

    async def pick(self, request: Request) -> Response:
        body = await _json_body(request)
        return JSONResponse(
            await run_in_threadpool(self.session.pick, body.get("x"), body.get("y"))
        )

    async def add_touch(self, request: Request) -> Response:
        body = await _json_body(request)
        await run_in_threadpool(self.session.add_touch, body.get("id"), body.get("robot"))
        return await self.state(request)

    async def drop_touch(self, request: Request) -> Response:
        await run_in_threadpool(self.session.drop_touch, _index(request.path_params["index"]))
        return await self.state(request)

    async def touches_csv(self, request: Request) -> Response:
        if request.method == "PUT":
            try:
                text = (await request.body()).decode("utf-8")
            except UnicodeDecodeError as e:
                raise ArgumentError(f"the CSV is not UTF-8 text: {e}") from None
            await run_in_threadpool(self.session.put_touches_csv, text)
            return await self.state(request)
        return Response(
            self.session.touches_csv(),
            media_type="text/csv",
            headers={"Content-Disposition": 'attachment; filename="touches.csv"'},
        )

    async def register(self, request: Request) -> Response:
        body = await _json_body(request)
        saved = await run_in_threadpool(self.session.register, body.get("force", False))
        return JSONResponse({"saved": str(saved)})

    async def handedness(self, request: Request) -> Response:
        body = await _json_body(request)
        await run_in_threadpool(self.session.set_handedness, body.get("handedness"))
        return await self.state(request)

    async def settings(self, request: Request) -> Response:
        await run_in_threadpool(self.session.set_settings, await _json_body(request))
        return await self.state(request)

    async def save_settings(self, request: Request) -> Response:
        saved = await run_in_threadpool(self.session.save_settings)
        return JSONResponse({"saved": str(saved)})


def create_app(session: LiveSession, *, token: str | None = None) -> ASGIApp:
    """The page and the API over ``session``; ``token``: required on every request."""
    api = _Api(session, token)
    routes = [
        Route("/", _guarded(api.page)),
        Route("/api/state", _guarded(api.state)),
        Route("/api/frame.jpg", _guarded(api.frame)),
        Route("/api/stream.mjpg", _guarded(api.stream)),
        Route("/api/mode", _guarded(api.mode), methods=["POST"]),
        Route("/api/capture", _guarded(api.capture), methods=["POST"]),
        Route("/api/placements/{index}", _guarded(api.drop_placement), methods=["DELETE"]),
        Route("/api/placements/{index}.png", _guarded(api.placement_png)),
        Route("/api/coverage.png", _guarded(api.coverage_png)),
        Route("/api/diagnostics.png", _guarded(api.diagnostics_png)),
        Route("/api/calibrate", _guarded(api.calibrate), methods=["POST"]),
        Route("/api/report/{name}", _guarded(api.figure)),
        Route("/api/save", _guarded(api.save), methods=["POST"]),
        Route("/api/calibration.json", _guarded(api.calibration_json)),
        Route("/api/pick", _guarded(api.pick), methods=["POST"]),
        Route("/api/touches", _guarded(api.add_touch), methods=["POST"]),
        Route("/api/touches/{index}", _guarded(api.drop_touch), methods=["DELETE"]),
        Route("/api/touches.csv", _guarded(api.touches_csv), methods=["GET", "PUT"]),
        Route("/api/register", _guarded(api.register), methods=["POST"]),
        Route("/api/handedness", _guarded(api.handedness), methods=["POST"]),
        Route("/api/settings", _guarded(api.settings), methods=["POST"]),
        Route("/api/settings/save", _guarded(api.save_settings), methods=["POST"]),
        Mount("/static", StaticFiles(directory=STATIC), name="static"),
    ]

    async def not_found(request: Request, error: Exception) -> Response:
        status = getattr(error, "status_code", 404)
        what = "no such page" if status == 404 else f"{request.method} is not allowed here"
        return JSONResponse({"error": f"{what}: {request.url.path}"}, status_code=status)

    handlers = {404: not_found, 405: not_found}
    return _Guard(Starlette(routes=routes, exception_handlers=handlers), token)

"""The HTTP predictor (FastAPI): ``POST /predict``, ``GET /health``, ``GET /model``.

Limits (``stiffnet serve`` options, :class:`Limits`):

* **Body size** - :class:`BodyLimit` (pure ASGI middleware) answers 413 when
  the ``Content-Length`` header is over the limit, and also counts the bytes
  actually streamed (chunked uploads, lying headers): once over the limit the
  body stream raises :class:`BodyTooLarge`, which becomes a 413.
* **Concurrency** - predictions run in a thread pool of ``max_concurrency``
  workers (the event loop never runs CPU work: body parsing and prediction both
  happen in the pool). At most ``max_queue`` more requests wait for a worker;
  beyond that the answer is 429 with ``Retry-After``. A request that timed out
  keeps its slot until its thread finishes, so abandoned work cannot pile up.
* **Time** - a request not answered within ``timeout_s`` (queueing included)
  gets 504.
* **Two lanes** - a body over ``small_upload_mb`` (or of unknown length) is
  *large*: at most ``max_large`` large predictions run (their own thread) and
  ``max_large_queue`` more are admitted to upload and wait; beyond that a large
  request gets 429 *before* its body is read. Small requests keep their own
  pool, so ``/health`` and small predictions stay responsive while big uploads
  queue. Memory is bounded by ``(max_large + max_large_queue)`` bodies plus the
  running predictions.
* **Samples** - a recording over ``max_samples`` samples gets 413: compute and
  memory of a prediction grow with the samples, not the bytes (a 20 MB ``.npy``
  holds 2.6 M samples, a CSV of the same size about 1 M).
* **Body read timeout** - a body not complete within ``body_timeout_s`` of the
  request's start gets 408 and the connection is closed (slow or stalled
  senders do not hold a connection for ever). A client that disconnects
  mid-body is logged as one line.
* **Access** - :class:`Guard`: an optional bearer token (every path except
  ``/health`` and the API docs; 401 without it), an optional list of allowed
  ``Host`` headers (400; ``stiffnet serve`` sets it, which blocks DNS rebinding),
  and CORS only for the origins given (none by default). ``/docs`` and ``/redoc``
  load Swagger UI and ReDoc from the ``fastapi-offline`` package: nothing is
  fetched from a CDN.

Every error is JSON ``{"error": "one line"}``: 400 malformed request or host,
401 missing token, 404/405, 408 body too slow, 413 too large (bytes or
samples), 415 wrong content type, 422 unusable recording
(:class:`~stiffnet.errors.StiffnetError`), 429 saturated, 504 timeout.
"""

from __future__ import annotations

import asyncio
import logging
import math
import re
import secrets
import tempfile
from collections.abc import Callable
from concurrent.futures import ThreadPoolExecutor
from contextlib import asynccontextmanager
from dataclasses import dataclass
from functools import partial
from pathlib import Path
from typing import Any

import numpy as np
from fastapi import FastAPI, Request
from fastapi.exceptions import RequestValidationError
from fastapi.responses import JSONResponse
from pydantic import ValidationError
from starlette.exceptions import HTTPException as StarletteHTTPException
from starlette.requests import ClientDisconnect

from serving.predictor import Predictor
from serving.schemas import (
    ErrorBody,
    HealthResponse,
    ModelResponse,
    PredictionResult,
    PredictRequest,
)
from stiffnet.errors import StiffnetError

#: One-line log of the server's events (uvicorn configures this logger).
log = logging.getLogger("uvicorn.error")


#: Small bodies (each <= small_upload_mb) being received at once; more get 429 unread.
MAX_SMALL_READERS = 256


class BodyTooLarge(Exception):
    """The request body exceeded the configured limit while streaming."""


class BodyTimeout(Exception):
    """The request body did not arrive within the body read timeout."""


class TooManySamples(StiffnetError):
    """The recording holds more samples than one request may (413)."""


@dataclass(frozen=True)
class Limits:
    """Server limits (see the module notes)."""

    max_upload_mb: float = 20.0
    timeout_s: float = 30.0
    max_concurrency: int = 2
    max_queue: int = 64
    max_samples: int = 2_000_000
    small_upload_mb: float = 1.0
    max_large: int = 1
    max_large_queue: int = 2
    body_timeout_s: float = 20.0

    @property
    def max_bytes(self) -> int:
        return int(self.max_upload_mb * 1024 * 1024)

    @property
    def small_bytes(self) -> int:
        return int(self.small_upload_mb * 1024 * 1024)

    @classmethod
    def checked(
        cls,
        max_upload_mb: float,
        timeout_s: float,
        max_concurrency: int,
        max_queue: int,
        **more: float,
    ) -> Limits:
        """Validated limits; :class:`StiffnetError` for a value out of range."""
        from stiffnet.inputs import available_cores, bounded_count

        values = {"max_upload_mb": max_upload_mb, "timeout_s": timeout_s, **more}
        for name, v in values.items():
            if isinstance(v, float) and not (math.isfinite(v) and v > 0):
                raise StiffnetError(f"--{name.replace('_', '-')} must be > 0, got {v}")
        # worker threads do CPU work: more than 4 per core only adds contention
        bounded_count(max_concurrency, "--max-concurrency", 1, 4 * available_cores())
        bounded_count(max_queue, "--max-queue", 0, 100_000)
        for name in ("max_samples", "max_large", "max_large_queue"):
            if name in more:
                lo = 0 if name == "max_large_queue" else 1
                bounded_count(more[name], f"--{name.replace('_', '-')}", lo, 10**9)
        return cls(float(max_upload_mb), float(timeout_s), int(max_concurrency), int(max_queue),
                   **more)  # fmt: skip


def _error(status: int, message: str, headers: dict[str, str] | None = None) -> JSONResponse:
    one_line = " ".join(str(message).split())[:1000] or "error"
    return JSONResponse({"error": one_line}, status_code=status, headers=headers)


class BodyLimit:
    """ASGI middleware: 413 on a too-large ``Content-Length``, :class:`BodyTooLarge` on streams."""

    def __init__(self, app: Any, max_bytes: int, timeout_s: float = 20.0) -> None:
        self.app = app
        self.max_bytes = max_bytes
        self.timeout_s = timeout_s

    async def __call__(self, scope: dict, receive: Callable, send: Callable) -> None:
        if scope["type"] != "http":
            await self.app(scope, receive, send)
            return
        for key, value in scope.get("headers", []):
            if key == b"content-length":
                try:
                    length = int(value)
                except ValueError:
                    await _error(400, "invalid Content-Length header")(scope, receive, send)
                    return
                if length > self.max_bytes:
                    await self._too_large(scope, receive, send)
                    return
        seen = 0
        loop = asyncio.get_running_loop()
        deadline = loop.time() + self.timeout_s

        async def limited() -> dict:
            nonlocal seen
            try:  # the whole body within timeout_s: a trickling sender is cut off too
                message = await asyncio.wait_for(receive(), max(0.0, deadline - loop.time()))
            except TimeoutError:
                raise BodyTimeout from None
            if message["type"] == "http.request":
                seen += len(message.get("body", b""))
                if seen > self.max_bytes:
                    raise BodyTooLarge
            return message

        await self.app(scope, limited, send)

    async def _too_large(self, scope: dict, receive: Callable, send: Callable) -> None:
        mb = self.max_bytes / (1024 * 1024)
        await _error(413, f"request body larger than the limit of {mb:g} MB")(scope, receive, send)


class Guard:
    """ASGI middleware: allowed ``Host`` headers (400) and an optional bearer token (401).

    ``/health`` and the API docs stay open (liveness probes; the schema is public).
    """

    OPEN = ("/health", "/docs", "/redoc", "/openapi.json", "/static-offline-docs/")

    def __init__(self, app: Any, token: str | None, allowed_hosts: list[str] | None) -> None:
        self.app = app
        self.token = token.encode() if token else None
        self.hosts = None if not allowed_hosts or "*" in allowed_hosts else set(allowed_hosts)

    async def __call__(self, scope: dict, receive: Callable, send: Callable) -> None:
        if scope["type"] != "http":
            await self.app(scope, receive, send)
            return
        headers = dict(scope.get("headers", []))
        if self.hosts is not None:
            host = headers.get(b"host", b"").decode("latin-1")
            name = host.rsplit(":", 1)[0] if not host.endswith("]") else host
            if name.strip("[]") not in self.hosts and name not in self.hosts:
                await _error(400, "host not allowed (see stiffnet serve --allowed-host)")(
                    scope, receive, send
                )
                return
        path = scope.get("path", "")
        if self.token is not None and not (path in self.OPEN or path.startswith(self.OPEN[-1])):
            auth = headers.get(b"authorization", b"")
            scheme, _, given = auth.partition(b" ")
            if scheme.lower() != b"bearer" or not secrets.compare_digest(given.strip(), self.token):
                await _error(401, "missing or wrong bearer token",
                             {"WWW-Authenticate": "Bearer"})(scope, receive, send)  # fmt: skip
                return
        await self.app(scope, receive, send)


_SUFFIX = re.compile(r"^\.[A-Za-z0-9]{1,8}$")


def _check_samples(n: int, max_samples: int) -> None:
    if n > max_samples:
        raise TooManySamples(
            f"recording has {n} samples; this server takes at most {max_samples} per request"
        )


def _predict_json(predictor: Predictor, body: bytes, max_samples: int = 2_000_000) -> dict:
    try:
        req = PredictRequest.model_validate_json(body)
    except ValidationError as exc:
        errs = exc.errors(include_url=False)
        first = errs[0] if errs else {"loc": (), "msg": str(exc)}
        where = ".".join(str(x) for x in first.get("loc", ())) or "body"
        more = f" (+{len(errs) - 1} more)" if len(errs) > 1 else ""
        raise StiffnetError(f"invalid JSON body: {where}: {first.get('msg')}{more}") from None
    _check_samples(len(req.samples), max_samples)
    return predictor.predict(
        np.asarray(req.samples, dtype=np.float64),
        req.fs_hz,
        natural_frequency_hz=req.natural_frequency_hz,
        source="request",
        natural_frequency_source="request",
        sensor=req.sensor,
    )


def _number_field(value: Any, name: str) -> float | None:
    if value is None or (isinstance(value, str) and not value.strip()):
        return None
    if not isinstance(value, str):
        raise StiffnetError(f"form field {name} must be a number, not a file")
    try:
        return float(value)
    except ValueError:
        raise StiffnetError(f"form field {name}: {value[:40]!r} is not a number") from None


def _text_field(value: Any, name: str) -> str | None:
    if value is None or (isinstance(value, str) and not value.strip()):
        return None
    if not isinstance(value, str):
        raise StiffnetError(f"form field {name} must be text, not a file")
    return value.strip()[:200]


def _predict_file(
    predictor: Predictor,
    data: bytes,
    filename: str,
    fs: Any,
    fn: Any,
    max_samples: int = 2_000_000,
    columns: Any = None,
    time_unit: Any = None,
) -> dict:
    from stiffnet.recordings import read_recording

    fs_hz = _number_field(fs, "fs_hz")
    layout = {
        "columns": _text_field(columns, "columns"),
        "time_unit": _text_field(time_unit, "time_unit"),
    }
    fn_hz = _number_field(fn, "natural_frequency_hz")
    suffix = Path(filename).suffix
    if not _SUFFIX.match(suffix):
        suffix = ""
    shown = re.sub(r"[^\w.\- ]", "_", Path(filename).name)[:80] or "upload"
    with tempfile.TemporaryDirectory(prefix="stiffnet-upload-") as tmp:
        path = Path(tmp) / f"upload{suffix}"
        path.write_bytes(data)
        try:
            rec = read_recording(path, fs_hz=fs_hz, **layout)
        except StiffnetError as exc:
            raise StiffnetError(str(exc).replace(str(path), shown)) from None
    _check_samples(rec.accel.size, max_samples)
    return predictor.predict(
        rec.accel,
        rec.fs_hz,
        natural_frequency_hz=fn_hz,
        source=shown,
        natural_frequency_source="request",
    )


_PREDICT_BODY = {
    "requestBody": {
        "required": True,
        "content": {
            "application/json": {"schema": PredictRequest.model_json_schema()},
            "multipart/form-data": {
                "schema": {
                    "type": "object",
                    "required": ["file"],
                    "properties": {
                        "file": {
                            "type": "string",
                            "format": "binary",
                            "description": "Recording: CSV t,accel, .npy, .wav, .tdms",
                        },
                        "fs_hz": {"type": "number", "description": "Sampling rate (.npy)"},
                        "natural_frequency_hz": {"type": "number"},
                        "columns": {
                            "type": "string",
                            "description": "CSV columns TIME,ACCEL (header names or 0-based "
                            "indices) when the header is not t,accel",
                            "examples": ["time_s,acc_g"],
                        },
                        "time_unit": {
                            "type": "string",
                            "enum": ["s", "ms", "us"],
                            "description": "Unit of the CSV time column (default s)",
                        },
                    },
                }
            },
        },
    }
}
_ERRORS = {
    code: {"model": ErrorBody, "description": text}
    for code, text in {
        400: "malformed request or host not allowed",
        401: "missing or wrong bearer token (when the server has one)",
        405: "method not allowed",
        408: "body not received in time",
        413: "body too large, or too many samples",
        415: "unsupported content type",
        422: "unusable recording",
        429: "too many requests waiting",
        504: "timed out",
    }.items()
}


#: Errors any route can answer (the body limit and method checks run before routing).
_GET_ERRORS = {
    code: {"model": ErrorBody, "description": text}
    for code, text in {405: "method not allowed", 413: "body too large"}.items()
}


def create_app(
    predictor: Predictor,
    limits: Limits | None = None,
    *,
    token: str | None = None,
    allowed_hosts: list[str] | None = None,
    cors_origins: list[str] | None = None,
) -> FastAPI:
    """The FastAPI application serving `predictor` under `limits` (see the module notes).

    ``token``: bearer token required on every path but ``/health`` and the docs;
    ``allowed_hosts``: accepted ``Host`` names (None: any); ``cors_origins``:
    origins allowed to call from a browser (None: no CORS headers).
    """
    from fastapi_offline import FastAPIOffline  # Swagger UI / ReDoc assets, no CDN

    limits = limits or Limits()
    small = ThreadPoolExecutor(max_workers=limits.max_concurrency, thread_name_prefix="predict")
    large = ThreadPoolExecutor(max_workers=limits.max_large, thread_name_prefix="predict-large")
    state = {"in_flight": 0, "large": 0, "reading": 0, "served": 0}

    @asynccontextmanager
    async def lifespan(_app: FastAPI):
        yield
        for pool in (small, large):
            pool.shutdown(wait=False, cancel_futures=True)

    app = FastAPIOffline(
        title="stiffnet predictor",
        version="1",
        description="Stiffness class and beta of an accelerometer recording (ONNX model) with "
        'the geometric inclination method as cross-check. Errors: {"error": "..."}.',
        lifespan=lifespan,
    )
    app.state.load = state  # requests in flight per lane (read by /health and tests)
    app.add_middleware(BodyLimit, max_bytes=limits.max_bytes, timeout_s=limits.body_timeout_s)
    app.add_middleware(Guard, token=token, allowed_hosts=allowed_hosts)
    if cors_origins:
        from starlette.middleware.cors import CORSMiddleware

        app.add_middleware(CORSMiddleware, allow_origins=list(cors_origins),
                           allow_methods=["GET", "POST"],
                           allow_headers=["Authorization", "Content-Type"])  # fmt: skip

    @app.exception_handler(StiffnetError)
    async def _stiffnet(_req: Request, exc: StiffnetError) -> JSONResponse:
        return _error(422, str(exc))

    @app.exception_handler(TooManySamples)
    async def _samples(_req: Request, exc: TooManySamples) -> JSONResponse:
        return _error(413, str(exc))

    @app.exception_handler(BodyTooLarge)
    async def _too_large(_req: Request, _exc: BodyTooLarge) -> JSONResponse:
        return _error(413, f"request body larger than the limit of {limits.max_upload_mb:g} MB")

    @app.exception_handler(BodyTimeout)
    async def _slow(_req: Request, _exc: BodyTimeout) -> JSONResponse:
        log.warning("408: request body not complete within %g s", limits.body_timeout_s)
        return _error(408, f"request body not received within {limits.body_timeout_s:g} s",
                      {"Connection": "close"})  # fmt: skip

    @app.exception_handler(ClientDisconnect)
    async def _gone(req: Request, _exc: ClientDisconnect) -> JSONResponse:
        client = f"{req.client.host}:{req.client.port}" if req.client else "client"
        log.warning("%s disconnected before its request body was complete", client)
        return _error(400, "client disconnected")  # not delivered: the client is gone

    @app.exception_handler(StarletteHTTPException)
    async def _http(_req: Request, exc: StarletteHTTPException) -> JSONResponse:
        return _error(exc.status_code, str(exc.detail), getattr(exc, "headers", None))

    @app.exception_handler(RequestValidationError)
    async def _validation(_req: Request, exc: RequestValidationError) -> JSONResponse:
        return _error(422, f"invalid request: {exc.errors()[:1]}")

    def release(key: str) -> Callable[[Any], None]:
        def done(_f: Any = None) -> None:
            state[key] -= 1

        return done

    async def body_job(request: Request, ctype: str) -> Callable[[], dict] | JSONResponse:
        """Read the body (the event loop only streams it) into a job for a worker thread."""
        n = limits.max_samples
        if ctype == "application/json":
            body = await request.body()
            return partial(_predict_json, predictor, body, n)
        async with request.form(max_files=1, max_fields=8) as form:
            upload = form.get("file")
            if upload is None or isinstance(upload, str):
                return _error(400, "multipart body needs a 'file' part holding the recording")
            data = await upload.read()
            return partial(_predict_file, predictor, data, upload.filename or "upload",
                           form.get("fs_hz"), form.get("natural_frequency_hz"), n,
                           form.get("columns"), form.get("time_unit"))  # fmt: skip

    @app.post(
        "/predict",
        response_model=PredictionResult,
        responses=_ERRORS,
        openapi_extra=_PREDICT_BODY,
        summary="Predict one recording (JSON samples or a file upload)",
    )
    async def predict(request: Request) -> JSONResponse:
        ctype = request.headers.get("content-type", "").split(";")[0].strip().lower()
        if ctype not in ("application/json", "multipart/form-data"):
            return _error(
                415, "send application/json {samples, fs_hz} or multipart/form-data (file)"
            )
        length = request.headers.get("content-length")
        is_large = length is None or not length.isdigit() or int(length) > limits.small_bytes
        # Large: admitted (reading, waiting or running) up to its cap, refused unread beyond.
        # Small: bodies being read are bounded apart (a stalled sender must not take a
        # worker's queue place); the worker queue counts read bodies only.
        key, cap = ("large", limits.max_large + limits.max_large_queue) if is_large else (
            "reading", MAX_SMALL_READERS)  # fmt: skip
        if state[key] >= cap:  # refused before its body is read: memory stays bounded
            what = "large requests" if is_large else "uploads being received"
            return _error(429, f"too many {what}; retry later", {"Retry-After": "1"})
        state[key] += 1
        done = release(key)
        try:
            job = await body_job(request, ctype)
        except BaseException:
            done()
            raise
        if not is_large:
            done()  # the small body is read: its reading slot is free
        if isinstance(job, JSONResponse):
            if is_large:
                done()
            return job
        if not is_large:
            if state["in_flight"] >= limits.max_concurrency + limits.max_queue:
                return _error(429, "too many requests in flight; retry later",
                              {"Retry-After": "1"})  # fmt: skip
            state["in_flight"] += 1
            done = release("in_flight")
        pool = large if is_large else small
        loop = asyncio.get_running_loop()
        fut = loop.run_in_executor(pool, job)
        fut.add_done_callback(done)  # a timed-out job keeps its slot until its thread ends
        try:
            result = await asyncio.wait_for(asyncio.shield(fut), limits.timeout_s)
        except TimeoutError:
            return _error(504, f"prediction did not finish within {limits.timeout_s:g} s")
        state["served"] += 1
        return JSONResponse(result)

    @app.get(
        "/health",
        response_model=HealthResponse,
        responses=_GET_ERRORS,
        summary="Liveness and load",
    )
    async def health() -> dict[str, Any]:
        return {
            "status": "ok",
            "model": predictor.name,
            "sha256": predictor.sha256,
            "in_flight": state["in_flight"],
            "large_in_flight": state["large"],
            "served": state["served"],
        }

    @app.get(
        "/model",
        response_model=ModelResponse,
        responses=_GET_ERRORS,
        summary="The served model and the server limits",
    )
    async def model() -> dict[str, Any]:
        return {
            **predictor.info(),
            "limits": {
                "max_upload_mb": limits.max_upload_mb,
                "timeout_s": limits.timeout_s,
                "max_concurrency": limits.max_concurrency,
                "max_queue": limits.max_queue,
                "max_samples": limits.max_samples,
                "small_upload_mb": limits.small_upload_mb,
                "max_large": limits.max_large,
                "max_large_queue": limits.max_large_queue,
                "body_timeout_s": limits.body_timeout_s,
            },
        }

    return app

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

Every error is JSON ``{"error": "one line"}``: 400 malformed request, 404/405,
413 too large, 415 wrong content type, 422 unusable recording
(:class:`~stiffnet.errors.StiffnetError`), 429 saturated, 504 timeout.
"""

from __future__ import annotations

import asyncio
import math
import re
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

from serving.predictor import Predictor
from serving.schemas import (
    ErrorBody,
    HealthResponse,
    ModelResponse,
    PredictionResult,
    PredictRequest,
)
from stiffnet.errors import StiffnetError


class BodyTooLarge(Exception):
    """The request body exceeded the configured limit while streaming."""


@dataclass(frozen=True)
class Limits:
    """Server limits (see the module notes)."""

    max_upload_mb: float = 20.0
    timeout_s: float = 30.0
    max_concurrency: int = 2
    max_queue: int = 64

    @property
    def max_bytes(self) -> int:
        return int(self.max_upload_mb * 1024 * 1024)

    @classmethod
    def checked(
        cls, max_upload_mb: float, timeout_s: float, max_concurrency: int, max_queue: int
    ) -> Limits:
        """Validated limits; :class:`StiffnetError` for a non-positive value."""
        for name, v in (
            ("max-upload-mb", max_upload_mb),
            ("timeout-s", timeout_s),
            ("max-concurrency", max_concurrency),
        ):
            if not (math.isfinite(v) and v > 0):
                raise StiffnetError(f"--{name} must be > 0, got {v}")
        if max_queue < 0:
            raise StiffnetError(f"--max-queue must be >= 0, got {max_queue}")
        return cls(float(max_upload_mb), float(timeout_s), int(max_concurrency), int(max_queue))


def _error(status: int, message: str, headers: dict[str, str] | None = None) -> JSONResponse:
    one_line = " ".join(str(message).split())[:1000] or "error"
    return JSONResponse({"error": one_line}, status_code=status, headers=headers)


class BodyLimit:
    """ASGI middleware: 413 on a too-large ``Content-Length``, :class:`BodyTooLarge` on streams."""

    def __init__(self, app: Any, max_bytes: int) -> None:
        self.app = app
        self.max_bytes = max_bytes

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

        async def limited() -> dict:
            nonlocal seen
            message = await receive()
            if message["type"] == "http.request":
                seen += len(message.get("body", b""))
                if seen > self.max_bytes:
                    raise BodyTooLarge
            return message

        await self.app(scope, limited, send)

    async def _too_large(self, scope: dict, receive: Callable, send: Callable) -> None:
        mb = self.max_bytes / (1024 * 1024)
        await _error(413, f"request body larger than the limit of {mb:g} MB")(scope, receive, send)


_SUFFIX = re.compile(r"^\.[A-Za-z0-9]{1,8}$")


def _predict_json(predictor: Predictor, body: bytes) -> dict[str, Any]:
    try:
        req = PredictRequest.model_validate_json(body)
    except ValidationError as exc:
        errs = exc.errors(include_url=False)
        first = errs[0] if errs else {"loc": (), "msg": str(exc)}
        where = ".".join(str(x) for x in first.get("loc", ())) or "body"
        more = f" (+{len(errs) - 1} more)" if len(errs) > 1 else ""
        raise StiffnetError(f"invalid JSON body: {where}: {first.get('msg')}{more}") from None
    return predictor.predict(
        np.asarray(req.samples, dtype=np.float64),
        req.fs_hz,
        natural_frequency_hz=req.natural_frequency_hz,
        source="request",
        natural_frequency_source="request",
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
        400: "malformed request",
        405: "method not allowed",
        413: "body too large",
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


def create_app(predictor: Predictor, limits: Limits | None = None) -> FastAPI:
    """The FastAPI application serving `predictor` under `limits`."""
    limits = limits or Limits()
    pool = ThreadPoolExecutor(max_workers=limits.max_concurrency, thread_name_prefix="predict")
    state = {"in_flight": 0, "served": 0}

    @asynccontextmanager
    async def lifespan(_app: FastAPI):
        yield
        pool.shutdown(wait=False, cancel_futures=True)

    app = FastAPI(
        title="stiffnet predictor",
        version="1",
        description="Stiffness class and beta of an accelerometer recording (ONNX model) with "
        'the geometric inclination method as cross-check. Errors: {"error": "..."}.',
        lifespan=lifespan,
    )
    app.add_middleware(BodyLimit, max_bytes=limits.max_bytes)

    @app.exception_handler(StiffnetError)
    async def _stiffnet(_req: Request, exc: StiffnetError) -> JSONResponse:
        return _error(422, str(exc))

    @app.exception_handler(BodyTooLarge)
    async def _too_large(_req: Request, _exc: BodyTooLarge) -> JSONResponse:
        return _error(413, f"request body larger than the limit of {limits.max_upload_mb:g} MB")

    @app.exception_handler(StarletteHTTPException)
    async def _http(_req: Request, exc: StarletteHTTPException) -> JSONResponse:
        return _error(exc.status_code, str(exc.detail), getattr(exc, "headers", None))

    @app.exception_handler(RequestValidationError)
    async def _validation(_req: Request, exc: RequestValidationError) -> JSONResponse:
        return _error(422, f"invalid request: {exc.errors()[:1]}")

    async def run_limited(job: Callable[[], dict]) -> JSONResponse:
        if state["in_flight"] >= limits.max_concurrency + limits.max_queue:
            return _error(429, "too many requests in flight; retry later", {"Retry-After": "1"})
        state["in_flight"] += 1
        loop = asyncio.get_running_loop()
        fut = loop.run_in_executor(pool, job)

        def done(_f: Any) -> None:
            state["in_flight"] -= 1

        fut.add_done_callback(done)
        try:
            result = await asyncio.wait_for(asyncio.shield(fut), limits.timeout_s)
        except TimeoutError:
            return _error(504, f"prediction did not finish within {limits.timeout_s:g} s")
        state["served"] += 1
        return JSONResponse(result)

    @app.post(
        "/predict",
        response_model=PredictionResult,
        responses=_ERRORS,
        openapi_extra=_PREDICT_BODY,
        summary="Predict one recording (JSON samples or a file upload)",
    )
    async def predict(request: Request) -> JSONResponse:
        ctype = request.headers.get("content-type", "").split(";")[0].strip().lower()
        if ctype == "application/json":
            body = await request.body()
            return await run_limited(partial(_predict_json, predictor, body))
        if ctype == "multipart/form-data":
            async with request.form(max_files=1, max_fields=8) as form:
                upload = form.get("file")
                if upload is None or isinstance(upload, str):
                    return _error(400, "multipart body needs a 'file' part holding the recording")
                data = await upload.read()
                job = partial(
                    _predict_file,
                    predictor,
                    data,
                    upload.filename or "upload",
                    form.get("fs_hz"),
                    form.get("natural_frequency_hz"),
                    form.get("columns"),
                    form.get("time_unit"),
                )
            return await run_limited(job)
        return _error(415, "send application/json {samples, fs_hz} or multipart/form-data (file)")

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
            },
        }

    return app

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
* **Time** - a request not answered within ``timeout_s`` (queueing included) gets 429
  if it was still queued; a started prediction is answered when it ends, up to a hard
  ceiling of ``(1 + OVERRUN_GRACE)`` times the timeout (90 s by default; its worker is held
  to its end anyway and its client is waiting; one log line at the timeout gives its
  progress), then 503 with ``Retry-After`` (the machine slowed beyond its price 3.75
  times: overloaded, not broken): the last guard, since load shedding refuses first what
  would pass it. A worker that takes a job too late for it
  to finish in time refuses it (429) before any work.
* **Load shedding** - :class:`LaneCost`: before a job is queued, its cost (its
  samples times the lane's seconds per sample, measured online from the lane's
  finished predictions, seeded conservatively) is added to the expected wait for a
  worker (the estimates of what the lane runs and holds queued); a job that would not
  finish within :data:`SHED_MARGIN` of ``timeout_s`` gets 429 and ``Retry-After`` (the
  seconds until it would fit) before any work. A job that finds a worker free is
  refused only if its CPU cost times the lane's slow-down now (:class:`Contention`:
  wall over CPU time of the lane's jobs of the last minute, and of its running jobs so
  far) passes that budget (``Retry-After`` is then the timeout). A large lane with none
  measured lately is priced at the machine's load (``(load + 1) / cores``); a small one
  at the large lane's, and with none at all it is started.
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
  request's start, or silent for ``body_idle_s``, gets 408 and the connection is
  closed (slow or stalled senders do not hold a connection for ever). A client
  that disconnects mid-body is logged as one line.
* **Per client** - one client address holds at most :data:`MAX_READERS_PER_CLIENT`
  small bodies being received and :data:`MAX_LARGE_PER_CLIENT` large requests: a
  client stalling its uploads locks out only itself.
* **Headers** - :class:`GuardedH11Protocol` (``stiffnet serve``): a connection that
  has not sent a whole request head within :data:`HEADER_TIMEOUT_S` gets 408 and is
  closed (a trickle of header lines no longer holds it open), and uvicorn's own
  400s (a malformed ``Content-Length``, a broken request line) are JSON too.
* **Samples before parsing** - a JSON body holding more numbers than
  ``max_samples`` (counted by its commas, before the parser builds anything), a
  CSV upload with more lines, or an ``.npy`` whose header says more, gets 413 unparsed.
* **Access log** - one line per request (client, method, path, status, bytes,
  milliseconds) on the ``stiffnet.access`` logger (``stiffnet serve`` prints it).
* **Access** - :class:`Guard`: an optional bearer token (every path except
  ``/health`` and the API docs; 401 without it), an optional list of allowed
  ``Host`` headers (400; ``stiffnet serve`` sets it, which blocks DNS rebinding),
  and CORS only for the origins given (none by default). ``/docs`` and ``/redoc``
  load Swagger UI and ReDoc from the ``fastapi-offline`` package: nothing is
  fetched from a CDN.

Every error is JSON ``{"error": "one line"}`` (a foreign CORS preflight's 400 too): 400
malformed request or host,
401 missing token, 404/405, 408 body too slow, 413 too large (bytes or
samples), 415 wrong content type, 422 unusable recording
(:class:`~stiffnet.errors.StiffnetError`, a CSV the parser refuses, an unknown form
field), 429 saturated or too busy to finish in time, 503 the server's disk or memory
failed, or a started prediction overran the timeout (with ``Retry-After``).
"""

from __future__ import annotations

import asyncio
import copy
import csv
import json
import logging
import math
import re
import secrets
import shutil
import sys
import tempfile
import time
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

from serving.load_shedding import (
    OVERRUN_LEFT,
    SEED_CPU_S_PER_SAMPLE,
    SEED_S_PER_SAMPLE,
    SHED_MARGIN,
    LaneCost,
    machine_slow_down,
    thread_cpu_clock,
)
from serving.predictor import Predictor
from serving.schemas import (
    ErrorBody,
    HealthResponse,
    LogResult,
    ModelResponse,
    PredictionResult,
    PredictRequest,
)
from stiffnet import __version__
from stiffnet.errors import StiffnetError
from stiffnet.inputs import HINT_CONTEXT, one_line, unit_hint

#: One-line log of the server's events (uvicorn configures this logger).
log = logging.getLogger("uvicorn.error")


#: Small bodies (each <= small_upload_mb) being received at once; more get 429 unread.
MAX_SMALL_READERS = 256
#: Small bodies one client address may have in reception at once.
MAX_READERS_PER_CLIENT = 16
#: Large requests (admitted, waiting or running) of one client address: fewer than the
#: lane holds (3 by default), so one client stalling its uploads leaves the lane open.
MAX_LARGE_PER_CLIENT = 2
#: Seconds a connection may take to send a whole request head (line and headers).
HEADER_TIMEOUT_S = 10.0
#: Time a prediction that started before the timeout is given beyond it, as a fraction of
#: the timeout: a started prediction holds its worker to its end anyway and its client is
#: waiting, so its result is answered when it ends, up to ``(1 + OVERRUN_GRACE) * timeout_s``
#: after its body was read (90 s by default): the hard ceiling, past which it is refused
#: (503). Admission prices a job to end within :data:`SHED_MARGIN` of the timeout, so a 503
#: needs the machine to slow it 3.75 times more than measured when it was admitted.
OVERRUN_GRACE = 2.0
#: Form fields of a multipart request; any other is refused, as unknown JSON keys are.
FORM_FIELDS = ("file", "fs_hz", "natural_frequency_hz", "columns", "time_unit", "channel", "sensor")
#: One line per request: client, method, path, status, bytes, milliseconds.
access_log = logging.getLogger("stiffnet.access")


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
    body_idle_s: float = 5.0
    header_timeout_s: float = HEADER_TIMEOUT_S

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

    def __init__(
        self, app: Any, max_bytes: int, timeout_s: float = 20.0, idle_s: float = 5.0
    ) -> None:
        self.app = app
        self.max_bytes = max_bytes
        self.timeout_s = timeout_s
        self.idle_s = idle_s

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
            # the whole body within timeout_s (a trickling sender is cut off too), and no
            # silence longer than idle_s (a stalled sender frees its slot early)
            wait = max(0.0, min(deadline - loop.time(), self.idle_s))
            try:
                message = await asyncio.wait_for(receive(), wait)
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


class JsonCORS:
    """Starlette's CORS middleware whose refusals (a foreign origin's preflight) are JSON."""

    def __new__(cls, app: Any, **options: Any) -> Any:
        from starlette.middleware.cors import CORSMiddleware

        class _Cors(CORSMiddleware):
            def preflight_response(self, request_headers: Any) -> Any:
                response = super().preflight_response(request_headers)
                if response.status_code != 200:
                    text = response.body.decode("utf-8", "replace")
                    return _error(response.status_code, text)
                return response

        return _Cors(app, **options)


class AccessLog:
    """ASGI middleware: one line per request on :data:`access_log`.

    ``client "METHOD path" status bytes ms`` (the query string is left out: it is not
    used, and a token must never reach a log).
    """

    def __init__(self, app: Any) -> None:
        self.app = app

    async def __call__(self, scope: dict, receive: Callable, send: Callable) -> None:
        if scope["type"] != "http" or not access_log.isEnabledFor(logging.INFO):
            await self.app(scope, receive, send)
            return
        t0 = time.perf_counter()
        seen = {"status": 0, "bytes": 0}

        async def counted(message: dict) -> None:
            if message["type"] == "http.response.start":
                seen["status"] = message["status"]
            elif message["type"] == "http.response.body":
                seen["bytes"] += len(message.get("body", b""))
            await send(message)

        try:
            await self.app(scope, receive, counted)
        finally:
            client = scope.get("client") or ("-", 0)
            path = "".join(ch if ch.isprintable() else "?" for ch in scope.get("path", ""))[:200]
            access_log.info('%s "%s %s" %d %d %.0f ms', client[0], scope.get("method", "-"),
                            path, seen["status"] or 500, seen["bytes"],
                            1e3 * (time.perf_counter() - t0))  # fmt: skip


def enable_access_log(stream: Any = None) -> None:
    """Print :data:`access_log` lines (``stiffnet serve``) on ``stream`` (stderr)."""
    if not access_log.handlers:
        handler = logging.StreamHandler(stream or sys.stderr)
        handler.setFormatter(logging.Formatter("%(asctime)s access %(message)s"))
        access_log.addHandler(handler)
    access_log.setLevel(logging.INFO)
    access_log.propagate = False


def _raw_json_response(status: int, reason: str, message: str) -> bytes:
    body = json.dumps({"error": message}).encode()
    head = (f"HTTP/1.1 {status} {reason}\r\ncontent-type: application/json\r\n"
            f"content-length: {len(body)}\r\nconnection: close\r\n\r\n")  # fmt: skip
    return head.encode() + body


def guarded_protocol(header_timeout_s: float = HEADER_TIMEOUT_S) -> type:
    """uvicorn's h11 protocol with a header-read timeout and JSON bodies for its own 400s.

    uvicorn cancels its keep-alive timer at the first byte of a request and arms no
    other until a response is sent: a client trickling header lines held the
    connection for ever. Here every request head must be complete within
    ``header_timeout_s`` of the connection (or of the previous response), else 408
    and close. A request uvicorn cannot parse gets ``{"error": ...}`` like every other
    error of the server.
    """
    import h11
    from uvicorn.protocols.http.h11_impl import H11Protocol

    class GuardedH11Protocol(H11Protocol):
        def connection_made(self, transport: Any) -> None:  # type: ignore[override]
            super().connection_made(transport)
            self._arm_header_timer()

        def _arm_header_timer(self) -> None:
            timer = getattr(self, "_header_timer", None)
            if timer is not None:
                timer.cancel()
            self._header_timer = self.loop.call_later(header_timeout_s, self._head_late)

        def _head_late(self) -> None:
            if self.transport.is_closing() or self.conn.their_state is not h11.IDLE:
                return  # closed, or a head arrived (its body has its own timeout)
            if self.cycle is not None and not self.cycle.response_complete:
                return  # a response is under way
            if self.conn.trailing_data[0]:  # part of a head arrived, then too little
                log.warning("408: request head not complete within %g s", header_timeout_s)
                message = f"request head not received within {header_timeout_s:g} s"
                self.transport.write(_raw_json_response(408, "Request Timeout", message))
            self.transport.close()

        def on_response_complete(self) -> None:
            super().on_response_complete()
            if not self.transport.is_closing():
                self._arm_header_timer()

        def connection_lost(self, exc: Exception | None) -> None:
            timer = getattr(self, "_header_timer", None)
            if timer is not None:
                timer.cancel()
            super().connection_lost(exc)

        def send_400_response(self, msg: str) -> None:
            message = "malformed HTTP request (request line, headers or Content-Length)"
            self.transport.write(_raw_json_response(400, "Bad Request", message))
            self.transport.close()

    return GuardedH11Protocol


_SUFFIX = re.compile(r"^\.[A-Za-z0-9]{1,8}$")


def _check_samples(n: int, max_samples: int, how: str = "") -> None:
    if n > max_samples:
        count = f"over {max_samples}" if how else str(n)
        raise TooManySamples(
            f"recording has {count} samples; this server takes at most {max_samples} per request"
        )


def _body_problems(exc: ValidationError, shown: int = 4) -> str:
    """A JSON body's problems in one line, the missing fields first: a body naming its
    samples ``accel`` was told only 'accel: Extra inputs are not permitted (+2 more)',
    not that ``samples`` and ``fs_hz`` were missing."""
    errs = exc.errors(include_url=False) or [{"loc": (), "msg": str(exc)}]
    errs = sorted(errs, key=lambda e: e.get("type") != "missing")  # stable: the rest in order
    said = []
    for e in errs[:shown]:
        where = ".".join(str(x) for x in e.get("loc", ())) or "body"
        said.append(f"{where}: {e.get('msg')}{_number_words(e)}")
    more = f" (+{len(errs) - shown} more)" if len(errs) > shown else ""
    return "; ".join(said) + more


def _number_words(error: dict) -> str:
    """The value a number field was refused for, and what to write where a lab's habit
    shows (``"1000,0"``: a decimal comma; ``"1 kHz"``: a unit); empty for other errors."""
    value = error.get("input")
    if error.get("type") not in ("float_parsing", "float_type") or not isinstance(value, str):
        return ""
    return f", got {value[:40]!r}{unit_hint(value)}"


def _predict_json(
    predictor: Predictor, body: bytes, max_samples: int = 2_000_000, what: str = "predict"
) -> dict:
    # the numbers are counted before the parser builds them: 20 MB of "0," is 10 M
    # samples and ~1 GB of Python floats, refused here for the price of one scan
    if body.count(b",") > max_samples + len(PredictRequest.model_fields):
        _check_samples(max_samples + 1, max_samples, "over")
    try:
        req = PredictRequest.model_validate_json(body)
    except ValidationError as exc:
        raise StiffnetError(f"invalid JSON body: {_body_problems(exc)}") from None
    _check_samples(len(req.samples), max_samples)
    accel = np.asarray(req.samples, dtype=np.float64)
    if what == "log":
        return _log(predictor, accel, req.fs_hz, req.natural_frequency_hz, "request", req.sensor)
    return predictor.predict(
        accel,
        req.fs_hz,
        natural_frequency_hz=req.natural_frequency_hz,
        source="request",
        natural_frequency_source="request",
        sensor=req.sensor,
    )


def _log(
    predictor: Predictor,
    accel: np.ndarray,
    fs: Any,
    fn: Any,
    source: str,
    sensor: dict | None = None,
) -> dict:
    """``POST /log``: the stiffness log of the samples (f_n required, as for /predict;
    `sensor`: the accelerometer chain's data sheet)."""
    from serving.log import stiffness_log
    from serving.predictor import record_natural_frequency
    from stiffnet.inputs import natural_frequency, sampling_rate

    if fn is None:
        record_natural_frequency(None, None)  # the one-line refusal
    doc = stiffness_log(predictor, accel, sampling_rate(fs), natural_frequency(fn), source=source,
                        sensor=sensor)  # fmt: skip
    doc["natural_frequency_source"] = "request"
    return doc


def _number_field(value: Any, name: str) -> float | None:
    if value is None or (isinstance(value, str) and not value.strip()):
        return None
    if not isinstance(value, str):
        raise StiffnetError(f"form field {name} must be a number, not a file")
    try:
        return float(value)
    except ValueError:
        raise StiffnetError(
            f"form field {name}: {value[:40]!r} is not a number{unit_hint(value)}"
        ) from None


def _text_field(value: Any, name: str) -> str | None:
    if value is None or (isinstance(value, str) and not value.strip()):
        return None
    if not isinstance(value, str):
        raise StiffnetError(f"form field {name} must be text, not a file")
    return value.strip()[:200]


def upload_suffix(filename: str) -> str:
    """The file name's extension if it is a plain one (it picks the reader), else ""."""
    suffix = Path(filename).suffix
    return suffix if _SUFFIX.match(suffix) else ""


def spool_upload(source: Any, filename: str) -> Path:
    """Copy an uploaded file part into a private temporary folder, in 1 MB chunks.

    A large upload waiting for its lane then holds a file, not 20 MB of memory;
    :func:`_predict_file` removes the folder.
    """
    folder = Path(tempfile.mkdtemp(prefix="stiffnet-upload-"))
    path = folder / f"upload{upload_suffix(filename)}"
    try:
        source.seek(0)
        with open(path, "wb") as fh:
            shutil.copyfileobj(source, fh, 1 << 20)
    except BaseException:
        shutil.rmtree(folder, ignore_errors=True)
        raise
    return path


def _npy_values(path: Path) -> int:
    """Values in an ``.npy`` file by its header (0 when unreadable: the reader says why)."""
    fmt = np.lib.format
    try:
        with open(path, "rb") as fh:
            version = fmt.read_magic(fh)
            read = fmt.read_array_header_1_0 if version == (1, 0) else fmt.read_array_header_2_0
            shape = read(fh)[0]
        return math.prod(int(n) for n in shape)
    except (OSError, ValueError, TypeError):
        return 0


def _lines_over(path: Path, limit: int) -> bool:
    n = 0
    with open(path, "rb") as fh:
        for chunk in iter(lambda: fh.read(1 << 20), b""):
            n += chunk.count(b"\n")
            if n > limit:
                return True
    return False


def _lines(path: Path) -> int:
    n = 0
    with open(path, "rb") as fh:
        for chunk in iter(lambda: fh.read(1 << 20), b""):
            n += chunk.count(b"\n")
    return n


def estimated_samples(path: Path) -> int:
    """Samples of a spooled upload as far as known before it is read, for its cost.

    An ``.npy`` header's values, a CSV's lines (a sample a line); another format by its
    bytes, at 2 a sample (16-bit audio; wider samples make it an over-estimate, never an
    under-estimate).
    """
    suffix = path.suffix.lower()
    if suffix == ".csv":
        return _lines(path)
    values = _npy_values(path) if suffix == ".npy" else 0
    return values or path.stat().st_size // 2


def check_upload_size(path: Path, max_samples: int) -> None:
    """Refuse a file over `max_samples` by what it says before it is read (a CSV's lines,
    an ``.npy`` header's shape); other formats are counted once read."""
    if path.suffix.lower() == ".csv" and _lines_over(path, max_samples + 2):  # a line a sample
        _check_samples(max_samples + 1, max_samples, "over")
    if path.suffix.lower() == ".npy":  # the header says the shape: refused before loading
        _check_samples(_npy_values(path), max_samples, "over")


def _predict_file(
    predictor: Predictor,
    data: bytes | Path,
    filename: str,
    fs: Any,
    fn: Any,
    max_samples: int = 2_000_000,
    columns: Any = None,
    time_unit: Any = None,
    channel: Any = None,
    what: str = "predict",
    sensor: Any = None,
) -> dict:
    """Predict an uploaded recording: its bytes, or a file of :func:`spool_upload` (removed)."""
    if isinstance(data, Path):
        try:
            return _predict_path(predictor, data, filename, fs, fn, max_samples, columns,
                                 time_unit, channel, what, sensor)  # fmt: skip
        finally:
            shutil.rmtree(data.parent, ignore_errors=True)
    with tempfile.TemporaryDirectory(prefix="stiffnet-upload-") as tmp:
        path = Path(tmp) / f"upload{upload_suffix(filename)}"
        path.write_bytes(data)
        return _predict_path(predictor, path, filename, fs, fn, max_samples, columns, time_unit,
                             channel, what, sensor)  # fmt: skip


def _predict_path(
    predictor: Predictor,
    path: Path,
    filename: str,
    fs: Any,
    fn: Any,
    max_samples: int,
    columns: Any,
    time_unit: Any,
    channel: Any = None,
    what: str = "predict",
    sensor: Any = None,
) -> dict:
    from stiffnet.recordings import read_recording
    from stiffnet.restoring_force.chain import parse_sensor_option

    fs_hz = _number_field(fs, "fs_hz")
    # the data sheet as the CLI's --sensor writes it (KEY=VALUE,...): a lab posting a file
    # gives it in the same form; its keys are checked where the JSON body's are
    sheet_text = _text_field(sensor, "sensor")
    sheet = None if sheet_text is None else parse_sensor_option(sheet_text, "form field sensor")
    layout = {
        "columns": _text_field(columns, "columns"),
        "time_unit": _text_field(time_unit, "time_unit"),
    }
    fn_hz = _number_field(fn, "natural_frequency_hz")
    shown = re.sub(r"[^\w.\- ]", "_", Path(filename).name)[:80] or "upload"
    check_upload_size(path, max_samples)
    try:
        rec = read_recording(path, fs_hz=fs_hz, channel=_text_field(channel, "channel"), **layout)
    except StiffnetError as exc:
        raise StiffnetError(str(exc).replace(str(path), shown)) from None
    _check_samples(rec.accel.size, max_samples)
    if what == "log":
        return _log(predictor, rec.accel, rec.fs_hz, fn_hz, shown, sheet)
    return predictor.predict(
        rec.accel,
        rec.fs_hz,
        natural_frequency_hz=fn_hz,
        source=shown,
        natural_frequency_source="request",
        sensor=sheet,
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
                            # the formats: _predict_body() fills them in from the registry
                        },
                        "fs_hz": {"type": "number"},
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
                        "channel": {"type": "string"},
                        "sensor": {
                            "type": "string",
                            "description": "The accelerometer chain's data sheet, KEY=VALUE,... "
                            "(resonance_hz, resonance_damping, lowpass_hz, lowpass_order, "
                            "highpass_hz), undone as given instead of fitted",
                            "examples": ["resonance_hz=4200,resonance_damping=0.03"],
                        },
                    },
                }
            },
        },
    }
}


def _predict_body() -> dict:
    """The request body's schema with the formats registered now (a plugin's included)."""
    from stiffnet.recordings import (
        channels_help,
        formats_help,
        rate_needed_for,
        supported_extensions,
    )

    body = copy.deepcopy(_PREDICT_BODY)
    form = body["requestBody"]["content"]["multipart/form-data"]["schema"]["properties"]
    form["file"]["description"] = "Recording; its name's extension picks the format: " + (
        formats_help()
    )
    form["file"]["x-extensions"] = list(supported_extensions())
    form["fs_hz"]["description"] = (
        f"Sampling rate in Hz (needed for {', '.join(rate_needed_for())}; otherwise checked "
        "against the file's own)"
    )
    form["channel"]["description"] = (
        "Channel of a multi-channel file (required when it has several): " + channels_help()
    )
    return body


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
        429: "too many requests waiting, or too busy to finish this one in time (Retry-After)",
        503: "overloaded: a started prediction did not finish within three times the timeout "
        "(Retry-After), or the server's disk or memory failed",
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
    access: bool = True,
) -> FastAPI:
    """The FastAPI application serving `predictor` under `limits` (see the module notes).

    ``token``: bearer token required on every path but ``/health`` and the docs;
    ``allowed_hosts``: accepted ``Host`` names (None: any); ``cors_origins``:
    origins allowed to call from a browser (None: no CORS headers); ``access``: the
    access-log middleware (lines appear once :func:`enable_access_log` is called).
    """
    from fastapi_offline import FastAPIOffline  # Swagger UI / ReDoc assets, no CDN

    limits = limits or Limits()
    admission = Admission(predictor, limits)

    @asynccontextmanager
    async def lifespan(_app: FastAPI):
        yield
        admission.shutdown()

    app = FastAPIOffline(
        title="stiffnet predictor",
        version=__version__,
        description="Stiffness class and beta of an accelerometer recording (ONNX model) with "
        'the geometric inclination method as cross-check. Errors: {"error": "..."}.',
        lifespan=lifespan,
    )
    app.state.load = admission.state  # requests in flight per lane (read by /health and tests)
    app.state.admission = admission  # its lanes' costs and backlogs (tests)
    _add_guards(app, limits, token, allowed_hosts, cors_origins, access)
    _add_error_handlers(app, limits)
    _add_routes(app, predictor, limits, admission)
    return app


def _add_guards(
    app: FastAPI,
    limits: Limits,
    token: str | None,
    allowed_hosts: list[str] | None,
    cors_origins: list[str] | None,
    access: bool,
) -> None:
    """Who may call and how much they may send: body limits, token and Host, CORS, access log."""
    app.add_middleware(BodyLimit, max_bytes=limits.max_bytes, timeout_s=limits.body_timeout_s,
                       idle_s=limits.body_idle_s)  # fmt: skip
    app.add_middleware(Guard, token=token, allowed_hosts=allowed_hosts)
    if cors_origins:
        app.add_middleware(JsonCORS, allow_origins=list(cors_origins),
                           allow_methods=["GET", "POST"],
                           allow_headers=["Authorization", "Content-Type"])  # fmt: skip
    if access:  # outermost: every answer is logged, the guards' refusals included
        app.add_middleware(AccessLog)


def _add_error_handlers(app: FastAPI, limits: Limits) -> None:
    """How each failure answers: a status and a JSON body with one line, never a traceback."""

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
        log.warning("408: request body not complete within %g s or silent for %g s",
                    limits.body_timeout_s, limits.body_idle_s)  # fmt: skip
        message = (f"request body not received within {limits.body_timeout_s:g} s "
                   f"(or silent for {limits.body_idle_s:g} s)")  # fmt: skip
        return _error(408, message, {"Connection": "close"})

    @app.exception_handler(ClientDisconnect)
    async def _gone(req: Request, _exc: ClientDisconnect) -> JSONResponse:
        client = f"{req.client.host}:{req.client.port}" if req.client else "client"
        log.warning("%s disconnected before its request body was complete", client)
        return _error(400, "client disconnected")  # not delivered: the client is gone

    @app.exception_handler(csv.Error)
    async def _csv(_req: Request, exc: csv.Error) -> JSONResponse:
        return _error(422, f"malformed CSV ({exc}): a cell or line is too long or badly quoted")

    @app.exception_handler(RecursionError)
    async def _deep(_req: Request, _exc: RecursionError) -> JSONResponse:
        return _error(422, "input nested too deeply to read")

    @app.exception_handler(OSError)
    async def _environment(_req: Request, exc: OSError) -> JSONResponse:
        log.warning("503: %s", exc.strerror or type(exc).__name__)
        return _error(503, f"the server cannot store the request ({exc.strerror or 'error'})",
                      {"Retry-After": "10"})  # fmt: skip

    @app.exception_handler(StarletteHTTPException)
    async def _http(_req: Request, exc: StarletteHTTPException) -> JSONResponse:
        return _error(exc.status_code, str(exc.detail), getattr(exc, "headers", None))

    @app.exception_handler(RequestValidationError)
    async def _validation(_req: Request, exc: RequestValidationError) -> JSONResponse:
        return _error(422, f"invalid request: {exc.errors()[:1]}")


class Admission:
    """Who gets a place, and where the work runs.

    Two lanes: small requests (bodies being read are bounded apart from the worker
    queue, which counts read bodies only) and large ones (admitted - reading,
    waiting or running - up to their cap, refused unread beyond); each lane also
    bounds what one client address holds, so a client stalling uploads blocks
    itself. ``state`` counts what each lane holds (``/health``, tests).
    """

    def __init__(self, predictor: Predictor, limits: Limits) -> None:
        self.predictor, self.limits = predictor, limits
        self.small = ThreadPoolExecutor(max_workers=limits.max_concurrency,
                                        thread_name_prefix="predict")  # fmt: skip
        self.large = ThreadPoolExecutor(max_workers=limits.max_large,
                                        thread_name_prefix="predict-large")  # fmt: skip
        self.state = {"in_flight": 0, "large": 0, "reading": 0, "served": 0}
        self.per_client: dict[tuple[str, str], int] = {}  # (lane, client address) -> requests
        self.cost = {
            lane: LaneCost(
                workers, SEED_S_PER_SAMPLE[lane], SEED_CPU_S_PER_SAMPLE[lane], live=lane == "large"
            )  # fmt: skip
            for lane, workers in (("small", limits.max_concurrency), ("large", limits.max_large))
        }

    def shutdown(self) -> None:
        for pool in (self.small, self.large):
            pool.shutdown(wait=False, cancel_futures=True)

    def release(self, key: str, host: str | None = None) -> Callable[[Any], None]:
        """A callback that frees one place of lane `key` (and of its client)."""

        def done(_f: Any = None) -> None:
            self.state[key] -= 1
            if host is not None:
                self.per_client[key, host] -= 1
                if not self.per_client[key, host]:
                    del self.per_client[key, host]

        return done

    async def body_job(
        self, request: Request, ctype: str, what: str
    ) -> Callable[[], dict] | JSONResponse:
        """Read the body (the event loop only streams it) into a job for a worker thread."""
        predictor, n = self.predictor, self.limits.max_samples
        if ctype == "application/json":
            body = await request.body()
            job = partial(_predict_json, predictor, body, n, what)
            # a sample a comma, as the parser will find them (a large body's scan in a thread)
            commas = (await asyncio.to_thread(body.count, b",")
                      if len(body) > self.limits.small_bytes else body.count(b","))  # fmt: skip
            if commas > n + len(PredictRequest.model_fields):  # 413 before a 429 for its cost
                _check_samples(n + 1, n, "over")
            job.samples = commas + 1  # type: ignore[attr-defined]
            return job
        async with request.form(max_files=1, max_fields=8) as form:
            upload = form.get("file")
            if upload is None or isinstance(upload, str):
                return _error(400, "multipart body needs a 'file' part holding the recording")
            unknown = sorted(k for k in form if k not in FORM_FIELDS)
            if unknown:  # as an unknown JSON key is: a misspelt field is not silently ignored
                return _error(422, f"unknown form field {unknown[0][:40]!r} (fields: "
                              f"{', '.join(FORM_FIELDS)})")  # fmt: skip
            name = upload.filename or "upload"
            spooled = await asyncio.to_thread(spool_upload, upload.file, name)
            try:  # an upload over the limit is refused now, not after its wait for a worker
                await asyncio.to_thread(check_upload_size, spooled, n)
                samples = await asyncio.to_thread(estimated_samples, spooled)
            except BaseException:
                shutil.rmtree(spooled.parent, ignore_errors=True)
                raise
            job = partial(_predict_file, predictor, spooled, name, form.get("fs_hz"),
                          form.get("natural_frequency_hz"), n, form.get("columns"),
                          form.get("time_unit"), form.get("channel"), what,
                          form.get("sensor"))  # fmt: skip
            job.spooled = spooled  # type: ignore[attr-defined]  # removed if it never runs
            job.samples = samples  # type: ignore[attr-defined]
            return job

    async def answer(self, request: Request, what: str) -> JSONResponse:
        """Admit the request to its lane (or 429), read its body, run it on a worker."""
        limits, state = self.limits, self.state
        ctype = request.headers.get("content-type", "").split(";")[0].strip().lower()
        if ctype not in ("application/json", "multipart/form-data"):
            return _error(
                415, "send application/json {samples, fs_hz} or multipart/form-data (file)"
            )
        length = request.headers.get("content-length")
        is_large = length is None or not length.isdigit() or int(length) > limits.small_bytes
        key, cap, mine = ("large", limits.max_large + limits.max_large_queue,
                          MAX_LARGE_PER_CLIENT) if is_large else (
            "reading", MAX_SMALL_READERS, MAX_READERS_PER_CLIENT)  # fmt: skip
        host = request.client.host if request.client else "unknown"
        lane = "large requests" if is_large else "uploads being received"
        if self.per_client.get((key, host), 0) >= mine:
            return _error(429, f"too many {lane} from this client; retry later",
                          {"Retry-After": "1"})  # fmt: skip
        if state[key] >= cap:  # refused before its body is read: memory stays bounded
            return _error(429, f"too many {lane}; retry later", {"Retry-After": "1"})
        state[key] += 1
        self.per_client[key, host] = self.per_client.get((key, host), 0) + 1
        done = self.release(key, host)
        try:
            job = await self.body_job(request, ctype, what)
        except BaseException:
            done()
            raise
        if not is_large:
            done()  # the small body is read: its reading slot is free
        if isinstance(job, JSONResponse):
            if is_large:
                done()
            return job
        if not is_large and state["in_flight"] >= limits.max_concurrency + limits.max_queue:
            _drop(job)
            return _error(429, "too many requests in flight; retry later", {"Retry-After": "1"})
        refusal = self.shed("large" if is_large else "small", job)
        if refusal is not None:
            _drop(job)
            if is_large:
                done()
            return refusal
        if not is_large:
            state["in_flight"] += 1
            done = self.release("in_flight")
        return await self._run(job, "large" if is_large else "small", done)

    def shed(self, lane: str, job: Callable[[], dict]) -> JSONResponse | None:
        """429 with ``Retry-After`` if `job` queued now would not finish in time, else None.

        Its expected finish is the wait for a worker plus its own cost
        (:class:`LaneCost`); the budget is :data:`SHED_MARGIN` of the timeout. A job that
        finds a worker free is weighed alone (:meth:`_too_slow_alone`). ``Retry-After``:
        the seconds until the lane's backlog has drained enough for it to fit (until the
        lane is idle, for a job that alone exceeds the budget).
        """
        cost, samples, now = self.cost[lane], getattr(job, "samples", 0), time.monotonic()
        wait = cost.expected_start_s(now)
        own = cost.expected_s(samples, now)
        budget = SHED_MARGIN * self.limits.timeout_s
        if wait <= 0:
            return self._too_slow_alone(lane, samples, now, budget)
        if wait + own <= budget:
            return None
        retry = max(1, math.ceil(wait if own >= budget else wait + own - budget))
        rate = cost.s_per_sample_now(now)
        basis = f"from {cost.measured} measured" if cost.measured else "assumed: none measured yet"
        message = (
            f"server busy: the {lane} predictions ahead need about {wait:.1f} s and this one "
            f"({samples} samples) about {own:.1f} s at {rate * 1e6:.3g} us per sample ({basis}), "
            f"so it would not finish within the {self.limits.timeout_s:g} s timeout; retry "
            f"after {retry} s"
        )
        return _shed(message, retry)

    def _too_slow_alone(
        self, lane: str, samples: int, now: float, budget: float
    ) -> JSONResponse | None:
        """429 for a job that, on a free worker, would not finish in time at the lane's
        slow-down now (its CPU cost times :meth:`_alone_s`'s slow-down), else None. With
        none measured lately (a small job) the job is started: it measures the load again,
        so a lane refused for a load that has fallen opens again."""
        cost = self.cost[lane]
        alone, slow, whose = self._alone_s(lane, samples, now)
        if alone is None or alone <= budget:
            return None
        retry = math.ceil(self.limits.timeout_s)  # the load, not a queue, has to change
        message = (
            f"server busy: this {lane} prediction ({samples} samples) needs about "
            f"{samples * cost.cpu_s_per_sample:.1f} s of CPU, about {alone:.1f} s at {whose} "
            f"slow-down now ({slow:.1f} times its CPU time), so it would not finish within "
            f"the {self.limits.timeout_s:g} s timeout; retry after {retry} s"
        )
        return _shed(message, retry)

    def _alone_s(self, lane: str, samples: int, now: float) -> tuple[float | None, float, str]:
        """Seconds a job would take on a free worker now: its CPU cost times the lane's own
        slow-down (:meth:`LaneCost.slow_down`: its finished jobs of the last minute and its
        running ones); None when none is. With the slow-down and whose it is.

        A large job whose lane has none is priced at the machine's load
        (:func:`machine_slow_down`), never at the small lane's: small requests are short and
        Python-bound, they wait on each other for the interpreter lock (17-29 times their
        CPU time at load 15-17) where an upload, mostly numpy and ONNX Runtime, waits for a
        core only. A small job whose lane has none takes the large lane's (the more
        pessimistic), and with none at all it is started: it measures the lane again."""
        cost = self.cost[lane]
        slow, whose = cost.slow_down(now), "this lane's"
        if slow is None and lane == "large":
            slow, whose = machine_slow_down(), "the machine's load"
        if slow is None:  # the other lane's jobs run on the same machine now
            others = [c.slow_down(now) for k, c in self.cost.items() if k != lane]
            slow, whose = (
                max((f for f in others if f is not None), default=None),
                "the other lane's",
            )
        if slow is None:
            return None, 1.0, whose
        return samples * cost.cpu_s_per_sample * slow, slow, whose

    async def _run(self, job: Callable[[], dict], lane: str, done: Callable) -> JSONResponse:
        loop = asyncio.get_running_loop()
        cost, samples = self.cost[lane], getattr(job, "samples", 0)
        ticket, queued = cost.submitted(samples), time.monotonic()
        ran: dict[str, float] = {}

        def timed() -> dict:
            t0, cpu0 = time.monotonic(), time.thread_time()
            late = self._late_start(lane, samples, t0 - queued, t0)
            if late is not None:  # refused by its worker before any work
                _drop(job)
                raise late
            ran["start"] = t0
            cost.started(ticket, t0, *thread_cpu_clock())
            hints = HINT_CONTEXT.set("http")  # its messages name fields, never CLI options
            try:
                result = job()  # a failed job is not measured: a refusal costs nothing
            finally:
                HINT_CONTEXT.reset(hints)
            cost.measure(samples, time.monotonic() - t0, time.thread_time() - cpu0)
            return result

        fut = loop.run_in_executor(self.large if lane == "large" else self.small, timed)
        fut.add_done_callback(lambda _f: cost.ended(ticket))
        fut.add_done_callback(done)  # a timed-out job keeps its slot until its thread ends
        try:
            result = await asyncio.wait_for(asyncio.shield(fut), self.limits.timeout_s)
        except ShedAtStart as late:
            return _shed(late.message, late.retry_after_s)
        except TimeoutError:
            self._overran(lane, ticket, samples, ran.get("start"))
            result = await self._grace(fut, ran)
            if result is None:
                fut.add_done_callback(_outcome_unheard)
                return self._overrun(lane, samples, queued, ran.get("start"))
        self.state["served"] += 1
        return JSONResponse(result)

    def _late_start(self, lane: str, samples: int, waited: float, now: float) -> ShedAtStart | None:
        """A job whose worker takes it too late to finish in time: refused before any work.

        Admission priced its wait; a rise of the load or a slower job ahead makes the real
        wait longer. Here it is known, and the worker is free: the job runs only if the
        wait plus its cost alone (:meth:`_alone_s`, as admission prices a job that finds
        a worker free; nothing when no slow-down is measured) fits the same budget,
        :data:`SHED_MARGIN` of the timeout.
        """
        budget = SHED_MARGIN * self.limits.timeout_s
        own = self._alone_s(lane, samples, now)[0] or 0.0
        if waited + own <= budget:
            return None
        retry = max(1, math.ceil(own))
        return ShedAtStart(
            f"server busy: this {lane} prediction ({samples} samples) waited {waited:.1f} s for "
            f"a worker and needs about {own:.1f} s more, so it would not finish within the "
            f"{self.limits.timeout_s:g} s timeout; refused before any work; retry after "
            f"{retry} s",
            retry,
        )

    async def _grace(self, fut: Any, ran: dict) -> dict | None:
        """A started job's result if it ends within :data:`OVERRUN_GRACE` of the timeout
        more, else None. Its worker is held until it ends whatever the answer, and a
        refusal would make the client run it again: waiting costs nothing the answer saves.
        A job still queued gets no grace (its worker refuses it before any work)."""
        if ran.get("start") is None:
            return None
        try:
            return await asyncio.wait_for(
                asyncio.shield(fut), OVERRUN_GRACE * self.limits.timeout_s
            )
        except TimeoutError:
            return None

    def _overran(self, lane: str, ticket: int, samples: int, started: float | None) -> None:
        """One log line for a started job at its timeout: what it ran and, from its own
        progress (CPU seconds done of its expected CPU cost, at its own slow-down so far),
        when it should end; it is then given up to the ceiling (:data:`OVERRUN_GRACE`)."""
        cost, now = self.cost[lane], time.monotonic()
        done = cost.progress(ticket, now)
        if started is None or done is None:
            return
        wall, cpu = done
        expected = samples * cost.cpu_s_per_sample  # it runs: something remains
        left = max(expected - cpu, OVERRUN_LEFT * expected) * wall / max(cpu, 1e-3)
        ceiling = (1 + OVERRUN_GRACE) * self.limits.timeout_s
        log.warning(
            "overran (given up to the %g s ceiling): this %s prediction (%d samples) ran %.1f s "
            "for %.1f s of CPU; about %.1f s more at its own slow-down",
            ceiling, lane, samples, wall, cpu, left,
        )  # fmt: skip

    def _overrun(
        self, lane: str, samples: int, queued: float, started: float | None
    ) -> JSONResponse:
        """The answer to a job not finished within the timeout: 429 (:func:`_shed`) if it is
        still queued (refused before any work: its worker will not start it), else 503 with
        ``Retry-After``: a started job passed the timeout and its grace (:meth:`_grace`),
        the machine slowed beyond its price. The server is overloaded, not broken (504 is
        a gateway's status): a refusal to retry, and the work goes on to its end on its
        worker, holding it."""
        now, timeout = time.monotonic(), self.limits.timeout_s
        if started is None:  # still queued: its worker will refuse it (_late_start)
            retry = max(1, math.ceil(self.cost[lane].expected_start_s(now)))
            return _shed(
                f"server busy: this {lane} prediction ({samples} samples) found no free "
                f"worker within the {timeout:g} s timeout; refused before any work; retry "
                f"after {retry} s",
                retry,
            )
        waited, running = started - queued, now - started
        left = self.cost[lane].expected_s(samples, now) - running
        retry = max(1, math.ceil(max(left, 0.0) + self.cost[lane].expected_start_s(now)))
        message = (
            f"server overloaded: this {lane} prediction ({samples} samples) did not finish "
            f"within the {timeout:g} s timeout and the {OVERRUN_GRACE * timeout:g} s more a "
            f"started prediction is given (it waited {waited:.1f} s for a worker and ran "
            f"{running:.1f} s); retry after {retry} s"
        )
        log.warning("503 (overrun): %s", message)
        return _error(503, message, {"Retry-After": str(retry)})


class ShedAtStart(Exception):
    """A queued job its worker refuses before any work (answered 429, :func:`_shed`)."""

    def __init__(self, message: str, retry_after_s: int) -> None:
        super().__init__(message)
        self.message, self.retry_after_s = message, retry_after_s


def _shed(message: str, retry_after_s: int) -> JSONResponse:
    """A job refused before any work (load shedding): 429 with ``Retry-After``, one log line."""
    log.warning("429 (load shed): %s", message)
    return _error(429, message, {"Retry-After": str(retry_after_s)})


def _drop(job: Callable[[], dict]) -> None:
    """A job that will never run: its spooled upload goes now."""
    spooled = getattr(job, "spooled", None)
    if spooled is not None:
        shutil.rmtree(spooled.parent, ignore_errors=True)


def _outcome_unheard(fut: Any) -> None:
    """A job whose request was answered 503 (overrun) ends later: one log line, never a
    traceback of an unretrieved exception."""
    exc = None if fut.cancelled() else fut.exception()
    if exc is not None and not isinstance(exc, ShedAtStart):  # that one was never started
        log.warning("a request answered 503 failed afterwards: %s", one_line(exc, 200))


def _add_routes(app: FastAPI, predictor: Predictor, limits: Limits, admission: Admission) -> None:
    """What is served: ``POST /predict``, ``POST /log``, ``GET /health``, ``GET /model``."""
    predict_body = _predict_body()  # the formats registered now
    state = admission.state

    @app.post(
        "/predict",
        response_model=PredictionResult,
        responses=_ERRORS,
        openapi_extra=predict_body,
        summary="Predict one recording (JSON samples or a file upload)",
    )
    async def predict(request: Request) -> JSONResponse:
        return await admission.answer(request, "predict")

    @app.post(
        "/log",
        response_model=LogResult,
        responses=_ERRORS,
        openapi_extra=predict_body,
        summary="Stiffness log of one recording: beta(t), layers, change times "
        "(the document of stiffnet log --json)",
    )
    async def log_route(request: Request) -> JSONResponse:
        return await admission.answer(request, "log")

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

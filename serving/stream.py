"""Sample streams for ``stiffnet log --follow``: a growing file or stdin, in chunks.

Two encodings of a DAQ stream:

``csv``
    one sample per line, as text: a number, or comma-separated numbers of which
    the acceleration is the last (``t,accel``) or the 0-based column ``column``;
    a first line that is not numeric is a header and is skipped (where it names a time
    column first, ``t`` or ``time`` in s, ``t_ms`` or ``time_ms`` in ms, and the rate is
    given, the rate of that column's first :data:`CLOCK_SAMPLES` times must agree with it:
    a stream read at another rate reads another beta), blank lines are ignored, any
    other line that is not a number stops the stream with its line number, and so does
    a line separated by ``;`` or tabs (decimal commas).
``f32``
    raw little-endian float32 samples, back to back.

:func:`sample_chunks` yields numpy chunks as the bytes arrive: a partial line or a
partial sample waits for the rest. A file is polled while it grows and ends after
``idle_timeout_s`` without new bytes (None: never); stdin ends at end of file. At
most :data:`READ_BYTES` are held at a time, so an endless stream runs in bounded
memory.
"""

from __future__ import annotations

import io
import os
import sys
import time
from collections.abc import Iterator
from pathlib import Path
from typing import BinaryIO

import numpy as np

from stiffnet.errors import StiffnetError

#: Bytes read per call.
READ_BYTES = 1 << 16
#: Seconds between two looks at a file that has not grown.
POLL_S = 0.05
#: Stream encodings.
FORMATS = ("csv", "f32")


def sample_chunks(
    source: str | Path,
    fmt: str = "csv",
    *,
    column: int | None = None,
    idle_timeout_s: float | None = None,
    stdin: BinaryIO | None = None,
    fs_hz: float | None = None,
) -> Iterator[np.ndarray]:
    """Chunks of samples from a growing file or ``"-"`` (stdin), as they arrive.

    Parameters
    ----------
    source : str or Path
        A file path, or ``"-"`` for stdin.
    fmt : {"csv", "f32"}
        Encoding (see the module notes).
    column : int, optional
        CSV: 0-based column of the acceleration (default the last).
    idle_timeout_s : float, optional
        A file ends after this many seconds without new bytes (None: follow forever).
    stdin : binary file, optional
        Stands in for ``sys.stdin.buffer`` (tests).
    fs_hz : float, optional
        The rate the samples are read at, checked against a CSV header's time column.

    Raises
    ------
    StiffnetError
        Unknown format, missing file, a line that is not a sample, a time column whose
        rate is not `fs_hz`.
    """
    if fmt not in FORMATS:
        raise StiffnetError(f"unknown stream format {fmt!r} (use {' or '.join(FORMATS)})")
    if str(source) == "-":
        fh = stdin if stdin is not None else sys.stdin.buffer
        yield from _decode(_read_pipe(fh), fmt, column, "stdin", fs_hz)
        return
    p = Path(source)
    if not p.is_file():
        raise StiffnetError(f"{p}: stream file not found")
    with open(p, "rb") as fh:
        yield from _decode(_read_growing(fh, idle_timeout_s), fmt, column, str(p), fs_hz)


def _read_pipe(fh: BinaryIO) -> Iterator[bytes]:
    read = getattr(fh, "read1", fh.read)  # what is there now, not a full buffer
    while True:
        data = read(READ_BYTES)
        if not data:
            return
        yield data


def _read_growing(fh: BinaryIO, idle_timeout_s: float | None) -> Iterator[bytes]:
    idle_since = time.monotonic()
    while True:
        data = fh.read(READ_BYTES)
        if data:
            idle_since = time.monotonic()
            yield data
            continue
        if idle_timeout_s is not None and time.monotonic() - idle_since >= idle_timeout_s:
            return
        time.sleep(POLL_S)


def _decode(
    blocks: Iterator[bytes], fmt: str, column: int | None, name: str, fs_hz: float | None = None
) -> Iterator[np.ndarray]:
    if fmt == "f32":
        rest = b""
        for data in blocks:
            data = rest + data
            n = len(data) // 4 * 4
            rest = data[n:]
            if n:
                yield np.frombuffer(data[:n], dtype="<f4").astype(np.float64)
        if rest:
            raise StiffnetError(f"{name}: the stream ended inside a float32 sample")
        return
    rest = b""
    line_no = 0
    clock = _Clock(fs_hz)
    for data in blocks:
        data = rest + data
        cut = data.rfind(b"\n")
        if cut < 0:
            rest = data
            continue
        rest = data[cut + 1 :]
        values, line_no = _parse_lines(data[: cut + 1], column, name, line_no, clock)
        if values.size:
            yield values
    if rest.strip():
        values, _ = _parse_lines(rest, column, name, line_no, clock)
        if values.size:
            yield values


#: Separators a spreadsheet or a European locale writes instead of commas (and then a
#: decimal comma): a line holding one is refused, never split at its decimal commas.
_OTHER_SEPARATORS = ((b";", "';'"), (b"\t", "tabs"))


#: Times of a stream's time column whose rate is checked against the one given.
CLOCK_SAMPLES = 64
#: A header's time column names, with the seconds per unit of each.
_TIME_COLUMNS = {b"t": 1.0, b"time": 1.0, b"t_s": 1.0, b"time_s": 1.0,
                 b"t_ms": 1e-3, b"time_ms": 1e-3, b"t_us": 1e-6, b"time_us": 1e-6}  # fmt: skip


class _Clock:
    """A CSV stream's time column (named by its header) checked against the given rate:
    ``--fs`` is the only rate a stream has, and one that contradicts the samples' own
    times read every window at the wrong time scale."""

    def __init__(self, fs_hz: float | None) -> None:
        self.fs_hz = fs_hz
        self.name = b""
        self.seconds = 0.0  # per unit of the time column; 0: no column to check
        self.times: list[float] = []

    def header(self, cells: list[bytes], column: int | None) -> None:
        first = cells[0].strip().lower()
        if self.fs_hz and len(cells) > 1 and column != 0 and first in _TIME_COLUMNS:
            self.name, self.seconds = cells[0].strip(), _TIME_COLUMNS[first]

    def tick(self, cells: list[bytes], name: str, line_no: int) -> None:
        if not self.seconds:
            return
        try:
            self.times.append(float(cells[0]) * self.seconds)
        except ValueError:
            self.seconds = 0.0  # not a time after all: nothing to check
            return
        if len(self.times) < CLOCK_SAMPLES:
            return
        from stiffnet.recordings.base import rates_agree

        step = float(np.median(np.diff(self.times)))
        self.seconds = 0.0  # checked once
        if step > 0 and not rates_agree(1.0 / step, self.fs_hz):
            raise StiffnetError(
                f"{name}: its time column {self.name.decode(errors='replace')!r} gives "
                f"{1.0 / step:.6g} Hz (up to line {line_no}) but --fs {self.fs_hz:g} was given; "
                "give the stream's own rate"
            )


def _parse_lines(
    text: bytes, column: int | None, name: str, line_no: int, clock: _Clock | None = None
) -> tuple[np.ndarray, int]:
    out = []
    for raw in io.BytesIO(text):
        line_no += 1
        line = raw.strip()
        if not line:
            continue
        for sep, word in _OTHER_SEPARATORS:
            if sep in line:  # '0,001;1,25' split at its commas reads 25 as the sample
                raise StiffnetError(
                    f"{name}: line {line_no}: its cells are separated by {word}, not commas; "
                    "send comma-separated numbers with '.' as the decimal point"
                )
        cells = line.split(b",")
        try:
            cell = cells[-1 if column is None else column]
        except IndexError:
            raise StiffnetError(
                f"{name}: line {line_no} has {len(cells)} cell(s), no column {column}"
            ) from None
        try:
            v = float(cell)
        except ValueError:
            if line_no == 1:
                if clock is not None:
                    clock.header(cells, column)
                continue  # a header
            raise StiffnetError(f"{name}: line {line_no} is not a sample") from None
        if clock is not None:
            clock.tick(cells, name, line_no)
        out.append(v)
    return np.asarray(out, dtype=np.float64), line_no


def is_stdin(source: str | os.PathLike[str]) -> bool:
    """Whether a stream source names stdin."""
    return str(source) == "-"

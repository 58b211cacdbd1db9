"""Sample streams for ``stiffnet log --follow``: a growing file or stdin, in chunks.

Two encodings of a DAQ stream:

``csv``
    one sample per line, as text: a number, or comma-separated numbers of which
    the acceleration is the last (``t,accel``) or the 0-based column ``column``;
    a first line that is not numeric is a header and is skipped, blank lines are
    ignored, any other line that is not a number stops the stream with its line
    number, and so does a line separated by ``;`` or tabs (decimal commas).
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

    Raises
    ------
    StiffnetError
        Unknown format, missing file, a line that is not a sample.
    """
    if fmt not in FORMATS:
        raise StiffnetError(f"unknown stream format {fmt!r} (use {' or '.join(FORMATS)})")
    if str(source) == "-":
        fh = stdin if stdin is not None else sys.stdin.buffer
        yield from _decode(_read_pipe(fh), fmt, column, "stdin")
        return
    p = Path(source)
    if not p.is_file():
        raise StiffnetError(f"{p}: stream file not found")
    with open(p, "rb") as fh:
        yield from _decode(_read_growing(fh, idle_timeout_s), fmt, column, str(p))


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
    blocks: Iterator[bytes], fmt: str, column: int | None, name: str
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
    for data in blocks:
        data = rest + data
        cut = data.rfind(b"\n")
        if cut < 0:
            rest = data
            continue
        rest = data[cut + 1 :]
        values, line_no = _parse_lines(data[: cut + 1], column, name, line_no)
        if values.size:
            yield values
    if rest.strip():
        values, _ = _parse_lines(rest, column, name, line_no)
        if values.size:
            yield values


#: Separators a spreadsheet or a European locale writes instead of commas (and then a
#: decimal comma): a line holding one is refused, never split at its decimal commas.
_OTHER_SEPARATORS = ((b";", "';'"), (b"\t", "tabs"))


def _parse_lines(
    text: bytes, column: int | None, name: str, line_no: int
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
                continue  # a header
            raise StiffnetError(f"{name}: line {line_no} is not a sample") from None
        out.append(v)
    return np.asarray(out, dtype=np.float64), line_no


def is_stdin(source: str | os.PathLike[str]) -> bool:
    """Whether a stream source names stdin."""
    return str(source) == "-"

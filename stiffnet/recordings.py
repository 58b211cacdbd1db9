"""Reading and writing single-channel acceleration recordings.

A recording is one accelerometer channel sampled at a uniform rate. Supported
files (chosen by extension):

``.csv``
    header ``t,accel``, time in seconds, acceleration in any unit (the sensor
    gain does not matter to stiffnet). The rate is inferred from ``t`` unless
    given, in which case ``t`` must agree with it. Other layouts are read with
    ``columns="TIME,ACCEL"`` (header names or 0-based indices; a single
    ``ACCEL`` means no time column, the rate is then required; with indices the
    file may have no header) and ``time_unit="s"|"ms"|"us"``.
``.npy``
    a 1-D numeric array, or 2-D ``(samples, channels)`` read with ``channel``
    (a column index); the rate must be given (the manifest's ``fs_hz``).
``.wav``
    integer samples are scaled to [-1, 1); the rate comes from the file. A
    multi-channel file needs ``channel`` (an index).
``.tdms``
    LabVIEW files, read with npTDMS (imported only when needed): the one
    channel holding data, or ``channel`` (``"name"``, ``"group/name"`` or the
    index among the channels holding data). The rate comes from the channel's
    ``wf_increment`` property when present.

A file with several channels and no ``channel`` is refused with one line listing
them: reading the first one in silence gave a force channel's "no contact" for a
LabVIEW file whose acceleration was the second. For CSV, ``channel`` names the
acceleration column (header name or index; the time column stays ``t``).

This module depends on numpy, scipy and pyarrow only, so that the light ONNX
predictor can use it.

CSV I/O goes through ``pyarrow.csv`` (a core dependency): on 1e6 rows it reads
about 3x faster than ``np.loadtxt`` and 10x faster than ``np.genfromtxt``, and
it writes floats in their shortest round-trip form, so a written recording
reads back bit for bit. The slow, line-by-line scan is only run when the fast
parser fails, to tell the user which line is wrong.
"""

from __future__ import annotations

import csv
import logging
import math
import os
import re
import tempfile
import threading
import warnings
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pyarrow as pa
import pyarrow.csv as pacsv

from stiffnet.errors import StiffnetError
from stiffnet.inputs import columns_hint, natural_frequency, quote_content, read_json

#: Extensions :func:`read_recording` understands.
SUPPORTED_EXTENSIONS = (".csv", ".npy", ".wav", ".tdms")
#: Column names of a CSV recording.
CSV_COLUMNS = ("t", "accel")
#: Units a CSV time column may be in, as seconds per unit.
TIME_UNITS = {"s": 1.0, "ms": 1e-3, "us": 1e-6}
#: Scale factors that betray a time column read in the wrong unit.
_UNIT_FACTORS = {1e3: ("milliseconds", "ms"), 1e6: ("microseconds", "us")}
#: A time column may deviate from the uniform grid by this fraction of a sample
#: period (rounding of the written times); a dropped sample deviates by >= 1/2.
TIME_JITTER_TOLERANCE = 0.2
#: CSV files larger than this are parsed on several threads (smaller ones start faster
#: on one: part of ``stiffnet predict``'s cold start).
THREADED_CSV_BYTES = 8 * 2**20
#: Relative tolerance between a given rate and the one a file carries.
FS_TOLERANCE = 1e-3

_TDMS_LOCK = threading.Lock()
#: Suffix of the sidecar JSON of a recording: ``run01.csv`` -> ``run01.csv.json``.
SIDECAR_SUFFIX = ".json"


def read_sidecar(recording: str | os.PathLike[str]) -> tuple[float | None, Path]:
    """Natural frequency from the recording's sidecar ``<recording>.json``, if present.

    The sidecar is a JSON object with at least ``natural_frequency_hz`` (Hz); any
    other keys (provenance, rig notes) are ignored here.

    Returns
    -------
    (float or None, Path)
        The value (None when there is no sidecar or it has no such key) and the sidecar path.

    Raises
    ------
    StiffnetError
        If the sidecar exists but is not valid JSON or the value is not a number > 0.
    """
    p = Path(str(recording) + SIDECAR_SUFFIX)
    if not p.is_file():
        return None, p
    d = read_json(p, "sidecar")  # bounded, finite, depth-checked
    if not isinstance(d, dict) or d.get("natural_frequency_hz") is None:
        return None, p
    return natural_frequency(d["natural_frequency_hz"], f"{p}: natural_frequency_hz"), p


@dataclass
class Recording:
    """One accelerometer channel.

    Attributes
    ----------
    accel : numpy.ndarray
        Samples, float64, 1-D; any unit.
    fs_hz : float
        Sampling rate in Hz.
    source : str
        Where the samples came from (file path, channel), for messages.
    """

    accel: np.ndarray
    fs_hz: float
    source: str = ""

    def __post_init__(self) -> None:
        self.accel = np.asarray(self.accel, dtype=np.float64)
        self.fs_hz = float(self.fs_hz)
        if self.accel.ndim != 1:
            raise StiffnetError(f"{self.source or 'recording'}: expected 1-D samples")
        if not (math.isfinite(self.fs_hz) and self.fs_hz > 0):
            raise StiffnetError(
                f"{self.source or 'recording'}: sampling rate must be > 0, got {self.fs_hz}"
            )

    def __len__(self) -> int:
        return self.accel.size

    @property
    def duration_s(self) -> float:
        """Length of the recording in seconds (``n / fs``)."""
        return self.accel.size / self.fs_hz

    @property
    def t(self) -> np.ndarray:
        """Sample times in seconds, starting at 0."""
        return np.arange(self.accel.size) / self.fs_hz


def read_recording(
    path: str | os.PathLike[str],
    fs_hz: float | None = None,
    channel: str | int | None = None,
    *,
    columns: str | Sequence[str | int] | None = None,
    time_unit: str | None = None,
) -> Recording:
    """Read one acceleration channel from a CSV, NPY, WAV or TDMS file.

    Parameters
    ----------
    path : str or os.PathLike
        The file; its extension selects the format.
    fs_hz : float, optional
        Sampling rate in Hz. Required for ``.npy``; for the other formats the
        file's own rate is used and must agree with it when both are known.
    channel : str or int, optional
        WAV, 2-D NPY: channel (column) index. TDMS: channel name, ``group/name``
        or index among the channels holding data. CSV: the acceleration column
        (header name or index; time in ``t``). Required when the file has
        several channels (the error lists them).
    columns : str or sequence, optional
        CSV only: ``"TIME,ACCEL"`` (or a pair), each a header name
        (case-insensitive) or a 0-based column index; a single ``"ACCEL"``
        reads a file without a time column (then `fs_hz` is required). Default
        ``t,accel``. With indices only, a file whose first line is numeric is
        read as having no header.
    time_unit : {"s", "ms", "us"}, optional
        CSV only: unit of the time column (default seconds).

    Returns
    -------
    Recording

    Raises
    ------
    StiffnetError
        Missing file, unknown extension, malformed content, fewer than two
        samples, NaN/inf samples, or a missing or invalid sampling rate.
    """
    p = Path(path)
    name = str(p)
    if fs_hz is not None:
        try:
            fs_hz = float(fs_hz)
        except (TypeError, ValueError):
            raise StiffnetError(f"{name}: sampling rate {fs_hz!r} is not a number") from None
        if not (math.isfinite(fs_hz) and fs_hz > 0):
            raise StiffnetError(f"{name}: sampling rate must be > 0, got {fs_hz}")
    ext = p.suffix.lower()
    if ext not in SUPPORTED_EXTENSIONS:
        raise StiffnetError(
            f"{name}: unknown recording extension {p.suffix or '(none)'!r} "
            f"(use one of {', '.join(SUPPORTED_EXTENSIONS)})"
        )
    if not p.is_file():
        raise StiffnetError(f"{name}: recording file not found")
    if channel is not None and str(channel).strip() == "":
        channel = None
    if channel is not None and ext == ".csv":
        if columns is not None:
            raise StiffnetError(f"{name}: give either 'columns' or 'channel' for a CSV, not both")
        columns = f"{CSV_COLUMNS[0]},{channel}"
    layout = _CsvLayout.parse(columns, time_unit, name)
    if ext != ".csv" and (columns is not None or time_unit is not None):
        what = "columns" if columns is not None else "time_unit"
        raise StiffnetError(f"{name}: '{what}' applies to CSV recordings only, not {ext}")
    if ext == ".csv":
        accel, fs, source = _read_csv(p, fs_hz, layout)
    else:
        reader = {".npy": _read_npy, ".wav": _read_wav, ".tdms": _read_tdms}[ext]
        accel, fs, source = reader(p, fs_hz, channel)
    if accel.size < 2:
        what = "is empty" if accel.size == 0 else "has only one sample"
        raise StiffnetError(f"{source}: recording {what} (need at least 2 samples)")
    bad = ~np.isfinite(accel)
    if np.any(bad):
        raise StiffnetError(
            f"{source}: {int(bad.sum())} NaN/inf samples (first at sample {int(np.argmax(bad))})"
        )
    return Recording(accel, fs, source)


def write_recording_csv(path: str | os.PathLike[str], accel: np.ndarray, fs_hz: float) -> Path:
    """Write a ``t,accel`` CSV recording atomically.

    The file is written to a temporary file in the same folder and moved into
    place with :func:`os.replace`, so readers never see a half-written file.
    Values are written in their shortest round-trip form (exact read-back).

    Parameters
    ----------
    path : str or os.PathLike
        Destination; parent folders are created.
    accel : numpy.ndarray
        1-D finite samples, any unit.
    fs_hz : float
        Sampling rate in Hz; ``t = n / fs_hz``.

    Returns
    -------
    pathlib.Path
        The written path.
    """
    p = Path(path)
    rec = Recording(accel, fs_hz, str(p))  # validates shape and rate
    if not np.all(np.isfinite(rec.accel)):
        raise StiffnetError(f"{p}: refusing to write NaN/inf samples")
    table = pa.table({"t": rec.t, "accel": rec.accel})
    p.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(dir=p.parent, prefix=f".{p.name[:100]}.", suffix=".tmp")
    try:
        with os.fdopen(fd, "wb") as fh:
            # pyarrow always quotes the header: write it ourselves
            fh.write((",".join(CSV_COLUMNS) + "\n").encode())
            pacsv.write_csv(table, fh, write_options=pacsv.WriteOptions(include_header=False))
        os.replace(tmp, p)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise
    return p


def _brief(exc: BaseException) -> str:
    """First line of an exception's message (or its type), for one-line errors."""
    text = str(exc).strip().splitlines()
    return text[0][:200] if text else type(exc).__name__


# ---------------------------------------------------------------------------- CSV


def unit_mistake_hint(fs_hz: float, lo_hz: float, hi_hz: float = math.inf) -> str:
    """A hint when `fs_hz` is implausible but 1e3x or 1e6x it would fit ``[lo_hz, hi_hz]``.

    A time column in milliseconds read as seconds gives a rate 1000 times too
    low; this names that mistake and the option that fixes it. Empty when no
    such factor fits.
    """
    for factor, (word, unit) in _UNIT_FACTORS.items():
        if lo_hz <= fs_hz * factor <= hi_hz:
            return (
                f"; if the time column is in {word}, give the time unit {unit} "
                f"(--time-unit {unit}; manifest/HTTP field time_unit), which gives "
                f"{fs_hz * factor:.6g} Hz"
            )
    return ""


@dataclass(frozen=True)
class _CsvLayout:
    """Which CSV columns hold time and acceleration, and the time unit."""

    time: str | int | None = CSV_COLUMNS[0]
    accel: str | int = CSV_COLUMNS[1]
    seconds_per_unit: float = 1.0
    custom: bool = False

    @classmethod
    def parse(
        cls, columns: str | Sequence[str | int] | None, time_unit: str | None, name: str
    ) -> _CsvLayout:
        scale = 1.0
        if time_unit is not None:
            unit = str(time_unit).strip().lower().replace("µ", "u")
            if unit not in TIME_UNITS:
                raise StiffnetError(
                    f"{name}: unknown time unit {time_unit!r} (use {', '.join(TIME_UNITS)})"
                )
            scale = TIME_UNITS[unit]
        if columns is None:
            return cls(seconds_per_unit=scale)
        parts = columns.split(",") if isinstance(columns, str) else list(columns)
        keys = [_column_key(c) for c in parts]
        if len(keys) not in (1, 2) or any(k == "" for k in keys):
            raise StiffnetError(
                f"{name}: columns must be 'TIME,ACCEL' or 'ACCEL' (names or 0-based "
                f"indices), got {columns!r}"
            )
        if len(keys) == 1:
            if time_unit is not None:
                raise StiffnetError(f"{name}: time_unit given but columns names no time column")
            return cls(None, keys[0], scale, True)
        if keys[0] == keys[1]:
            raise StiffnetError(f"{name}: columns names the same column twice ({columns!r})")
        return cls(keys[0], keys[1], scale, True)

    @property
    def wanted(self) -> list[str | int]:
        return [k for k in (self.time, self.accel) if k is not None]


def _column_key(cell: str | int) -> str | int:
    if isinstance(cell, int):
        return cell
    text = str(cell).strip()
    return int(text) if text.isdigit() else text.lower()


def _is_number(cell: str) -> bool:
    try:
        float(cell)
    except ValueError:
        return False
    return True


#: What a quotable column name looks like: words, units in brackets, no separators of
#: other file formats (``root:*:...`` is not a header).
_COLUMN_NAME = re.compile(r"^[\w ()\[\]/.\-]{1,32}$")


def _header_hint(header: list[str]) -> str:
    """How to read a file whose header is not ``t,accel``."""
    if len(header) == 1:
        return " (the file must be comma-separated)"
    if all(_is_number(c) for c in header if c.strip()):
        return f"; no header: {columns_hint('0,1')} (indices; give the sampling rate if needed)"
    time, accel = header[0].strip(), header[1].strip()
    unit = None
    low = time.lower()
    for u in ("ms", "us"):
        if low.endswith((f"_{u}", f"({u})", f"[{u}]", f" {u}")):
            unit = u
    # column names are quoted only when they look like names (a secret's line does not)
    example = f"{time},{accel}" if all(map(_COLUMN_NAME.match, (time, accel))) else "TIME,ACCEL"
    return f"; {columns_hint(example, unit)}" + _channels_hint(header)


def _channels_hint(header: list[str]) -> str:
    """With more than two columns, which ones the file has (only names that look like names)."""
    names = [c.strip() for c in header]
    if len(names) <= 2 or not all(map(_COLUMN_NAME.match, names)):
        return ""
    return f"; its {len(names)} columns: {', '.join(names)} (--channel NAME picks the acceleration)"


def _read_csv(p: Path, fs_hz: float | None, layout: _CsvLayout) -> tuple[np.ndarray, float, str]:
    name = str(p)
    try:
        with open(p, encoding="utf-8-sig", newline="") as fh:  # -sig: Excel's BOM
            first = fh.readline()
    except UnicodeDecodeError:
        raise StiffnetError(f"{name}: not a UTF-8 text file (expected a CSV 't,accel')") from None
    if not first.strip():
        raise StiffnetError(f"{name}: missing header (expected 't,accel' on line 1)")
    raw = next(csv.reader([first]))
    header = [c.strip().lower() for c in raw]
    if not layout.custom and tuple(header) != CSV_COLUMNS:
        # never echo what is not a column list (a link to a secret shows only its shape)
        names = [c.strip() for c in raw]
        shown = quote_content(first.strip(), cells=4) or f"({len(raw)} cell(s), not shown)"
        if len(raw) <= 4 and all(map(_COLUMN_NAME.match, names)):  # names: shown, as the hint
            shown = repr(",".join(names))
        raise StiffnetError(
            f"{name}: wrong header {shown}, expected 't,accel' on line 1{_header_hint(raw)}"
        )
    has_header = not (
        all(isinstance(k, int) for k in layout.wanted) and all(_is_number(c) for c in raw)
    )
    index = [_column_index(k, header if has_header else None, len(raw), name)
             for k in layout.wanted]  # fmt: skip
    names = [f"c{i}" for i in range(len(raw))]
    wanted = [names[i] for i in index]
    try:
        table = pacsv.read_csv(
            p,
            read_options=pacsv.ReadOptions(
                skip_rows=int(has_header),
                column_names=names,
                # starting the thread pool costs ~40 ms: worth it only for large files
                use_threads=p.stat().st_size > THREADED_CSV_BYTES,
            ),
            convert_options=pacsv.ConvertOptions(
                include_columns=wanted,
                column_types={c: pa.float64() for c in wanted},
                null_values=[],  # empty cells are errors, 'nan' parses as NaN
                strings_can_be_null=False,
            ),
        )
    except (pa.ArrowInvalid, UnicodeDecodeError):
        # the fast parser does not say where: find the line ourselves
        raise StiffnetError(f"{name}: {_locate_csv_problem(p, raw, index, has_header)}") from None
    accel = _float_column(table, wanted[-1])
    t = _float_column(table, wanted[0]) * layout.seconds_per_unit if len(wanted) == 2 else None
    if accel.size < 2:
        return accel, fs_hz or 1.0, name  # read_recording reports it
    if not (np.all(np.isfinite(accel)) and (t is None or np.all(np.isfinite(t)))):
        raise StiffnetError(f"{name}: {_locate_csv_problem(p, raw, index, has_header)}")
    if t is None:
        if fs_hz is None:
            raise StiffnetError(f"{name}: sampling rate missing (no time column; give fs_hz)")
        return accel, fs_hz, name
    tname = raw[index[0]].strip() if has_header else f"{index[0]}"
    fs = _rate_from_times(t, name, f"column {tname}", first_line=1 + int(has_header))
    if fs_hz is not None and abs(fs - fs_hz) > FS_TOLERANCE * fs_hz:
        hint = ""
        for factor, (word, unit) in _UNIT_FACTORS.items():
            if abs(fs * factor - fs_hz) <= FS_TOLERANCE * fs_hz:
                hint = f" (is the time in {word}? give time unit {unit})"
        raise StiffnetError(
            f"{name}: column {tname} gives fs = {fs:.6g} Hz but fs_hz = {fs_hz:.6g} Hz "
            f"was given{hint}"
        )
    return accel, fs_hz if fs_hz is not None else fs, name


def _float_column(table: pa.Table, name: str) -> np.ndarray:
    """A float64 column without nulls as numpy, read from its buffers.

    ``ChunkedArray.to_numpy`` imports pandas (0.2 s) to check for pandas types;
    reading the value buffers keeps ``stiffnet predict``'s cold start short.
    """
    chunks = table.column(name).chunks
    parts = [
        np.frombuffer(c.buffers()[1], dtype=np.float64, count=len(c), offset=c.offset * 8)
        for c in chunks
        if len(c)
    ]
    return np.concatenate(parts) if parts else np.empty(0)


def _column_index(key: str | int, header: list[str] | None, n: int, name: str) -> int:
    if header is not None and isinstance(key, str):
        if key in header:
            if header.count(key) > 1:
                raise StiffnetError(f"{name}: column {key!r} appears twice in the header")
            return header.index(key)
        listed = ",".join(header)
        raise StiffnetError(f"{name}: no column {key!r} in the header ({listed})")
    if isinstance(key, str):
        raise StiffnetError(f"{name}: column {key!r} given by name but the file has no header")
    if not 0 <= key < n:
        raise StiffnetError(f"{name}: column index {key} out of range (the file has {n} columns)")
    return key


def _rate_from_times(t: np.ndarray, name: str, col: str = "column t", first_line: int = 2) -> float:
    """Sampling rate of a time column, checking it is strictly increasing and uniform."""
    dt = np.diff(t)
    if np.any(dt <= 0):
        i = int(np.argmax(dt <= 0))
        raise StiffnetError(
            f"{name}: {col} is not strictly increasing (line {i + first_line + 1}: "
            f"t = {float(t[i + 1])!r} after {float(t[i])!r})"
        )
    step = (t[-1] - t[0]) / (t.size - 1)
    dev = np.abs(t - (t[0] + np.arange(t.size) * step))
    if dev.max() > TIME_JITTER_TOLERANCE * step:
        i = int(np.argmax(dev))
        raise StiffnetError(
            f"{name}: {col} is not uniformly sampled (line {i + first_line} is "
            f"{dev[i] / step:.2g} sample periods off the uniform grid: dropped or repeated "
            "samples?)"
        )
    return float(1.0 / step)


def _locate_csv_problem(p: Path, raw: list[str], index: list[int], has_header: bool) -> str:
    """Describe the first malformed data line (slow path, run only on error)."""
    n = len(raw)
    labels = [raw[i].strip() if has_header else f"#{i}" for i in index]
    layout = ",".join(c.strip() for c in raw) if has_header else f"{n} columns"
    try:
        with open(p, encoding="utf-8-sig", newline="") as fh:
            reader = csv.reader(fh)
            if has_header:
                next(reader, None)  # header, checked already
            for row in reader:
                line = reader.line_num
                if not row or all(not c.strip() for c in row):
                    continue
                if len(row) != n:
                    return f"line {line} has {len(row)} cells, expected {n} ({layout})"
                for col, i in zip(labels, index, strict=True):
                    cell = row[i]
                    try:
                        value = float(cell)
                    except ValueError:
                        shown = quote_content(cell.strip()) or "the cell"
                        return f"line {line}, column {col}: {shown} is not a number"
                    if not math.isfinite(value):
                        return f"line {line}, column {col}: {cell.strip()} is not a finite number"
    except UnicodeDecodeError:
        return "not a UTF-8 text file"
    return "malformed CSV content"


# ---------------------------------------------------------------------------- NPY


def _read_npy(
    p: Path, fs_hz: float | None, channel: str | int | None
) -> tuple[np.ndarray, float, str]:
    name = str(p)
    if fs_hz is None:
        raise StiffnetError(f"{name}: sampling rate missing (a .npy file needs fs_hz)")
    try:
        arr = np.load(p, allow_pickle=False)
    except Exception as exc:  # noqa: BLE001 - a corrupt header raises assorted types
        raise StiffnetError(f"{name}: not a readable .npy array ({_brief(exc)})") from None
    if not isinstance(arr, np.ndarray):
        raise StiffnetError(f"{name}: expected one array, not an archive")
    if arr.ndim == 2 and arr.shape[1] > 1:
        if channel is None:
            raise StiffnetError(
                f"{name}: {arr.shape[1]} channels (columns 0..{arr.shape[1] - 1} of shape "
                f"{arr.shape}); choose one with --channel INDEX (manifest/HTTP field channel)"
            )
        idx = _channel_index(channel, arr.shape[1], name, "NPY")
        arr, name = arr[:, idx], f"{name} (channel {idx})"
    elif arr.ndim == 2:
        arr = arr[:, 0]
    elif channel not in (None, 0, "0"):
        raise StiffnetError(f"{name}: channel {channel!r} requested but the file has one channel")
    if arr.ndim != 1:
        raise StiffnetError(f"{name}: expected a 1-D array, got shape {arr.shape}")
    if not (np.issubdtype(arr.dtype, np.floating) or np.issubdtype(arr.dtype, np.integer)):
        raise StiffnetError(f"{name}: expected real numbers, got dtype {arr.dtype}")
    return arr.astype(np.float64), fs_hz, name


# ---------------------------------------------------------------------------- WAV


def _read_wav(
    p: Path, fs_hz: float | None, channel: str | int | None
) -> tuple[np.ndarray, float, str]:
    from scipy.io import wavfile

    name = str(p)
    try:
        with warnings.catch_warnings():  # e.g. "chunk not understood": keep errors one line
            warnings.simplefilter("ignore", wavfile.WavFileWarning)
            rate, data = wavfile.read(p)
    except Exception as exc:  # noqa: BLE001 - a corrupt header raises assorted types
        raise StiffnetError(f"{name}: not a readable WAV file ({_brief(exc)})") from None
    if data.ndim == 2 and data.shape[1] > 1 and channel is None:
        raise StiffnetError(
            f"{name}: {data.shape[1]} channels (0..{data.shape[1] - 1}); choose one with "
            "--channel INDEX (manifest/HTTP field channel)"
        )
    if data.ndim == 2:
        idx = _channel_index(channel, data.shape[1], name)
        data = data[:, idx]
        name = f"{name} (channel {idx})"
    elif channel not in (None, 0, "0"):
        raise StiffnetError(f"{name}: channel {channel!r} requested but the file has one channel")
    if data.dtype == np.uint8:  # 8-bit WAV is offset binary
        accel = (data.astype(np.float64) - 128.0) / 128.0
    elif np.issubdtype(data.dtype, np.integer):
        accel = data.astype(np.float64) / float(2 ** (8 * data.dtype.itemsize - 1))
    else:
        accel = data.astype(np.float64)
    fs = float(rate)
    if fs <= 0:
        raise StiffnetError(f"{name}: sampling rate must be > 0, the file says {rate}")
    if fs_hz is not None and abs(fs - fs_hz) > FS_TOLERANCE * fs_hz:
        raise StiffnetError(f"{name}: the file says fs = {fs:.6g} Hz but fs_hz = {fs_hz:.6g} Hz")
    return accel, fs, name


def _channel_index(channel: str | int | None, n: int, name: str, kind: str = "WAV") -> int:
    if channel is None:
        return 0
    try:
        idx = int(channel)
    except (TypeError, ValueError):
        raise StiffnetError(f"{name}: {kind} channel must be an index, got {channel!r}") from None
    if not 0 <= idx < n:
        raise StiffnetError(f"{name}: channel {idx} requested but the file has {n} channels")
    return idx


# ---------------------------------------------------------------------------- TDMS


def _read_tdms(
    p: Path, fs_hz: float | None, channel: str | int | None
) -> tuple[np.ndarray, float, str]:
    try:
        from nptdms import TdmsFile
    except ImportError:  # pragma: no cover - npTDMS is a core dependency
        raise StiffnetError(f"{p}: reading .tdms needs the npTDMS package") from None

    name = str(p)
    with open(p, "rb") as fh:  # npTDMS reads any bytes as an empty file
        if fh.read(4) != b"TDSm":
            raise StiffnetError(f"{name}: not a readable TDMS file (no 'TDSm' lead-in)")
    from nptdms.log import log_manager

    # npTDMS logs warnings on stderr for corrupt files, which would break the
    # one-line errors: silence them while reading (under a lock: it is global state).
    with _TDMS_LOCK:
        level = log_manager.log_level
        log_manager.set_level(logging.ERROR)
        try:
            tdms = TdmsFile.read(p)
        except Exception as exc:  # npTDMS raises assorted types on corrupt files
            raise StiffnetError(f"{name}: not a readable TDMS file ({_brief(exc)})") from None
        finally:
            log_manager.set_level(level)
    channels = [(g.name, c) for g in tdms.groups() for c in g.channels()]
    with_data = [(g, c) for g, c in channels if len(c) > 0]
    if channel is None:
        if not with_data:
            raise StiffnetError(f"{name}: recording is empty (no TDMS channel holds data)")
        if len(with_data) > 1:
            listed = ", ".join(f"{g}/{c.name}" for g, c in with_data)
            raise StiffnetError(
                f"{name}: {len(with_data)} channels hold data ({listed}); choose one with "
                "--channel NAME (manifest/HTTP field channel)"
            )
        group, chan = with_data[0]
    else:
        want = str(channel)
        found = [(g, c) for g, c in channels if want in (c.name, f"{g}/{c.name}")]
        if not found and want.isdigit() and int(want) < len(with_data):
            found = [with_data[int(want)]]  # an index among the channels holding data
        if not found:
            listed = ", ".join(f"{g}/{c.name}" for g, c in channels) or "none"
            raise StiffnetError(f"{name}: no TDMS channel {want!r} (channels: {listed})")
        if len(found) > 1:
            raise StiffnetError(f"{name}: channel name {want!r} is ambiguous, use 'group/name'")
        group, chan = found[0]
    source = f"{name} (channel {group}/{chan.name})"
    data = chan[:]
    if not (np.issubdtype(data.dtype, np.floating) or np.issubdtype(data.dtype, np.integer)):
        raise StiffnetError(f"{source}: channel holds {data.dtype} values, not numbers")
    fs = fs_hz
    increment = chan.properties.get("wf_increment")
    if increment is not None:
        try:
            file_fs = 1.0 / float(increment)
        except (TypeError, ValueError, ZeroDivisionError):
            raise StiffnetError(f"{source}: invalid wf_increment {increment!r}") from None
        if not (math.isfinite(file_fs) and file_fs > 0):
            raise StiffnetError(f"{source}: invalid wf_increment {increment!r}")
        if fs_hz is not None and abs(file_fs - fs_hz) > FS_TOLERANCE * fs_hz:
            raise StiffnetError(
                f"{source}: wf_increment gives fs = {file_fs:.6g} Hz but fs_hz = {fs_hz:.6g} Hz"
            )
        fs = file_fs
    if fs is None:
        raise StiffnetError(f"{source}: sampling rate missing (no wf_increment; give fs_hz)")
    return np.asarray(data, dtype=np.float64), fs, source

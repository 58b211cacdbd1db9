"""Reading and writing single-channel acceleration recordings.

A recording is one accelerometer channel sampled at a uniform rate. Supported
files (chosen by extension):

``.csv``
    header ``t,accel``, time in seconds, acceleration in any unit (the sensor
    gain does not matter to stiffnet). The rate is inferred from ``t`` unless
    given, in which case ``t`` must agree with it.
``.npy``
    a 1-D numeric array; the rate must be given (the manifest's ``fs_hz``).
``.wav``
    integer samples are scaled to [-1, 1); the rate comes from the file. A
    multi-channel file gives its first channel, or ``channel`` (an index).
``.tdms``
    LabVIEW files, read with npTDMS (imported only when needed): the first
    channel holding data, or ``channel`` (``"name"`` or ``"group/name"``). The
    rate comes from the channel's ``wf_increment`` property when present.

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
import tempfile
import threading
import warnings
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pyarrow as pa
import pyarrow.csv as pacsv

from stiffnet.errors import StiffnetError
from stiffnet.inputs import quote_content

#: Extensions :func:`read_recording` understands.
SUPPORTED_EXTENSIONS = (".csv", ".npy", ".wav", ".tdms")
#: Column names of a CSV recording.
CSV_COLUMNS = ("t", "accel")
#: A time column may deviate from the uniform grid by this fraction of a sample
#: period (rounding of the written times); a dropped sample deviates by >= 1/2.
TIME_JITTER_TOLERANCE = 0.2
#: Relative tolerance between a given rate and the one a file carries.
FS_TOLERANCE = 1e-3

_TDMS_LOCK = threading.Lock()


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
        WAV: channel index (default 0). TDMS: channel name or ``group/name``
        (default: the first channel holding data).

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
    if channel is not None and ext in (".csv", ".npy"):
        raise StiffnetError(f"{name}: a {ext} recording has one channel; do not give 'channel'")
    reader = {".csv": _read_csv, ".npy": _read_npy, ".wav": _read_wav, ".tdms": _read_tdms}[ext]
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
    fd, tmp = tempfile.mkstemp(dir=p.parent, prefix=f".{p.name}.", suffix=".tmp")
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


def _read_csv(
    p: Path, fs_hz: float | None, channel: str | int | None
) -> tuple[np.ndarray, float, str]:
    name = str(p)
    try:
        with open(p, encoding="utf-8-sig", newline="") as fh:  # -sig: Excel's BOM
            first = fh.readline()
    except UnicodeDecodeError:
        raise StiffnetError(f"{name}: not a UTF-8 text file (expected a CSV 't,accel')") from None
    if not first.strip():
        raise StiffnetError(f"{name}: missing header (expected 't,accel' on line 1)")
    header = [c.strip().lower() for c in first.strip().split(",")]
    if tuple(header) != CSV_COLUMNS:
        hint = " (the file must be comma-separated)" if len(header) == 1 else ""
        # never echo what is not a column list (a link to a secret shows only its shape)
        shown = quote_content(first.strip(), cells=4) or f"({len(header)} cell(s), not shown)"
        raise StiffnetError(f"{name}: wrong header {shown}, expected 't,accel' on line 1{hint}")
    try:
        table = pacsv.read_csv(
            p,
            read_options=pacsv.ReadOptions(skip_rows=1, column_names=list(CSV_COLUMNS)),
            convert_options=pacsv.ConvertOptions(
                column_types={c: pa.float64() for c in CSV_COLUMNS},
                null_values=[],  # empty cells are errors, 'nan' parses as NaN
                strings_can_be_null=False,
            ),
        )
    except (pa.ArrowInvalid, UnicodeDecodeError):
        # the fast parser does not say where: find the line ourselves
        raise StiffnetError(f"{name}: {_locate_csv_problem(p)}") from None
    t = table.column("t").to_numpy()
    accel = table.column("accel").to_numpy()
    if accel.size < 2:
        return accel, fs_hz or 1.0, name  # read_recording reports it
    if not (np.all(np.isfinite(t)) and np.all(np.isfinite(accel))):
        raise StiffnetError(f"{name}: {_locate_csv_problem(p)}")  # names the line
    fs = _rate_from_times(t, name)
    if fs_hz is not None and abs(fs - fs_hz) > FS_TOLERANCE * fs_hz:
        raise StiffnetError(
            f"{name}: column t gives fs = {fs:.6g} Hz but fs_hz = {fs_hz:.6g} Hz was given"
        )
    return accel, fs_hz if fs_hz is not None else fs, name


def _rate_from_times(t: np.ndarray, name: str) -> float:
    """Sampling rate of a time column, checking it is strictly increasing and uniform."""
    dt = np.diff(t)
    if np.any(dt <= 0):
        i = int(np.argmax(dt <= 0))
        raise StiffnetError(
            f"{name}: column t is not strictly increasing (line {i + 3}: t = {float(t[i + 1])!r} "
            f"after {float(t[i])!r})"
        )
    step = (t[-1] - t[0]) / (t.size - 1)
    dev = np.abs(t - (t[0] + np.arange(t.size) * step))
    if dev.max() > TIME_JITTER_TOLERANCE * step:
        i = int(np.argmax(dev))
        raise StiffnetError(
            f"{name}: column t is not uniformly sampled (line {i + 2} is {dev[i] / step:.2g} "
            "sample periods off the uniform grid: dropped or repeated samples?)"
        )
    return float(1.0 / step)


def _locate_csv_problem(p: Path) -> str:
    """Describe the first malformed data line (slow path, run only on error)."""
    try:
        with open(p, encoding="utf-8-sig", newline="") as fh:
            reader = csv.reader(fh)
            next(reader, None)  # header, checked already
            for row in reader:
                line = reader.line_num
                if not row or all(not c.strip() for c in row):
                    continue
                if len(row) != len(CSV_COLUMNS):
                    return f"line {line} has {len(row)} cells, expected 2 (t,accel)"
                for col, cell in zip(CSV_COLUMNS, row, strict=True):
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


def _channel_index(channel: str | int | None, n: int, name: str) -> int:
    if channel is None:
        return 0
    try:
        idx = int(channel)
    except (TypeError, ValueError):
        raise StiffnetError(f"{name}: WAV channel must be an index, got {channel!r}") from None
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
    if channel is None:
        found = [(g, c) for g, c in channels if len(c) > 0]
        if not found:
            raise StiffnetError(f"{name}: recording is empty (no TDMS channel holds data)")
        group, chan = found[0]
    else:
        want = str(channel)
        found = [(g, c) for g, c in channels if want in (c.name, f"{g}/{c.name}")]
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

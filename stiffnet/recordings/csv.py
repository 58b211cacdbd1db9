"""CSV recordings: ``t,accel`` by default, any layout by ``columns`` and ``time_unit``.

Header ``t,accel``, time in seconds, acceleration in any unit (the sensor gain does
not matter to stiffnet). The rate is inferred from ``t`` unless given, in which
case ``t`` must agree with it. Other layouts are read with ``columns="TIME,ACCEL"``
(header names or 0-based indices; a single ``ACCEL`` means no time column, the rate
is then required; with indices the file may have no header) and
``time_unit="s"|"ms"|"us"``; ``channel`` names the acceleration column (the time
column stays ``t``).

I/O goes through ``pyarrow.csv`` (a core dependency, imported when a file is read):
on 1e6 rows it reads about 3x faster than ``np.loadtxt`` and 10x faster than
``np.genfromtxt``, and it writes floats in their shortest round-trip form, so a
written recording reads back bit for bit. The slow, line-by-line scan is only run
when the fast parser fails, to tell the user which line is wrong.

Loggers often write a preamble of ``#`` comment lines (operator, rig, settings) before the
header; they are skipped (:func:`_preamble`). numpy's ``savetxt(header="t,accel")`` writes
the header itself as a comment, ``# t,accel``: the last comment line is the header when it
names the columns and the line after it holds numbers.
"""

from __future__ import annotations

import csv
import math
import os
import re
import tempfile
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

from stiffnet.errors import RateMismatch, StiffnetError
from stiffnet.inputs import (
    columns_hint,
    not_utf8_words,
    quote_content,
    where_given,
    without_unnamed_tail,
)
from stiffnet.recordings.base import (
    Recording,
    RecordingReader,
    Samples,
    channel_given,
    rates_agree,
)

if TYPE_CHECKING:
    import numpy as np
    import pyarrow as pa

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
#: Longest first line read as a header: a header names a few columns, and a file without
#: line ends must not be read whole to find where its first line ends.
HEADER_MAX_CHARS = 2**16
#: Most comment lines skipped before the header: a file of comments alone is not read whole.
PREAMBLE_MAX_LINES = 1000


class CsvReader(RecordingReader):
    """Comma-separated text: a time column and an acceleration column."""

    name = "CSV"
    extensions = (".csv",)
    description = "header t,accel (other layouts: columns, time_unit), rate from the time column"
    options = ("columns", "time_unit")
    channel_help = "the acceleration column's name or index"

    def channels(self, path: Path) -> list[str]:
        """The header's column names (indices for a file without a header)."""
        try:
            with open(path, encoding="utf-8-sig", newline="") as fh:
                _, first, _ = _preamble(fh)
                raw = next(csv.reader([first]), [])
        except UnicodeDecodeError:
            raise StiffnetError(
                f"{path}: not a UTF-8 text file (expected a CSV){not_utf8_words(path)}"
            ) from None
        if raw and all(_is_number(c) for c in raw):
            return [str(i) for i in range(len(raw))]
        return [c.strip() for c in raw]

    def read(
        self,
        path: Path,
        fs_hz: float | None,
        channel: str | int | None,
        columns: str | Sequence[str | int] | None = None,
        time_unit: str | None = None,
        **_: Any,
    ) -> Samples:
        name = str(path)
        if channel is not None:
            if columns is not None:
                raise StiffnetError(
                    f"{name}: give either 'columns' or 'channel' for a CSV, not both"
                )
            columns = f"{CSV_COLUMNS[0]},{channel}"
        layout = _CsvLayout.parse(columns, time_unit, name)
        return Samples(*_read_csv(path, fs_hz, layout))


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
    import numpy as np
    import pyarrow as pa
    import pyarrow.csv as pacsv

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


def unit_mistake_hint(fs_hz: float, lo_hz: float, hi_hz: float = math.inf) -> str:
    """A hint when `fs_hz` is implausible but 1e3x or 1e6x it would fit ``[lo_hz, hi_hz]``.

    A time column in milliseconds read as seconds gives a rate 1000 times too
    low; this names that mistake and the option that fixes it. Empty when no
    such factor fits.
    """
    for factor, (word, unit) in _UNIT_FACTORS.items():
        if lo_hz <= fs_hz * factor <= hi_hz:
            given = where_given(f"--time-unit {unit}", f"the manifest's column time_unit {unit}",
                                f"the field time_unit={unit}")  # fmt: skip
            return (
                f"; if the time column is in {word}, give the time unit {unit} "
                f"({given}), which gives "
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


def _preamble(fh: Any) -> tuple[int, str, str | None]:
    """Read past the ``#`` comment lines before the header.

    Returns how many were skipped, the first other line (empty at the end of the file) and
    the last comment without its ``#`` (None without comments), which may be the header
    numpy's ``savetxt`` writes. Each line is read bounded by :data:`HEADER_MAX_CHARS`: a
    file without line ends (zeros, a binary dump) would otherwise be read whole.
    """
    skipped, last = 0, None
    line = fh.readline(HEADER_MAX_CHARS + 1)
    while line.lstrip().startswith("#") and skipped < PREAMBLE_MAX_LINES:
        skipped, last = skipped + 1, line.lstrip()[1:].strip()
        line = fh.readline(HEADER_MAX_CHARS + 1)
    return skipped, line, last


def _header_names(cells: list[str]) -> tuple[str, ...]:
    """A header's column names as compared with :data:`CSV_COLUMNS`."""
    return tuple(c.strip().lower() for c in without_unnamed_tail(cells))


def _all_numbers(line: str) -> bool:
    """Whether a line's cells are all numbers (a data line, not a header)."""
    cells = next(csv.reader([line]), [])
    return bool(cells) and all(_is_number(c) for c in cells)


def _is_number(cell: str) -> bool:
    try:
        float(cell)
    except ValueError:
        return False
    return True


#: What a quotable column name looks like: words, units in brackets, no separators of
#: other file formats (``root:*:...`` is not a header).
_COLUMN_NAME = re.compile(r"^[\w ()\[\]/.\-]{1,32}$")


def _refuse_a_manifest(name: str, names: list[str]) -> None:
    """A campaign's manifest given as a recording: said so, with what reads it (its header
    would otherwise be taken for a recording's columns, ``--columns recording,fs_hz``)."""
    from stiffnet.campaign.manifest import REQUIRED_COLUMNS

    if not set(REQUIRED_COLUMNS) <= {n.lower() for n in names}:
        return
    how = where_given(
        "give its campaign folder to predict-batch, evaluate or diagnose",
        "list its recordings, not the manifest",
        "post each of its recordings, with its row's values as fields",
    )
    raise StiffnetError(
        f"{name}: a campaign manifest (columns {', '.join(names[:4])}"
        f"{', ...' if len(names) > 4 else ''}), not a recording: {how}"
    )


def _other_separator(cell: str) -> str:
    """Where a one-cell header is names joined by ``;`` or tabs (a spreadsheet's export with
    decimal commas): which separator, the names and how to save it; else empty."""
    for sep, what in ((";", "';'"), ("\t", "tabs")):
        names = [c.strip() for c in cell.split(sep)]
        if len(names) > 1 and all(map(_COLUMN_NAME.match, names)):
            shown = ", ".join(names[:4]) + (", ..." if len(names) > 4 else "")
            return (
                f"its columns are separated by {what}, not commas: {shown}; save it "
                "comma-separated, with '.' as the decimal point"
            )
    return ""


def _header_hint(header: list[str]) -> str:
    """How to read a file whose header is not ``t,accel``."""
    if len(header) == 1:
        other = _other_separator(header[0])
        return f" ({other})" if other else " (the file must be comma-separated)"
    if all(_is_number(c) for c in header if c.strip()):
        return f"; no header: {columns_hint('0,1')} (indices; give the sampling rate if needed)"
    names = [c.strip() for c in header]
    if len(names) > 2 and all(map(_COLUMN_NAME.match, names)):
        # never propose the first two of several columns: a force or index column there
        # would be read as the acceleration or the time
        return _several_columns_hint(names)
    time, accel = names[0], names[1]
    unit = _time_unit_of(time)
    # column names are quoted only when they look like names (a secret's line does not)
    example = f"{time},{accel}" if all(map(_COLUMN_NAME.match, (time, accel))) else "TIME,ACCEL"
    return f"; {columns_hint(example, unit)}" + _channels_hint(header)


#: Header names of a logger's sample counter: an index, not a time.
_INDEX_NAMES = frozenset({"sample", "samples", "sample_index", "index", "idx", "n", "i", "row"})


def _time_like(name: str) -> bool:
    low = name.lower()
    return low in ("t", "time") or low.startswith(("t_", "t ", "t[", "t(", "time"))


def _accel_like(name: str) -> bool:
    low = name.lower()
    return low.startswith("acc") or low in ("a", "ax", "ay", "az") or low.startswith("a_")


def _time_unit_of(name: str) -> str | None:
    """The time unit a column's name carries (``time_ms``, ``t [us]``), if not seconds."""
    low = name.lower()
    for u in ("ms", "us"):
        if low.endswith((f"_{u}", f"({u})", f"[{u}]", f" {u}")):
            return u
    return None


def _several_columns_hint(names: list[str]) -> str:
    """How to read a file of several named columns: the time and acceleration columns
    chosen by their names (none by position), the rate asked for where no column is a time
    (a sample counter is not one), the columns listed."""
    time = next((c for c in names if _time_like(c)), None)
    accels = [c for c in names if _accel_like(c)]
    if CSV_COLUMNS[1] in accels:  # the default name among several axes
        accels = [CSV_COLUMNS[1]]
    listed = _channels_hint(names)
    if len(accels) != 1:  # none, or several axes: the user picks
        return f"; {columns_hint('TIME,ACCEL')}" + listed
    if time is not None:
        return f"; {columns_hint(f'{time},{accels[0]}', _time_unit_of(time))}" + listed
    index = next((c for c in names if c.lower() in _INDEX_NAMES), None)
    counter = f" ({index!r} counts samples: it is not a time)" if index else ""
    rate = where_given("--fs HZ", "the manifest's column fs_hz", "the field fs_hz")
    return (
        f"; no time column{counter}: {columns_hint(accels[0])} and give the rate ({rate})" + listed
    )


def _channels_hint(header: list[str]) -> str:
    """With more than two columns, which ones the file has (only names that look like names)."""
    names = [c.strip() for c in header]
    if len(names) <= 2 or not all(map(_COLUMN_NAME.match, names)):
        return ""
    pick = channel_given("NAME")
    return f"; its {len(names)} columns: {', '.join(names)} ({pick} picks the acceleration)"


def _read_csv(p: Path, fs_hz: float | None, layout: _CsvLayout) -> tuple[np.ndarray, float, str]:
    import numpy as np

    name = str(p)
    try:
        with open(p, encoding="utf-8-sig", newline="") as fh:  # -sig: Excel's BOM
            skipped, first, commented_header = _preamble(fh)
    except UnicodeDecodeError:
        raise StiffnetError(
            f"{name}: not a UTF-8 text file (expected a CSV 't,accel'){not_utf8_words(p)}"
        ) from None
    if not first and skipped:
        raise StiffnetError(f"{name}: {skipped} comment line(s) ('#') and no data after them")
    if not first:  # a logger's failed copy or transfer, not a file without its header
        raise StiffnetError(f"{name}: the file is empty (0 bytes; expected 't,accel' on line 1)")
    if commented_header is not None and _all_numbers(first):
        names = _header_names(next(csv.reader([commented_header])))
        named = [k for k in layout.wanted if isinstance(k, str)]
        if (names == CSV_COLUMNS and not layout.custom) or (
            layout.custom and named and all(k.lower() in names for k in named)
        ):
            # numpy's savetxt: the header is the preamble's last line, the data follow
            first, skipped = commented_header, skipped - 1
    if "\x00" in first:  # a preallocated file never written, or a binary one
        raise StiffnetError(
            f"{name}: line {skipped + 1} holds NUL bytes, not text (a binary file, or one "
            "allocated and never written); expected a CSV 't,accel'"
        )
    if len(first) > HEADER_MAX_CHARS:
        raise StiffnetError(
            f"{name}: line {skipped + 1} is longer than {HEADER_MAX_CHARS} characters, not a "
            f"header (expected 't,accel' on line {skipped + 1})"
        )
    if not first.strip():
        raise StiffnetError(f"{name}: missing header (expected 't,accel' on line {skipped + 1})")
    cells = next(csv.reader([first]))
    raw = without_unnamed_tail(cells)
    if layout.custom and len(raw) == 1 and (other := _other_separator(raw[0])):
        # the columns named are there, joined into one cell: said so, not 'no column'
        raise StiffnetError(f"{name}: line {skipped + 1}: {other}")
    header = [c.strip().lower() for c in raw]
    if not layout.custom and tuple(header) != CSV_COLUMNS:
        # never echo what is not a column list (a link to a secret shows only its shape)
        names = [c.strip() for c in raw]
        named = all(map(_COLUMN_NAME.match, names))
        if named:
            _refuse_a_manifest(name, names)
        shown = quote_content(first.strip(), cells=4) or f"({len(raw)} cell(s), not shown)"
        if named:  # names: shown, as the hint shows them (past four, the hint lists them)
            shown = repr(",".join(names)) if len(raw) <= 4 else f"of {len(raw)} named columns"
        raise StiffnetError(
            f"{name}: wrong header {shown}, expected 't,accel' on line {skipped + 1}"
            f"{_header_hint(raw)}"
        )
    has_header = not (
        all(isinstance(k, int) for k in layout.wanted) and all(_is_number(c) for c in raw)
    )
    if has_header and layout.time == CSV_COLUMNS[0] and CSV_COLUMNS[0] not in header:
        # the channel named the acceleration; the time column is the default 't'
        rate = where_given("--fs HZ", "the manifest's column fs_hz", "the field fs_hz")
        raise StiffnetError(
            f"{name}: no time column 't' in the header ({','.join(c.strip() for c in raw)}); "
            f"{columns_hint(f'TIME,{layout.accel}')}, or without a time column "
            f"{columns_hint(str(layout.accel)).removeprefix('name its columns').lstrip(': ')} "
            f"and give the rate ({rate})"
        )
    index = [_column_index(k, header if has_header else None, len(raw), name)
             for k in layout.wanted]  # fmt: skip
    names = [f"c{i}" for i in range(len(cells))]  # the unnamed tail too: every row has it
    wanted = [names[i] for i in index]
    import pyarrow as pa
    import pyarrow.csv as pacsv

    try:
        table = pacsv.read_csv(
            p,
            read_options=pacsv.ReadOptions(
                skip_rows=skipped + int(has_header),
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
        problem = _locate_csv_problem(p, raw, index, has_header, skipped)
        raise StiffnetError(f"{name}: {problem}") from None
    accel = _float_column(table, wanted[-1])
    t = _float_column(table, wanted[0]) * layout.seconds_per_unit if len(wanted) == 2 else None
    if accel.size < 2:
        return accel, fs_hz or 1.0, name  # read_recording reports it
    if not (np.all(np.isfinite(accel)) and (t is None or np.all(np.isfinite(t)))):
        raise StiffnetError(f"{name}: {_locate_csv_problem(p, raw, index, has_header, skipped)}")
    if t is None:
        if fs_hz is None:
            rate = where_given("--fs HZ", "the manifest's column fs_hz", "the field fs_hz")
            raise StiffnetError(f"{name}: sampling rate missing (no time column; give {rate})")
        return accel, fs_hz, name
    tname = raw[index[0]].strip() if has_header else f"{index[0]}"
    fs = _rate_from_times(t, name, f"column {tname}", first_line=1 + skipped + int(has_header))
    if fs_hz is not None and not rates_agree(fs, fs_hz):
        hint = ""
        for factor, (word, unit) in _UNIT_FACTORS.items():
            if rates_agree(fs * factor, fs_hz):
                hint = f" (is the time in {word}? give time unit {unit})"
        raise RateMismatch(
            f"{name}: column {tname} gives fs = {fs:.6g} Hz but fs_hz = {fs_hz:.6g} Hz "
            f"was given{hint}"
        )
    return accel, fs_hz if fs_hz is not None else fs, name


def _float_column(table: pa.Table, name: str) -> np.ndarray:
    """A float64 column without nulls as numpy, read from its buffers.

    ``ChunkedArray.to_numpy`` imports pandas (0.2 s) to check for pandas types;
    reading the value buffers keeps ``stiffnet predict``'s cold start short.
    """
    import numpy as np

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
    import numpy as np

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
        # a gap stretches the mean step, so the grid's offsets do not count what is missing:
        # the typical step does
        typical = float(np.median(dt))
        j = int(np.argmax(dt))
        if dt[j] > (2 - TIME_JITTER_TOLERANCE) * typical:
            missing = round(dt[j] / typical) - 1
            raise StiffnetError(
                f"{name}: {col} has a gap: t jumps from {float(t[j])!r} to {float(t[j + 1])!r} "
                f"(line {j + first_line + 1}), {dt[j]:.4g} s where the other steps are "
                f"{typical:.4g} s: about {missing} sample(s) missing (a logger's dropout); "
                "the recording must be sampled without gaps"
            )
        i = int(np.argmax(dev))
        raise StiffnetError(
            f"{name}: {col} is not uniformly sampled (line {i + first_line} is "
            f"{dev[i] / step:.2g} sample periods off the uniform grid: repeated samples or a "
            "jittering clock?)"
        )
    return float(1.0 / step)


#: A date and/or time of day as loggers stamp their rows (``2026-12-02T10:00:00.001``,
#: ``2026-12-02 10:00:00``, ``10:00:00.001``): safe to quote, and a time that is not seconds.
_TIMESTAMP = re.compile(
    r"^(\d{4}-\d{2}-\d{2}([T ]\d{1,2}:\d{2}(:\d{2}([.,]\d+)?)?)?|\d{1,2}:\d{2}:\d{2}([.,]\d+)?)"
    r"(Z|[+-]\d{2}:?\d{2})?$"
)


def _timestamp_problem(line: int, col: str, cell: str, accel: str) -> str:
    """A time column of clock stamps: what it is, and how to read the file (the
    acceleration column ``accel`` alone with the rate)."""
    rate = where_given("--fs HZ", "the manifest's column fs_hz", "the field fs_hz")
    return (
        f"line {line}, column {col}: {cell!r} is a clock time, not a time in seconds; "
        f"{columns_hint(accel)} and give the rate ({rate}), or write the time in seconds"
    )


def _locate_csv_problem(
    p: Path, raw: list[str], index: list[int], has_header: bool, skipped: int = 0
) -> str:
    """Describe the first malformed data line (slow path, run only on error; ``skipped``
    comment lines before the header)."""
    n = len(raw)
    labels = [raw[i].strip() if has_header else f"#{i}" for i in index]
    layout = ",".join(c.strip() for c in raw) if has_header else f"{n} columns"
    try:
        with open(p, encoding="utf-8-sig", newline="") as fh:
            for _ in range(skipped):
                fh.readline()
            reader = csv.reader(fh)
            if has_header:
                next(reader, None)  # header, checked already
            for row in reader:
                line = reader.line_num + skipped
                if not row or all(not c.strip() for c in row):
                    continue
                if len(row) != n:
                    return f"line {line} has {len(row)} cells, expected {n} ({layout})"
                for col, i in zip(labels, index, strict=True):
                    cell = row[i]
                    try:
                        value = float(cell)
                    except ValueError:
                        if len(index) == 2 and i == index[0] and _TIMESTAMP.match(cell.strip()):
                            accel = raw[index[1]].strip() if has_header else str(index[1])
                            return _timestamp_problem(line, col, cell.strip(), accel)
                        shown = quote_content(cell.strip()) or "the cell"
                        return f"line {line}, column {col}: {shown} is not a number"
                    if not math.isfinite(value):
                        return f"line {line}, column {col}: {cell.strip()} is not a finite number"
    except UnicodeDecodeError:
        return f"not a UTF-8 text file{not_utf8_words(p)}"
    return "malformed CSV content"

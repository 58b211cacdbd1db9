"""Campaign manifests: the model of one row, reading and writing ``manifest.csv``, and
a loaded campaign (a folder of recordings described by its manifest).

A row's physical-unit columns (forcing frequency in Hz, base acceleration or
displacement, gap in mm, and their tolerances) are converted to the model columns of
the paper's eqs (11)-(12) when the row is validated (``docs/campaign.md``, "Units").
"""

from __future__ import annotations

import csv
import itertools
import math
import os
import posixpath
import re
import secrets
from collections.abc import Iterator, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Literal

import numpy as np
from pydantic import (
    BaseModel,
    ConfigDict,
    Field,
    PrivateAttr,
    ValidationError,
    ValidationInfo,
    field_validator,
    model_validator,
)

from stiffnet.errors import RateMismatch, StiffnetError
from stiffnet.inputs import not_utf8_words, quote_content, unit_hint, without_unnamed_tail
from stiffnet.recordings import Recording, read_recording
from stiffnet.recordings.read import case_twin_hint
from stiffnet.simulator.batch import PAPER_NATURAL_FREQUENCY_HZ

MANIFEST_NAME = "manifest.csv"
#: Ground truth of a synthetic campaign (:mod:`stiffnet.campaign.synthetic`).
CARD_NAME = "campaign_card.json"
#: Columns every manifest has.
REQUIRED_COLUMNS = ("recording", "fs_hz")
#: Standard gravity, m/s^2: simulated recordings are written in g.
STANDARD_GRAVITY = 9.80665
#: Model length unit assumed when converting simulated accelerations to g, m.
MODEL_LENGTH_UNIT_M = 1e-3
MODEL_LENGTH_MM = MODEL_LENGTH_UNIT_M * 1e3


def _div(v: float | None, d: float) -> float | None:
    return None if v is None else v / d


class ManifestRow(BaseModel):
    """One recording of a campaign (one line of ``manifest.csv``).

    Optional model parameters are in the units of the paper's eqs (11)-(12):
    lengths in a common (arbitrary) unit, frequencies as ratios to ``f_n``.

    Attributes
    ----------
    recording : str
        Path of the recording file, relative to the campaign folder (``/``-separated).
    fs_hz : float
        Sampling rate in Hz (> 0).
    natural_frequency_hz : float, optional
        ``f_n`` of the oscillator in Hz (> 0).
    frequency_ratio : float, optional
        Forcing frequency over ``f_n`` (``w``, > 0).
    amplitude : float, optional
        Base-excitation amplitude ``a`` (> 0, model length).
    gap : float, optional
        Gap ``e`` between the mass at rest and the restraint (model length).
    damping_ratio : float, optional
        ``xi`` in (0, 1).
    beta : float, optional
        Known stiffness ratio (>= 0): the label of a lab calibration.
    duration_s : float, optional
        Length of a simulated recording, s (> 0).
    noise : float, optional
        White-noise std of a simulated recording as a fraction of ``a w^2`` (>= 0).
    channel : str, optional
        Channel to read from a multi-channel WAV (index) or TDMS (name) file.
    columns : str, optional
        CSV recordings: ``TIME;ACCEL`` (or ``TIME,ACCEL`` in a quoted cell),
        header names or 0-based indices, when the header is not ``t,accel``.
    time_unit : {"s", "ms", "us"}, optional
        CSV recordings: unit of the time column (default s).
    sensor : str, optional
        The accelerometer chain's data sheet, ``KEY=VALUE`` items separated by ``;`` (or
        ``,`` in a quoted cell) with the keys of ``--sensor`` (``resonance_hz``,
        ``resonance_damping``, ``lowpass_hz``, ``lowpass_order``, ``highpass_hz``): the
        restoring-force estimate undoes it as given instead of fitting the chain.
    """

    model_config = ConfigDict(extra="forbid", allow_inf_nan=False, str_strip_whitespace=True)

    recording: str = Field(min_length=1)
    fs_hz: float = Field(gt=0)
    natural_frequency_hz: float | None = Field(None, gt=0)
    frequency_ratio: float | None = Field(None, gt=0)
    amplitude: float | None = Field(None, gt=0)
    gap: float | None = None
    damping_ratio: float | None = Field(None, gt=0, lt=1)
    beta: float | None = Field(None, ge=0)
    duration_s: float | None = Field(None, gt=0)
    noise: float | None = Field(None, ge=0)
    channel: str | None = None
    columns: str | None = None
    time_unit: Literal["s", "ms", "us"] | None = None
    sensor: str | None = None
    # physical units (converted to the model columns above, see docs/campaign.md)
    forcing_frequency_hz: float | None = Field(None, gt=0)
    base_acceleration_ms2: float | None = Field(None, gt=0)
    base_acceleration_g: float | None = Field(None, gt=0)
    base_displacement_mm: float | None = Field(None, gt=0)
    gap_mm: float | None = None
    # tolerances (+-, in the unit of their nominal)
    frequency_ratio_tol: float | None = Field(None, ge=0)
    amplitude_tol: float | None = Field(None, ge=0)
    gap_tol: float | None = Field(None, ge=0)
    damping_ratio_tol: float | None = Field(None, ge=0)
    beta_tol: float | None = Field(None, ge=0)
    forcing_frequency_hz_tol: float | None = Field(None, ge=0)
    base_acceleration_ms2_tol: float | None = Field(None, ge=0)
    base_acceleration_g_tol: float | None = Field(None, ge=0)
    base_displacement_mm_tol: float | None = Field(None, ge=0)
    gap_mm_tol: float | None = Field(None, ge=0)

    #: Manifest line the row was read from (for messages); None when built in code.
    _line: int | None = PrivateAttr(None)
    #: The row's f_n is its recording's sidecar's (the row left the column empty).
    _fn_from_sidecar: bool = PrivateAttr(False)

    @field_validator("recording")
    @classmethod
    def _relative_path(cls, value: str) -> str:
        # Manifests written on Windows use backslashes; paths are stored with "/".
        norm = posixpath.normpath(value.replace("\\", "/"))
        if norm.startswith("/") or (len(norm) > 1 and norm[1] == ":"):
            raise ValueError("must be a path relative to the campaign folder")
        if norm == ".." or norm.startswith("../"):
            raise ValueError("must stay inside the campaign folder (no leading '..')")
        if norm in (".", ""):
            raise ValueError("must name a file")
        if "\x00" in norm or any(len(part.encode()) > 255 for part in norm.split("/")):
            raise ValueError("must be a usable file name (no NUL byte, names <= 255 bytes)")
        return norm

    @field_validator("sensor")
    @classmethod
    def _sensor_sheet(cls, value: str | None, info: ValidationInfo) -> str | None:
        # the CLI's --sensor reader, so that a cell and the option say the same
        from stiffnet.restoring_force.chain import sensor_sheet

        if value is None:
            return None
        try:
            sensor_sheet(value, info.data.get("fs_hz") or math.inf, what="data sheet")
        except StiffnetError as exc:
            raise ValueError(str(exc)) from None
        return value

    def sensor_sheet(self) -> dict[str, float] | None:
        """The ``sensor`` cell as the data-sheet mapping the estimates take (None: not given,
        the chain is fitted)."""
        from stiffnet.restoring_force.chain import parse_sensor_option

        return None if self.sensor is None else parse_sensor_option(self.sensor, "sensor")

    @model_validator(mode="after")
    def _physical_units(self) -> ManifestRow:
        """Fill the model columns from the physical ones (docs/campaign.md, "Units")."""
        f_n = self.natural_frequency_hz or PAPER_NATURAL_FREQUENCY_HZ
        derived: dict[str, tuple[float, float | None]] = {}
        if self.forcing_frequency_hz is not None:
            tol = self.forcing_frequency_hz_tol
            derived["frequency_ratio"] = (
                self.forcing_frequency_hz / f_n,
                None if tol is None else tol / f_n,
            )
        ratio = derived.get("frequency_ratio", (self.frequency_ratio, None))[0]
        accel = [
            (v, t, k)
            for v, t, k in (
                (self.base_acceleration_ms2, self.base_acceleration_ms2_tol, 1.0),
                (self.base_acceleration_g, self.base_acceleration_g_tol, STANDARD_GRAVITY),
            )
            if v is not None
        ]
        given = len(accel) + (self.base_displacement_mm is not None)
        if given > 1:
            raise ValueError("give one of base_acceleration_ms2, base_acceleration_g, "
                             "base_displacement_mm")  # fmt: skip
        if self.base_displacement_mm is not None:
            t = self.base_displacement_mm_tol
            derived["amplitude"] = (
                self.base_displacement_mm / MODEL_LENGTH_MM,
                _div(t, MODEL_LENGTH_MM),
            )
        elif accel:
            if ratio is None:
                raise ValueError("a base acceleration needs forcing_frequency_hz (or "
                                 "frequency_ratio) to become a displacement")  # fmt: skip
            v, t, k = accel[0]
            w2 = (2 * math.pi * ratio * f_n) ** 2 * MODEL_LENGTH_UNIT_M  # m/s^2 per model unit
            derived["amplitude"] = (v * k / w2, None if t is None else t * k / w2)
        if self.gap_mm is not None:
            derived["gap"] = (self.gap_mm / MODEL_LENGTH_MM, _div(self.gap_mm_tol, MODEL_LENGTH_MM))
        for col, (value, tol) in derived.items():
            own = getattr(self, col)
            if own is not None and not math.isclose(own, value, rel_tol=1e-6, abs_tol=1e-9):
                raise ValueError(f"{col}={own} disagrees with the physical columns ({value:.6g})")
            object.__setattr__(self, col, float(value))
            if tol is not None and getattr(self, f"{col}_tol") is None:
                object.__setattr__(self, f"{col}_tol", float(tol))
        return self

    @property
    def natural_frequency_from_sidecar(self) -> bool:
        """Whether the row's f_n is its recording's sidecar's (the manifest gave none)."""
        return self._fn_from_sidecar

    def natural_frequency_source(self, manifest: str | os.PathLike[str]) -> str | None:
        """Where the row's f_n comes from, as ``natural_frequency_source`` says it:
        ``sidecar:<path>`` when the row took its recording's sidecar's, ``manifest:<where>``
        when the row gives it, None when neither does."""
        if self.natural_frequency_from_sidecar:
            from stiffnet.recordings.sidecar import sidecar_path

            return f"sidecar:{sidecar_path(Path(manifest).parent / self.recording)}"
        if self.natural_frequency_hz is None:
            return None
        return "manifest:" + self.where(manifest)

    def where(self, manifest: str | os.PathLike[str] = MANIFEST_NAME) -> str:
        """``manifest: line N (recording)`` for messages about this row."""
        line = f"line {self._line} " if self._line is not None else ""
        return f"{manifest}: {line}({self.recording})"


#: Columns that say how to read a recording file (not properties of the measurement).
READ_COLUMNS = ("channel", "columns", "time_unit")
#: Manifest columns in their canonical (written) order.
COLUMNS: tuple[str, ...] = tuple(ManifestRow.model_fields)


# ------------------------------------------------------------------------- manifest I/O


def read_manifest(path: str | os.PathLike[str]) -> list[ManifestRow]:
    """Read and validate a campaign manifest.

    Parameters
    ----------
    path : str or os.PathLike
        The ``manifest.csv`` file (comma-separated, header on the first line;
        blank lines are skipped, empty cells mean "not given").

    Returns
    -------
    list of ManifestRow
        In file order.

    Raises
    ------
    StiffnetError
        Missing or empty file, unknown/missing/duplicate columns, a cell out of
        range or not a number (naming the line and column), duplicate recordings.
    """
    return read_manifest_with_columns(path)[1]


def _file_and_folder(name: str, seen: dict[str, int], folders: set[str], where: str) -> None:
    """Refuse a recording that is also a folder of another (``a.csv`` and ``a.csv/b.csv``)."""
    parts = name.split("/")
    parents = ["/".join(parts[:i]) for i in range(1, len(parts))]
    clash = next((d for d in parents if d in seen), None)
    if clash is not None or name in folders:
        other = clash or next(r for r in seen if r.startswith(name + "/"))
        raise StiffnetError(f"{where}: recording {name!r} and {other!r}: one path cannot be "
                            "both a file and a folder")  # fmt: skip
    folders.update(parents)


def read_manifest_with_columns(
    path: str | os.PathLike[str],
) -> tuple[list[str], list[ManifestRow]]:
    """The manifest's columns (as written, in order) and its rows; see :func:`read_manifest`."""
    p = Path(path)
    if not p.is_file():
        raise StiffnetError(f"{p}: manifest not found")
    try:
        with open(p, encoding="utf-8-sig", newline="") as fh:  # -sig: Excel's BOM
            reader = csv.reader(fh)
            header = next((r for r in reader if any(c.strip() for c in r)), None)
            if header is None:
                raise StiffnetError(f"{p}: manifest is empty (expected a header line)")
            if header[0].lstrip().startswith("#"):
                # a lab's export notes above the table: not 'unknown column 1 (name not shown)'
                raise StiffnetError(
                    f"{p}: line {reader.line_num} is a comment (it starts with '#'), not the "
                    "header: a manifest's first line is its header (recording,fs_hz,...); "
                    "delete the comment lines"
                )
            # a spreadsheet's export keeps the empty columns right of the table: named by
            # nobody, holding nothing, they are not columns (a value under one still is)
            header = without_unnamed_tail(header)
            columns = _check_header(p, [c.strip().lower() for c in header], reader.line_num,
                                    header)  # fmt: skip
            rows: list[ManifestRow] = []
            seen: dict[str, int] = {}
            folders: set[str] = set()
            problems: list[str] = []  # a lab sheet's every bad row, not one per run
            for cells in reader:
                line = reader.line_num
                if not any(c.strip() for c in cells):
                    continue
                if cells[0].lstrip().startswith("#"):
                    problems.append(f"{p}: line {line} is a comment (it starts with '#'): a "
                                    "manifest has no comment lines; delete it")  # fmt: skip
                    continue
                if len(cells) > len(columns) and not any(c.strip() for c in cells[len(columns) :]):
                    cells = cells[: len(columns)]
                try:
                    rows.append(_read_row(p, line, columns, cells, seen, folders))
                except StiffnetError as exc:
                    problems.append(str(exc))
            raise_problems(p, problems)
    except UnicodeDecodeError:
        raise StiffnetError(f"{p}: manifest is not a UTF-8 text file{not_utf8_words(p)}") from None
    except csv.Error as exc:
        raise StiffnetError(f"{p}: malformed CSV ({exc})") from None
    if not rows:
        raise StiffnetError(f"{p}: manifest lists no recordings (only a header)")
    return columns, rows


#: A header cell with its unit written beside the name, as spreadsheets do:
#: ``gap_mm [mm]``, ``fs (Hz)``, ``base_acceleration / g``.
#: A unit is a few plain symbols: a cell with anything else is never quoted back.
_UNIT = r"[a-z0-9/^²%.*· -]{1,12}"
_UNIT_BESIDE = re.compile(
    rf"^(?P<name>[a-z][a-z0-9_ ]*?)\s*"
    rf"(?:\[(?P<b>{_UNIT})\]|\((?P<p>{_UNIT})\)|/\s*(?P<s>{_UNIT}))$"
)
#: Units written beside a name, as the suffix of the column that carries that unit.
_UNIT_SUFFIX = {"hz": "hz", "mm": "mm", "g": "g", "m/s^2": "ms2", "m/s2": "ms2", "m/s²": "ms2",
                "ms^-2": "ms2", "ms-2": "ms2", "s": "s", "-": "", "1": ""}  # fmt: skip
_UNIT_SHOWN = {"hz": "Hz", "mm": "mm", "g": "g", "ms2": "m/s²", "s": "s"}
#: Columns that are ratios: a unit written beside one is a quantity the column does not hold.
_RATIOS = {
    "beta": "a ratio without a unit (the restraint's stiffness over the primary spring's)",
    "damping_ratio": "a ratio without a unit",
    "frequency_ratio": "a ratio without a unit (the forcing frequency over f_n)",
}


def _unit_in_header(col: str, written: str | None = None) -> str | None:
    """Why a header cell such as ``gap_mm [mm]`` is refused and which name to write, or
    None when the cell is not a known column with a unit beside it.

    The unit is never read from beside the name: ``gap [mm]`` could mean the model's
    ``gap`` or ``gap_mm``, and a column's unit is fixed by its name
    (docs/campaign.md, "Physical units and tolerances").
    """
    m = _UNIT_BESIDE.match(col)
    if not m:
        return None
    name = m["name"].strip().replace(" ", "_")
    unit = (m["b"] or m["p"] or m["s"]).strip()
    suffix = _UNIT_SUFFIX.get(unit.lower().replace(" ", ""))
    if suffix and f"{name}_{suffix}" in COLUMNS:
        fix = f"{name}_{suffix}"
    elif name in COLUMNS:
        fix = name
    else:
        return None
    own = next((u for u in _UNIT_SUFFIX.values() if u and fix.endswith(f"_{u}")), "")
    shown = (written or col).strip()  # as the user wrote it: "N/m", not "n/m"
    if len(shown) != len(col):  # lower() kept every span of an ASCII cell
        shown = col
    group = next(g for g in ("b", "p", "s") if m[g])
    unit_shown = shown[m.start(group) : m.end(group)].strip()
    if fix in _RATIOS and suffix != "":  # '-' or '1' beside a ratio is its own (no) unit
        hint = f"write {fix!r}, {_RATIOS[fix]} ({unit_shown!r} is not its unit)"
    elif suffix is None or (own or suffix) != suffix:
        own_unit = _UNIT_SHOWN.get(own, "the unit docs/campaign.md gives it")
        hint = f"write {fix!r}, in {own_unit} ({unit_shown!r} is not its unit)"
    else:
        hint = f"write {fix!r}"
    # the cell is a known column's name and a short unit: quoting it echoes no file content
    return f"{shown!r}: a unit beside a column's name is not read (the name carries it); {hint}"


def _tail_in_folder(value: str, folder: Path) -> str | None:
    """The longest tail of an absolute path that names a file inside ``folder``, else None:
    what a manifest written on another machine (a Windows path from its drive letter on)
    means, said to the user rather than guessed."""
    parts = [x for x in value.replace("\\", "/").split("/") if x]
    if not parts or not (value.startswith(("/", "\\")) or (len(value) > 1 and value[1] == ":")):
        return None
    root = folder.resolve()
    for i in range(1, len(parts)):
        tail = "/".join(parts[i:])
        try:
            found = (root / tail).resolve()
        except OSError:  # a name the file system cannot hold
            continue
        if found.is_relative_to(root) and found.is_file():
            return tail
    return None


def _read_row(
    p: Path,
    line: int,
    columns: list[str],
    cells: list[str],
    seen: dict[str, int],
    folders: set[str],
) -> ManifestRow:
    """One line of the manifest validated, unique and not a folder of another row."""
    if len(cells) != len(columns):
        raise StiffnetError(
            f"{p}: line {line} has {len(cells)} cells, expected {len(columns)} "
            f"({','.join(columns)})"
        )
    data = {c: v.strip() for c, v in zip(columns, cells, strict=True) if v.strip()}
    try:
        row = _validate_row(data, f"{p}: line {line}")
    except StiffnetError as exc:
        tail = _tail_in_folder(data.get("recording", ""), p.parent)
        if tail is None or "must be a path relative" not in str(exc):
            raise
        raise StiffnetError(f"{exc} (an absolute path: write its tail {tail!r}, a file of "
                            "this folder)") from None  # fmt: skip
    sidecar_fn = _sidecar_natural_frequency(p, line, row)
    if sidecar_fn is not None and row.natural_frequency_hz is None:
        # the physical columns (forcing in Hz, acceleration in g) convert with the rig's f_n
        row = _validate_row({**data, "natural_frequency_hz": sidecar_fn}, f"{p}: line {line}")
        row._fn_from_sidecar = True
    row._line = line
    if row.recording in seen:
        raise StiffnetError(
            f"{p}: line {line}: recording {row.recording!r} is listed twice "
            f"(also on line {seen[row.recording]})"
        )
    seen[row.recording] = line
    _file_and_folder(row.recording, seen, folders, f"{p}: line {line}")
    return row


#: Relative difference between a row's f_n and its sidecar's read as the same value (the
#: tolerance of a file's own rate against the manifest's).
NATURAL_FREQUENCY_AGREEMENT = 1e-3


def _sidecar_natural_frequency(p: Path, line: int, row: ManifestRow) -> float | None:
    """The f_n of the row's sidecar ``<recording>.json`` (None: none), refused where the row
    gives another: a recording has one rig, and ``predict`` (which reads the sidecar) and
    the campaign's commands (which read the manifest) must not read it at two."""
    from stiffnet.recordings.sidecar import read_sidecar

    value, sidecar = read_sidecar(p.parent / row.recording)
    own = row.natural_frequency_hz
    if value is not None and own is not None:
        if not math.isclose(value, own, rel_tol=NATURAL_FREQUENCY_AGREEMENT):
            raise StiffnetError(
                f"{p}: line {line}, column natural_frequency_hz: {own:g} Hz disagrees with the "
                f"recording's sidecar {sidecar.name} ({value:g} Hz); a recording has one rig: "
                "mend one"
            )
    return value


#: Problems of a manifest a message spells out before counting the rest.
SHOWN_PROBLEMS = 5


def raise_problems(manifest: Path, problems: list[str]) -> None:
    """Raise one line naming every problem of ``manifest`` (the first few in full), if any.

    Each problem reads ``<manifest>: line N ...``; the ones after the first lose the
    repeated manifest path.
    """
    if not problems:
        return
    if len(problems) == 1:
        raise StiffnetError(problems[0])
    prefix = f"{manifest}: "
    rest = [q.removeprefix(prefix) for q in problems[1:SHOWN_PROBLEMS]]
    more = len(problems) - SHOWN_PROBLEMS
    tail = f"; and {more} more" if more > 0 else ""
    raise StiffnetError(f"{len(problems)} problems: {problems[0]}; also {'; '.join(rest)}{tail}")


def _check_header(
    p: Path, columns: list[str], line: int, written: list[str] | None = None
) -> list[str]:
    for i, col in enumerate(columns):
        if not col:
            raise StiffnetError(f"{p}: line {line}: column {i + 1} of the header has no name")
        if col not in COLUMNS:
            unit_hint = _unit_in_header(col, None if written is None else written[i])
            if unit_hint:
                raise StiffnetError(f"{p}: column {i + 1} {unit_hint}")
            if len(columns) == 1:
                _refuse_other_separator(p, col)
            hint = " (the file must be comma-separated)" if len(columns) == 1 else ""
            shown = quote_content(col) or f"{i + 1} (name not shown)"  # never echo a secret
            raise StiffnetError(
                f"{p}: unknown column {shown} (allowed: {', '.join(COLUMNS)}){hint}"
            )
    dup = sorted({c for c in columns if columns.count(c) > 1})
    if dup:
        raise StiffnetError(f"{p}: column {dup[0]!r} appears twice in the header")
    missing = [c for c in REQUIRED_COLUMNS if c not in columns]
    if missing:
        raise StiffnetError(f"{p}: missing required column {', '.join(missing)}")
    return columns


def _refuse_other_separator(p: Path, header: str) -> None:
    """A header of manifest columns joined by ``;`` or a tab (a spreadsheet's export where
    the decimal mark is a comma): said so, with how to save it, not 'unknown column 1
    (name not shown)' beside the list of every allowed column."""
    for sep, name in ((";", "';'"), ("\t", "tabs")):
        names = [c.strip() for c in header.split(sep)]
        if len(names) > 1 and all(c in COLUMNS for c in names):
            raise StiffnetError(
                f"{p}: the header's columns are separated by {name}, not commas "
                f"({', '.join(names[:3])}, ...); save the manifest comma-separated, with '.' "
                "as the decimal point"
            )


#: pydantic constraint errors, as ``(context key, operator)``.
_BOUNDS = {
    "greater_than": ("gt", ">"),
    "greater_than_equal": ("ge", ">="),
    "less_than": ("lt", "<"),
}
_MESSAGES = {"finite_number": "must be a finite number", "float_parsing": "not a number"}


def _validate_row(data: dict[str, Any], where: str) -> ManifestRow:
    try:
        return ManifestRow(**data)
    except ValidationError as exc:
        err = exc.errors()[0]
        col = ".".join(str(x) for x in err["loc"])
        kind = err["type"]
        if kind == "missing":
            raise StiffnetError(f"{where}, column {col}: a value is required") from None
        if kind in _BOUNDS:
            key, op = _BOUNDS[kind]
            msg = f"must be {op} {err['ctx'][key]}"
        else:
            msg = _MESSAGES.get(kind, err["msg"].removeprefix("Value error, "))
        if not col:  # a rule across columns
            raise StiffnetError(f"{where}: {msg}") from None
        got = quote_content(str(err["input"])) if isinstance(err["input"], str) else None
        got = f" (got {got})" if got else ""
        if kind == "float_parsing":  # '1000 Hz' in fs_hz: say what to write
            got += unit_hint(err["input"])
        raise StiffnetError(f"{where}, column {col}: {msg}{got}") from None


def write_manifest(
    path: str | os.PathLike[str],
    rows: Sequence[ManifestRow],
    columns: Sequence[str] | None = None,
) -> Path:
    """Write a manifest atomically (temporary file in the same folder + ``os.replace``).

    Parameters
    ----------
    path : str or os.PathLike
        Destination file.
    rows : sequence of ManifestRow
    columns : sequence of str, optional
        Columns to write, in order; default: the required columns and every
        optional column some row has a value for, in canonical order.

    Returns
    -------
    pathlib.Path
        The written path.
    """
    p = Path(path)
    if columns is None:
        used = {c for r in rows for c in COLUMNS if getattr(r, c) is not None}
        columns = [c for c in COLUMNS if c in REQUIRED_COLUMNS or c in used]
    columns = list(columns)
    unknown = [c for c in columns if c not in COLUMNS]
    if unknown:
        raise StiffnetError(f"{p}: unknown manifest column {unknown[0]!r}")
    for c in REQUIRED_COLUMNS:
        if c not in columns:
            raise StiffnetError(f"{p}: manifest column {c!r} is required")
    for r in rows:
        lost = [c for c in COLUMNS if c not in columns and getattr(r, c) is not None]
        if lost:
            raise StiffnetError(f"{p}: {r.recording}: column {lost[0]!r} has a value")
    p.parent.mkdir(parents=True, exist_ok=True)
    tmp = p.parent / f".{p.name}.{secrets.token_hex(4)}.tmp"
    try:
        with open(tmp, "w", encoding="utf-8", newline="") as fh:
            writer = csv.writer(fh, lineterminator="\n")
            writer.writerow(columns)
            for r in rows:
                writer.writerow([_cell(getattr(r, c)) for c in columns])
        os.replace(tmp, p)
    except BaseException:
        tmp.unlink(missing_ok=True)
        raise
    return p


def _cell(value: Any) -> str:
    if value is None:
        return ""
    if isinstance(value, float):
        text = repr(value)  # shortest round-trip form
        return text.removesuffix(".0")
    return str(value)


# ---------------------------------------------------------------------------- campaigns


@dataclass
class Campaign:
    """A loaded campaign: validated rows; recordings are read on access.

    Recordings are not cached (a campaign can be larger than memory): each
    :meth:`recording` call reads the file again.
    """

    folder: Path
    manifest_path: Path
    rows: list[ManifestRow]

    def __len__(self) -> int:
        return len(self.rows)

    def __iter__(self) -> Iterator[ManifestRow]:
        return iter(self.rows)

    def row(self, key: int | str) -> ManifestRow:
        """The row at index ``key`` or with ``recording == key``."""
        if isinstance(key, int):
            return self.rows[key]
        norm = posixpath.normpath(key.replace("\\", "/"))
        for r in self.rows:
            if r.recording == norm:
                return r
        raise StiffnetError(f"{self.manifest_path}: no recording {key!r} in the manifest")

    def path(self, key: int | str) -> Path:
        """Absolute path of a recording file."""
        row = self.row(key)
        return _inside(self.folder, row.recording, row.where(self.manifest_path))

    def recording(self, key: int | str) -> Recording:
        """Read one recording with the row's ``fs_hz`` (and ``channel``)."""
        row = self.row(key)
        try:
            return read_recording(
                self.path(key),
                fs_hz=row.fs_hz,
                channel=row.channel,
                columns=None if row.columns is None else row.columns.replace(";", ","),
                time_unit=row.time_unit,
            )
        except RateMismatch as exc:  # the row gave the rate: say which line to mend
            raise RateMismatch(f"{row.where(self.manifest_path)}, column fs_hz: {exc}") from None

    def recordings(self) -> Iterator[tuple[ManifestRow, Recording]]:
        """``(row, recording)`` pairs in manifest order, one file at a time."""
        for i, row in enumerate(self.rows):
            yield row, self.recording(i)

    @property
    def betas(self) -> np.ndarray:
        """Known stiffness ratios, NaN where the manifest gives none."""
        return np.array([np.nan if r.beta is None else r.beta for r in self.rows])

    @property
    def is_calibration(self) -> bool:
        """True when every recording has a known ``beta``."""
        return all(r.beta is not None for r in self.rows)


def load_campaign(folder: str | os.PathLike[str]) -> Campaign:
    """Load a campaign folder (or its manifest file) and check its recordings exist.

    Parameters
    ----------
    folder : str or os.PathLike
        The campaign folder holding ``manifest.csv``, or the manifest itself
        (recordings are then relative to the manifest's folder).

    Returns
    -------
    Campaign

    Raises
    ------
    StiffnetError
        No manifest, an invalid manifest, a recording path leaving the folder
        (symbolic links included) or a recording file that does not exist.
    """
    p = Path(folder)
    if p.is_file():
        manifest, p = p, p.parent
    elif p.is_dir():
        manifest = p / MANIFEST_NAME
        if not manifest.is_file():
            raise StiffnetError(
                f"{p}: not a campaign folder (no {MANIFEST_NAME}){_manifest_below_hint(p)}"
            )
    else:
        raise StiffnetError(f"{p}: campaign folder not found")
    rows = read_manifest(manifest)
    root = p.resolve()
    problems = []
    for row in rows:
        path = _inside(root, row.recording, row.where(manifest))
        if not path.is_file():
            problems.append(
                f"{row.where(manifest)}: recording file not found: {path}{case_twin_hint(path)}"
            )
    raise_problems(manifest, problems)
    return Campaign(root, manifest, rows)


def unlisted_recordings(manifest: str | os.PathLike[str], listed: Sequence[str]) -> list[str]:
    """Recording files in a campaign's folder that its manifest does not list.

    A folder a lab filled holds what it recorded; a row left out of the manifest (a missing
    line in the export) made the file's recording vanish from every result in silence.

    Parameters
    ----------
    manifest : str or os.PathLike
        The campaign's ``manifest.csv``; its folder is searched (bounded, links not
        followed, hidden files and folders skipped).
    listed : sequence of str
        The recordings the manifest lists, relative to its folder.

    Returns
    -------
    list of str
        The unlisted files of a registered recording format, relative to the folder, sorted;
        empty where the folder is too large to search
        (:data:`stiffnet.inputs.MAX_WALK_ENTRIES`).
    """
    from stiffnet.inputs import walk_files
    from stiffnet.recordings import supported_extensions

    m = Path(manifest)
    folder = m.parent
    known = {(folder / r).resolve() for r in listed} | {m.resolve()}
    try:
        files = walk_files(str(folder), what="campaign folder")
    except StiffnetError:  # too large to search: nothing said rather than a refusal
        return []
    kinds = supported_extensions()
    found = []
    for f in files:
        rel = f.relative_to(folder)
        if any(part.startswith(".") for part in rel.parts) or f.suffix.lower() not in kinds:
            continue
        if f.resolve() not in known:
            found.append(rel.as_posix())
    return sorted(found)


def unlisted_words(unlisted: Sequence[str]) -> str | None:
    """The warning for recording files the manifest does not list (None: none)."""
    if not unlisted:
        return None
    shown = ", ".join(unlisted[:3]) + (", ..." if len(unlisted) > 3 else "")
    return (
        f"{len(unlisted)} recording file(s) in the campaign folder are not in its manifest "
        f"({shown}): not read; a row for each reads it"
    )


#: Entries of a folder looked at for a manifest one level down (a folder of recordings
#: alone can hold many: the hint must not cost a scan of them all).
_MANIFEST_BELOW_ENTRIES = 1000


def _manifest_below_hint(folder: Path) -> str:
    """Where a folder without a manifest has one in a subfolder (``meta/manifest.csv`` whose
    paths climb out with ``../``): where a campaign's manifest must sit."""
    try:
        below = [
            e.name
            for e in itertools.islice(folder.iterdir(), _MANIFEST_BELOW_ENTRIES)
            if not e.name.startswith(".") and (e / MANIFEST_NAME).is_file()
        ]
    except OSError:
        return ""
    if not below:
        return ""
    return (
        f" ({below[0]}/{MANIFEST_NAME} is one, but a campaign is the folder its manifest sits "
        "in, its recordings' paths starting there without '..': move it here and write its "
        "paths from here)"
    )


def campaign_row_of(recording: str | os.PathLike[str]) -> tuple[Path, ManifestRow] | None:
    """The manifest row listing ``recording`` in the campaign it sits in, and the manifest.

    The campaign is the nearest folder above the recording holding a ``manifest.csv``
    (a campaign folder, docs/campaign.md); None where there is none or it does not list the
    file. ``predict`` on one recording of a campaign reads it as ``predict-batch`` does.

    Raises
    ------
    StiffnetError
        That manifest does not read (its problems, naming it: it is the recording's
        campaign, so a broken row there is not passed over in silence).
    """
    manifest = campaign_manifest_above(recording)
    if manifest is None:
        return None
    path = Path(recording).resolve()
    try:
        rows = read_manifest(manifest)
    except StiffnetError as exc:  # the user asked for a recording: say why a manifest is read
        raise StiffnetError(
            f"{exc} (the manifest of the campaign {Path(recording).name} sits in, read for its "
            "row: fix it, or copy the recording out of the folder to read it alone)"
        ) from None
    for row in rows:
        if (manifest.parent / row.recording).resolve() == path:
            return manifest, row
    return None


def campaign_manifest_above(recording: str | os.PathLike[str]) -> Path | None:
    """The ``manifest.csv`` of the campaign folder a recording sits in: the nearest folder
    above it holding one (None: none). Read for the recording's row, and never written
    over by a command reading the recording."""
    for folder in Path(recording).resolve().parents:
        if (folder / MANIFEST_NAME).is_file():
            return folder / MANIFEST_NAME
    return None


def _inside(root: Path, relative: str, where: str) -> Path:
    """``root / relative`` resolved, refusing anything outside ``root``."""
    root = root.resolve()
    path = (root / relative).resolve()
    if not path.is_relative_to(root):
        raise StiffnetError(f"{where}: recording path leaves the campaign folder ({path})")
    return path

"""Campaigns: a folder of recordings described by a ``manifest.csv``.

A campaign is how users bring measurements to stiffnet (see ``docs/campaign.md``)::

    my_campaign/
        manifest.csv          recording,fs_hz[,natural_frequency_hz,...,beta]
        run01.csv             t,accel   (or .npy / .wav / .tdms)
        day2/run02.tdms

:func:`simulate_campaign` turns a manifest of parameters into a synthetic
campaign with the same layout, plus a ``campaign_card.json`` holding the ground
truth that a real campaign would not tell (the effects and their drawn values).
"""

from __future__ import annotations

import csv
import json
import math
import os
import posixpath
import secrets
import shutil
import zlib
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
    field_validator,
    model_validator,
)

from stiffnet.effects.base import Effect
from stiffnet.errors import StiffnetError
from stiffnet.inputs import quote_content
from stiffnet.io_utils import check_replaceable_folder, output_lock
from stiffnet.progress import task as progress_task
from stiffnet.recordings import Recording, read_recording, write_recording_csv
from stiffnet.simulator.batch import PAPER_NATURAL_FREQUENCY_HZ

MANIFEST_NAME = "manifest.csv"
CARD_NAME = "campaign_card.json"
#: Columns every manifest has.
REQUIRED_COLUMNS = ("recording", "fs_hz")
#: Columns :func:`simulate_campaign` needs besides the required ones.
SIMULATION_COLUMNS = ("beta", "gap", "amplitude", "frequency_ratio", "damping_ratio")
#: White-noise level (fraction of ``a w^2``) of simulated rows without ``noise``.
DEFAULT_NOISE = 0.02
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
        return norm

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
    return _read_manifest(Path(path))[1]


def _read_manifest(p: Path) -> tuple[list[str], list[ManifestRow]]:
    """The manifest's columns (as written) and its rows."""
    if not p.is_file():
        raise StiffnetError(f"{p}: manifest not found")
    try:
        with open(p, encoding="utf-8-sig", newline="") as fh:  # -sig: Excel's BOM
            reader = csv.reader(fh)
            header = next((r for r in reader if any(c.strip() for c in r)), None)
            if header is None:
                raise StiffnetError(f"{p}: manifest is empty (expected a header line)")
            columns = _check_header(p, [c.strip().lower() for c in header], reader.line_num)
            rows: list[ManifestRow] = []
            seen: dict[str, int] = {}
            for cells in reader:
                line = reader.line_num
                if not any(c.strip() for c in cells):
                    continue
                if len(cells) != len(columns):
                    raise StiffnetError(
                        f"{p}: line {line} has {len(cells)} cells, expected {len(columns)} "
                        f"({','.join(columns)})"
                    )
                data = {c: v.strip() for c, v in zip(columns, cells, strict=True) if v.strip()}
                row = _validate_row(data, f"{p}: line {line}")
                row._line = line
                if row.recording in seen:
                    raise StiffnetError(
                        f"{p}: line {line}: recording {row.recording!r} is listed twice "
                        f"(also on line {seen[row.recording]})"
                    )
                seen[row.recording] = line
                rows.append(row)
    except UnicodeDecodeError:
        raise StiffnetError(f"{p}: manifest is not a UTF-8 text file") from None
    except csv.Error as exc:
        raise StiffnetError(f"{p}: malformed CSV ({exc})") from None
    if not rows:
        raise StiffnetError(f"{p}: manifest lists no recordings (only a header)")
    return columns, rows


def _check_header(p: Path, columns: list[str], line: int) -> list[str]:
    for i, col in enumerate(columns):
        if not col:
            raise StiffnetError(f"{p}: line {line}: column {i + 1} of the header has no name")
        if col not in COLUMNS:
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
        return read_recording(
            self.path(key),
            fs_hz=row.fs_hz,
            channel=row.channel,
            columns=None if row.columns is None else row.columns.replace(";", ","),
            time_unit=row.time_unit,
        )

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
            raise StiffnetError(f"{p}: not a campaign folder (no {MANIFEST_NAME})")
    else:
        raise StiffnetError(f"{p}: campaign folder not found")
    rows = read_manifest(manifest)
    root = p.resolve()
    for row in rows:
        path = _inside(root, row.recording, row.where(manifest))
        if not path.is_file():
            raise StiffnetError(f"{row.where(manifest)}: recording file not found: {path}")
    return Campaign(root, manifest, rows)


def _inside(root: Path, relative: str, where: str) -> Path:
    """``root / relative`` resolved, refusing anything outside ``root``."""
    root = root.resolve()
    path = (root / relative).resolve()
    if not path.is_relative_to(root):
        raise StiffnetError(f"{where}: recording path leaves the campaign folder ({path})")
    return path


# --------------------------------------------------------------------------- simulation


def sensor_gain(natural_frequency_hz: float) -> float:
    """Model acceleration to g, for a model length unit of 1 mm.

    Model time is ``2 pi f_n t``, so one model unit of acceleration is
    ``L (2 pi f_n)^2`` m/s^2 with ``L`` the length unit. Any positive factor
    would do: stiffnet does not depend on the sensor gain.
    """
    return MODEL_LENGTH_UNIT_M * (2 * math.pi * natural_frequency_hz) ** 2 / STANDARD_GRAVITY


def simulate_campaign(
    manifest_path: str | os.PathLike[str],
    out_dir: str | os.PathLike[str],
    effects: Sequence[Effect | str] = (),
    seed: int = 0,
    default_duration_s: float = 10.0,
    overwrite: bool = False,
    *,
    scheduler: str | None = None,
    workers: int | None = None,
) -> Path:
    """Simulate one recording per manifest row: a synthetic campaign.

    Each row needs ``beta``, ``gap``, ``amplitude``, ``frequency_ratio`` and
    ``damping_ratio``; ``natural_frequency_hz`` defaults to the paper's
    9.48 Hz, ``duration_s`` to ``default_duration_s`` and ``noise`` to
    :data:`DEFAULT_NOISE`. Rows are simulated one at a time by
    :class:`~stiffnet.simulator.Simulator` with the given effects, sampled at
    ``fs_hz`` (``fs_ratio = fs_hz / f_n``), and written in g (see
    :func:`sensor_gain`) under the row's relative name (``.csv`` as ``t,accel``,
    or ``.npy``).

    The output folder holds the recordings, ``manifest.csv`` (the input's
    columns and values) and ``campaign_card.json`` (the ground truth a real
    campaign would not tell: effects, their per-recording drawn values, gains,
    seed, stiffnet version). It is built in a hidden sibling folder and moved
    into place at the end, so an interrupted run leaves nothing that looks
    complete.

    Parameters
    ----------
    manifest_path : str or os.PathLike
        Input manifest (its recordings need not exist).
    out_dir : str or os.PathLike
        Folder to create.
    effects : sequence of Effect or str
        Effects to simulate with; a string is parsed as ``NAME[:k=v,...]``.
    seed : int
        Base seed. Each row draws from ``(seed, crc32(recording))``: the same
        seed gives identical files, whatever the order of the rows.
    default_duration_s : float
        Duration of rows without ``duration_s``.
    overwrite : bool
        Replace ``out_dir`` if it exists and is not empty.
    scheduler, workers : str or None, int or None
        Simulate the rows as Dask tasks on this scheduler, or on a LocalCluster of
        this many worker processes (see :mod:`stiffnet.distributed`); by default
        in-process. The files are the same either way: a row depends only on
        ``(seed, recording)``, and the recordings are written here, not on workers.

    Returns
    -------
    pathlib.Path
        ``out_dir``.
    """
    from stiffnet.distributed.cluster import check_target

    manifest = Path(manifest_path)
    out = Path(out_dir).resolve()  # a real name and parent, even for "." or "a/.."
    if not isinstance(seed, int | np.integer) or isinstance(seed, bool) or seed < 0:
        raise StiffnetError(f"seed must be a non-negative integer, got {seed!r}")
    if not (math.isfinite(default_duration_s) and default_duration_s > 0):
        raise StiffnetError(f"default_duration_s must be > 0, got {default_duration_s}")
    check_target(scheduler, workers)
    columns, rows = _read_manifest(manifest)
    with output_lock(out):  # one writer per folder: a concurrent run is refused
        _check_out_dir(out, manifest, overwrite)
        _simulate_into(manifest, out, columns, rows, effects, seed, default_duration_s,
                       scheduler, workers)  # fmt: skip
    return Path(out_dir)


def _simulate_into(
    manifest: Path,
    out: Path,
    columns: list[str],
    rows: list[ManifestRow],
    effects: Sequence[Effect | str],
    seed: int,
    default_duration_s: float,
    scheduler: str | None,
    workers: int | None,
) -> None:
    from stiffnet import __version__
    from stiffnet.distributed.tasks import run_tasks
    from stiffnet.effects.registry import build_effect, parse_effect_option
    from stiffnet.simulator.compiled import limited_threads

    eff = [build_effect(*parse_effect_option(e)) if isinstance(e, str) else e for e in effects]

    # Check every row before simulating anything.
    for row in rows:
        missing = [c for c in SIMULATION_COLUMNS if getattr(row, c) is None]
        if missing:
            raise StiffnetError(
                f"{row.where(manifest)}: column {', '.join(missing)} is required for simulation"
            )
        if Path(row.recording).suffix.lower() not in (".csv", ".npy"):
            raise StiffnetError(
                f"{row.where(manifest)}: simulated recordings are .csv or .npy files"
            )
        if row.recording in (MANIFEST_NAME, CARD_NAME):
            raise StiffnetError(f"{row.where(manifest)}: {row.recording} is a reserved name")
        duration = row.duration_s or default_duration_s
        if round(duration * row.fs_hz) < 2:
            raise StiffnetError(f"{row.where(manifest)}: duration_s * fs_hz is under 2 samples")

    # Simulate first (rows as tasks, results back here), then write: workers need no
    # access to the output folder, and a failed row leaves nothing behind.
    jobs = [_RowJob(row, eff, int(seed), default_duration_s, row.where(manifest)) for row in rows]
    with progress_task("simulating recordings", len(jobs)) as bar:
        report = run_tasks(simulate_row, jobs, scheduler=scheduler, workers=workers,
                           names=[row.recording for row in rows], thread_limit=limited_threads,
                           progress=lambda done, _: bar.update(done))  # fmt: skip
    if report.failed:
        name, msg = next(iter(report.failed.items()))
        raise StiffnetError(msg) from report.errors.get(name)
    out.parent.mkdir(parents=True, exist_ok=True)
    tmp = out.parent / f".{out.name}.{secrets.token_hex(4)}.partial"
    tmp.mkdir()
    try:
        card_rows = []
        for row, (accel, card_row) in zip(rows, report.results, strict=True):
            target = tmp / row.recording
            if target.suffix.lower() == ".npy":
                target.parent.mkdir(parents=True, exist_ok=True)
                np.save(target, accel)
            else:
                write_recording_csv(target, accel, row.fs_hz)
            card_rows.append(card_row)
        # simulated CSVs are written as t,accel in seconds: drop the input's read options
        plain = [r.model_copy(update=dict.fromkeys(READ_COLUMNS)) for r in rows]
        write_manifest(tmp / MANIFEST_NAME, plain, [c for c in columns if c not in READ_COLUMNS])
        card = {
            "stiffnet_version": __version__,
            "generator": "stiffnet.campaign.simulate_campaign",
            "source_manifest": manifest.name,
            "seed": int(seed),
            "default_duration_s": default_duration_s,
            "accel_unit": "g, for a model length unit of 1 mm (sensor_gain = model to g)",
            "effects": [
                {
                    "name": e.name,
                    "class": f"{type(e).__module__}:{type(e).__qualname__}",
                    "kind": e.kind,
                    "params": e.params.model_dump(),
                }
                for e in eff
            ],
            "recordings": card_rows,
        }
        (tmp / CARD_NAME).write_text(json.dumps(card, indent=2) + "\n", encoding="utf-8")
        _swap_in(tmp, out)
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise


@dataclass(frozen=True)
class _RowJob:
    """One campaign row to simulate (a task: picklable, independent of the others)."""

    row: ManifestRow
    effects: list[Effect]
    seed: int
    default_duration_s: float
    where: str


def simulate_row(job: _RowJob) -> tuple[np.ndarray, dict[str, Any]]:
    """Simulate one campaign row: the recording in g and its entry of the campaign card."""
    from stiffnet.simulator.batch import PAPER_NATURAL_FREQUENCY_HZ, OscillatorBatch
    from stiffnet.simulator.simulator import Simulator

    row = job.row
    f_n = row.natural_frequency_hz or PAPER_NATURAL_FREQUENCY_HZ
    duration = row.duration_s or job.default_duration_s
    noise = DEFAULT_NOISE if row.noise is None else row.noise
    entropy = [job.seed, zlib.crc32(row.recording.encode())]
    try:
        batch = OscillatorBatch.single(
            row.beta, row.gap, row.amplitude, row.frequency_ratio, row.damping_ratio, f_n
        )
        res = Simulator(job.effects).simulate(
            batch,
            fs_ratio=row.fs_hz / f_n,
            n_samples=int(round(duration * row.fs_hz)),
            noise=noise,
            rng=np.random.default_rng(entropy),
        )
    except StiffnetError as exc:
        raise StiffnetError(f"{job.where}: {exc}") from None
    gain = sensor_gain(f_n)
    accel = res.accel[0] * gain
    entry = {
        "recording": row.recording,
        "seed_entropy": entropy,
        "n_samples": int(accel.size),
        "fs_hz": row.fs_hz,
        "natural_frequency_hz": f_n,
        "fs_ratio": row.fs_hz / f_n,
        "noise": noise,
        "sensor_gain": gain,
        "engine": res.engine,
        "n_impacts": int(res.impacts.sum()),
        "effects": {
            name: {k: float(v[0]) for k, v in params.items()}
            for name, params in res.effect_params.items()
        },
    }
    return accel, entry


def _check_out_dir(out: Path, manifest: Path, overwrite: bool) -> None:
    if not out.exists():
        return
    if not out.is_dir():
        raise StiffnetError(f"{out}: exists and is not a folder")
    if not any(out.iterdir()):
        return
    if not overwrite:
        raise StiffnetError(f"{out}: folder exists and is not empty (use overwrite to replace it)")
    if manifest.resolve().is_relative_to(out.resolve()):
        raise StiffnetError(f"{out}: refusing to overwrite the folder holding the input manifest")
    check_replaceable_folder(out, (CARD_NAME,))  # only a campaign stiffnet wrote is replaced


def _swap_in(tmp: Path, out: Path) -> None:
    """Move the finished ``tmp`` folder to ``out``, replacing what is there."""
    if not out.exists():
        os.replace(tmp, out)
        return
    old = out.parent / f".{out.name}.{secrets.token_hex(4)}.old"
    os.replace(out, old)
    try:
        os.replace(tmp, out)
    except BaseException:
        os.replace(old, out)
        raise
    shutil.rmtree(old, ignore_errors=True)

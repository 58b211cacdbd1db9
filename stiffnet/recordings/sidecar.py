"""The sidecar ``<recording>.json``: what a recording's file does not say (f_n, the sensor).

One home for the sidecar: the commands (``analyze``, ``predict``, ``log``,
``predict-batch``) and the predictor resolve a recording's natural frequency through
:func:`natural_frequency_of` (the option, else the sidecar, else the manifest row of the
campaign listing the recording), so each says the same about where the value came from.
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import Any

from stiffnet.inputs import natural_frequency, read_json

#: Suffix of the sidecar JSON of a recording: ``run01.csv`` -> ``run01.csv.json``.
SIDECAR_SUFFIX = ".json"


def sidecar_path(recording: str | os.PathLike[str]) -> Path:
    """Where a recording's sidecar lives: ``run01.csv`` -> ``run01.csv.json``."""
    return Path(str(recording) + SIDECAR_SUFFIX)


def sidecar_entry(recording: str | os.PathLike[str], key: str) -> object | None:
    """One entry of the recording's sidecar (None without a sidecar or without the key).

    Read here, bounded and depth-checked like every user JSON, so that every part of
    the sidecar (f_n here, the sensor chain's data sheet in the restoring-force check) comes
    from one reader.
    """
    p = sidecar_path(recording)
    if not p.is_file():
        return None
    d = read_json(p, "sidecar")
    return d.get(key) if isinstance(d, dict) else None


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
    p = sidecar_path(recording)
    value = sidecar_entry(recording, "natural_frequency_hz")
    if value is None:
        return None, p
    return natural_frequency(value, f"{p}: natural_frequency_hz"), p


def natural_frequency_of(
    recording: str | os.PathLike[str] | None,
    given_hz: float | None,
    option: str = "--fn",
    *,
    campaign_row: tuple[Path, Any] | None = None,
    find_row: bool = True,
) -> tuple[float | None, str]:
    """A recording's f_n and where it came from: the option, else its sidecar, else the row
    of the campaign manifest listing it (:func:`stiffnet.campaign.manifest.campaign_row_of`).

    ``campaign_row``: that ``(manifest, row)`` when the caller has already read it (None: it
    lists none); ``find_row=False`` then keeps the manifest from being parsed again.

    Returns
    -------
    (float or None, str)
        The value in Hz (range-checked) and its source: ``"option --fn"``,
        ``"sidecar:<path>"``, ``"manifest:<manifest>: line N (<recording>)"``, or
        ``(None, "unknown")`` when none gives it (the caller decides whether that is a
        refusal).
    """
    if given_hz is not None:
        return natural_frequency(given_hz, option), f"option {option}"
    if recording is not None:
        value, sidecar = read_sidecar(recording)
        if value is not None:
            return value, f"sidecar:{sidecar}"
        listed = campaign_row
        if listed is None and find_row:
            from stiffnet.campaign.manifest import campaign_row_of  # the campaign reads files

            listed = campaign_row_of(recording)
        if listed is not None and listed[1].natural_frequency_hz is not None:
            manifest, row = listed
            return row.natural_frequency_hz, row.natural_frequency_source(manifest)
    return None, "unknown"

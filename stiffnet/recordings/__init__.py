"""Recordings: one accelerometer channel from a file, whatever its format.

A recording is one channel sampled at a uniform rate. The format is chosen by the
file's extension among the registered readers (:mod:`.registry`): one module per
format in this package (``csv``, ``npy``, ``wav``, ``tdms``), each a
:class:`~.base.RecordingReader` (the extensions it claims, a one-line
description, whether the file carries its rate, how it lists and reads channels).
Adding a format is one new module here, or :func:`register_reader` from elsewhere.
A file with several channels and no ``channel`` is refused with one line listing
them: reading the first one in silence gave a force channel's "no contact" for a
LabVIEW file whose acceleration was the second.

What every format shares is here once: the check of a rate (:func:`check_rate`,
and a file's own rate against a given one, :data:`FS_TOLERANCE`), the sidecar
``<recording>.json`` (:mod:`.sidecar`), at least two finite samples
(:func:`read_recording`). The package imports no numpy, scipy, pyarrow or npTDMS
until a file is read (the command line's help lists the formats at no cost); it
depends on numpy, scipy, pyarrow and npTDMS only, so that the light ONNX predictor
can use it.
"""

from __future__ import annotations

from typing import Any

from stiffnet.recordings.base import (
    FS_TOLERANCE,
    Recording,
    RecordingReader,
    Samples,
    check_agreement,
    check_rate,
)
from stiffnet.recordings.csv import (
    CSV_COLUMNS,
    TIME_JITTER_TOLERANCE,
    TIME_UNITS,
    unit_mistake_hint,
    write_recording_csv,
)
from stiffnet.recordings.read import read_recording
from stiffnet.recordings.registry import (
    channels_help,
    formats_help,
    rate_needed_for,
    reader_for,
    readers,
    register_reader,
    require_rate,
    supported_extensions,
    unregister_reader,
)
from stiffnet.recordings.sidecar import (
    SIDECAR_SUFFIX,
    natural_frequency_of,
    read_sidecar,
    sidecar_entry,
    sidecar_path,
)

__all__ = [
    "CSV_COLUMNS",
    "FS_TOLERANCE",
    "SIDECAR_SUFFIX",
    "SUPPORTED_EXTENSIONS",
    "TIME_JITTER_TOLERANCE",
    "TIME_UNITS",
    "Recording",
    "RecordingReader",
    "Samples",
    "check_agreement",
    "check_rate",
    "channels_help",
    "formats_help",
    "natural_frequency_of",
    "rate_needed_for",
    "read_recording",
    "read_sidecar",
    "sidecar_entry",
    "reader_for",
    "readers",
    "register_reader",
    "require_rate",
    "sidecar_path",
    "supported_extensions",
    "unit_mistake_hint",
    "unregister_reader",
    "write_recording_csv",
]


def __getattr__(name: str) -> Any:
    # the extensions of the formats registered now (a plugin may add one later)
    if name == "SUPPORTED_EXTENSIONS":
        return supported_extensions()
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")

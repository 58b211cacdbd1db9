"""``read_recording``: what every format shares around its reader.

The given rate is checked once (:func:`~stiffnet.recordings.base.check_rate`), the
reader is picked by extension from the registry, a blank channel means none, layout
options reach only the formats that declare them, and every recording has at least
two samples, all finite.
"""

from __future__ import annotations

import os
from collections.abc import Sequence
from pathlib import Path

from stiffnet.errors import StiffnetError
from stiffnet.recordings.base import Recording, check_rate
from stiffnet.recordings.registry import reader_for, readers


def read_recording(
    path: str | os.PathLike[str],
    fs_hz: float | None = None,
    channel: str | int | None = None,
    *,
    columns: str | Sequence[str | int] | None = None,
    time_unit: str | None = None,
) -> Recording:
    """Read one acceleration channel from a recording file of a registered format.

    Parameters
    ----------
    path : str or os.PathLike
        The file; its extension selects the format
        (:func:`stiffnet.recordings.registry.formats_help`).
    fs_hz : float, optional
        Sampling rate in Hz. Required for a format whose file has none (``.npy``);
        for the others the file's own rate is used and must agree with it when
        both are known.
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
    import numpy as np

    p = Path(path)
    if fs_hz is not None:
        fs_hz = check_rate(fs_hz, str(p))
    reader = reader_for(p)
    if not p.is_file():
        raise StiffnetError(f"{p}: recording file not found{case_twin_hint(p)}")
    if channel is not None and str(channel).strip() == "":
        channel = None
    options = {"columns": columns, "time_unit": time_unit}
    for what, value in options.items():
        if value is not None and what not in reader.options:
            takers = [r.name for r in readers() if what in r.options] or ["no"]
            raise StiffnetError(
                f"{p}: '{what}' applies to {'/'.join(takers)} recordings only, "
                f"not {p.suffix.lower()}"
            )
    given = {k: v for k, v in options.items() if k in reader.options}
    samples = reader.read(p, fs_hz, channel, **given)
    accel, source = samples.accel, samples.source
    if accel.size < 2:
        what = "is empty" if accel.size == 0 else "has only one sample"
        raise StiffnetError(f"{source}: recording {what} (need at least 2 samples)")
    bad = ~np.isfinite(accel)
    if np.any(bad):
        raise StiffnetError(
            f"{source}: {int(bad.sum())} NaN/inf samples (first at sample {int(np.argmax(bad))})"
        )
    return Recording(accel, samples.fs_hz, source)


def case_twin_hint(path: str | os.PathLike[str]) -> str:
    """Where a missing file, or the first missing folder above it, has a twin differing only
    in letter case (a path typed on Windows or macOS, whose file systems ignore case): the
    name to write, to append to the refusal; else empty.

    Parameters
    ----------
    path : str or os.PathLike
        The file not found.

    Returns
    -------
    str
        ``" (the folder holds 'rec', ...)"`` or ``""``.
    """
    p = Path(path)
    missing, parent = p, p.parent
    while not parent.exists() and parent != parent.parent:  # the topmost missing name
        missing, parent = parent, parent.parent
    try:
        twins = [q.name for q in parent.iterdir() if q.name.lower() == missing.name.lower()]
    except OSError:  # unreadable: nothing to compare
        return ""
    if len(twins) != 1:
        return ""
    whose = "" if missing == p else f" (where {missing.name!r} was written)"
    return (
        f" (the folder holds {twins[0]!r}{whose}, which differs only in letter case: names "
        "are case-sensitive here)"
    )

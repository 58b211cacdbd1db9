"""LabVIEW TDMS recordings, read with npTDMS (imported only when a file is read).

The one channel holding data, or ``channel`` (``"name"``, ``"group/name"`` or the
index among the channels holding data). The rate comes from the channel's
``wf_increment`` property when present, else it must be given.
"""

from __future__ import annotations

import math
import threading
from pathlib import Path
from typing import Any

from stiffnet.errors import StiffnetError
from stiffnet.inputs import where_given
from stiffnet.recordings.base import (
    RecordingReader,
    Samples,
    brief,
    check_agreement,
    choose_channel,
)

#: npTDMS's log level is global state: set it under a lock.
_TDMS_LOCK = threading.Lock()


class TdmsReader(RecordingReader):
    """National Instruments TDMS files (groups of named channels)."""

    name = "TDMS"
    extensions = (".tdms",)
    channel_help = "a channel name, group/name, or index among those holding data"
    description = "LabVIEW file, one channel (see channel), rate from wf_increment or given"

    def channels(self, path: Path) -> list[str]:
        """``group/name`` of every channel holding data."""
        return [f"{g}/{c.name}" for g, c in _channels(path) if len(c) > 0]

    def read(self, path: Path, fs_hz: float | None, channel: str | int | None, **_: Any) -> Samples:
        import numpy as np

        name = str(path)
        channels = _channels(path)
        group, chan = _pick(channels, channel, name)
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
            fs = check_agreement(
                file_fs,
                fs_hz,
                f"{source}: wf_increment gives fs = {file_fs:.6g} Hz but fs_hz = "
                f"{fs_hz or 0:.6g} Hz",
            )
        if fs is None:
            rate = where_given("--fs HZ", "the manifest's column fs_hz", "the field fs_hz")
            raise StiffnetError(f"{source}: sampling rate missing (no wf_increment; give {rate})")
        return Samples(np.asarray(data, dtype=np.float64), fs, source)


def _channels(path: Path) -> list[tuple[str, Any]]:
    """Every ``(group name, channel)`` of the file."""
    import logging  # here: the CLI's help imports this module (logging costs ~7 ms)

    try:
        from nptdms import TdmsFile
        from nptdms.log import log_manager
    except ImportError:  # pragma: no cover - npTDMS is a core dependency
        raise StiffnetError(f"{path}: reading .tdms needs the npTDMS package") from None
    with open(path, "rb") as fh:  # npTDMS reads any bytes as an empty file
        if fh.read(4) != b"TDSm":
            raise StiffnetError(f"{path}: not a readable TDMS file (no 'TDSm' lead-in)")
    # npTDMS logs warnings on stderr for corrupt files, which would break the
    # one-line errors: silence them while reading.
    with _TDMS_LOCK:
        level = log_manager.log_level
        log_manager.set_level(logging.ERROR)
        try:
            tdms = TdmsFile.read(path)
        except Exception as exc:  # npTDMS raises assorted types on corrupt files
            raise StiffnetError(f"{path}: not a readable TDMS file ({brief(exc)})") from None
        finally:
            log_manager.set_level(level)
    return [(g.name, c) for g in tdms.groups() for c in g.channels()]


def _pick(channels: list[tuple[str, Any]], channel: str | int | None, name: str) -> tuple:
    """The channel asked for, or the one holding data; refused with the list otherwise."""
    with_data = [(g, c) for g, c in channels if len(c) > 0]
    if channel is None:
        if not with_data:
            raise StiffnetError(f"{name}: recording is empty (no TDMS channel holds data)")
        if len(with_data) > 1:
            listed = ", ".join(f"{g}/{c.name}" for g, c in with_data)
            raise StiffnetError(
                f"{name}: {len(with_data)} channels hold data ({listed}); " + choose_channel("NAME")
            )
        return with_data[0]
    want = str(channel)
    found = [(g, c) for g, c in channels if want in (c.name, f"{g}/{c.name}")]
    if not found and want.isdigit() and int(want) < len(with_data):
        found = [with_data[int(want)]]  # an index among the channels holding data
    if not found:
        listed = ", ".join(f"{g}/{c.name}" for g, c in channels) or "none"
        raise StiffnetError(f"{name}: no TDMS channel {want!r} (channels: {listed})")
    if len(found) > 1:
        raise StiffnetError(f"{name}: channel name {want!r} is ambiguous, use 'group/name'")
    return found[0]

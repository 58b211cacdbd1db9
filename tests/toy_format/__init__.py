"""A toy recording format defined outside the library: one number per line (``.txt``).

An optional first line ``# fs_hz = 5000`` carries the rate; without it the rate must
be given. It joins through :func:`stiffnet.recordings.register_reader` and nothing in
the library names it (tests/test_recording_formats.py).
"""

from __future__ import annotations

import re
from pathlib import Path
from typing import Any

import numpy as np

from stiffnet.errors import StiffnetError
from stiffnet.recordings import RecordingReader, Samples, check_agreement, check_rate

_RATE_LINE = re.compile(r"#\s*fs_hz\s*=\s*(\S+)\s*$")


class TextColumnReader(RecordingReader):
    """One acceleration value per line, an optional ``# fs_hz = …`` first line."""

    extensions = (".txt",)
    name, channel_help = "TXT", "none (one channel)"
    description = "one value per line, rate from a '# fs_hz = …' first line or given"

    def channels(self, path: Path) -> list[str]:
        return ["0"]

    def read(self, path: Path, fs_hz: float | None, channel: str | int | None, **_: Any) -> Samples:
        lines = path.read_text(encoding="utf-8").splitlines()
        match = _RATE_LINE.match(lines[0]) if lines else None
        fs = fs_hz
        if match:
            own = check_rate(match.group(1), f"{path} line 1")
            fs = check_agreement(own, fs_hz, f"{path}: line 1 says {own:g} Hz, not {fs_hz} Hz")
            lines = lines[1:]
        if fs is None:
            raise StiffnetError(f"{path}: sampling rate missing (no '# fs_hz' line; give fs_hz)")
        if channel not in (None, 0, "0"):
            raise StiffnetError(f"{path}: channel {channel!r} requested but the file has one")
        try:
            accel = np.array([float(x) for x in lines if x.strip()])
        except ValueError as exc:
            raise StiffnetError(f"{path}: {exc}") from None
        return Samples(accel, fs, str(path))


def write_text_recording(path: Path, accel: np.ndarray, fs_hz: float | None) -> Path:
    """Write ``accel`` one value per line (shortest round-trip repr), with the rate if given."""
    head = [f"# fs_hz = {fs_hz!r}"] if fs_hz is not None else []
    path.write_text("\n".join(head + [repr(float(x)) for x in accel]) + "\n", encoding="utf-8")
    return path

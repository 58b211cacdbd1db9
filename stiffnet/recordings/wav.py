"""WAV recordings: integer or float PCM; integers scaled to [-1, 1); rate from the file.

A multi-channel file needs ``channel`` (an index).
"""

from __future__ import annotations

import warnings
from pathlib import Path
from typing import Any

from stiffnet.errors import StiffnetError
from stiffnet.recordings.base import (
    RecordingReader,
    Samples,
    brief,
    channel_index,
    check_agreement,
    check_rate,
    choose_channel,
)


class WavReader(RecordingReader):
    """RIFF WAVE files through :func:`scipy.io.wavfile.read`."""

    name = "WAV"
    extensions = (".wav",)
    description = "integer or float PCM (integers scaled to [-1, 1)), rate from the file"

    def channels(self, path: Path) -> list[str]:
        """Channel indices."""
        _, data = _load(path)
        return [str(i) for i in range(data.shape[1] if data.ndim == 2 else 1)]

    def read(self, path: Path, fs_hz: float | None, channel: str | int | None, **_: Any) -> Samples:
        import numpy as np

        name = str(path)
        rate, data = _load(path)
        if data.ndim == 2 and data.shape[1] > 1 and channel is None:
            raise StiffnetError(
                f"{name}: {data.shape[1]} channels (0..{data.shape[1] - 1}); "
                + choose_channel("INDEX")
            )
        if data.ndim == 2:
            idx = channel_index(channel, data.shape[1], name, "WAV")
            data = data[:, idx]
            name = f"{name} (channel {idx})"
        elif channel not in (None, 0, "0"):
            raise StiffnetError(
                f"{name}: channel {channel!r} requested but the file has one channel"
            )
        if data.dtype == np.uint8:  # 8-bit WAV is offset binary
            accel = (data.astype(np.float64) - 128.0) / 128.0
        elif np.issubdtype(data.dtype, np.integer):
            accel = data.astype(np.float64) / float(2 ** (8 * data.dtype.itemsize - 1))
        else:
            accel = data.astype(np.float64)
        fs = check_rate(rate, f"{name} (WAV header)")
        fs = check_agreement(
            fs, fs_hz, f"{name}: the file says fs = {fs:.6g} Hz but fs_hz = {fs_hz or 0:.6g} Hz"
        )
        return Samples(accel, fs, name)


def _load(path: Path) -> tuple[int, Any]:
    from scipy.io import wavfile

    try:
        with warnings.catch_warnings():  # e.g. "chunk not understood": keep errors one line
            warnings.simplefilter("ignore", wavfile.WavFileWarning)
            return wavfile.read(path)
    except Exception as exc:  # noqa: BLE001 - a corrupt header raises assorted types
        raise StiffnetError(f"{path}: not a readable WAV file ({brief(exc)})") from None

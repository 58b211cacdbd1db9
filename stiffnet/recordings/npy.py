"""NumPy ``.npy`` recordings: a 1-D array, or 2-D ``(samples, channels)`` with ``channel``.

The file holds no rate: it must be given (``--fs``, the manifest's ``fs_hz``).
"""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING, Any

from stiffnet.errors import StiffnetError
from stiffnet.recordings.base import RecordingReader, Samples, brief, channel_index, choose_channel

if TYPE_CHECKING:
    import numpy as np


class NpyReader(RecordingReader):
    """``numpy.save`` arrays of real numbers (no pickles, no archives)."""

    name = "NPY"
    extensions = (".npy",)
    description = "a 1-D array or 2-D (samples, channels) with channel, no rate: give it"
    rate_in_file = False
    channel_help = "a column index"

    def channels(self, path: Path) -> list[str]:
        """Column indices of a 2-D array (one entry for a 1-D array)."""
        arr = _load(path, mmap=True)
        return [str(i) for i in range(arr.shape[1] if arr.ndim == 2 else 1)]

    def read(self, path: Path, fs_hz: float | None, channel: str | int | None, **_: Any) -> Samples:
        import numpy as np

        name = str(path)
        if fs_hz is None:
            raise StiffnetError(f"{name}: sampling rate missing (a .npy file needs fs_hz)")
        arr = _load(path)
        if arr.ndim == 2 and arr.shape[1] > 1:
            if channel is None:
                raise StiffnetError(
                    f"{name}: {arr.shape[1]} channels (columns 0..{arr.shape[1] - 1} of shape "
                    f"{arr.shape}); " + choose_channel("INDEX")
                )
            idx = channel_index(channel, arr.shape[1], name, "NPY")
            arr, name = arr[:, idx], f"{name} (channel {idx})"
        elif arr.ndim == 2:
            arr = arr[:, 0]
        elif channel not in (None, 0, "0"):
            raise StiffnetError(
                f"{name}: channel {channel!r} requested but the file has one channel"
            )
        if arr.ndim != 1:
            raise StiffnetError(f"{name}: expected a 1-D array, got shape {arr.shape}")
        if not (np.issubdtype(arr.dtype, np.floating) or np.issubdtype(arr.dtype, np.integer)):
            raise StiffnetError(f"{name}: expected real numbers, got dtype {arr.dtype}")
        return Samples(arr.astype(np.float64), fs_hz, name)


def _load(path: Path, mmap: bool = False) -> np.ndarray:
    import numpy as np

    try:
        arr = np.load(path, allow_pickle=False, mmap_mode="r" if mmap else None)
    except Exception as exc:  # noqa: BLE001 - a corrupt header raises assorted types
        raise StiffnetError(f"{path}: not a readable .npy array ({brief(exc)})") from None
    if not isinstance(arr, np.ndarray):
        raise StiffnetError(f"{path}: expected one array, not an archive")
    return arr

"""The reader contract, the recording, and the one check of a sampling rate.

A format is a :class:`RecordingReader` subclass in its own module of this package
(pysindy style): the extensions it claims, a one-line description for help texts,
whether the file carries its own rate, the layout options it accepts, how it lists
a file's channels and how it reads one channel. :mod:`stiffnet.recordings.registry`
finds every reader; :func:`stiffnet.recordings.read_recording` does what every
format shares (the rate given, the extension, the channel, at least two finite
samples).

Every rate a recording carries or is given goes through :func:`check_rate` (a
number, finite, > 0) and, when the file has its own, :func:`check_agreement`
(within :data:`FS_TOLERANCE`). The physical range of a rate is a separate, later
question (:func:`stiffnet.inputs.sampling_rate`).
"""

from __future__ import annotations

import math
from abc import ABC, abstractmethod
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any, ClassVar

from stiffnet.errors import RateMismatch, StiffnetError
from stiffnet.inputs import where_given

if TYPE_CHECKING:
    import numpy as np

#: Relative tolerance between a given rate and the one a file carries.
FS_TOLERANCE = 1e-3


def check_rate(
    value: Any, where: str = "recording", error: type[StiffnetError] = StiffnetError
) -> float:
    """A sampling rate as a float: a number, finite and > 0.

    Parameters
    ----------
    value : Any
        The rate in Hz (a number or a numeric string).
    where : str
        What the message names first (the file, ``--fs``).
    error : type
        The error raised (a :class:`StiffnetError` subclass).

    Raises
    ------
    StiffnetError
        Not a number, or not finite and positive.
    """
    try:
        fs = float(value)
    except (TypeError, ValueError):
        raise error(f"{where}: sampling rate {value!r} is not a number") from None
    if not (math.isfinite(fs) and fs > 0):
        raise error(f"{where}: sampling rate must be > 0, got {fs}")
    return fs


def rates_agree(file_fs: float, given_fs: float) -> bool:
    """Whether a file's own rate and a given one agree within :data:`FS_TOLERANCE`."""
    return abs(file_fs - given_fs) <= FS_TOLERANCE * given_fs


def check_agreement(file_fs: float, given_fs: float | None, message: str) -> float:
    """The file's own rate, after checking a given one agrees with it.

    `message` is the error's text when they disagree (it names where each came from).
    """
    if given_fs is not None and not rates_agree(file_fs, given_fs):
        raise RateMismatch(message)
    return file_fs


def brief(exc: BaseException) -> str:
    """First line of an exception's message (or its type), for one-line errors."""
    text = str(exc).strip().splitlines()
    return text[0][:200] if text else type(exc).__name__


def channel_given(what: str) -> str:
    """How the user names a channel where they are (``what``: INDEX or NAME): an option on
    the command line, a column in a manifest, a field over HTTP."""
    return where_given(f"--channel {what}", "the manifest's column channel", "the field channel")


def choose_channel(what: str) -> str:
    """``choose one with ...`` (:func:`channel_given`)."""
    return f"choose one with {channel_given(what)}"


def channel_index(channel: str | int | None, n: int, name: str, kind: str) -> int:
    """A channel given as a column index among `n` (0 when none is given)."""
    if channel is None:
        return 0
    try:
        idx = int(channel)
    except (TypeError, ValueError):
        raise StiffnetError(f"{name}: {kind} channel must be an index, got {channel!r}") from None
    if not 0 <= idx < n:
        raise StiffnetError(f"{name}: channel {idx} requested but the file has {n} channels")
    return idx


@dataclass
class Recording:
    """One accelerometer channel.

    Attributes
    ----------
    accel : numpy.ndarray
        Samples, float64, 1-D; any unit.
    fs_hz : float
        Sampling rate in Hz.
    source : str
        Where the samples came from (file path, channel), for messages.
    """

    accel: np.ndarray
    fs_hz: float
    source: str = ""

    def __post_init__(self) -> None:
        import numpy as np

        self.accel = np.asarray(self.accel, dtype=np.float64)
        where = self.source or "recording"
        if self.accel.ndim != 1:
            raise StiffnetError(f"{where}: expected 1-D samples")
        self.fs_hz = check_rate(self.fs_hz, where)

    def __len__(self) -> int:
        return self.accel.size

    @property
    def duration_s(self) -> float:
        """Length of the recording in seconds (``n / fs``)."""
        return self.accel.size / self.fs_hz

    @property
    def t(self) -> np.ndarray:
        """Sample times in seconds, starting at 0."""
        import numpy as np

        return np.arange(self.accel.size) / self.fs_hz


@dataclass(frozen=True)
class Samples:
    """What a reader returns: one channel's samples, its rate and its name for messages.

    ``fs_hz`` is the file's own rate (checked against a given one) or the given one.
    """

    accel: np.ndarray
    fs_hz: float
    source: str


class RecordingReader(ABC):
    """One file format.

    Subclass it in a module of :mod:`stiffnet.recordings` (found by the registry) or
    anywhere else and pass an instance to
    :func:`stiffnet.recordings.registry.register_reader`.

    Attributes
    ----------
    name : str
        Short name (``"CSV"``), for help texts.
    extensions : tuple of str
        Lower-case file extensions with the dot (``(".csv",)``) this reader claims.
    description : str
        One line for help texts: what the file holds and where its rate comes from.
    rate_in_file : bool
        Whether the file carries its own sampling rate; when False the rate must be
        given (``--fs``, the manifest's ``fs_hz``, the HTTP field ``fs_hz``).
    options : tuple of str
        Layout keywords of :func:`~stiffnet.recordings.read_recording` this format
        accepts besides ``fs_hz`` and ``channel`` (CSV: ``columns``, ``time_unit``).
    channel_help : str
        How ``channel`` names one of its channels (``"an index"``), for help texts.
    """

    name: ClassVar[str]
    extensions: ClassVar[tuple[str, ...]]
    description: ClassVar[str]
    channel_help: ClassVar[str] = "an index"
    rate_in_file: ClassVar[bool] = True
    options: ClassVar[tuple[str, ...]] = ()

    @abstractmethod
    def channels(self, path: Path) -> list[str]:
        """The file's channels by the names ``channel`` accepts (one entry: one channel)."""

    @abstractmethod
    def read(
        self, path: Path, fs_hz: float | None, channel: str | int | None, **options: Any
    ) -> Samples:
        """Read one channel.

        Parameters
        ----------
        path : pathlib.Path
            An existing file with one of :attr:`extensions`.
        fs_hz : float or None
            The given rate, already through :func:`check_rate`. A reader whose file
            carries a rate checks it with :func:`check_agreement`; one whose file
            does not refuses None (the message names the option that gives it).
        channel : str, int or None
            The channel, never blank; None when not given (a file with several
            channels is then refused with one line listing them).
        **options
            Only the keywords in :attr:`options`, possibly None.

        Raises
        ------
        StiffnetError
            One line naming the file and the problem.
        """

    def __repr__(self) -> str:
        return f"{type(self).__name__}({', '.join(self.extensions)})"

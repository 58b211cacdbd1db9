"""The formats: every :class:`RecordingReader` of this package, plus registered ones.

Discovery, pysindy style: every module of :mod:`stiffnet.recordings` that defines a
concrete :class:`~stiffnet.recordings.base.RecordingReader` subclass is a format, so
adding one is one new file here; a reader defined elsewhere (a plugin, a test) joins
with :func:`register_reader`. The command line's help, the HTTP schema,
``predict-batch``'s folder scan and :func:`~stiffnet.recordings.read_recording` all
ask this registry, so no other module lists the formats.

Discovery imports the format modules, which import numpy, scipy, pyarrow and
npTDMS only when a file is read: the help texts cost no heavy import.
"""

from __future__ import annotations

import os
import threading
from pathlib import Path

from stiffnet.errors import StiffnetError
from stiffnet.plugins import discover
from stiffnet.recordings.base import RecordingReader

_LOCK = threading.RLock()
#: extension -> reader, in the order formats were found (CSV first: the common one).
_READERS: dict[str, RecordingReader] = {}
_DISCOVERED = False
#: Formats listed first in help texts and messages; the others follow by name.
_FIRST = ("csv",)
#: Suffixes of a compressed file (``run.csv.gz``), named as such in the refusal.
COMPRESSED_SUFFIXES = (".gz", ".bz2", ".xz", ".zip", ".zst", ".7z")


def discover_readers(package: str = "stiffnet.recordings") -> list[RecordingReader]:
    """One instance of every concrete reader class defined in a module of `package`
    (:func:`stiffnet.plugins.discover`: ``_private`` modules and imported classes skipped).
    """
    return [
        cls() for cls in discover(package, RecordingReader, order=lambda n: (n not in _FIRST, n))
    ]


def _ensure() -> dict[str, RecordingReader]:
    global _DISCOVERED
    with _LOCK:
        if not _DISCOVERED:
            _DISCOVERED = True  # first, so a format module that asks the registry cannot loop
            for reader in discover_readers():
                _add(reader)
        return _READERS


def _add(reader: RecordingReader) -> None:
    for ext in reader.extensions:
        if ext != ext.lower() or not ext.startswith(".") or len(ext) < 2:
            raise ValueError(f"{reader!r}: extension {ext!r} must be lower case with its dot")
        other = _READERS.get(ext)
        if other is not None and type(other) is not type(reader):
            raise ValueError(f"{reader!r}: extension {ext} is already read by {other!r}")
    for ext in reader.extensions:
        _READERS[ext] = reader


def register_reader(reader: RecordingReader) -> RecordingReader:
    """Add a format defined outside this package (one instance of its reader).

    Raises
    ------
    ValueError
        An extension is already claimed by another reader, or is not ``.lower``.
    """
    if not isinstance(reader, RecordingReader):
        raise TypeError(f"{reader!r} is not a RecordingReader instance")
    with _LOCK:
        _ensure()
        _add(reader)
    return reader


def unregister_reader(reader: RecordingReader) -> None:
    """Remove a registered format (its extensions no longer read)."""
    with _LOCK:
        for ext in [e for e, r in _ensure().items() if r is reader]:
            del _READERS[ext]


def readers() -> tuple[RecordingReader, ...]:
    """Every format, each once, in the order help texts list them."""
    seen: dict[int, RecordingReader] = {}
    for reader in _ensure().values():
        seen.setdefault(id(reader), reader)
    return tuple(seen.values())


def supported_extensions() -> tuple[str, ...]:
    """Every extension a reader claims (``.csv``, ...), in the order of :func:`readers`."""
    return tuple(_ensure())


def reader_for(path: str | os.PathLike[str]) -> RecordingReader:
    """The reader of a file, by its extension (case-insensitive).

    Raises
    ------
    StiffnetError
        No reader claims the extension (the message lists those that exist).
    """
    p = Path(path)
    reader = _ensure().get(p.suffix.lower())
    if reader is None:
        inner = Path(p.stem).suffix.lower()
        # a compressed recording (run.csv.gz): the reader exists, the file needs unpacking
        packed = (
            f"; it is a compressed {inner} file: decompress it first"
            if p.suffix.lower() in COMPRESSED_SUFFIXES and inner in _ensure()
            else ""
        )
        raise StiffnetError(
            f"{p}: unknown recording extension {p.suffix or '(none)'!r} "
            f"(use one of {', '.join(supported_extensions())}){packed}"
        )
    return reader


def rate_needed_for() -> tuple[str, ...]:
    """Extensions whose files carry no sampling rate (it must be given)."""
    return tuple(e for e, r in _ensure().items() if not r.rate_in_file)


def formats_help() -> str:
    """The formats in one sentence, for help texts: ``.csv: …; .npy: …; …``."""
    return "; ".join(f"{'/'.join(r.extensions)}: {r.description}" for r in readers())


def channels_help() -> str:
    """How each format names a channel, for help texts: ``.csv: …; .npy: …``."""
    return "; ".join(f"{'/'.join(r.extensions)}: {r.channel_help}" for r in readers())


def require_rate(path: str | os.PathLike[str], fs_hz: float | None, option: str = "--fs") -> None:
    """Refuse early (before loading a model) a file whose format needs a rate not given.

    Raises
    ------
    StiffnetError
        The format carries no rate and `fs_hz` is None.
    """
    p = Path(path)
    reader = _ensure().get(p.suffix.lower())
    if fs_hz is None and reader is not None and not reader.rate_in_file:
        raise StiffnetError(
            f"{p}: sampling rate missing (a {p.suffix.lower()} recording needs {option} HZ)"
        )

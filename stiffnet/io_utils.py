"""Atomic file and folder writes: nothing half-written ever looks complete."""

from __future__ import annotations

import contextlib
import hashlib
import json
import math
import os
import re
import shutil
import stat
import tempfile
import uuid
from collections.abc import Iterator
from pathlib import Path
from typing import Any

from stiffnet.errors import StiffnetError


def _umask() -> int:
    mask = os.umask(0)
    os.umask(mask)
    return mask


def write_bytes_atomic(path: str | Path, data: bytes) -> None:
    """Write ``data`` to a temporary file beside ``path``, then rename it into place.

    The rename only ever replaces a regular file: a symbolic link, FIFO, device or
    folder at ``path`` is refused (it is not ours to replace).
    """
    path = Path(path)
    _check_replaceable_file(path)
    try:
        fd, tmp = tempfile.mkstemp(prefix=f".{path.name[:100]}.", suffix=".tmp", dir=path.parent)
    except OSError as exc:
        raise StiffnetError(f"{path}: cannot write here ({exc.strerror})") from None
    try:
        os.fchmod(fd, 0o666 & ~_umask())  # mkstemp makes 0600; a normal file honours the umask
        with os.fdopen(fd, "wb") as fh:
            fh.write(data)
            fh.flush()
            os.fsync(fh.fileno())
        os.replace(tmp, path)
    except BaseException:
        with contextlib.suppress(FileNotFoundError):
            os.unlink(tmp)
        raise


def _check_replaceable_file(path: Path) -> None:
    try:
        mode = os.lstat(path).st_mode
    except FileNotFoundError:
        return
    if not stat.S_ISREG(mode):
        kind = "a symbolic link" if stat.S_ISLNK(mode) else (
            "a folder" if stat.S_ISDIR(mode) else "not a regular file")  # fmt: skip
        raise StiffnetError(f"{path} is {kind}: refusing to replace it")


def json_text(obj: Any) -> str:
    """``obj`` as strict JSON text (NaN and infinities as ``null``), one final newline."""
    return json.dumps(_finite(obj), indent=2, default=_json_default, allow_nan=False) + "\n"


def write_json_atomic(path: str | Path, obj: Any) -> None:
    """Write ``obj`` as JSON atomically; NaN and infinities become ``null`` (JSON has none)."""
    write_bytes_atomic(path, json_text(obj).encode())


def _finite(obj: Any) -> Any:
    """``obj`` with non-finite floats (numpy's included) replaced by None."""
    if isinstance(obj, float):
        return obj if math.isfinite(obj) else None
    if isinstance(obj, dict):
        return {k: _finite(v) for k, v in obj.items()}
    if isinstance(obj, list | tuple):
        return [_finite(v) for v in obj]
    try:
        import numpy as np
    except ImportError:  # pragma: no cover
        return obj
    if isinstance(obj, np.floating):
        return float(obj) if np.isfinite(obj) else None
    if isinstance(obj, np.ndarray) and obj.dtype.kind == "f":
        return [_finite(v) for v in obj.tolist()]
    return obj


def _json_default(obj: Any) -> Any:
    import numpy as np

    if isinstance(obj, np.integer):
        return int(obj)
    if isinstance(obj, np.floating):
        return float(obj)
    if isinstance(obj, np.ndarray):
        return obj.tolist()
    if isinstance(obj, Path):
        return str(obj)
    raise TypeError(f"not JSON serialisable: {type(obj).__name__}")


def sha256_file(path: str | Path) -> str:
    h = hashlib.sha256()
    with open(path, "rb") as fh:
        for chunk in iter(lambda: fh.read(1 << 20), b""):
            h.update(chunk)
    return h.hexdigest()


@contextlib.contextmanager
def atomic_directory(out: str | Path, overwrite: bool = False) -> Iterator[Path]:
    """Build a folder under a temporary name and rename it to ``out`` on success.

    Refuses (before any work) to replace an existing non-empty ``out`` unless
    ``overwrite``. On failure the temporary folder is removed, so an interrupted
    run leaves no partial result under the final name.
    """
    out = Path(out)
    if out.exists() and not out.is_dir():
        raise StiffnetError(f"output path exists and is not a folder: {out}")
    if out.is_dir() and any(out.iterdir()):
        if not overwrite:
            raise StiffnetError(f"output folder {out} exists and is not empty (use --overwrite)")
        check_replaceable_folder(out)
    out.parent.mkdir(parents=True, exist_ok=True)
    tmp = Path(tempfile.mkdtemp(prefix=f".{out.name[:100]}.partial-", dir=out.parent))
    tmp.chmod(0o777 & ~_umask())  # mkdtemp makes 0700; a normal folder honours the umask
    try:
        yield tmp
        if out.exists():
            trash = Path(tempfile.mkdtemp(prefix=f".{out.name[:100]}.old-", dir=out.parent))
            os.replace(out, trash / "old")
            os.replace(tmp, out)
            shutil.rmtree(trash, ignore_errors=True)
        else:
            os.replace(tmp, out)
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise


#: The marker file of a folder stiffnet wrote (run folders, figure folders, parts).
RUN_MARKER = "stiffnet-run.json"
#: Files that may mark a folder as stiffnet's; each counts only with the content of
#: :func:`new_marker` (a ``stiffnet-`` kind and a run id): a user's ``card.json`` or
#: ``job.json`` does not.
OWN_MARKERS = (RUN_MARKER,)
_RUN_ID = re.compile(r"^[0-9a-f]{32}$")


def new_marker(kind: str, **more: Any) -> dict[str, Any]:
    """The content of a marker: ``kind`` (``stiffnet-...``), a fresh run id, the version."""
    from stiffnet import __version__

    if not kind.startswith("stiffnet-"):
        raise ValueError(f"marker kinds start with 'stiffnet-', got {kind!r}")
    return {"kind": kind, "run_id": uuid.uuid4().hex, "stiffnet_version": __version__, **more}


def read_marker(path: str | Path) -> dict[str, Any] | None:
    """A marker written by :func:`new_marker`, or None (absent, foreign or malformed)."""
    p = Path(path)
    try:
        if not stat.S_ISREG(os.lstat(p).st_mode) or os.lstat(p).st_size > 1 << 20:
            return None
        d = json.loads(p.read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return None
    if not (isinstance(d, dict) and isinstance(d.get("kind"), str)
            and d["kind"].startswith("stiffnet-") and isinstance(d.get("run_id"), str)
            and _RUN_ID.match(d["run_id"])):  # fmt: skip
        return None
    return d


def check_replaceable_folder(out: str | Path, markers: tuple[str, ...] = OWN_MARKERS) -> None:
    """Refuse to delete ``out`` unless stiffnet wrote it (``--overwrite``).

    ``out`` must carry one of ``markers`` holding a stiffnet marker (:func:`read_marker`:
    a ``stiffnet-`` kind and a run id) and must not be the working directory or one of
    its ancestors.
    """
    p = Path(out)
    real = p.resolve()
    if Path.cwd().resolve().is_relative_to(real):
        raise StiffnetError(f"{p}: refusing to overwrite the working directory or a parent of it")
    if not any(read_marker(p / m) is not None for m in markers):
        raise StiffnetError(
            f"{p}: refusing to overwrite a folder stiffnet did not write (no stiffnet marker "
            f"with a run id in {' or '.join(markers)}); choose another output folder"
        )


#: Environment variable naming the folder of the output locks (default: per user, in /tmp).
LOCK_DIR_ENV = "STIFFNET_LOCK_DIR"


def lock_path(folder: str | Path) -> Path:
    """The lock file of an output folder.

    Kept out of the user's folders (nothing is left beside an output): one file per
    resolved output path in a per-user lock folder, so two names of one folder
    (``data/x`` and ``./data/../data/x``) share a lock.
    """
    real = str(Path(folder).resolve())
    root = Path(
        os.environ.get(LOCK_DIR_ENV)
        or Path(tempfile.gettempdir()) / f"stiffnet-locks-{os.getuid()}"
    )
    return root / (hashlib.sha256(real.encode()).hexdigest()[:32] + ".lock")


@contextlib.contextmanager
def output_lock(folder: str | Path) -> Iterator[None]:
    """Hold the output's lock (``filelock``) or refuse: another run is writing it.

    An OS-level lock (``flock``): it is released when the holder exits, even by
    ``kill -9``, so a crashed run never blocks the next one. Files are locked the
    same way as folders (``--json``, ``--out`` of ``report`` and ``predict-batch``).
    """
    from filelock import FileLock, Timeout

    path = lock_path(folder)
    path.parent.mkdir(mode=0o700, parents=True, exist_ok=True)
    lock = FileLock(str(path), timeout=0)
    try:
        lock.acquire()
    except Timeout:
        raise StiffnetError(
            f"{folder}: another stiffnet run is writing this output (lock {path}); "
            "wait for it or choose another output"
        ) from None
    try:
        yield
    finally:
        lock.release()


def fresh_run_folder(prefix: str, root: str | Path = "runs") -> Path:
    """A new, not yet existing ``runs/PREFIX-YYYYmmdd-HHMMSS[-N]`` folder name."""
    import time

    stamp = time.strftime("%Y%m%d-%H%M%S")
    base = Path(root) / f"{prefix}-{stamp}"
    path, n = base, 1
    while path.exists():
        n += 1
        path = base.with_name(f"{base.name}-{n}")
    return path


def _earlier_run(out: Path, kind: str) -> bool:
    """Whether ``out`` holds an earlier run of ``kind`` (False: absent or empty); refuses
    the working directory (or a parent of it) and a non-empty folder of anything else."""
    if Path.cwd().resolve().is_relative_to(out.resolve()):
        raise StiffnetError(f"{out}: refusing to write a run into the working directory or a "
                            "parent of it; choose a new folder")  # fmt: skip
    if not (out.is_dir() and any(out.iterdir())):
        return False
    marker = read_marker(out / RUN_MARKER)
    if marker is None or marker.get("kind") != kind:
        raise StiffnetError(
            f"{out}: folder is not empty and is not an earlier {kind} run (no {RUN_MARKER} of "
            "that kind): choose a new or empty folder"
        )
    return True


def start_run_folder(out: str | Path, kind: str) -> dict[str, Any]:
    """Make ``out`` a fresh run folder of ``kind``; call it holding :func:`output_lock`.

    An empty or absent folder is used as it is; an earlier run of the same kind
    (its marker says so, with a run id) is removed first, so a killed run's files
    never mix with the new ones; any other non-empty folder is refused, and so is
    the working directory. Returns the new marker.
    """
    out = Path(out)
    if _earlier_run(out, kind):
        check_replaceable_folder(out, (RUN_MARKER,))
        trash = Path(tempfile.mkdtemp(prefix=f".{out.name[:100]}.old-", dir=out.parent))
        os.replace(out, trash / "old")
        shutil.rmtree(trash, ignore_errors=True)
    out.mkdir(parents=True, exist_ok=True)
    marker = new_marker(kind, status="running")
    write_json_atomic(out / RUN_MARKER, marker)
    return marker


def claim_run_folder(out: str | Path, kind: str) -> dict[str, Any]:
    """Make ``out`` an output folder of ``kind`` that keeps its other files (``train --out``).

    Absent or empty: created. Non-empty: only a folder marked as an earlier run of
    ``kind`` (the shipped ``models/`` is one) is written into, its own files replaced
    one by one; a user's folder and the working directory are refused. Call it
    holding :func:`output_lock`; returns the new marker.
    """
    out = Path(out)
    if out.exists() and not out.is_dir():
        raise StiffnetError(f"{out}: exists and is not a folder")
    _earlier_run(out, kind)
    out.mkdir(parents=True, exist_ok=True)
    marker = new_marker(kind, status="running")
    write_json_atomic(out / RUN_MARKER, marker)
    return marker


def finish_run_folder(out: str | Path, marker: dict[str, Any]) -> None:
    """Mark the run folder ``out`` (started by :func:`start_run_folder`) complete."""
    write_json_atomic(Path(out) / RUN_MARKER, {**marker, "status": "complete"})


def claim_parts_folder(parts: str | Path, run: str) -> None:
    """Make ``parts`` the folder of one run's parts (``run``: the whole run's fingerprint).

    Absent: created with its marker. Ours and of the same run: kept (a resume). Ours
    and of another run: emptied of its own parts files, never mixed. Anything else
    (a user's folder of that name) is refused; nothing of it is deleted.
    """
    parts = Path(parts)
    if parts.is_symlink() or (parts.exists() and not parts.is_dir()):
        raise StiffnetError(f"{parts}: exists and is not a parts folder stiffnet wrote; "
                            "move it or choose another --out")  # fmt: skip
    if parts.is_dir():
        marker = read_marker(parts / RUN_MARKER)
        if marker is None or marker.get("kind") != "stiffnet-parts":
            raise StiffnetError(f"{parts}: folder exists and stiffnet did not write it (no "
                                f"{RUN_MARKER}); move it or choose another --out")  # fmt: skip
        if marker.get("run") == run:
            return
        remove_parts_folder(parts)  # a user's file in it stays, and so does the folder
    parts.mkdir(parents=True, exist_ok=True)
    write_json_atomic(parts / RUN_MARKER, new_marker("stiffnet-parts", run=run))


#: What a parts folder may hold: its marker, parts, their records, atomic-write temporaries.
_PART_FILE = re.compile(r"^(part-\d{5}\.(parquet|json)|\.part-\d{5}\.(parquet|json)\.\w+\.tmp)$")


def remove_parts_folder(parts: str | Path) -> None:
    """Delete a parts folder's own files (marker, parts, records), then the folder if empty.

    A file stiffnet did not name (a user's) stays, and so does the folder holding it.
    """
    parts = Path(parts)
    if read_marker(parts / RUN_MARKER) is None:
        return
    for entry in parts.iterdir():
        if entry.is_file() and not entry.is_symlink() and _PART_FILE.match(entry.name):
            entry.unlink()
    (parts / RUN_MARKER).unlink()
    with contextlib.suppress(OSError):
        parts.rmdir()


def is_run_folder(folder: str | Path, kind: str) -> bool:
    """Whether ``folder`` carries the marker of a finished run of ``kind``."""
    try:
        d = json.loads((Path(folder) / RUN_MARKER).read_text())
    except (OSError, ValueError):
        return False
    return isinstance(d, dict) and d.get("kind") == kind and d.get("status") == "complete"

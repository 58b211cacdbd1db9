"""The restoring-force method's costly fits kept for reuse while a caller asks for it.

Three fits make most of the restoring-force check's CPU on a campaign behind a sensor chain:
the chain identified from a record's impacts (:func:`~.chain.fit_chain`, 1-8 s a record),
the high-pass corner profiled by the contact law (:func:`~.estimate._auto_map`, ~20 maps)
and the law with an onset per impact (:func:`~.impact_onsets.fit_impact_onset_law`). None
depends on the model that reads the campaign (its weights, its learned law's stage ratio):
each is a function of the record's samples and the method's settings only.
A measurement loop evaluates the same recordings with every new model, so it asks for them
to be kept (:func:`fits_kept`): each fit then runs once per distinct input, in this process
and, with a file, across the loop's runs (a resumed loop is a new process).

A fit's key is the SHA-256 of everything it reads: its arrays' bytes, dtype and shape, its
scalars exactly (``float.hex``), the fit's kind, and :func:`code_version` (the source of this
package and the class edges it reads, with numpy's and scipy's versions), so a changed
record, setting or method never returns a kept fit. Outside :func:`fits_kept` nothing is
kept: every call fits, as before.
"""

from __future__ import annotations

import contextlib
import functools
import hashlib
import pickle
from collections.abc import Callable, Iterator
from contextvars import ContextVar
from pathlib import Path
from typing import Any, TypeVar

import numpy as np

T = TypeVar("T")


class KeptFits:
    """Fits by key, optionally read from and written to one file.

    Attributes
    ----------
    path : Path or None
        The file the fits are read from at the start and written to by :meth:`save`.
    fitted, reused : int
        Fits computed here, fits returned from the store (in this process).
    """

    def __init__(self, path: str | Path | None = None) -> None:
        self.path = None if path is None else Path(path)
        self.fitted = 0
        self.reused = 0
        self._fits: dict[str, Any] = _read(self.path) if self.path is not None else {}
        self._saved = len(self._fits)

    def __len__(self) -> int:
        return len(self._fits)

    def get(self, kind: str, inputs: tuple, compute: Callable[[], T]) -> T:
        """``compute()`` once per ``(kind, inputs)`` (every input the fit reads)."""
        key = fit_key(kind, inputs)
        if key in self._fits:
            self.reused += 1
        else:
            self._fits[key] = compute()
            self.fitted += 1
        # a copy: a caller that changes its result must not change the kept one
        return pickle.loads(pickle.dumps(self._fits[key]))

    def save(self) -> None:
        """Write the fits to :attr:`path` atomically (nothing without a path or a new fit)."""
        from stiffnet.io_utils import write_bytes_atomic

        if self.path is None or len(self._fits) == self._saved:
            return
        blob = {"code": code_version(), "fits": self._fits}
        write_bytes_atomic(self.path, pickle.dumps(blob, protocol=pickle.HIGHEST_PROTOCOL))
        self._saved = len(self._fits)


def _read(path: Path) -> dict[str, Any]:
    """The fits kept in `path`; none where it is missing, unreadable or of other code."""
    try:
        blob = pickle.loads(path.read_bytes())
    except (OSError, pickle.UnpicklingError, EOFError, AttributeError, ImportError, TypeError):
        return {}
    # the keys hold the code version too: this only drops a stale file's fits at once
    if not isinstance(blob, dict) or blob.get("code") != code_version():
        return {}
    return dict(blob.get("fits") or {})


_KEPT: ContextVar[KeptFits | None] = ContextVar("kept_restoring_force_fits", default=None)


@contextlib.contextmanager
def fits_kept(path: str | Path | None = None) -> Iterator[KeptFits]:
    """Keep the restoring-force method's chain, corner and onset fits within the block (in `path`
    too where given: read now, written by :meth:`KeptFits.save` and at the block's end)."""
    kept = KeptFits(path)
    token = _KEPT.set(kept)
    try:
        yield kept
    finally:
        _KEPT.reset(token)
        kept.save()


def kept(kind: str, inputs: tuple, compute: Callable[[], T]) -> T:
    """``compute()``, kept by ``(kind, inputs)`` inside :func:`fits_kept`; else just run."""
    store = _KEPT.get()
    return compute() if store is None else store.get(kind, inputs, compute)


def fit_key(kind: str, inputs: tuple) -> str:
    """The SHA-256 of a fit's kind, its inputs (arrays by dtype, shape and bytes; floats
    exactly; None, bools, ints and strings by type and value) and :func:`code_version`."""
    h = hashlib.sha256(code_version().encode())
    h.update(kind.encode())
    for x in inputs:
        h.update(b"|")
        if isinstance(x, np.ndarray):
            a = np.ascontiguousarray(x)
            h.update(f"array {a.dtype.str} {a.shape}".encode())
            h.update(a.tobytes())
        elif isinstance(x, bool | np.bool_) or x is None or isinstance(x, int | np.integer | str):
            h.update(f"{type(x).__name__} {x!r}".encode())
        elif isinstance(x, float | np.floating):
            h.update(f"float {float(x).hex()}".encode())
        else:
            raise TypeError(f"a kept fit's input must be an array or a scalar, got {type(x)}")
    return h.hexdigest()


@functools.cache
def code_version() -> str:
    """The SHA-256 of this package's source, of the class edges it reads, and of numpy's
    and scipy's versions: a kept fit is another code's after any of them changed."""
    import scipy

    here = Path(__file__).parent
    files = sorted(here.glob("*.py")) + [here.parent / "geometry" / "calibration.py"]
    h = hashlib.sha256(f"numpy {np.__version__} scipy {scipy.__version__}".encode())
    for f in files:
        h.update(f.name.encode())
        h.update(f.read_bytes())
    return h.hexdigest()

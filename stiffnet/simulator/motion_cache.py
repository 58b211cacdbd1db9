"""Reuse of the motion between simulations that differ only in their measurement chain.

A fit of a measurement effect (a sensor's resonance, coloured noise, an ADC) moves
nothing the oscillator integrates: every evaluation of its objective simulates
the same motion and passes it through another measurement chain. Inside
:func:`reuse_motion`, :class:`~stiffnet.simulator.simulator.Simulator` keys the
engine's output (the motion sampled, before any measurement effect or noise) by
everything it depends on (the engine, the batch, every dynamics effect's
per-row parameters, the initial state, the transient, the sampling, the
substeps and the numerical engine's warm start) and returns the stored motion
when the key repeats. The engines draw no random numbers, so the measurement
chain that follows sees the same generator state either way: the signals are
bitwise those of a fresh simulation.

Outside :func:`reuse_motion` nothing is stored (a caller that mutates a
result in place cannot corrupt another's).
"""

from __future__ import annotations

import hashlib
from collections import OrderedDict
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from typing import Any

import numpy as np

#: The active stores, innermost last, each with its capacity.
_STORE: list[tuple[OrderedDict[bytes, Any], int]] = []


@contextmanager
def reuse_motion(size: int = 2) -> Iterator[None]:
    """Within the block, simulations with the same motion share it (at most ``size`` motions
    kept, least recently used dropped: a motion of 24 rows oversampled 8x is ~100 MB)."""
    entry: tuple[OrderedDict[bytes, Any], int] = (OrderedDict(), max(1, int(size)))
    _STORE.append(entry)
    try:
        yield
    finally:
        _STORE[:] = [e for e in _STORE if e is not entry]


def motion_key(*parts: Any) -> bytes:
    """A digest of numbers, arrays, strings and nested dicts/tuples/lists of them."""
    h = hashlib.blake2b(digest_size=20)

    def add(x: Any) -> None:
        if isinstance(x, dict):
            h.update(b"{")
            for k in sorted(x):
                add(str(k))
                add(x[k])
            h.update(b"}")
        elif isinstance(x, list | tuple):
            h.update(b"(")
            for v in x:
                add(v)
            h.update(b")")
        elif isinstance(x, str):
            h.update(b"s" + x.encode() + b"\0")
        elif x is None or isinstance(x, bool | int | float | np.ndarray | np.number):
            a = np.ascontiguousarray(np.asarray(x, dtype=np.float64))
            h.update(b"a" + repr(a.shape).encode())
            h.update(a.tobytes())
        else:  # anything else an effect holds (a learned law's terms): its repr
            h.update(b"r" + repr(x).encode() + b"\0")

    for p in parts:
        add(p)
    return h.digest()


def motion(
    key: Callable[[], bytes],
    compute: Callable[[], Any],
    n_samples: int,
    prefix: Callable[[Any, int], Any],
) -> Any:
    """``compute()``, or the motion stored under ``key()`` inside :func:`reuse_motion`.

    ``key`` leaves the number of samples out: a stored motion at least ``n_samples`` long
    serves a shorter one as its first ``n_samples`` (``prefix(motion, n)``; the samples of a
    longer record are the same, followed by more), e.g. a shorter lead-in before a record."""
    if not _STORE:
        return compute()
    (store, size), k = _STORE[-1], key()
    if k in store and store[k][0] >= n_samples:
        store.move_to_end(k)
        n, out = store[k]
        return out if n == n_samples else prefix(out, n_samples)
    out = compute()
    store[k] = (n_samples, out)
    store.move_to_end(k)
    while len(store) > size:
        store.popitem(last=False)
    return out


__all__ = ["motion", "motion_key", "reuse_motion"]

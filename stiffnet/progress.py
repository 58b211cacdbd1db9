"""Progress of long work: library code reports steps, the command line draws them.

Long loops (shards, epochs, effects, evaluations, stages) open a :func:`task` and
advance it. Nothing is shown unless a display is installed with :func:`reporting`:
the CLI installs a rich progress bar (with ETA) when stderr is a terminal, so
library calls, tests, pipes and ``--json``-only scripted use stay silent. The
display lives in a context variable: no global state is shared between threads
that did not inherit it, and Dask workers never see it (their driver loop
reports instead).

This module imports nothing heavy (no rich): the predictor may import it.
"""

from __future__ import annotations

from collections.abc import Iterator
from contextlib import contextmanager
from contextvars import ContextVar
from typing import Any, Protocol


class Display(Protocol):
    """What a display must do (``rich.progress.Progress`` does)."""

    def add_task(self, description: str, total: float | None = ..., **fields: Any) -> Any: ...

    def update(self, task_id: Any, **kwargs: Any) -> None: ...

    def remove_task(self, task_id: Any) -> None: ...


_display: ContextVar[Display | None] = ContextVar("stiffnet_progress", default=None)


class Task:
    """Handle of one progress line; every method is a no-op without a display."""

    def __init__(self, display: Display | None = None, task_id: Any = None) -> None:
        self._display = display
        self._id = task_id

    def advance(self, steps: float = 1, note: str | None = None) -> None:
        """Count `steps` more done; `note` replaces the text after the bar (e.g. losses)."""
        if self._display is not None:
            extra = {} if note is None else {"note": note}
            self._display.update(self._id, advance=steps, **extra)

    def update(
        self, completed: float | None = None, total: float | None = None, note: str | None = None
    ) -> None:
        """Set the done count, the total (when it becomes known) or the note."""
        if self._display is None:
            return
        kwargs: dict[str, Any] = {}
        if completed is not None:
            kwargs["completed"] = completed
        if total is not None:
            kwargs["total"] = total
        if note is not None:
            kwargs["note"] = note
        self._display.update(self._id, **kwargs)


@contextmanager
def task(description: str, total: float | None = None) -> Iterator[Task]:
    """A progress line for the duration of the block (``total=None``: unknown, a spinner)."""
    display = _display.get()
    if display is None:
        yield Task()
        return
    task_id = display.add_task(description, total=total, note="")
    try:
        yield Task(display, task_id)
    finally:
        display.remove_task(task_id)


def active() -> bool:
    """True when a display is installed (to skip work done only for the display)."""
    return _display.get() is not None


@contextmanager
def reporting(display: Display | None) -> Iterator[None]:
    """Send the :func:`task` lines of the block to `display` (None: stay silent)."""
    token = _display.set(display)
    try:
        yield
    finally:
        _display.reset(token)

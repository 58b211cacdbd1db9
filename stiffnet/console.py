"""What every ``stiffnet`` command shares: consoles, JSON output, error mapping, progress.

The command modules (:mod:`stiffnet.cli`, :mod:`serving.commands`,
:mod:`stiffnet.measurement.commands`, :mod:`stiffnet.distributed.commands`) import
these from here; nothing imports :mod:`stiffnet.cli`, which only assembles the app.
A light module (typer and rich): ``stiffnet --help`` and the predictor's commands
load nothing heavier through it.
"""

from __future__ import annotations

import functools
from collections.abc import Callable
from pathlib import Path
from typing import Any, TypeVar

import typer
from rich.console import Console
from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeElapsedColumn

from stiffnet.errors import StiffnetError

#: Messages, progress and errors (stderr): stdout stays for results.
console = Console(stderr=True)
#: Results: tables and summaries (stdout).
out = Console()

F = TypeVar("F", bound=Callable[..., Any])


def user_errors(fn: F) -> F:
    """Report :class:`StiffnetError` as one line on stderr and exit with code 2."""

    @functools.wraps(fn)
    def wrapper(*args: Any, **kwargs: Any) -> Any:
        try:
            return fn(*args, **kwargs)
        except StiffnetError as exc:
            console.print(f"[bold red]error:[/] {exc}", highlight=False, soft_wrap=True)
            raise typer.Exit(2) from None

    return wrapper  # type: ignore[return-value]


def write_json(path: Path | None, result: Any) -> None:
    """Write ``result`` as JSON to ``path`` (atomically) when a path is given."""
    if path is not None:
        from stiffnet.io_utils import write_json_atomic

        write_json_atomic(path, result)


def progress_bar(description: str) -> Progress:
    """A progress bar on stderr, shown only on a terminal."""
    return Progress(
        TextColumn(description),
        BarColumn(),
        MofNCompleteColumn(),
        TimeElapsedColumn(),
        console=console,
        disable=not console.is_terminal,
    )

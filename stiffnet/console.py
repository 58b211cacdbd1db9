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
from rich.markup import escape
from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeElapsedColumn

from stiffnet.errors import StiffnetError

#: Messages, progress and errors (stderr): stdout stays for results.
console = Console(stderr=True)
#: Results: tables and summaries (stdout).
out = Console()

F = TypeVar("F", bound=Callable[..., Any])


def report_error(message: object) -> None:
    """``error: message`` on one line of stderr (control characters and markup escaped)."""
    from stiffnet.inputs import one_line

    console.print(f"[bold red]error:[/] {escape(one_line(message))}", highlight=False,
                  soft_wrap=True)  # fmt: skip


#: Parameters every command names the same way: checked before the command runs.
_OUTPUT_FILES = ("json_path", "out_path")
_OUTPUT_FOLDERS = ("plots", "out_dir")


def check_arguments(kwargs: dict[str, Any]) -> None:
    """Validate the shared options (rates, knobs, output paths) before any work.

    See :mod:`stiffnet.inputs`: ``--fs``/``--fn`` in physical ranges, ``--threads``
    and ``--workers`` at most the available cores, output paths usable.
    """
    from stiffnet import inputs

    if kwargs.get("fs") is not None:
        inputs.sampling_rate(kwargs["fs"], "--fs")
    if kwargs.get("fn") is not None:
        inputs.natural_frequency(kwargs["fn"], "--fn")
    if kwargs.get("fs") is not None and kwargs.get("fn") is not None:
        inputs.rate_ratio(kwargs["fs"], kwargs["fn"], "--fs/--fn")
    inputs.threads(kwargs.get("threads"))
    inputs.bounded_count(kwargs.get("workers"), "--workers", 1, inputs.max_local_workers())
    flags = {"json_path": "--json", "out_path": "--out", "plots": "--plots", "out_dir": "--out"}
    for name in _OUTPUT_FILES:
        inputs.output_file(kwargs.get(name), flags[name])
    for name in _OUTPUT_FOLDERS:
        inputs.output_folder(kwargs.get(name), flags[name])


def user_errors(fn: F) -> F:
    """Check shared options first; report :class:`StiffnetError` as one line, exit code 2."""

    @functools.wraps(fn)
    def wrapper(*args: Any, **kwargs: Any) -> Any:
        try:
            check_arguments(kwargs)
            return fn(*args, **kwargs)
        except StiffnetError as exc:
            report_error(exc)
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

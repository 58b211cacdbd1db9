"""What every ``stiffnet`` command shares: consoles, JSON output, error mapping, progress.

The command modules (:mod:`stiffnet.cli`, :mod:`serving.commands`,
:mod:`stiffnet.measurement.commands`) import these from here; nothing imports
:mod:`stiffnet.cli`, which only assembles the app.
A light module (typer and rich): ``stiffnet --help`` and the predictor's commands
load nothing heavier through it.
"""

from __future__ import annotations

import functools
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any, TypeVar

import typer
from rich.console import Console
from rich.markup import escape
from rich.table import Table
from rich.text import Text

from stiffnet import progress
from stiffnet.errors import StiffnetError

#: Width of ``--wide`` output: tables at their natural width (for files, wide terminals).
WIDE_COLUMNS = 400


def fit_table(table: Table, width: int) -> Table:
    """Let a table fit `width` columns without cutting anything a user needs.

    Numbers keep their whole width (a number cut in two misreads) and headers
    wrap only at spaces; the text columns (recording paths, effect parameters)
    share the rest in proportion to their length and fold at any character, so a
    long name goes onto a second line instead of ending in an ellipsis. A table
    that fits already is left alone; ``--wide`` prints at the natural width.
    """
    cols = table.columns
    cells = [[Text.from_markup(c).plain if isinstance(c, str) else str(c) for c in col.cells]
             for col in cols]  # fmt: skip
    heads = [str(col.header) for col in cols]
    word = [max((len(w) for w in h.split()), default=0) for h in heads]
    natural = [max([len(h), *map(len, cs)]) for h, cs in zip(heads, cells, strict=True)]
    numeric = [bool(cs) and all(_looks_numeric(c) for c in cs) for cs in cells]
    for col, num in zip(cols, numeric, strict=True):
        col.overflow = "fold"
        if num:
            col.justify = "right"
    room = width - (1 + 3 * len(cols))  # borders and one space of padding each side
    if sum(natural) <= room:
        return table
    need = [max([w, *map(len, cs)]) if num else 0
            for w, cs, num in zip(word, cells, numeric, strict=True)]  # fmt: skip
    text = [i for i, num in enumerate(numeric) if not num]
    left = room - sum(need)
    if not text or left < 6 * len(text):
        return table  # too narrow for a plan: rich's own wrapping
    for i in text:  # floor: the longest header word or cell token (up to 16)
        token = max((len(t) for c in cells[i] for t in c.split()), default=0)
        need[i] = min(natural[i], max(6, word[i], min(token, 16)))
    floors = sum(need[i] for i in text)
    if floors > left:  # not room for every floor: shrink them alike
        for i in text:
            need[i] = max(6, need[i] * left // floors)
    spare = room - sum(need)
    if spare < 0:
        return table
    extra = {i: natural[i] - need[i] for i in text}
    total = sum(extra.values()) or 1
    for i in text:  # the rest in proportion to what each still lacks
        need[i] += extra[i] * spare // total
    for col, w in zip(cols, need, strict=True):
        col.width = w
    return table


def _looks_numeric(text: str) -> bool:
    t = text.strip().rstrip("%").replace("–", "").replace("-", "").replace("[", "")
    t = t.split(" ")[0].replace(",", "").replace("]", "")
    try:
        float(t or "0")
    except ValueError:
        return False
    return True


class _Out(Console):
    """stdout console whose tables fit its width (:func:`fit_table`)."""

    def print(self, *objects: Any, **kwargs: Any) -> None:  # noqa: D102
        objects = tuple(fit_table(o, self.width) if isinstance(o, Table) else o for o in objects)
        super().print(*objects, **kwargs)


#: Messages, progress and errors (stderr): stdout stays for results.
console = Console(stderr=True)
#: Results: tables and summaries (stdout), fitted to the terminal's width.
out = _Out()

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


@contextmanager
def show_progress() -> Iterator[None]:
    """Draw the :mod:`stiffnet.progress` tasks of the block as rich bars with an ETA.

    Only when stderr is a terminal: piped, redirected or scripted (``--json``) runs
    stay silent, as do library calls (no display is installed outside this block).
    """
    if not console.is_terminal:
        yield
        return
    from rich.progress import (
        BarColumn,
        MofNCompleteColumn,
        Progress,
        SpinnerColumn,
        TextColumn,
        TimeElapsedColumn,
        TimeRemainingColumn,
    )

    bar = Progress(
        SpinnerColumn(),
        TextColumn("{task.description}"),
        BarColumn(bar_width=24),
        MofNCompleteColumn(),
        TimeElapsedColumn(),
        TextColumn("eta"),
        TimeRemainingColumn(),
        TextColumn("{task.fields[note]}"),
        console=console,
        transient=True,
        # steps of a diagnosis can take minutes: keep their speed for the ETA meanwhile
        speed_estimate_period=3600.0,
    )
    with bar, progress.reporting(bar):
        yield

"""What every ``stiffnet`` command shares: consoles, JSON output, error mapping, progress.

The command modules (:mod:`stiffnet.cli`, :mod:`stiffnet.cli.predict`,
:mod:`stiffnet.cli.measurement`) import these from here; nothing imports
:mod:`stiffnet.cli`, which only assembles the app.
A light module (typer and rich): ``stiffnet --help`` and the predictor's commands
load nothing heavier through it.
"""

from __future__ import annotations

import csv
import errno
import functools
import os
import re
import sys
from collections.abc import Callable, Iterator
from contextlib import ExitStack, contextmanager
from pathlib import Path
from typing import Any, TypeVar

import typer
from rich.cells import cell_len
from rich.console import Console
from rich.markup import escape
from rich.table import Table
from rich.text import Text

from stiffnet import progress
from stiffnet.errors import StiffnetError

#: Width of ``--wide`` output: tables at their natural width (for files, wide terminals).
WIDE_COLUMNS = 400


def fit_table(table: Table, width: int) -> Table:
    """Let a table fit ``width`` columns without ever splitting a word or a number.

    A number or a name cut in two misreads (``resonance_damping=0.`` / ``01``), so a
    cell wraps only at spaces: each column gets at least its longest word (numbers
    their whole width) and the rest of the room in proportion to what each still
    lacks. When even the longest words do not fit side by side, the table turns
    vertical: one ``column: value`` line per cell, a record after another. A table
    that fits already is left alone; ``--wide`` prints at the natural width.
    """
    cols = table.columns
    if not cols:
        return table
    if table.title is not None:  # the title wraps at the table's width: a path stays whole
        longest = min(width, _longest_word(_plain(table.title)))
        table.min_width = max(table.min_width or 0, longest)
    cells = [[_plain(c) for c in col.cells] for col in cols]
    heads = [_plain(col.header) for col in cols]
    natural = [max(_longest_line(x) for x in [h, *cs]) for h, cs in zip(heads, cells, strict=True)]
    numeric = [bool(cs) and all(_looks_numeric(c) for c in cs) for cs in cells]
    for col, num in zip(cols, numeric, strict=True):
        col.overflow = "fold"  # only a word longer than the whole table folds
        if num:
            col.justify = "right"
    room = width - _frame(table)
    if sum(natural) <= room:
        return table
    # the floor of a column: its longest word (a number: its longest cell, whole;
    # headers wrap at spaces)
    floor = [max(_longest_word(heads[i]),
                 *(_longest_line(c) if numeric[i] else _longest_word(c) for c in cells[i]))
             for i in range(len(cols))]  # fmt: skip
    if sum(floor) > room:
        return _vertical(table, heads, width) if len(cols) > 2 or table.show_header else table
    spare = room - sum(floor)
    extra = [n - f for n, f in zip(natural, floor, strict=True)]
    total = sum(extra) or 1
    widths = [f + e * spare // total for f, e in zip(floor, extra, strict=True)]
    for col, w in zip(cols, widths, strict=True):
        col.width = w
    return table


def _plain(cell: Any) -> str:
    if isinstance(cell, Text):
        return cell.plain
    return Text.from_markup(cell).plain if isinstance(cell, str) else str(cell)


def _longest_line(text: str) -> int:
    return max((cell_len(line) for line in text.splitlines()), default=0)


def _longest_word(text: str) -> int:
    # rich wraps words with their leading spaces (" aa" is one word of 3 cells)
    return max((cell_len(w) for w in re.findall(r"\s*\S+", text)), default=0)


def _frame(table: Table) -> int:
    """Columns taken by the borders and the padding of ``table``."""
    n = len(table.columns)
    _, right, _, left = table.padding
    pad = (left + right) * (n if table.pad_edge else max(n - 1, 0))
    if table.box is None:
        return pad
    return pad + (n - 1) + (2 if table.show_edge else 0)


def _vertical(table: Table, heads: list[str], width: int) -> Table:
    """The rows of ``table`` as ``column  value`` lines, one record after another."""
    tall = Table(title=table.title, show_header=False, title_justify=table.title_justify,
                 box=table.box, show_lines=False)  # fmt: skip
    tall.add_column("column", style="bold")
    tall.add_column("value")
    rows = list(zip(*(col.cells for col in table.columns), strict=True))
    for r, row in enumerate(rows):
        for i, (head, cell) in enumerate(zip(heads, row, strict=True)):
            last = i == len(heads) - 1 and r < len(rows) - 1
            tall.add_row(head or f"#{i + 1}", cell, end_section=last)
    return fit_table(tall, width)


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
_OUTPUT_FILES = {"json_path": "--json", "out_path": "--out", "rows_path": "--rows",
                 "plot_path": "--plot"}  # fmt: skip
_OUTPUT_FOLDERS = {"out_dir": "--out", "state": "--state"}
_FIGURES = {"plots": "--plots"}
#: What the commands read (argument name -> how a message names it).
_INPUTS = ("recording", "recordings", "campaign", "manifest", "data", "config", "model",
           "diagnosis", "loop_json")  # fmt: skip
_EFFECT_OPTIONS = {"effect": "--effect", "add_effect": "--add-effect", "only": "--only"}
#: ``--json -``: the result goes to stdout (and the tables to stderr).
STDOUT = Path("-")


def check_arguments(kwargs: dict[str, Any]) -> None:
    """Validate the shared options (rates, knobs, seeds, effects, URIs, outputs) first.

    See :mod:`stiffnet.inputs`: ``--fs``/``--fn`` in physical ranges, ``--threads``
    and ``--workers`` at most the available cores, ``--seed`` a numpy seed, effect
    names resolved without importing anything foreign, the tracking URI usable, and
    every output usable, none on an input, inside one or on another output.
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
    inputs.seed(kwargs.get("seed"))
    _check_effects(kwargs)
    if kwargs.get("tracking", True) is not False:
        inputs.tracking_uri(kwargs.get("tracking_uri"))
    outputs: dict[str, tuple[Path, str]] = {}
    for name, flag in _OUTPUT_FILES.items():
        if kwargs.get(name) is not None and kwargs[name] != STDOUT:
            outputs[flag] = (inputs.output_file(kwargs[name], flag), "file")
    for name, flag in _OUTPUT_FOLDERS.items():
        if kwargs.get(name) is not None:
            outputs[flag] = (inputs.output_folder(kwargs[name], flag), "folder")
    for name, flag in _FIGURES.items():
        if kwargs.get(name) is not None:
            outputs[flag] = (inputs.figure_folder(kwargs[name], flag), "folder")
    # paths only (`train --model gbm` names a family); a folder or glob of recordings is
    # text, and so is `log`'s recording (`-` is stdin)
    text_inputs = ("recordings", "recording")
    ins = {name: Path(kwargs[name]) for name in _INPUTS
           if (isinstance(kwargs.get(name), Path) or (name in text_inputs and kwargs.get(name)
                                                      and kwargs[name] != "-"))
           and os.path.lexists(str(kwargs[name]))}  # fmt: skip
    if outputs and "recording" in ins and ins["recording"].is_file():
        ins.update(_read_beside(ins["recording"]))
    inputs.check_outputs(outputs, ins)


def _read_beside(recording: Path) -> dict[str, Path]:
    """What a command reading one recording reads beside it: its sidecar (f_n, the data
    sheet) and its campaign's manifest (its row): inputs no output may replace."""
    from stiffnet.campaign.manifest import campaign_manifest_above
    from stiffnet.recordings.sidecar import sidecar_path

    found = {"recording's sidecar": sidecar_path(recording),
             "recording's campaign manifest": campaign_manifest_above(recording)}  # fmt: skip
    return {name: path for name, path in found.items() if path is not None and path.is_file()}


def _check_effects(kwargs: dict[str, Any]) -> None:
    """Effect options resolve to stiffnet effects with valid values, before any work."""
    specs = [(flag, text) for name, flag in _EFFECT_OPTIONS.items()
             for text in kwargs.get(name) or ()]  # fmt: skip
    if not specs:
        return
    from stiffnet.effects.registry import check_effect_option

    for flag, text in specs:
        check_effect_option(text, flag)


def _locked_outputs(kwargs: dict[str, Any]) -> list[Path]:
    """Outputs the command itself writes (folders are locked by the library's writers)."""
    names = (*_OUTPUT_FILES, *_FIGURES)
    return [Path(kwargs[n]) for n in names if kwargs.get(n) is not None and kwargs[n] != STDOUT]


#: errno values of a failing environment (exit 1), not of a wrong input (exit 2).
_ENVIRONMENT_ERRNOS = {errno.ENOSPC, errno.EDQUOT, errno.EIO, errno.EROFS, errno.ENOMEM}


def _environment_message(exc: OSError) -> tuple[str, int]:
    where = f"{exc.filename}: " if exc.filename else ""
    what = exc.strerror or type(exc).__name__
    if exc.errno in (errno.ENOSPC, errno.EDQUOT):
        return f"{where}{what} (nothing half-written was kept; free space and run again)", 1
    return f"{where}{what}", 1 if exc.errno in _ENVIRONMENT_ERRNOS else 2


def user_errors(fn: F) -> F:
    """Check shared options first, hold the outputs' locks, and report failures in one line.

    A :class:`StiffnetError` is exit 2 (1 for an
    :class:`~stiffnet.errors.EnvironmentFailure`); a full disk or another failing
    file system is exit 1; a CSV the parser refuses or input nested too deeply for
    Python is exit 2. Never a traceback.
    """

    @functools.wraps(fn)
    def wrapper(*args: Any, **kwargs: Any) -> Any:
        from stiffnet.inputs import HINT_CONTEXT

        # a command with --columns takes hints for its options; the others read a
        # campaign's recordings: hints for the manifest's columns
        hints = HINT_CONTEXT.set("cli" if "columns" in kwargs else "manifest")
        try:
            check_arguments(kwargs)
            if kwargs.get("json_path") == STDOUT:
                out.file = sys.stderr  # stdout holds the JSON alone
            with ExitStack() as stack:
                from stiffnet.io_utils import output_lock

                for path in _locked_outputs(kwargs):
                    stack.enter_context(output_lock(path))
                if kwargs.get("plots") is not None:  # claimed first: a failed run's figures
                    from stiffnet.inputs import mark_figure_folder  # can be replaced later

                    mark_figure_folder(Path(kwargs["plots"]))
                rv = fn(*args, **kwargs)
            return rv
        except StiffnetError as exc:
            report_error(exc)
            raise typer.Exit(getattr(exc, "exit_code", 2)) from None
        except OSError as exc:
            message, code = _environment_message(exc)
            report_error(message)
            raise typer.Exit(code) from None
        except csv.Error as exc:
            report_error(f"malformed CSV ({exc}); a cell or line is too long or badly quoted")
            raise typer.Exit(2) from None
        except RecursionError:
            report_error("an input is nested too deeply to read (a JSON or YAML document)")
            raise typer.Exit(2) from None
        finally:
            out.file = None  # type: ignore[assignment]  # back to sys.stdout
            HINT_CONTEXT.reset(hints)

    return wrapper  # type: ignore[return-value]


def write_json(path: Path | None, result: Any) -> None:
    """Write ``result`` as JSON to ``path`` (atomically), or to stdout for ``-``."""
    if path is None:
        return
    if path == STDOUT:
        from stiffnet.io_utils import json_text

        sys.stdout.write(json_text(result))
        sys.stdout.flush()
        return
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

"""``stiffnet predict-batch`` (registered by :mod:`stiffnet.cli`).

Everything heavy (Dask, onnxruntime) is imported inside the functions; the shared
console helpers (``user_errors``, ``out``...) come from :mod:`stiffnet.console`.
"""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

from stiffnet.cli_options import (
    ColumnsOption,
    FsOption,
    ModelOption,
    NaturalFrequencyOption,
    SchedulerOption,
    TimeUnitOption,
    WorkersOption,
)


def predict_batch_cmd(
    recordings: Annotated[
        str,
        typer.Argument(
            metavar="DIR_OR_GLOB",
            help="A folder (searched recursively), a glob ('runs/**/*.csv') or one recording.",
        ),
    ],
    out_path: Annotated[
        Path, typer.Option("--out", help="Result table (Parquet), one row per recording.")
    ],
    model: ModelOption = None,
    fn: NaturalFrequencyOption = None,
    fs: FsOption = None,
    columns: ColumnsOption = None,
    time_unit: TimeUnitOption = None,
    part_size: Annotated[int, typer.Option(help="Recordings per task.")] = 16,
    scheduler: SchedulerOption = None,
    workers: WorkersOption = None,
    overwrite: Annotated[bool, typer.Option(help="Replace an existing result table.")] = False,
    resume: Annotated[
        bool, typer.Option(help="Keep the finished parts of an interrupted run.")
    ] = True,
    json_path: Annotated[
        Path | None, typer.Option("--json", help="Also write the summary as JSON to this path.")
    ] = None,
) -> None:
    """Predict many recordings into one Parquet table, in parts, in-process or on Dask.

    A recording that cannot be predicted gets a row with its error; an interrupted run
    resumes without predicting its finished parts again.
    """
    from rich.table import Table

    from stiffnet import progress
    from stiffnet.console import out, show_progress, write_json
    from stiffnet.distributed.batch import predict_batch

    with show_progress(), progress.task("predicting parts") as bar:
        summary = predict_batch(
            recordings,
            out_path,
            model_path=model,
            fs_hz=fs,
            natural_frequency_hz=fn,
            columns=columns,
            time_unit=time_unit,
            part_size=part_size,
            scheduler=scheduler,
            workers=workers,
            overwrite=overwrite,
            resume=resume,
            progress=lambda done, total: bar.update(completed=done, total=total),
        )
    table = Table(title=f"{summary['recordings']} recordings -> {out_path}")
    table.add_column("class")
    table.add_column("recordings", justify="right")
    for name, count in summary["class_counts"].items():
        table.add_row(name, str(count))
    table.add_row("error", str(summary["errors"]))
    out.print(table)
    notes = [f"model {summary['model']['name']}", f"{summary['parts']} part(s)"]
    if summary["parts_kept"]:
        notes.append(f"{summary['parts_kept']} kept from an earlier run")
    if summary["rerun"]:
        notes.append(f"run again by the cluster: {', '.join(summary['rerun'])}")
    out.print(f"{'; '.join(notes)}; {summary['seconds']:.1f} s ({summary['backend']})")
    write_json(json_path, summary)


def register(app: typer.Typer) -> None:
    """Add ``predict-batch`` to the ``stiffnet`` app."""
    from stiffnet.console import user_errors

    app.command("predict-batch")(user_errors(predict_batch_cmd))

"""Command-line options shared by several ``stiffnet`` commands.

A light module (typer and pathlib only): the command modules that
:mod:`stiffnet.cli` assembles import it at module level.
"""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

#: Environment variable that ``--scheduler`` reads (see docs/distributed.md).
SCHEDULER_ENVVAR = "STIFFNET_SCHEDULER"

JsonOption = Annotated[
    Path | None, typer.Option("--json", help="Also write the result as JSON to this path.")
]
SchedulerOption = Annotated[
    str | None,
    typer.Option(
        envvar=SCHEDULER_ENVVAR,
        help="Dask scheduler address (tcp://host:8786): run the tasks on that cluster.",
    ),
]
WorkersOption = Annotated[
    int | None,
    typer.Option(help="Run the tasks on a local Dask cluster of N worker processes."),
]
FsOption = Annotated[
    float | None, typer.Option("--fs", help="Sampling rate in Hz (needed for .npy).")
]
ColumnsOption = Annotated[
    str | None,
    typer.Option(
        "--columns",
        metavar="TIME,ACCEL",
        help="CSV columns holding time and acceleration: header names or 0-based indices "
        "(e.g. time_s,acc_g or 0,3); a single ACCEL means no time column (give --fs). "
        "Default t,accel.",
    ),
]
TimeUnitOption = Annotated[
    str | None,
    typer.Option("--time-unit", metavar="s|ms|us", help="Unit of the CSV time column (default s)."),
]
NaturalFrequencyOption = Annotated[
    float | None,
    typer.Option(
        "--fn",
        help="Natural frequency of the rig in Hz (default: the recording's sidecar "
        "<recording>.json; without either the command refuses).",
    ),
]
ModelOption = Annotated[Path | None, typer.Option(help="ONNX model (default models/cnn.onnx).")]
ChannelOption = Annotated[
    str | None,
    typer.Option(
        "--channel",
        metavar="NAME|INDEX",
        help="Channel of a multi-channel recording: a TDMS channel name (or group/name), a WAV "
        "or NPY column index, a CSV column name or index (required when the file has several).",
    ),
]

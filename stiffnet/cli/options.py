"""Command-line options shared by several ``stiffnet`` commands.

A light module (typer, pathlib and the reader registry, which imports no numpy until a
file is read): the command modules that
:mod:`stiffnet.cli` assembles import it at module level.
"""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

from stiffnet.recordings.registry import channels_help, formats_help, rate_needed_for

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
#: The recording argument's help: the formats from the reader registry.
RECORDING_HELP = f"Recording; the format by its extension: {formats_help()}."
FsOption = Annotated[
    float | None,
    typer.Option(
        "--fs",
        help=f"Sampling rate in Hz (needed for {', '.join(rate_needed_for())}; "
        "otherwise checked against the file's own).",
    ),
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
        "<recording>.json, else the natural_frequency_hz of the campaign manifest listing it; "
        "without any the command refuses).",
    ),
]
SensorOption = Annotated[
    str | None,
    typer.Option(
        "--sensor",
        help="The accelerometer chain's data sheet, KEY=VALUE,... with keys resonance_hz, "
        "resonance_damping, lowpass_hz, lowpass_order, highpass_hz (a stage left out is "
        "none); undone as given instead of fitted (default: the sidecar's 'sensor', else "
        "fitted from the impacts).",
    ),
]
ModelOption = Annotated[Path | None, typer.Option(help="ONNX model (default models/cnn.onnx).")]
ChannelOption = Annotated[
    str | None,
    typer.Option(
        "--channel",
        metavar="NAME|INDEX",
        help=f"Channel of a multi-channel recording (required when the file has several): "
        f"{channels_help()}.",
    ),
]

"""The ``stiffnet`` command line (also ``python -m stiffnet``).

The top of the package: it assembles the app from its own commands and the
command modules of the packages below, which share :mod:`stiffnet.console`;
nothing imports this module.
"""

from __future__ import annotations

import sys
from pathlib import Path
from typing import Annotated, Any

import typer
from rich.table import Table
from typer.core import TyperGroup

# Command modules keep their heavy imports inside the command functions:
# ``stiffnet predict`` must not import torch, scikit-learn or mlflow, and
# ``stiffnet --help`` must stay fast.
from serving import commands as serving_commands  # predict, predict-batch, serve
from stiffnet import progress
from stiffnet.cli_options import (
    ColumnsOption,
    FsOption,
    JsonOption,
    SchedulerOption,
    SensorOption,
    TimeUnitOption,
    WorkersOption,
)
from stiffnet.console import (
    WIDE_COLUMNS,
    out,
    report_error,
    show_progress,
    user_errors,
    write_json,
)
from stiffnet.measurement import commands as measurement_commands  # evaluate ... report


class OneLineErrors(TyperGroup):
    """Usage errors (``--fs abc``, a missing argument) as one ``error:`` line, exit 2.

    Typer would draw a multi-line box; the contract is one line naming the problem.
    """

    def main(self, *args: Any, standalone_mode: bool = True, **kwargs: Any) -> Any:
        if not standalone_mode:
            return super().main(*args, standalone_mode=False, **kwargs)
        try:
            rv = super().main(*args, standalone_mode=False, **kwargs)
        except typer.TyperException as exc:  # typer's (vendored click's) usage errors
            if type(exc).__name__ == "NoArgsIsHelpError":
                exc.show()  # `stiffnet` alone: the help, as before
                sys.exit(exc.exit_code)
            ctx = getattr(exc, "ctx", None)
            hint = f" (see '{ctx.command_path} --help')" if ctx is not None else ""
            message = exc.format_message() if hasattr(exc, "format_message") else str(exc)
            report_error(f"{message}{hint}")
            sys.exit(2)
        except typer.Abort:
            report_error("aborted")
            sys.exit(1)
        sys.exit(rv if isinstance(rv, int) else 0)


app = typer.Typer(
    cls=OneLineErrors,
    name="stiffnet",
    help="Identify the stiffness of an impacted material from one accelerometer.",
    no_args_is_help=True,
    add_completion=False,
    pretty_exceptions_enable=False,
)


@app.callback()
def _options(
    wide: Annotated[
        bool,
        typer.Option(
            "--wide",
            help="Print tables at full width, without wrapping (for wide terminals or files).",
        ),
    ] = False,
) -> None:
    """Identify the stiffness of an impacted material from one accelerometer."""
    out.width = WIDE_COLUMNS if wide else None  # type: ignore[assignment]  # None: auto


@app.command()
@user_errors
def simulate(
    config: Annotated[
        Path | None,
        typer.Option(
            help="Simulation config (YAML); default: stiffnet's configs/sim/default.yaml."
        ),
    ] = None,
    out_dir: Annotated[Path, typer.Option("--out", help="Output dataset folder.")] = Path(
        "data/default"
    ),
    seed: Annotated[int | None, typer.Option(help="Override the config's seed.")] = None,
    n_trajectories: Annotated[
        int | None, typer.Option(help="Override the number of trajectories.")
    ] = None,
    overwrite: Annotated[bool, typer.Option(help="Replace an existing dataset.")] = False,
    resume: Annotated[
        bool, typer.Option(help="Keep the finished shards of an interrupted run.")
    ] = True,
    scheduler: SchedulerOption = None,
    workers: WorkersOption = None,
    json_path: JsonOption = None,
) -> None:
    """Simulate a labelled dataset of acceleration windows (atomic Parquet shards).

    Shards run in-process, on a local Dask cluster (--workers) or on a Dask cluster
    (--scheduler); the dataset is the same either way. An interrupted run resumes.
    """
    from stiffnet.config import load_yaml, validate_config
    from stiffnet.config.sim import SimulationConfig
    from stiffnet.dataset.generate import generate_dataset, shard_sizes
    from stiffnet.shipped import default_config

    config = config or default_config("sim/default.yaml")
    data = load_yaml(config)
    if seed is not None:
        data["seed"] = seed
    if n_trajectories is not None:
        data["n_trajectories"] = n_trajectories
    cfg = validate_config(SimulationConfig, data, str(config))
    with show_progress(), progress.task("simulating shards", len(shard_sizes(cfg))) as bar:
        card = generate_dataset(
            cfg,
            out_dir,
            overwrite=overwrite,
            progress=lambda done, _: bar.update(completed=done),
            scheduler=scheduler,
            workers=workers,
            resume=resume,
        )
    summary = {k: v for k, v in card.items() if k not in ("config", "shards")}
    summary["out"] = str(out_dir)
    table = Table(title=f"dataset {out_dir}")
    table.add_column("class")
    table.add_column("windows", justify="right")
    for name, count in card["class_balance"].items():
        table.add_row(name, str(count))
    out.print(table)
    out.print(f"{card['n_windows']} windows from {card['n_trajectories']} trajectories "
              f"in {card['seconds']:.1f} s (engine: {card['engine']})")  # fmt: skip
    run = card["run"]
    if run["shards_kept"]:
        out.print(f"resumed: {run['shards_kept']} finished shard(s) kept from an earlier run")
    if run["rerun"]:
        out.print(f"run again by the cluster (lost worker or retried error): "
                  f"{', '.join(run['rerun'])}")  # fmt: skip
    write_json(json_path, summary)


@app.command("simulate-campaign")
@user_errors
def simulate_campaign_cmd(
    manifest: Annotated[Path, typer.Argument(help="Manifest CSV of the campaign to simulate.")],
    out_dir: Annotated[Path, typer.Option("--out", help="Output campaign folder.")],
    effect: Annotated[
        list[str] | None,
        typer.Option(help="Effect to add, NAME[:key=value,...] (repeatable; lo..hi is a range)."),
    ] = None,
    seed: Annotated[int, typer.Option(help="Random seed.")] = 0,
    overwrite: Annotated[bool, typer.Option(help="Replace an existing campaign folder.")] = False,
    scheduler: SchedulerOption = None,
    workers: WorkersOption = None,
    json_path: JsonOption = None,
) -> None:
    """Write a synthetic campaign (recordings + manifest) for a manifest, with chosen effects."""
    from stiffnet.effects.registry import build_effect, parse_effect_option

    effects = [build_effect(*parse_effect_option(text)) for text in effect or []]
    from stiffnet.campaign import simulate_campaign

    with show_progress():
        path = simulate_campaign(manifest, out_dir, effects, seed=seed, overwrite=overwrite,
                                 scheduler=scheduler, workers=workers)  # fmt: skip
    result = {"out": str(path), "effects": [repr(e) for e in effects], "seed": seed}
    out.print(f"campaign written to {path} with effects: {', '.join(result['effects']) or 'none'}")
    write_json(json_path, result)


@app.command()
@user_errors
def train(
    data: Annotated[Path, typer.Option("--data", help="Dataset folder from `stiffnet simulate`.")],
    model: Annotated[str, typer.Option(help="Model family: gbm or cnn.")] = "gbm",
    config: Annotated[
        Path | None,
        typer.Option(help="Training config (YAML); default: stiffnet's configs/train/MODEL.yaml."),
    ] = None,
    out_dir: Annotated[
        Path | None,
        typer.Option(
            "--out",
            help="Folder for the ONNX model and card (default: a fresh runs/train-MODEL-TIME; "
            "the shipped models/ is only replaced when named).",
        ),
    ] = None,
    tracking_uri: Annotated[
        str | None, typer.Option(help="MLflow tracking URI (default: the config's, sqlite).")
    ] = None,
    json_path: JsonOption = None,
) -> None:
    """Train a stiffness model on a dataset, export it to ONNX and track it in MLflow."""
    from stiffnet.config import load_config, validate_config
    from stiffnet.config.train import TrainConfig
    from stiffnet.errors import ConfigError

    if model not in ("gbm", "cnn"):
        raise ConfigError(f"model {model!r} is not available: use gbm or cnn")
    from stiffnet.shipped import default_config

    default = default_config(f"train/{model}.yaml")
    if config is not None:
        cfg = load_config(TrainConfig, config)
    elif default.is_file():
        cfg = load_config(TrainConfig, default)
    else:
        cfg = validate_config(TrainConfig, {"model": model})
    if cfg.model != model:
        raise ConfigError(f"{config or default}: the config trains {cfg.model!r}, not {model!r}")
    from stiffnet.io_utils import fresh_run_folder, output_lock
    from training.train import train as run_training

    out_dir = out_dir or fresh_run_folder(f"train-{model}")
    with output_lock(out_dir), show_progress(), progress.task(f"training {model}"):
        result = run_training(data, cfg, out_dir, tracking_uri=tracking_uri)
    out.print(f"model written to {out_dir}")
    metrics = result.get("metrics", {})
    table = Table(title=f"{model} on {data} (test windows)")
    for col in ("method", "accuracy", "macro-F1", "beta MAPE"):
        table.add_column(col)
    for method in (model, "geometric"):
        values = (metrics.get(f"{method}/{k}", float("nan")) for k in ("accuracy", "macro_f1",
                                                                       "beta_mape"))  # fmt: skip
        table.add_row(method, *(f"{v:.3f}" for v in values))
    out.print(table)
    write_json(json_path, result)


@app.command()
@user_errors
def analyze(
    recording: Annotated[Path, typer.Argument(help="Recording: CSV t,accel, .npy, WAV, TDMS.")],
    fs: FsOption = None,
    columns: ColumnsOption = None,
    time_unit: TimeUnitOption = None,
    plots: Annotated[
        Path | None, typer.Option(help="Write figures (PNG) into this folder.")
    ] = None,
    json_path: JsonOption = None,
    fn: Annotated[
        float | None,
        typer.Option(
            "--fn", help="Natural frequency of the rig in Hz (default 9.48, the paper's)."
        ),
    ] = None,
    sensor: SensorOption = None,
) -> None:
    """Nonlinear time-series analysis, the geometric and the restoring-force estimates."""
    from stiffnet.analyze import analyze_signal
    from stiffnet.recordings import read_recording
    from stiffnet.restoring_force.chain import parse_sensor_option

    sheet = parse_sensor_option(sensor) if sensor is not None else None
    rec = read_recording(recording, fs_hz=fs, columns=columns, time_unit=time_unit)
    analysis = analyze_signal(rec.accel, rec.fs_hz, fn, sensor=sheet)
    result = {"recording": str(recording), **analysis.summary()}
    table = Table(title=f"analysis of {recording}", show_header=False)
    for key, value in result.items():
        if isinstance(value, dict):  # the restoring-force details: in the JSON only
            continue
        table.add_row(key, f"{value:.4g}" if isinstance(value, float) else str(value))
    out.print(table)
    if plots is not None:
        from stiffnet.plots import analysis_plots

        result["plots"] = [str(p) for p in analysis_plots(analysis, rec.accel, plots)]
        out.print(f"figures written to {plots}")
    write_json(json_path, result)


@app.command()
@user_errors
def effects(json_path: JsonOption = None) -> None:
    """List the physical effects with their parameters, defaults and ranges."""
    from stiffnet.effects.registry import available_effects

    result = []
    for cls in available_effects():
        table = Table(title=f"{cls.name} ({cls.kind})", title_justify="left")
        for col in ("parameter", "default", "range", "unit", "description"):
            table.add_column(col)
        rows = cls.parameter_table()
        for row in rows:
            lo, hi = row["range"]
            table.add_row(row["name"], f"{row['default']:g}", f"[{lo:g}, {hi:g}]", row["unit"],
                          row["description"])  # fmt: skip
        out.print(table)
        doc = (cls.__doc__ or "").strip().splitlines()
        result.append({"name": cls.name, "kind": cls.kind, "summary": doc[0] if doc else "",
                       "parameters": rows})  # fmt: skip
    write_json(json_path, result)


for _commands in (serving_commands, measurement_commands):
    _commands.register(app)


def main() -> None:
    """Entry point of the console script."""
    app(prog_name="stiffnet")


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())

"""The ``stiffnet`` command line (also ``python -m stiffnet``).

The top of the package: it assembles the app from its own commands and the
command modules of the packages below, which share :mod:`stiffnet.cli.console`;
nothing imports this module.
"""

from __future__ import annotations

import inspect
import os
import sys
from pathlib import Path
from typing import Annotated, Any

import typer
from rich.table import Table
from typer.core import TyperGroup

from stiffnet import progress
from stiffnet.cli import measurement as measurement_commands  # evaluate ... report

# Command modules keep their heavy imports inside the command functions:
# ``stiffnet predict`` must not import torch, scikit-learn or mlflow, and
# ``stiffnet --help`` must stay fast.
from stiffnet.cli import predict as serving_commands  # predict, predict-batch, serve
from stiffnet.cli.console import (
    WIDE_COLUMNS,
    out,
    report_error,
    show_progress,
    user_errors,
    write_json,
)
from stiffnet.cli.options import (
    RECORDING_HELP,
    ChannelOption,
    ColumnsOption,
    FsOption,
    JsonOption,
    SchedulerOption,
    SensorOption,
    TimeUnitOption,
    WorkersOption,
)


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
            if "--plugin" in message or "--version" in message:  # options of `stiffnet` itself
                hint = " (give it before the command: stiffnet --plugin FILE.py COMMAND ...)"
            report_error(f"{message}{hint}")
            sys.exit(2)
        except typer.Abort:
            report_error("aborted")
            sys.exit(1)
        sys.exit(rv if isinstance(rv, int) else 0)

    def get_command(self, ctx: Any, cmd_name: str) -> Any:
        command = super().get_command(ctx, cmd_name)
        if command is not None and command.help:
            command.help = reflowed_help(command.help)
        return command


def reflowed_help(text: str) -> str:
    """A command's docstring with each paragraph on one line and ``code`` marks shown bare.

    Typer keeps the line breaks of every paragraph past the first, so at 80 columns a
    docstring's own wrapping and the terminal's cut a sentence into short lines; rich
    markup shows double backticks as they are. A paragraph starting with click's ``\\b``
    (keep as written) and what follows ``\\f`` (hidden) are left alone.
    """
    paragraphs = inspect.cleandoc(text).split("\n\n")
    for i, paragraph in enumerate(paragraphs):
        if paragraph.startswith(("\b", "\f")):
            break
        paragraphs[i] = " ".join(paragraph.split()).replace("``", "")
    return "\n\n".join(paragraphs)


app = typer.Typer(
    cls=OneLineErrors,
    name="stiffnet",
    help="Identify the stiffness of an impacted material from one accelerometer.",
    no_args_is_help=True,
    add_completion=True,  # --install-completion / --show-completion (bash, zsh, fish, pwsh)
    pretty_exceptions_enable=False,
)


def _version(value: bool) -> None:
    if value:
        from stiffnet import __version__

        typer.echo(f"stiffnet {__version__}")
        raise typer.Exit()


def _plugins(paths: list[Path] | None) -> list[Path] | None:
    """Load each ``--plugin`` file now: its effects are then known by ``module:Class``."""
    from stiffnet.errors import StiffnetError

    for path in paths or []:
        from stiffnet.effects.registry import register_plugin

        try:
            register_plugin(path)
        except StiffnetError as exc:
            raise typer.BadParameter(str(exc), param_hint="--plugin") from None
    return paths


@app.callback()
def _options(
    wide: Annotated[
        bool,
        typer.Option(
            "--wide",
            help="Print tables at full width, without wrapping (for wide terminals or files).",
        ),
    ] = False,
    plugin: Annotated[
        list[Path] | None,
        typer.Option(
            "--plugin",
            metavar="FILE.py",
            callback=_plugins,
            help="Load user effects from this Python file (repeatable): name them "
            "MODULE:Class, MODULE being the file's name without .py. Effect names never "
            "import anything else (not from the working folder).",
        ),
    ] = None,
    version: Annotated[
        bool,
        typer.Option(
            "--version", callback=_version, is_eager=True, help="Print the version and exit."
        ),
    ] = False,  # fmt: skip
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


def _train_config(family: str | None, config: Path | None) -> Any:
    """The training config: `config`, else the shipped ``configs/train/FAMILY.yaml``."""
    from stiffnet.config import load_config, validate_config
    from stiffnet.errors import ConfigError
    from stiffnet.shipped import default_config
    from training.config import TrainConfig
    from training.families import default_family, get_family

    if config is not None:
        cfg = load_config(TrainConfig, config)
        if family is not None and cfg.model != family:
            raise ConfigError(f"{config}: the config trains {cfg.model!r}, not {family!r}")
        return cfg
    name = get_family(family).name if family is not None else default_family("train").name
    default = default_config(f"train/{name}.yaml")
    if default.is_file():
        return load_config(TrainConfig, default)
    return validate_config(TrainConfig, {"model": name})


@app.command()
@user_errors
def train(
    data: Annotated[Path, typer.Option("--data", help="Dataset folder from `stiffnet simulate`.")],
    family: Annotated[
        str | None,
        typer.Option(
            "--family",
            help="Model family (`stiffnet families` lists them; default: the config's, else "
            "the family marked as train's default there).",
        ),
    ] = None,
    model: Annotated[
        str | None,
        typer.Option("--model", help="Deprecated: the old name of --family.", hidden=True),
    ] = None,
    config: Annotated[
        Path | None,
        typer.Option(help="Training config (YAML); default: stiffnet's configs/train/FAMILY.yaml."),
    ] = None,
    out_dir: Annotated[
        Path | None,
        typer.Option(
            "--out",
            help="Folder for the ONNX model and card (default: a fresh runs/train-FAMILY-TIME; "
            "the shipped models/ is only replaced when named).",
        ),
    ] = None,
    tracking_uri: Annotated[
        str | None, typer.Option(help="MLflow tracking URI (default: the config's, sqlite).")
    ] = None,
    json_path: JsonOption = None,
) -> None:
    """Train a stiffness model on a dataset, export it to ONNX and track it in MLflow."""
    from stiffnet.cli.console import console
    from stiffnet.errors import ConfigError

    if model is not None:
        if family is not None and family != model:
            raise ConfigError(f"--model {model} and --family {family} disagree: use --family")
        console.print("note: `train --model` is deprecated (it is a file elsewhere): use --family")
        family = model
    cfg = _train_config(family, config)
    from stiffnet.inputs import tracking_uri as checked_uri
    from stiffnet.io_utils import claim_run_folder, finish_run_folder, fresh_run_folder, output_lock

    if cfg.tracking and tracking_uri is None:  # the config's URI: checked before the work too
        checked_uri(cfg.tracking_uri, f"{config or 'the training config'}: tracking_uri")
    name = str(cfg.model)
    out_dir = out_dir or fresh_run_folder(f"train-{name}")
    with output_lock(out_dir):
        marker = claim_run_folder(out_dir, "stiffnet-train")  # a foreign folder: refused
        from training.train import train as run_training

        with show_progress(), progress.task(f"training {name}"):
            result = run_training(data, cfg, out_dir, tracking_uri=tracking_uri)
        finish_run_folder(out_dir, marker)
    out.print(f"model written to {out_dir}")
    metrics = result.get("metrics", {})
    table = Table(title=f"{name} on {data} (test windows)")
    for col in ("method", "accuracy", "macro-F1", "beta MAPE"):
        table.add_column(col)
    for method, prefix in ((name, ""), ("geometric", "geometric/")):
        values = (metrics.get(f"{prefix}{k}", float("nan")) for k in ("accuracy", "macro_f1",
                                                                        "beta_mape"))  # fmt: skip
        table.add_row(method, *(f"{v:.3f}" for v in values))
    out.print(table)
    write_json(json_path, result)


@app.command()
@user_errors
def families(json_path: JsonOption = None) -> None:
    """List the model families `train`, `loop` and `recalibrate` know."""
    from training.families import families as registered

    table = Table(title="model families")
    for col in ("family", "model_kind", "ONNX input", "default of", "module"):
        table.add_column(col)
    result = []
    for name, cls in registered().items():
        row = {
            "family": name,
            "model_kind": cls.serving.model_kind,
            "input": cls.serving.input_name,
            "default_of": list(cls.defaults),
            "module": cls.__module__,
        }
        result.append(row)
        table.add_row(name, row["model_kind"], row["input"], ", ".join(cls.defaults), row["module"])
    out.print(table)
    write_json(json_path, result)


@app.command()
@user_errors
def recalibrate(
    model: Annotated[Path, typer.Argument(help="The trained model (NAME.onnx with its card).")],
    data: Annotated[Path, typer.Option("--data", help="The dataset it was trained on.")],
    config: Annotated[
        Path | None,
        typer.Option(help="Training config (YAML); default: stiffnet's configs/train/FAMILY.yaml."),
    ] = None,
    json_path: JsonOption = None,
    calibration_set: Annotated[
        bool,
        typer.Option(
            "--calibration-set",
            help="DATA is an independent set simulated from the current priors: refit only "
            "the interval's conformal quantile on all of it (the alarm is kept).",
        ),
    ] = False,
) -> None:
    """Refit a trained model's interval and alarm (its ONNX metadata and card updated in place)."""
    from stiffnet.io_utils import output_lock
    from training.recalibrate import recalibrate as run_recalibration
    from training.recalibrate import recalibrate_interval, recalibration_config

    cfg = recalibration_config(model, config)
    with output_lock(model.parent):
        if calibration_set:
            result = recalibrate_interval(model, data, cfg.coverage)
        else:
            result = run_recalibration(model, data, cfg)
    out.print(f"recalibrated {model}: " + ", ".join(f"{k} {v}" for k, v in result.items()))
    write_json(json_path, result)


@app.command()
@user_errors
def analyze(
    recording: Annotated[Path, typer.Argument(help=RECORDING_HELP)],
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
            "--fn",
            help="Natural frequency of the rig in Hz (default: the sidecar <recording>.json; "
            "without either the restoring-force estimate is not run).",
        ),
    ] = None,
    channel: ChannelOption = None,
    sensor: SensorOption = None,
) -> None:
    """Nonlinear time-series analysis, the geometric and the restoring-force estimates."""
    from stiffnet.analyze import analyze_signal
    from stiffnet.recordings import natural_frequency_of, read_recording
    from stiffnet.restoring_force.chain import parse_sensor_option

    sheet = parse_sensor_option(sensor) if sensor is not None else None
    rec = read_recording(recording, fs_hz=fs, channel=channel, columns=columns,
                         time_unit=time_unit)  # fmt: skip
    fn, fn_source = natural_frequency_of(recording, fn)
    analysis = analyze_signal(rec.accel, rec.fs_hz, fn, sensor=sheet)
    result = {"recording": str(recording), **analysis.summary()}
    result["natural_frequency_source"] = fn_source
    table = Table(title=f"analysis of {recording}", show_header=False)
    for key, value in result.items():
        if isinstance(value, dict | list):  # details (restoring force, spans): the JSON only
            continue
        table.add_row(key, f"{value:.4g}" if isinstance(value, float) else str(value))
    rf = result.get("restoring_force") or {}
    if rf.get("beta") is None and rf.get("reason"):  # a None beta with why, not in silence
        table.add_row("restoring_force_reason", str(rf["reason"]))
    out.print(table)
    if plots is not None:
        from stiffnet.plots import analysis_plots

        result["plots"] = [str(p) for p in analysis_plots(analysis, rec.accel, plots)]
        out.print(f"figures written to {plots}")
    write_json(json_path, result)


@app.command()
@user_errors
def effects(json_path: JsonOption = None) -> None:
    """List the physical effects (shipped, then plugins') with their parameters and ranges."""
    from stiffnet.effects.registry import available_effects, user_effects

    result = []
    named = [(cls.name, cls) for cls in available_effects()]
    for name, cls in [*named, *user_effects()]:
        table = Table(title=f"{name} ({cls.kind})", title_justify="left")
        for col in ("parameter", "default", "range", "unit", "description"):
            table.add_column(col)
        rows = cls.parameter_table()
        for row in rows:
            lo, hi = row["range"]
            table.add_row(row["name"], f"{row['default']:g}", f"[{lo:g}, {hi:g}]", row["unit"],
                          row["description"])  # fmt: skip
        out.print(table)
        doc = (cls.__doc__ or "").strip().splitlines()
        result.append({"name": name, "kind": cls.kind, "summary": doc[0] if doc else "",
                       "parameters": rows})  # fmt: skip
    write_json(json_path, result)


for _commands in (serving_commands, measurement_commands):
    _commands.register(app)


#: Variables OpenBLAS reads for its thread count, in its order of precedence; a user who set
#: one has chosen, and keeps the choice.
BLAS_THREAD_VARIABLES = ("OPENBLAS_NUM_THREADS", "GOTO_NUM_THREADS", "OMP_NUM_THREADS")


def single_threaded_blas(environ: dict[str, str] | os._Environ = os.environ) -> bool:
    """Give numpy's and scipy's OpenBLAS one thread, unless the user chose a count.

    Stiffnet's numerics are many small problems (least squares over a campaign's impacts,
    the sparse products of their solvers, filters of one record), too small for BLAS to
    share, run beside the diagnosis's own worker processes. On 2 cores OpenBLAS's default
    of a thread per core makes its threads wait on each other: the contact-law discovery
    of a 24-recording campaign took over 300 s of CPU at a load of 8-13, and 12.6 s with
    one thread. Set before numpy loads OpenBLAS (the command line imports it lazily), so
    it holds for this process and the processes it starts; only ``OPENBLAS_NUM_THREADS``
    is set, so torch's and scikit-learn's OpenMP threads keep their defaults.

    Returns whether the variable was set.
    """
    if any(name in environ for name in BLAS_THREAD_VARIABLES):
        return False
    environ["OPENBLAS_NUM_THREADS"] = "1"
    return True


def main() -> None:
    """Entry point of the console script."""
    single_threaded_blas()
    app(prog_name="stiffnet")


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())

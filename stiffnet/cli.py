"""The ``stiffnet`` command line (also ``python -m stiffnet``)."""

from __future__ import annotations

import functools
import importlib
import sys
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Annotated, Any, TypeVar

import typer
from rich.console import Console
from rich.table import Table
from rich.text import Text

from stiffnet import progress
from stiffnet.cli_options import (
    ColumnsOption,
    FsOption,
    JsonOption,
    SchedulerOption,
    TimeUnitOption,
    WorkersOption,
)
from stiffnet.errors import StiffnetError

app = typer.Typer(
    name="stiffnet",
    help="Identify the stiffness of an impacted material from one accelerometer.",
    no_args_is_help=True,
    add_completion=False,
    pretty_exceptions_enable=False,
)
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


console = Console(stderr=True)
out = _Out()


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
    )
    with bar, progress.reporting(bar):
        yield


@app.command()
@user_errors
def simulate(
    config: Annotated[Path, typer.Option(help="Simulation config (YAML).")] = Path(
        "configs/sim/default.yaml"
    ),
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
        Path | None, typer.Option(help="Training config (YAML); default configs/train/MODEL.yaml.")
    ] = None,
    out_dir: Annotated[
        Path, typer.Option("--out", help="Folder for the ONNX model and card.")
    ] = Path("models"),
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
    default = Path("configs/train") / f"{model}.yaml"
    if config is not None:
        cfg = load_config(TrainConfig, config)
    elif default.is_file():
        cfg = load_config(TrainConfig, default)
    else:
        cfg = validate_config(TrainConfig, {"model": model})
    if cfg.model != model:
        raise ConfigError(f"{config or default}: the config trains {cfg.model!r}, not {model!r}")
    from training.train import train as run_training

    with show_progress(), progress.task(f"training {model}"):
        result = run_training(data, cfg, out_dir, tracking_uri=tracking_uri)
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
) -> None:
    """Nonlinear time-series analysis and the geometric stiffness estimate of a recording."""
    from stiffnet.analyze import analyze_signal
    from stiffnet.recordings import read_recording

    rec = read_recording(recording, fs_hz=fs, columns=columns, time_unit=time_unit)
    analysis = analyze_signal(rec.accel, rec.fs_hz)
    result = {"recording": str(recording), **analysis.summary()}
    table = Table(title=f"analysis of {recording}", show_header=False)
    for key, value in result.items():
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


#: Modules that add commands to `app` through ``register(app)``. They keep their heavy
#: imports inside the command functions: ``stiffnet predict`` must not import torch,
#: scikit-learn or mlflow, and ``stiffnet --help`` must stay fast.
COMMAND_MODULES = (
    "serving.commands",  # predict, serve
    "stiffnet.measurement.commands",  # evaluate, compare, diagnose, loop, report
    "stiffnet.distributed.commands",  # predict-batch
)
for _module in COMMAND_MODULES:
    importlib.import_module(_module).register(app)


def main() -> None:
    """Entry point of the console script."""
    app(prog_name="stiffnet")


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())

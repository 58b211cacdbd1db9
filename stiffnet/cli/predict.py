"""``stiffnet predict``, ``predict-batch`` and ``serve`` (registered by :mod:`stiffnet.cli`).

Heavy imports (onnxruntime, FastAPI, uvicorn, Dask) stay inside the command functions,
so ``stiffnet --help`` stays fast and ``stiffnet predict`` never loads torch,
scikit-learn or mlflow. The shared console helpers come from :mod:`stiffnet.cli.console`.
"""

from __future__ import annotations

import re
from pathlib import Path
from typing import Annotated, Any

import typer

from stiffnet.cli.options import (
    RECORDING_HELP,
    ChannelOption,
    ColumnsOption,
    FsOption,
    JsonOption,
    ModelOption,
    NaturalFrequencyOption,
    SchedulerOption,
    SensorOption,
    TimeUnitOption,
    WorkersOption,
)


def predict(
    recording: Annotated[Path, typer.Argument(help=RECORDING_HELP)],
    fs: FsOption = None,
    fn: NaturalFrequencyOption = None,
    columns: ColumnsOption = None,
    time_unit: TimeUnitOption = None,
    channel: ChannelOption = None,
    model: ModelOption = None,
    threads: Annotated[int, typer.Option(help="ONNX Runtime threads.")] = 1,
    json_path: JsonOption = None,
    sensor: SensorOption = None,
) -> None:
    """Stiffness class and beta of a recording by the ONNX model, cross-checked geometrically.

    A recording listed in the manifest of the campaign folder it sits in is read with its
    row (f_n, rate, columns, time unit, channel, data sheet) where the options leave them
    empty, as ``predict-batch`` reads it; ``--fn`` still wins."""
    from serving.batch_prediction import row_settings
    from serving.predictor import Predictor, predict_recording
    from stiffnet.campaign.manifest import campaign_row_of
    from stiffnet.cli.console import out, write_json
    from stiffnet.recordings import require_rate
    from stiffnet.restoring_force.chain import parse_sensor_option

    sheet = parse_sensor_option(sensor) if sensor is not None else None
    listed = campaign_row_of(recording)  # read once: the f_n below reuses it
    if listed is not None:  # its campaign's row, as predict-batch reads it (--fn or not)
        given = (fs, None, columns, time_unit, channel, sheet)
        theirs = list(row_settings(listed[1]))
        if columns is not None or channel is not None:
            # --columns and --channel each say which column to read: the row's say no more
            theirs[2] = theirs[4] = None
        fs, _, columns, time_unit, channel, sheet = (  # f_n: the sidecar's, else the row's
            mine if mine is not None else row for mine, row in zip(given, theirs, strict=True)
        )
    require_rate(recording, fs)  # before loading the model
    predictor = Predictor.load(model, threads=threads)
    result = predict_recording(
        recording,
        fs_hz=fs,
        natural_frequency_hz=fn,
        predictor=predictor,
        columns=columns,
        time_unit=time_unit,
        channel=channel,
        sensor=sheet,
        natural_frequency_source=None if fn is None else "option --fn",
        campaign_row=listed,
        find_row=False,  # read above: the manifest is parsed once
    )
    for renderable in result_tables(result, str(recording)):
        out.print(renderable)
    write_json(json_path, result)


def _num(v: float | None, fmt: str = ".3g") -> str:
    return "-" if v is None else format(v, fmt)


def _source_text(result: dict[str, Any]) -> str:
    """Where f_n came from, short enough for a table cell: a sidecar by its file name (it
    sits beside the recording; the JSON keeps the whole path)."""
    source = str(result["natural_frequency_source"])
    if source.startswith("sidecar:"):
        return "sidecar " + Path(source.removeprefix("sidecar:")).name
    row = re.match(r"manifest:(.+): (line \d+) ", source)  # its campaign's row
    if row:
        return f"{Path(row[1]).name} {row[2]}"
    return source


def result_tables(result: dict[str, Any], title: str) -> list[Any]:
    """Rich renderables of a prediction: summary with the cross-check, probabilities, segments."""
    from rich.table import Table

    p = Table(title="class probabilities (mean over windows)")
    for name in result["probabilities"]:
        p.add_column(name, justify="right")
    p.add_row(*(f"{v:.3f}" for v in result["probabilities"].values()))
    parts: list[Any] = [_summary_table(result, title), p]
    if len(result.get("layers") or []) > 1:
        parts.append(_layers_table(result["layers"]))
    if len(result["segments"]) > 1:
        parts.append(_segments_table(result["segments"]))
    for w in result["warnings"]:
        parts.append(f"[yellow]warning:[/] {w}")
    return parts


def _summary_table(result: dict[str, Any], title: str) -> Any:
    """The model beside the geometric method, the restoring force, the alarm, the inputs."""
    from rich.table import Table

    g = result["geometric"]
    m = result["model"]
    t = Table(title=f"prediction for {title}")
    t.add_column("")
    t.add_column(
        f"model {m['name']}" + (f" ({m['kind']})" if m["kind"] != m["name"] else ""),
        overflow="fold",
    )
    t.add_column("geometric (paper, section 5)")
    interval = result["beta_interval"]
    beta = _num(result["beta"])
    if interval:
        cov = result.get("beta_interval_coverage")
        beta += f"  [{interval[0]:.3g}, {interval[1]:.3g}]"
        beta += f" ({cov:.0%})" if cov else ""
    by_beta = result.get("class_decided_by") == "beta_head"  # near an edge: beta's class
    t.add_row("class", f"[bold]{result['class']}[/]" + (" (from beta)" if by_beta else ""),
              g["class"])  # fmt: skip
    t.add_row("beta", beta, _num(g["beta"]))
    t.add_row(
        "inclination before / after",
        "",
        f"{_num(g['inclination_before_deg'], '.1f')} / "
        f"{_num(g['inclination_after_deg'], '.1f')} deg",
    )
    t.add_row(
        "contact",
        str(result["contact_detected"]),
        f"{g['contact_detected']} ({g['n_windows_with_contact']}/{g['n_windows']} windows)",
    )
    t.add_row("agreement", "[green]yes[/]" if result["agreement"] else "[red]no[/]", "")
    t.add_row("restoring force", _restoring_force_text(result), "")
    for name, text in _alarm_rows(result.get("alarm")):
        t.add_row(name, text, "")
    t.add_row(
        "windows",
        f"{result['n_windows']} x {result['window_s']:.3g} s, hop {result['hop_s']:.3g} s",
        "",
    )
    t.add_row(
        "natural frequency",
        f"{result['natural_frequency_hz']:.4g} Hz ({_source_text(result)})",
        "",
    )
    t.add_row("model sha256", m["sha256"][:16] + "...", "")
    return t


def _restoring_force_text(result: dict[str, Any]) -> str:
    """The restoring-force reading and whether it agrees with the model, or why it refused."""
    rf = result["restoring_force"]
    if rf["beta"] is None:
        return f"{rf['class'] or 'no estimate'}: {rf['reason']}"
    lo, hi = rf["beta_interval"]
    text = f"{rf['class']}, beta {rf['beta']:.3g} [{lo:.3g}, {hi:.3g}]"
    return text + ("  agrees" if result["restoring_force_agreement"] else "  [red]disagrees[/]")


#: The alarm's notes (:func:`stiffnet.uncertainty.unseen_law.with_unseen_law_check`): what the
#: contact-law check could not read, and what would resolve an exponent alarm. A reader of
#: the table needs them as much as a reader of the JSON.
ALARM_NOTES = ("contact_law_unread", "exponent_unread", "exponent_chain_unknown")


def _alarm_rows(alarm: dict[str, Any] | None) -> list[tuple[str, str]]:
    """The alarm's verdict and each check's score against its threshold."""
    if alarm is None:
        return []
    verdict = "[red]UNRELIABLE[/]: " + ", ".join(alarm["fired"]) if alarm["flag"] else (
        "[green]none[/]")  # fmt: skip
    scores = ", ".join(
        # the restoring_force check's score is a log-gap that fires above 0: "0/0" would read
        # as a ratio
        f"{k} log-gap {_num(v)} (fires > 0)"
        if k == "restoring_force"
        else f"{k} {_num(v)}/{_num(alarm['thresholds'][k])}"
        for k, v in alarm["scores"].items()
        if k in alarm["thresholds"]
    )
    notes = [("alarm note", str(alarm[k])) for k in ALARM_NOTES if alarm.get(k)]
    return [("alarm", verdict), ("alarm checks (score/threshold)", scores), *notes]


def _layers_table(layers: list[dict[str, Any]]) -> Any:
    """Where beta changes along the record, each layer with its interval."""
    from rich.table import Table

    t = Table(title="layers: beta changes along this record (the overall beta is a blend)")
    for col in ("from s", "to s", "class", "beta [interval]", "windows"):
        t.add_column(col, justify="right")
    for la in layers:
        iv = la["beta_interval"]
        t.add_row(
            f"{la['start_s']:.1f}" + (f" ±{la['start_sd_s']:.1f}" if la["start_sd_s"] else ""),
            f"{la['end_s']:.1f}" + (f" ±{la['end_sd_s']:.1f}" if la["end_sd_s"] else ""),
            la["class"],
            _num(la["beta"]) + (f" [{iv[0]:.3g}, {iv[1]:.3g}]" if iv else ""),
            str(la["n_points"]),
        )
    return t


def _segments_table(segments: list[dict[str, Any]]) -> Any:
    """The model's reading over consecutive stretches of windows."""
    from rich.table import Table

    t = Table(title="segments")
    for col in ("from s", "to s", "windows", "class", "beta"):
        t.add_column(col, justify="right")
    for seg in segments:
        t.add_row(
            f"{seg['start_s']:.1f}",
            f"{seg['end_s']:.1f}",
            str(seg["n_windows"]),
            seg["class"],
            _num(seg["beta"]),
        )
    return t


#: Environment variable holding the bearer token of ``stiffnet serve`` (``--token``).
TOKEN_ENVVAR = "STIFFNET_TOKEN"
LOOPBACK_NAMES = ("localhost", "127.0.0.1", "::1")


def _opt(kind: type, help_text: str) -> Any:
    """A plain option of `kind` with its help (serve's limits: one line each)."""
    return Annotated[kind, typer.Option(help=help_text)]


def serve(
    host: _opt(str, "Interface to listen on.") = "127.0.0.1",
    port: _opt(int, "TCP port.") = 8000,
    model: ModelOption = None,
    max_upload_mb: _opt(float, "Largest request body in MB (413).") = 20.0,
    timeout_s: _opt(float, "Per-request time limit (504).") = 30.0,
    max_concurrency: _opt(int, "Small predictions running at once (worker threads).") = 2,
    max_queue: _opt(int, "Requests waiting for a worker beyond which 429 is returned.") = 64,
    max_samples: _opt(
        int, "Most samples in one recording (413): bounds compute and memory."
    ) = 2_000_000,
    small_upload_mb: _opt(
        float, "Bodies above this are large: their own lane (1 at a time)."
    ) = 1.0,
    max_large_queue: _opt(int, "Large requests admitted to wait; more get 429 unread.") = 2,
    body_timeout_s: _opt(float, "Whole request body within this time, else 408.") = 20.0,
    body_idle_s: _opt(float, "A body silent this long gets 408 (a stalled upload).") = 5.0,
    header_timeout_s: _opt(float, "Whole request head (line and headers) within this time.") = 10.0,
    token: Annotated[
        str | None,
        typer.Option(
            envvar=TOKEN_ENVVAR,
            show_default=False,
            help=f"Require 'Authorization: Bearer TOKEN' (prefer ${TOKEN_ENVVAR}).",
        ),
    ] = None,  # fmt: skip
    allowed_host: Annotated[
        list[str] | None,
        typer.Option(
            help="Accepted Host header (repeatable; default the loopback names and "
            "--host; '*' accepts any)."
        ),
    ] = None,  # fmt: skip
    cors_origin: Annotated[
        list[str] | None,
        typer.Option(help="Browser origin allowed to call the API (repeatable; default none)."),
    ] = None,
    threads: _opt(int, "ONNX Runtime threads per prediction.") = 1,
) -> None:
    """Serve the predictor over HTTP (FastAPI): POST /predict, GET /health, GET /model."""
    import uvicorn

    from serving.app import Limits, create_app, enable_access_log, guarded_protocol
    from serving.predictor import Predictor
    from serving.warm_up import warm_up
    from stiffnet.cli.console import console
    from stiffnet.errors import StiffnetError

    limits = Limits.checked(
        max_upload_mb, timeout_s, max_concurrency, max_queue, max_samples=max_samples,
        small_upload_mb=small_upload_mb, max_large_queue=max_large_queue,
        body_timeout_s=body_timeout_s, body_idle_s=body_idle_s, header_timeout_s=header_timeout_s,
    )  # fmt: skip
    if not 0 <= port <= 65535:
        raise StiffnetError(f"port must be in 0..65535, got {port}")
    if token is not None and len(token) < 16:
        raise StiffnetError("--token must be at least 16 characters (a random secret)")
    sock = listen_socket(host, port)  # before loading anything: a busy port is one line
    predictor = Predictor.load(model, threads=threads)
    hosts = allowed_host or [*LOOPBACK_NAMES, "[::1]", host]
    if not is_loopback(host):
        console.print(
            f"[yellow]warning:[/] listening on {host}, beyond loopback: other machines can reach "
            f"this server ({'token required' if token else 'no --token set'}; "
            f"Host headers allowed: {', '.join(hosts)})",
            highlight=False,
            soft_wrap=True,
        )
    console.print(
        f"serving {predictor.name} ({predictor.sha256[:12]}) on http://{host}:{port} "
        f"(docs at /docs)"
    )
    app = create_app(predictor, limits, token=token, allowed_hosts=hosts, cors_origins=cors_origin)
    # before the port is served: the first client pays no start-up cost, and a server that
    # cannot predict refuses to start (one line, exit 1)
    console.print(warm_up(app.state.admission), highlight=False, soft_wrap=True)
    enable_access_log()
    config = uvicorn.Config(
        app,
        log_level="warning",
        timeout_keep_alive=5,
        http=guarded_protocol(limits.header_timeout_s),
    )
    uvicorn.Server(config).run(sockets=[sock])


def is_loopback(host: str) -> bool:
    """Whether ``host`` is a loopback name or address."""
    import ipaddress

    if host in LOOPBACK_NAMES:
        return True
    try:
        return ipaddress.ip_address(host.strip("[]")).is_loopback
    except ValueError:
        return False


def listen_socket(host: str, port: int) -> Any:
    """A listening TCP socket on ``host:port``, or one error line (busy port, bad host)."""
    import socket

    from stiffnet.errors import StiffnetError

    try:
        family, kind, proto, _, addr = socket.getaddrinfo(
            host.strip("[]"), port, type=socket.SOCK_STREAM
        )[0]
    except (socket.gaierror, UnicodeError) as exc:
        raise StiffnetError(f"--host {host!r}: cannot resolve it ({exc})") from None
    sock = socket.socket(family, kind, proto)
    sock.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
    try:
        sock.bind(addr)
        sock.listen(2048)
    except OSError as exc:
        sock.close()
        raise StiffnetError(f"cannot listen on {host}:{port}: {exc.strerror}") from None
    sock.set_inheritable(True)
    return sock


def predict_batch_cmd(
    recordings: Annotated[
        str,
        typer.Argument(
            metavar="DIR_OR_GLOB",
            help="A campaign folder (its manifest.csv), a folder (searched recursively), a "
            "glob ('runs/**/*.csv') or one recording.",
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
    channel: ChannelOption = None,
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

    A campaign folder is read through its manifest.csv (fs, f_n, columns, time unit,
    channel per recording). A recording that cannot be predicted gets a row with its
    error, is named on stderr and makes the command exit 1; an interrupted run resumes
    without predicting its finished parts again.
    """
    from rich.table import Table

    from serving.batch_prediction import predict_batch
    from stiffnet import progress
    from stiffnet.campaign.manifest import unlisted_words
    from stiffnet.cli.console import out, show_progress, write_json

    with show_progress(), progress.task("predicting parts") as bar:
        summary = predict_batch(
            recordings,
            out_path,
            model_path=model,
            fs_hz=fs,
            natural_frequency_hz=fn,
            columns=columns,
            time_unit=time_unit,
            channel=channel,
            part_size=part_size,
            scheduler=scheduler,
            workers=workers,
            overwrite=overwrite,
            resume=resume,
            progress=lambda done, total: bar.update(completed=done, total=total),
        )
    # the path on a line of its own: a title wraps at the narrow table's width, inside it
    out.print(f"{summary['recordings']} recordings -> {out_path}", soft_wrap=True, markup=False)
    table = Table()
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
    if summary.get("sensor"):  # a campaign: its one accelerometer's chain, pooled or why not
        out.print(f"sensor chain: {summary['sensor']['reason']}")
    if summary.get("campaign_law"):  # a campaign: its one rig's contact law, judged on all
        out.print(f"contact law: {summary['campaign_law']['message']}")
    if said := unlisted_words(summary.get("unlisted") or []):
        out.print(f"[yellow]warning:[/] {said}")
    write_json(json_path, summary)
    if summary["failed"]:
        from stiffnet.cli.console import console

        for f in summary["failed"]:
            # a reader's error names its file already
            said = f["error"] if f["error"].startswith(f"{f['path']}:") else (
                f"{f['path']}: {f['error']}")  # fmt: skip
            console.print(f"[red]failed:[/] {said}", highlight=False, soft_wrap=True)
        console.print(
            f"[bold red]error:[/] {len(summary['failed'])} of {summary['recordings']} "
            f"recording(s) failed (rows with their error in {out_path})",
            highlight=False,
        )
        raise typer.Exit(1)


def register(app: typer.Typer) -> None:
    """Add ``predict``, ``predict-batch``, ``serve`` and ``log`` to the ``stiffnet`` app."""
    from stiffnet.cli.console import user_errors

    app.command("predict")(user_errors(predict))
    app.command("predict-batch")(user_errors(predict_batch_cmd))
    app.command("serve")(user_errors(serve))
    app.command("log")(user_errors(log_cmd))


def log_cmd(
    recording: Annotated[
        str,
        typer.Argument(
            metavar="RECORDING|-",
            help=RECORDING_HELP + " With --follow a growing file or - (stdin).",
        ),
    ],
    follow: Annotated[
        bool,
        typer.Option(help="Read a growing file or stdin; print points and layers as they come."),
    ] = False,
    fs: FsOption = None,
    fn: NaturalFrequencyOption = None,
    columns: ColumnsOption = None,
    time_unit: TimeUnitOption = None,
    channel: ChannelOption = None,
    model: ModelOption = None,
    hop: Annotated[
        float | None,
        typer.Option(help="Seconds between points (<= 0.5; default configs/log.yaml's, 0.5)."),
    ] = None,
    restoring_force_every: Annotated[
        float | None,
        typer.Option(
            "--restoring-force-every",
            # the option's earlier name, kept so that scripts written before still run
            "--physical-every",
            help="Seconds between restoring-force cross-checks (0: none; default "
            "configs/log.yaml's, 10).",
        ),
    ] = None,
    stream_format: Annotated[
        str, typer.Option(help="--follow: csv (one sample per line) or f32 (raw float32).")
    ] = "csv",
    stream_column: Annotated[
        int | None,
        typer.Option(help="--follow csv: 0-based column of the acceleration (default last)."),
    ] = None,
    idle_timeout: Annotated[
        float | None,
        typer.Option(help="--follow FILE: stop after this many seconds without new samples."),
    ] = 10.0,
    threads: Annotated[int, typer.Option(help="ONNX Runtime threads.")] = 1,
    json_path: JsonOption = None,
    rows_path: Annotated[
        Path | None,
        typer.Option("--rows", help="Points as a table: .csv or .parquet (one row per point)."),
    ] = None,
    plot_path: Annotated[
        Path | None, typer.Option("--plot", help="The log as a PNG picture.")
    ] = None,
    sensor: SensorOption = None,
) -> None:
    """Stiffness log along a record: beta(t) with intervals, layers and their change times."""
    import math

    from serving.log import log_settings
    from serving.predictor import Predictor
    from stiffnet.cli.console import console, out, write_json
    from stiffnet.errors import StiffnetError
    from stiffnet.restoring_force.chain import parse_sensor_option

    _check_log_outputs(rows_path, plot_path)
    sheet = parse_sensor_option(sensor) if sensor is not None else None
    predictor = Predictor.load(model, threads=threads)
    settings = log_settings()
    hop = settings.hop_s if hop is None else hop
    if restoring_force_every is None:
        every = settings.restoring_force_every_s
    elif not (math.isfinite(restoring_force_every) and restoring_force_every >= 0):
        raise StiffnetError(
            f"--restoring-force-every must be >= 0 s, got {restoring_force_every:g}"
        )
    else:
        every = restoring_force_every or None
    if follow:
        stream = (stream_format, stream_column, idle_timeout)
        result = _followed_log(predictor, recording, fs, fn, (columns, time_unit, channel), hop,
                               every, stream, sheet)  # fmt: skip
    else:
        result = _recorded_log(predictor, recording, fs, fn, (columns, time_unit, channel), hop,
                               every, sheet)  # fmt: skip
    for renderable in log_tables(result):
        (console if follow else out).print(renderable)  # a stream's stdout is its NDJSON
    write_json(json_path, result)
    if rows_path is not None:
        write_log_rows(result, rows_path)
    if plot_path is not None:
        from serving.log_plot import log_figure

        log_figure(result, plot_path, (predictor.alarm.info if predictor.alarm else {}).get(
            "class_edges"))  # fmt: skip


#: Points ``log --follow`` keeps for its final outputs (two hours at a 0.5 s hop).
FOLLOW_POINTS = 14_400


def _check_log_outputs(rows_path: Path | None, plot_path: Path | None) -> None:
    """Refuse, before any work, a --rows that is not .csv/.parquet or a --plot not .png."""
    from stiffnet import inputs
    from stiffnet.errors import StiffnetError

    for path, what in ((rows_path, "--rows"), (plot_path, "--plot")):
        inputs.output_file(path, what)
    if rows_path is not None and rows_path.suffix.lower() not in (".csv", ".parquet"):
        raise StiffnetError(f"--rows {rows_path}: use a .csv or .parquet file name")
    if plot_path is not None and plot_path.suffix.lower() != ".png":
        raise StiffnetError(f"--plot {plot_path}: use a .png file name")


def _recorded_log(
    predictor: Any, recording: str, fs: float | None, fn: float | None, reading: tuple,
    hop: float, every: float | None, sheet: dict | None,
) -> dict[str, Any]:  # fmt: skip
    """The log of a recording file, with a progress bar (`reading`: columns, time unit,
    channel; `sheet`: the chain's data sheet, else the sidecar's)."""
    from serving.log import stiffness_log
    from serving.predictor import record_natural_frequency
    from serving.restoring_force_check import sidecar_sensor
    from stiffnet import progress
    from stiffnet.cli.console import show_progress
    from stiffnet.recordings import read_recording

    columns, time_unit, channel = reading
    rec = read_recording(recording, fs_hz=fs, channel=channel, columns=columns,
                         time_unit=time_unit)  # fmt: skip
    fn_value, fn_source = record_natural_frequency(recording, fn)
    with show_progress(), progress.task("logging", total=rec.accel.size) as bar:
        result = stiffness_log(
            predictor, rec.accel, rec.fs_hz, fn_value, hop_s=hop, restoring_force_every_s=every,
            source=rec.source, sensor=sheet if sheet is not None else sidecar_sensor(recording),
            progress=lambda done, total: bar.update(completed=done, total=total),
        )  # fmt: skip
    result["natural_frequency_source"] = fn_source
    return result


def _followed_log(
    predictor: Any, recording: str, fs: float | None, fn: float | None, reading: tuple,
    hop: float, every: float | None, stream: tuple, sheet: dict | None,
) -> dict[str, Any]:  # fmt: skip
    """The log of a growing file or stdin (`stream`: format, column, idle timeout; `sheet`:
    the chain's data sheet, else a file's sidecar's): each point and closed layer printed as
    it comes, the last FOLLOW_POINTS kept for the final outputs."""
    from collections import deque

    from serving.log import StiffnessLogger, log_result
    from serving.predictor import record_natural_frequency
    from serving.restoring_force_check import sidecar_sensor
    from serving.stream import sample_chunks
    from stiffnet import inputs
    from stiffnet.cli.console import console
    from stiffnet.errors import StiffnetError

    if fs is None:
        raise StiffnetError("--follow needs --fs HZ (a stream carries no sampling rate)")
    if any(v is not None for v in reading):
        raise StiffnetError(
            "--columns, --time-unit and --channel read files; a --follow stream takes "
            "--stream-format and --stream-column"
        )
    fn_value, fn_source = record_natural_frequency(None if recording == "-" else recording, fn)
    rate = inputs.sampling_rate(fs, "--fs")
    if sheet is None and recording != "-":
        sheet = sidecar_sensor(recording)
    logger = StiffnessLogger(predictor, rate, fn_value, hop_s=hop, restoring_force_every_s=every,
                             sensor=sheet)  # fmt: skip
    console.print(
        f"following {recording}: window {logger.window_s:.3g} s, hop {logger.hop_s:g} s, "
        f"f_n {fn_value:.4g} Hz ({fn_source})",
        highlight=False,
    )
    # an endless stream keeps the last FOLLOW_POINTS points (and every layer, a few
    # per hour) for the final --json/--rows/--plot: memory stays bounded
    points: deque = deque(maxlen=FOLLOW_POINTS)
    layers: list = []
    stream_format, stream_column, idle_timeout = stream
    chunks = sample_chunks(recording, stream_format, column=stream_column,
                           idle_timeout_s=idle_timeout, fs_hz=rate)  # fmt: skip
    for chunk in chunks:
        for kind, item in logger.feed(chunk):
            _emit(kind, item, points, layers)
    for kind, item in logger.finish():
        _emit(kind, item, points, layers)
    result = log_result(logger, list(points), layers, recording, logger.n_total / logger.fs)
    if logger.segmenter.n_seen > len(points):
        result["warnings"].append(
            f"--json/--rows/--plot hold the last {len(points)} of "
            f"{logger.segmenter.n_seen} points (stdout had them all)"
        )
    result["natural_frequency_source"] = fn_source
    return result


def _emit(kind: str, item: dict[str, Any], points: Any, layers: list) -> None:
    """One NDJSON line on stdout per point or closed layer, flushed (a DAQ reads it live)."""
    import json
    import sys

    (points if kind == "point" else layers).append(item)
    sys.stdout.write(json.dumps({"type": kind, **item}, allow_nan=False) + "\n")
    sys.stdout.flush()


def log_tables(result: dict[str, Any]) -> list[Any]:
    """Rich renderables of a stiffness log: the layers with their changes, and warnings."""
    from rich.table import Table

    t = Table(
        title=f"stiffness log of {result['source'] or 'the stream'}: {len(result['layers'])} "
        f"layer(s), {result['n_points']} points every {result['hop_s']:g} s "
        f"(window {result['window_s']:.3g} s)"
    )
    for col in ("layer", "from s", "to s", "class", "beta [interval]", "alarm", "restoring force"):
        t.add_column(col, justify="right" if col.endswith("s") else "left")
    for la in result["layers"]:
        beta = _num(la["beta"])
        if la["beta_interval"]:
            beta += f" [{la['beta_interval'][0]:.3g}, {la['beta_interval'][1]:.3g}]"
        ph = la["restoring_force"]
        if ph["beta"] is not None:
            rf = f"{ph['beta']:.3g} " + ("agrees" if ph["agreement"] else "[red]disagrees[/]")
        else:
            rf = "-"
        t.add_row(
            str(la["index"]),
            f"{la['start_s']:.1f}" + (f" ±{la['start_sd_s']:.1f}" if la["start_sd_s"] else ""),
            f"{la['end_s']:.1f}" + (f" ±{la['end_sd_s']:.1f}" if la["end_sd_s"] else ""),
            la["class"] + (" (edge)" if la["near_edge"] else ""),
            beta
            + (
                f" (drifts {_num(d['from_beta'])} -> {_num(d['to_beta'])})"
                if (d := la.get("drift"))
                else ""
            ),  # fmt: skip
            f"[red]{la['alarm_fraction']:.0%}[/]" if la["alarm"] else f"{la['alarm_fraction']:.0%}",
            rf,
        )
    parts: list[Any] = [t]
    for c in result["changes"]:
        parts.append(
            f"change at {c['t_s']:.1f} ± {c['sd_s']:.1f} s: {c['from']} -> {c['to']} "
            f"(beta {_num(c['from_beta'])} -> {_num(c['to_beta'])})"
        )
    if not result["changes"]:
        parts.append("no change of beta along this record")
    for w in result["warnings"]:
        parts.append(f"[yellow]warning:[/] {w}")
    return parts


def write_log_rows(result: dict[str, Any], path: Path) -> None:
    """The log's points as a CSV or Parquet table (one row per point), written atomically."""
    import io

    import numpy as np
    import pyarrow as pa

    from stiffnet.io_utils import write_bytes_atomic

    pts = result["points"]
    ends = np.array([la["end_s"] for la in result["layers"]])
    last = len(ends) - 1
    layer_of = [min(int(np.searchsorted(ends, p["t_s"], side="right")), last) for p in pts]
    iv = [p["beta_interval"] or [None, None] for p in pts]
    table = pa.table({
        "t_s": [p["t_s"] for p in pts],
        "beta": [p["beta"] for p in pts],
        "beta_lo": [v[0] for v in iv],
        "beta_hi": [v[1] for v in iv],
        "class": [p["class"] for p in pts],
        "near_edge": [p["near_edge"] for p in pts],
        "alarm": [p["alarm"] for p in pts],
        "alarm_fired": [",".join(p["alarm_fired"]) for p in pts],
        "layer": layer_of,
        "restoring_force_beta": [p.get("restoring_force", {}).get("beta") for p in pts],
    })  # fmt: skip
    buf = io.BytesIO()
    if path.suffix.lower() == ".parquet":
        import pyarrow.parquet as pq

        pq.write_table(table, buf)
    else:
        import pyarrow.csv as pacsv

        pacsv.write_csv(table, buf)
    write_bytes_atomic(path, buf.getvalue())

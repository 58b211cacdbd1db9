"""``stiffnet predict``, ``predict-batch`` and ``serve`` (registered by :mod:`stiffnet.cli`).

Heavy imports (onnxruntime, FastAPI, uvicorn, Dask) stay inside the command functions,
so ``stiffnet --help`` stays fast and ``stiffnet predict`` never loads torch,
scikit-learn or mlflow. The shared console helpers come from :mod:`stiffnet.console`.
"""

from __future__ import annotations

from pathlib import Path
from typing import Annotated, Any

import typer

from stiffnet.cli_options import (
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
    recording: Annotated[Path, typer.Argument(help="Recording: CSV t,accel, .npy, WAV, TDMS.")],
    fs: FsOption = None,
    fn: NaturalFrequencyOption = None,
    columns: ColumnsOption = None,
    time_unit: TimeUnitOption = None,
    model: ModelOption = None,
    threads: Annotated[int, typer.Option(help="ONNX Runtime threads.")] = 1,
    json_path: JsonOption = None,
    sensor: SensorOption = None,
) -> None:
    """Stiffness class and beta of a recording by the ONNX model, cross-checked geometrically."""
    from serving.predictor import Predictor, predict_recording
    from stiffnet.console import out, write_json

    if fs is None and recording.suffix.lower() == ".npy":
        from stiffnet.errors import StiffnetError

        raise StiffnetError(f"{recording}: sampling rate missing (a .npy recording needs --fs HZ)")
    from stiffnet.restoring_force.chain import parse_sensor_option

    sheet = parse_sensor_option(sensor) if sensor is not None else None
    predictor = Predictor.load(model, threads=threads)
    result = predict_recording(
        recording,
        fs_hz=fs,
        natural_frequency_hz=fn,
        predictor=predictor,
        columns=columns,
        time_unit=time_unit,
        sensor=sheet,
    )
    if fn is not None:
        result["natural_frequency_source"] = "option --fn"
    for renderable in result_tables(result, str(recording)):
        out.print(renderable)
    write_json(json_path, result)


def _num(v: float | None, fmt: str = ".3g") -> str:
    return "-" if v is None else format(v, fmt)


def result_tables(result: dict[str, Any], title: str) -> list[Any]:
    """Rich renderables of a prediction: summary with the cross-check, probabilities, segments."""
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
    t.add_row("class", f"[bold]{result['class']}[/]", g["class"])
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
    ph = result["physical"]
    if ph["beta"] is not None:
        lo, hi = ph["beta_interval"]
        rf = f"{ph['class']}, beta {ph['beta']:.3g} [{lo:.3g}, {hi:.3g}]"
        rf += "  agrees" if result["physical_agreement"] else "  [red]disagrees[/]"
    else:
        rf = f"{ph['class'] or 'no estimate'}: {ph['reason']}"
    t.add_row("restoring force", rf, "")
    alarm = result.get("alarm")
    if alarm is not None:
        verdict = "[red]UNRELIABLE[/]: " + ", ".join(alarm["fired"]) if alarm["flag"] else (
            "[green]none[/]")  # fmt: skip
        t.add_row("alarm", verdict, "")
        scores = ", ".join(
            # the physical check's score is a log-gap that fires above 0: "0/0" would read
            # as a ratio
            f"{k} log-gap {_num(v)} (fires > 0)"
            if k == "physical"
            else f"{k} {_num(v)}/{_num(alarm['thresholds'][k])}"
            for k, v in alarm["scores"].items()
            if k in alarm["thresholds"]
        )
        t.add_row("alarm checks (score/threshold)", scores, "")
    t.add_row("windows", f"{result['n_windows']} x {result['window_s']:.3g} s", "")
    t.add_row(
        "natural frequency",
        f"{result['natural_frequency_hz']:.4g} Hz ({result['natural_frequency_source']})",
        "",
    )
    t.add_row("model sha256", m["sha256"][:16] + "...", "")
    p = Table(title="class probabilities (mean over windows)")
    for name in result["probabilities"]:
        p.add_column(name, justify="right")
    p.add_row(*(f"{v:.3f}" for v in result["probabilities"].values()))
    parts: list[Any] = [t, p]
    if len(result["segments"]) > 1:
        s = Table(title="segments")
        for col in ("from s", "to s", "windows", "class", "beta"):
            s.add_column(col, justify="right")
        for seg in result["segments"]:
            s.add_row(
                f"{seg['start_s']:.1f}",
                f"{seg['end_s']:.1f}",
                str(seg["n_windows"]),
                seg["class"],
                _num(seg["beta"]),
            )
        parts.append(s)
    for w in result["warnings"]:
        parts.append(f"[yellow]warning:[/] {w}")
    return parts


#: Environment variable holding the bearer token of ``stiffnet serve`` (``--token``).
TOKEN_ENVVAR = "STIFFNET_TOKEN"
LOOPBACK_NAMES = ("localhost", "127.0.0.1", "::1")


def serve(
    host: Annotated[str, typer.Option(help="Interface to listen on.")] = "127.0.0.1",
    port: Annotated[int, typer.Option(help="TCP port.")] = 8000,
    model: ModelOption = None,
    max_upload_mb: Annotated[float, typer.Option(help="Largest request body in MB (413).")] = 20.0,
    timeout_s: Annotated[float, typer.Option(help="Per-request time limit (504).")] = 30.0,
    max_concurrency: Annotated[
        int, typer.Option(help="Small predictions running at once (worker threads).")
    ] = 2,
    max_queue: Annotated[
        int, typer.Option(help="Requests waiting for a worker beyond which 429 is returned.")
    ] = 64,
    max_samples: Annotated[
        int, typer.Option(help="Most samples in one recording (413): bounds compute and memory.")
    ] = 2_000_000,
    small_upload_mb: Annotated[
        float, typer.Option(help="Bodies above this are large: their own lane (1 at a time).")
    ] = 1.0,
    max_large_queue: Annotated[
        int, typer.Option(help="Large requests admitted to wait; more get 429 unread.")
    ] = 2,
    body_timeout_s: Annotated[
        float, typer.Option(help="Whole request body within this time, else 408.")
    ] = 20.0,
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
    threads: Annotated[int, typer.Option(help="ONNX Runtime threads per prediction.")] = 1,
) -> None:
    """Serve the predictor over HTTP (FastAPI): POST /predict, GET /health, GET /model."""
    import uvicorn

    from serving.app import Limits, create_app
    from serving.predictor import Predictor
    from stiffnet.console import console
    from stiffnet.errors import StiffnetError

    limits = Limits.checked(
        max_upload_mb, timeout_s, max_concurrency, max_queue, max_samples=max_samples,
        small_upload_mb=small_upload_mb, max_large_queue=max_large_queue,
        body_timeout_s=body_timeout_s,
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
    config = uvicorn.Config(app, log_level="warning", timeout_keep_alive=5)
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

    from serving.batch import predict_batch
    from stiffnet import progress
    from stiffnet.console import out, show_progress, write_json

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
    """Add ``predict``, ``predict-batch`` and ``serve`` to the ``stiffnet`` app."""
    from stiffnet.console import user_errors

    app.command("predict")(user_errors(predict))
    app.command("predict-batch")(user_errors(predict_batch_cmd))
    app.command("serve")(user_errors(serve))

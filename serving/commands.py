"""``stiffnet predict`` and ``stiffnet serve`` (registered by :mod:`stiffnet.cli`).

Heavy imports (onnxruntime, FastAPI, uvicorn) stay inside the command functions,
so ``stiffnet --help`` stays fast and ``stiffnet predict`` never loads torch,
scikit-learn or mlflow. The shared console helpers come from :mod:`stiffnet.console`.
"""

from __future__ import annotations

from pathlib import Path
from typing import Annotated, Any

import typer

from stiffnet.cli_options import (
    FsOption,
    JsonOption,
    ModelOption,
    NaturalFrequencyOption,
)


def predict(
    recording: Annotated[Path, typer.Argument(help="Recording: CSV t,accel, .npy, WAV, TDMS.")],
    fs: FsOption = None,
    fn: NaturalFrequencyOption = None,
    model: ModelOption = None,
    threads: Annotated[int, typer.Option(help="ONNX Runtime threads.")] = 1,
    json_path: JsonOption = None,
) -> None:
    """Stiffness class and beta of a recording by the ONNX model, cross-checked geometrically."""
    from serving.predictor import Predictor, predict_recording
    from stiffnet.console import out, write_json

    if fs is None and recording.suffix.lower() == ".npy":
        from stiffnet.errors import StiffnetError

        raise StiffnetError(f"{recording}: sampling rate missing (a .npy recording needs --fs HZ)")
    predictor = Predictor.load(model, threads=threads)
    result = predict_recording(recording, fs_hz=fs, natural_frequency_hz=fn, predictor=predictor)
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
    alarm = result.get("alarm")
    if alarm is not None:
        verdict = "[red]UNRELIABLE[/]: " + ", ".join(alarm["fired"]) if alarm["flag"] else (
            "[green]none[/]")  # fmt: skip
        t.add_row("alarm", verdict, "")
        scores = ", ".join(
            f"{k} {_num(v)}/{_num(alarm['thresholds'][k])}"
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


def serve(
    host: Annotated[str, typer.Option(help="Interface to listen on.")] = "127.0.0.1",
    port: Annotated[int, typer.Option(help="TCP port.")] = 8000,
    model: ModelOption = None,
    max_upload_mb: Annotated[float, typer.Option(help="Largest request body in MB (413).")] = 20.0,
    timeout_s: Annotated[float, typer.Option(help="Per-request time limit (504).")] = 30.0,
    max_concurrency: Annotated[
        int, typer.Option(help="Predictions running at once (worker threads).")
    ] = 2,
    max_queue: Annotated[
        int, typer.Option(help="Requests waiting for a worker beyond which 429 is returned.")
    ] = 64,
    threads: Annotated[int, typer.Option(help="ONNX Runtime threads per prediction.")] = 1,
) -> None:
    """Serve the predictor over HTTP (FastAPI): POST /predict, GET /health, GET /model."""
    import uvicorn

    from serving.app import Limits, create_app
    from serving.predictor import Predictor
    from stiffnet.console import console

    limits = Limits.checked(max_upload_mb, timeout_s, max_concurrency, max_queue)
    predictor = Predictor.load(model, threads=threads)
    if not 0 <= port <= 65535:
        from stiffnet.errors import StiffnetError

        raise StiffnetError(f"port must be in 0..65535, got {port}")
    console.print(
        f"serving {predictor.name} ({predictor.sha256[:12]}) on http://{host}:{port} "
        f"(docs at /docs)"
    )
    uvicorn.run(create_app(predictor, limits), host=host, port=port, log_level="warning")


def register(app: typer.Typer) -> None:
    """Add ``predict`` and ``serve`` to the ``stiffnet`` app."""
    from stiffnet.console import user_errors

    app.command("predict")(user_errors(predict))
    app.command("serve")(user_errors(serve))

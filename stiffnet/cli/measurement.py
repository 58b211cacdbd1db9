"""CLI commands of the measurement loop: ``evaluate``, ``compare``, ``diagnose``, ``loop``,
``report`` (registered by :mod:`stiffnet.cli`).

Heavy imports (matplotlib, mlflow, scikit-learn, torch) are imported inside the
command functions; the shared console helpers come from :mod:`stiffnet.cli.console`.
"""

from __future__ import annotations

from pathlib import Path
from typing import Annotated, Any

import typer

from stiffnet.cli.options import JsonOption, SchedulerOption, WorkersOption
from stiffnet.progress import task as progress_task
from stiffnet.shipped import default_config

DEFAULT_SIM_CONFIG = default_config("sim/ideal.yaml")

CampaignArg = Annotated[Path, typer.Argument(help="Campaign folder (or its manifest.csv).")]
ConfigOpt = Annotated[
    Path | None,
    typer.Option(
        "--config",
        help="Simulator config (YAML); default: stiffnet's configs/sim/ideal.yaml (base model).",
    ),
]
SeedOpt = Annotated[int, typer.Option(help="Common-random-number seed of the simulations.")]


def _io() -> tuple[Any, Any, Any]:
    from stiffnet.cli.console import console, out, write_json

    return out, console, write_json


def _progress() -> Any:
    """Bars with ETA on a terminal (see :func:`stiffnet.cli.console.show_progress`)."""
    from stiffnet.cli.console import show_progress

    return show_progress()


def _load(campaign: Path, config: Path | None) -> tuple[Any, Any]:
    from stiffnet.campaign import LoadedCampaign, load_campaign
    from stiffnet.config import load_config
    from stiffnet.config.sim import SimulationConfig

    # one object read once: every stage of a command (and every loop iteration) shares it
    camp = LoadedCampaign.of(load_campaign(campaign))
    if config is not None:
        cfg = load_config(SimulationConfig, config)
    elif DEFAULT_SIM_CONFIG.is_file():
        cfg = load_config(SimulationConfig, DEFAULT_SIM_CONFIG)
    else:
        cfg = SimulationConfig()
    return camp, cfg


def assumed_natural_frequency(camp: Any) -> str | None:
    """The warning for rows with no f_n (neither the manifest nor a sidecar gives it): the
    campaign's commands read them at the paper's 9.48 Hz, and a rig at another f_n then
    reads wrong (a 14.2 Hz rig: learned accuracy 0.33, beta MAPE 0.54) - said, never silent.
    None when every row gives it."""
    from stiffnet.simulator.batch import PAPER_NATURAL_FREQUENCY_HZ

    rows = [r.recording for r in camp.rows if r.natural_frequency_hz is None]
    if not rows:
        return None
    shown = ", ".join(rows[:3]) + (", ..." if len(rows) > 3 else "")
    return (
        f"natural frequency not given for {len(rows)} of {len(camp.rows)} recordings ({shown}): "
        f"read at the paper's {PAPER_NATURAL_FREQUENCY_HZ:g} Hz; a rig at another f_n reads "
        "wrong (give the manifest's column natural_frequency_hz, or a sidecar "
        "<recording>.json)"
    )


#: Keys (and their JSON types) a `--diagnosis` / `--loop` result must have.
_RESULT_KEYS: dict[str, dict[str, type | tuple[type, ...]]] = {
    "diagnosis": {"baseline_discrepancy": (int, float), "ranking": list,
                  "missing_effect": (str, type(None))},
    "loop": {"before": dict, "after": dict, "iterations": list},
}  # fmt: skip


#: Keys a result may have, with their JSON types (a list of str: ``(list, str)``).
_OPTIONAL_KEYS: dict[str, dict[str, tuple[type, ...]]] = {
    "diagnosis": {"noise_floor": (int, float, type(None)), "verdict": (str, type(None)),
                  "summary": (str,), "missing_effects": (list, str),
                  "restoring_force": (dict, type(None))},
}  # fmt: skip
_COMMAND = {"diagnosis": "diagnose", "loop": "loop"}
#: Keys that results written by earlier versions carry under another name (old: new): the
#: restoring-force estimate was also called "physical" (``physical_beta``, ...) and its
#: campaign summary "evidence".
_EARLIER_KEYS = {"restoring_force_evidence": "restoring_force"}
_EARLIER_PREFIX = ("physical_", "restoring_force_")


def _with_current_keys(data: Any, depth: int = 4) -> Any:
    """A saved result with the keys of earlier versions renamed to today's down to `depth`
    levels (a loop's iterations' rows lie at 3; where both names stand, today's wins)."""
    if depth < 0:
        return data
    if isinstance(data, list):
        return [_with_current_keys(v, depth - 1) for v in data]
    if not isinstance(data, dict):
        return data
    out: dict[str, Any] = {}
    for k, v in data.items():
        new = _EARLIER_KEYS.get(k, k)
        if new.startswith(_EARLIER_PREFIX[0]):
            new = _EARLIER_PREFIX[1] + new.removeprefix(_EARLIER_PREFIX[0])
        if new == k or new not in data:
            out[new] = _with_current_keys(v, depth - 1)
    return out


def _read_json(path: Path | None, what: str) -> Any:
    """A `diagnose --json` / `loop --json` result, checked at the boundary (stiffnet.inputs)."""
    from stiffnet.errors import StiffnetError
    from stiffnet.inputs import check_fields, read_json_object

    if path is None:
        return None
    data = _with_current_keys(read_json_object(path, f"{what} JSON"))
    for key, kind in _RESULT_KEYS.get(what, {}).items():
        if not isinstance(data.get(key), kind) or isinstance(data.get(key), bool):
            raise StiffnetError(
                f"{path}: not a `{_COMMAND[what]} --json` result (key {key!r} missing or wrong)"
            )
    check_fields(data, _OPTIONAL_KEYS.get(what, {}), f"{path}: not a `{_COMMAND[what]} --json` "
                 "result")  # fmt: skip
    if what == "diagnosis":
        evidence = data.get("restoring_force") or {}
        check_fields(evidence, {"summary": (str, type(None))}, f"{path}: restoring_force")
        for i, r in enumerate(data["ranking"]):
            if isinstance(r, dict):
                check_fields(r, {"reasons": (list, str)}, f"{path}: ranking[{i}]")
            ok = isinstance(r, dict) and isinstance(r.get("effect"), str)
            ok = ok and isinstance(r.get("params"), dict) and isinstance(r.get("fitted", []), list)
            ok = ok and isinstance(r.get("significant"), bool)
            numbers = [*r.get("params", {}).values(), r.get("relative_reduction"),
                       r.get("discrepancy_reduction")] if ok else []  # fmt: skip
            ok = ok and all(isinstance(v, int | float) and not isinstance(v, bool) for v in numbers)
            if not ok:
                raise StiffnetError(f"{path}: ranking[{i}] is not a diagnosed effect")
    return data


def _metrics_table(title: str, metrics: dict[str, Any]) -> Any:
    from rich.table import Table

    table = Table(title=title)
    keys = ("n", "accuracy", "macro_f1", "beta_mape", "interval_coverage", "alarm_rate")
    for col in ("method", "n", "accuracy", "macro-F1", "beta MAPE", "interval coverage", "alarms"):
        table.add_column(col)
    for method, m in metrics.items():
        vals = [m.get(k) for k in keys]
        table.add_row(method, *("–" if v is None else f"{v:.3g}" for v in vals))
    return table


def evaluate(
    campaign: CampaignArg,
    model: Annotated[
        Path | None, typer.Option(help="ONNX model (default: the predictor's, models/cnn.onnx).")
    ] = None,
    config: ConfigOpt = None,
    json_path: JsonOption = None,
) -> None:
    """Learned model, geometric and restoring-force cross-checks and beta by simulation
    against the known betas."""
    from stiffnet.campaign.manifest import unlisted_recordings, unlisted_words
    from stiffnet.measurement.compare import config_effects, config_settings
    from stiffnet.measurement.evaluate import evaluate_campaign
    from stiffnet.measurement.simulation_reading import summary_lines

    out, _, write_json = _io()
    camp, cfg = _load(campaign, config)
    assumed = assumed_natural_frequency(camp)
    unlisted = unlisted_words(
        unlisted_recordings(camp.manifest_path, [r.recording for r in camp.rows])
    )
    with _progress(), progress_task("predicting recordings"):
        res = evaluate_campaign(camp, str(model) if model else None, config_effects(cfg),
                                settings=config_settings(cfg))  # fmt: skip
    out.print(_metrics_table(f"{res['model']['name']} on {campaign}", res["metrics"]))
    for said in (assumed, unlisted):  # under the metrics they qualify, and in the JSON
        if said:
            out.print(f"[yellow]warning:[/] {said}")
            res["warnings"] = [*res.get("warnings", []), said]
    unscored = [r["recording"] for r in res["recordings"] if r["beta"] is None]
    if unscored:  # the table's n counts the others only: say which rows it leaves out
        out.print(
            f"not scored: {len(unscored)} of {len(res['recordings'])} recordings have no beta "
            f"in the manifest ({', '.join(unscored[:5])}{', ...' if len(unscored) > 5 else ''}):"
            " predicted, left out of the metrics"
        )
    worst = ", ".join(f"{w['recording']} ({w['error']:.2f})" for w in res["worst"][:3])
    out.print(f"worst recordings by error (1 for a wrong class + relative beta error): {worst}")
    flagged = [r for r in res["recordings"] if r["ood"]]
    if flagged:
        out.print(
            f"alarm: {len(flagged)} of {len(res['recordings'])} recordings are unreliable "
            "(" + ", ".join(f"{r['recording']}: {'+'.join(r['ood_checks'])}" for r in flagged[:5])
            + (", ..." if len(flagged) > 5 else "") + ")"
        )  # fmt: skip
    else:
        out.print("alarm: no recording flagged as unreliable")
    for line in summary_lines(res):
        out.print(line)
    out.print(f"sensor chain: {res['sensor']['reason']}")  # the campaign's one accelerometer
    out.print(f"contact law: {res['campaign_law']['message']}")  # the campaign's one rig
    write_json(json_path, res)


def compare(
    campaign: CampaignArg,
    config: ConfigOpt = None,
    plots: Annotated[
        Path | None, typer.Option(help="Write the figures (PNG) into this folder.")
    ] = None,
    seed: SeedOpt = 20_241,
    json_path: JsonOption = None,
) -> None:
    """Simulator versus measurement by phase-independent statistics: where the model fails."""
    from rich.table import Table

    from stiffnet.measurement.compare import compare_campaign, config_effects, config_settings

    out, _, write_json = _io()
    camp, cfg = _load(campaign, config)
    with _progress(), progress_task("simulating and comparing"):
        cmp = compare_campaign(camp, config_effects(cfg), config_settings(cfg), seed)
    res = cmp.result
    table = Table(title=f"simulator vs {campaign}: discrepancy {res['discrepancy']:.3g}")
    for col in (
        "recording",
        "beta",
        "discrepancy",
        "worst statistic",
        "contact Σd²",
        "free-flight Σd²",
        "global Σd²",
    ):
        table.add_column(col)
    for r in res["recordings"]:
        g = r.get("groups") or {}
        table.add_row(
            r["recording"],
            f"{r['beta']}",
            f"{r['discrepancy'] or float('nan'):.3g}",
            str(r.get("worst_component")),
            *(f"{g.get(k, 0):.3g}" for k in ("contact", "free_flight", "global")),
        )
    out.print(table)
    f = res["failure"]
    out.print(
        f"fails mostly in {f['group']} (statistic {f['component']}, beta class "
        f"{f['beta_class']}, recording {f['recording']})"
    )
    if plots is not None:
        from stiffnet.measurement.report_figures import comparison_figures

        plots.mkdir(parents=True, exist_ok=True)
        figures, said = comparison_figures(cmp, plots, "compare_")
        res["plots"] = [str(f.path) for f in figures]
        out.print(f"figures written to {plots}. {' '.join(said)}")
    write_json(json_path, res)


def diagnose(
    campaign: CampaignArg,
    config: ConfigOpt = None,
    effect: Annotated[
        list[str] | None,
        typer.Option(help="Also try this user effect, module.path:ClassName (repeatable)."),
    ] = None,
    only: Annotated[
        list[str] | None,
        typer.Option(help="Try only these effects (repeatable; default: the whole library)."),
    ] = None,
    budget: Annotated[
        int | None,
        typer.Option(
            help="Evaluations of one closed-form fit (default: its design + 8-24 refinement steps)."
        ),
    ] = None,
    budget_numerical: Annotated[
        int | None, typer.Option(help="Evaluations per numerical-engine effect (6).")
    ] = None,
    inclination: Annotated[
        bool, typer.Option(help="Include the geometric inclination statistics.")
    ] = True,
    scheduler: SchedulerOption = None,
    workers: WorkersOption = None,
    seed: SeedOpt = 20_241,
    json_path: JsonOption = None,
) -> None:
    """Fit every effect to the campaign and rank them: which physical effect is missing."""
    from stiffnet.measurement.compare import config_effects
    from stiffnet.measurement.diagnose import diagnose_campaign

    out, console, write_json = _io()
    camp, cfg = _load(campaign, config)
    with _progress():
        res = diagnose_campaign(
            camp,
            config_effects(cfg),
            effects=only,
            user_effects=effect or [],
            budget=budget,
            budget_numerical=budget_numerical,
            seed=seed,
            inclination=inclination,
            scheduler=scheduler,
            workers=workers,
        )
    from stiffnet.measurement.report_units import with_physical_units

    # the fitted values in the manifest's units beside the model's (one conversion for the
    # table, the JSON and the report); saved before anything is printed
    res = with_physical_units(res, camp.rows)
    write_json(json_path, res)
    out.print(diagnosis_table(res, f"diagnosis of {campaign}"))
    if res.get("per_recording"):
        out.print(recording_table(res["per_recording"]))
    for line in diagnosis_lines(res):
        out.print(line, markup=False)  # data, not markup (an equation has [ ])


def _number(v: Any) -> str:
    return f"{v:.3g}" if isinstance(v, int | float) and not isinstance(v, bool) else str(v)


def fitted_values(entry: dict[str, Any]) -> str:
    """``k=v unit`` for the parameters a ranking entry fitted (those it has; never a KeyError):
    in the campaign's units where :func:`~stiffnet.measurement.report_units.with_physical_units`
    gave them, the model's value beside them."""
    from stiffnet.measurement.report_units import reading_of

    params = entry.get("params") or {}
    said = entry.get("params_physical") or {}
    return ", ".join(
        f"{k}={reading_of(said[k]) if isinstance(said.get(k), dict) else _number(params[k])}"
        for k in entry.get("fitted") or []
        if k in params
    )


def diagnosis_table(res: dict[str, Any], title: str) -> Any:
    """The ranking of a ``diagnose`` result as a rich table (effects, fits, why not)."""
    from rich.table import Table

    table = Table(
        title=f"{title}: baseline discrepancy {_number(res['baseline_discrepancy'])}"
        f"{carried_note(res.get('baseline_per_recording'), res.get('recordings'))}, "
        f"noise floor {_number(res['noise_floor'])}"
    )
    for col in ("effect", "reduction", "of excess", "params", "selected", "why not"):
        table.add_column(col)
    for r in res["ranking"]:
        excess = r.get("excess_reduction")
        table.add_row(
            str(r["effect"]),
            _number(r.get("discrepancy_reduction")),
            f"{excess:.0%}" if isinstance(excess, int | float) else "–",
            fitted_values(r),
            "yes" if r.get("selected") else "no",
            "; ".join(r.get("reasons") or []),
        )
    return table


def recording_table(recordings: list[dict[str, Any]]) -> Any:
    """Each recording against its own noise floor, with its orbit and the simulation's."""
    from rich.table import Table

    table = Table(title="per recording: the final model against each recording's own floor")
    for col in ("recording", "floor", "residual", "x floor", "measured orbit",
                "simulated orbit (starts on it / distinct orbits)", "note"):  # fmt: skip
        table.add_column(col)
    for r in recordings:
        ratio = r.get("ratio")
        flag = " above" if r.get("above_floor") and not r.get("non_repeatable") else ""
        starts = r.get("starts_on_measured_orbit")
        reach = f" ({'–' if starts is None else starts} / {r.get('distinct_orbits', '–')})"
        table.add_row(
            str(r.get("recording")),
            _number(r.get("floor")),
            _number(r.get("residual")),
            (f"{ratio:.2g}" if isinstance(ratio, int | float) else "–") + flag,
            str(r.get("measured_orbit", "–")),
            str(r.get("simulated_orbit", "–")) + reach,
            str(r.get("note", "")),
        )
    return table


#: Share of a campaign's mean discrepancy one recording must carry before the headline says
#: so: above half, the mean describes that recording, not the campaign (an ideal campaign's
#: wandering orbit read 1,140 against a median of 0.008 and made the headline 48.1).
CARRIED_SHARE = 0.5


def carried_note(values: Any, names: Any) -> str:
    """``, N% of it from X, median M`` where one recording carries more than
    :data:`CARRIED_SHARE` of the campaign's mean discrepancy (``values``, one per name in
    ``names``), else ``""``."""
    import numpy as np

    try:
        v = np.asarray(values, dtype=np.float64)
    except (TypeError, ValueError):
        return ""
    ok = np.isfinite(v)
    if v.ndim != 1 or ok.sum() < 3 or not isinstance(names, list) or len(names) != v.size:
        return ""
    total = float(v[ok].sum())
    top = int(np.nanargmax(np.where(ok, v, -np.inf)))
    if not (total > 0 and v[top] > CARRIED_SHARE * total):
        return ""
    median = _number(float(np.median(v[ok])))
    return f", {v[top] / total:.0%} of it from {names[top]}, median {median}"


def diagnosis_lines(res: dict[str, Any]) -> list[str]:
    """The verdict and the restoring-force evidence in words."""
    explained = res.get("explained_fraction")
    carried = carried_note(res.get("residual_per_recording"), res.get("recordings"))
    lines = [
        f"verdict: {res['verdict']} (residual {_number(res.get('residual_discrepancy'))}"
        f"{carried}, explained {explained:.0%}): {res.get('summary', '')}"
        if isinstance(explained, int | float)
        else f"verdict: {res['verdict']}: {res.get('summary', '')}"
    ]
    from stiffnet.measurement.report_units import nuisance_lines

    units = res.get("units")
    if isinstance(units, dict) and units.get("said"):  # how the fitted values above read
        lines.append(str(units["said"]))
    lines += nuisance_lines(res)
    evidence = res.get("restoring_force") or {}
    if evidence.get("summary"):
        lines.append(str(evidence["summary"]))
    if (res.get("learned_law") or {}).get("ran"):  # the library lacked the contact law
        lines.append(str(res["learned_law"]["summary"]))
    return lines


def loop(
    campaign: CampaignArg,
    state: Annotated[
        Path | None,
        typer.Option(
            "--state",
            help="State folder (default: CAMPAIGN-loop beside the campaign; runs/loop-NAME for "
            "a shipped example). An existing one resumes after its last iteration.",
        ),
    ] = None,
    iterations: Annotated[
        int, typer.Option(help="New iterations to run (iteration 0, the start, comes first).")
    ] = 1,
    add_effect: Annotated[
        list[str] | None,
        typer.Option(
            "--add-effect",
            help="Effect the next iteration adds instead of the diagnosed ones, NAME or "
            "NAME:k=v,... (repeatable; without values it is fitted).",
        ),
    ] = None,
    diagnosis: Annotated[
        Path | None,
        typer.Option(help="A `diagnose --json` result against the last iteration's config."),
    ] = None,
    config: ConfigOpt = None,
    family: Annotated[
        str | None,
        typer.Option(
            "--family",
            help="Model family (`stiffnet families`; default: the shipped model's); a resumed "
            "loop keeps its own.",
        ),
    ] = None,
    model_family: Annotated[
        str | None,
        typer.Option("--model", help="Deprecated: the old name of --family.", hidden=True),
    ] = None,
    n_trajectories: Annotated[
        int | None,
        typer.Option(
            help="Trajectories per generated dataset (default 1000 over the sweep; at the "
            "operating points, configs/operating_points.yaml's trajectories)."
        ),
    ] = None,
    spread: Annotated[
        float | None,
        typer.Option(help="Relative half-width of the prior around each fitted value (0.25)."),
    ] = None,
    effect: Annotated[
        list[str] | None,
        typer.Option(
            "--effect", help="Candidate effect of the diagnosis (repeatable; default all)."
        ),
    ] = None,
    max_epochs: Annotated[
        int | None,
        typer.Option(help="Epochs per iteration, for a family trained in epochs (CNN: 15)."),
    ] = None,
    keep_data: Annotated[bool, typer.Option(help="Keep each iteration's dataset.")] = False,
    seed: Annotated[int | None, typer.Option(help="Seed of the diagnosis and discrepancy.")] = None,
    tracking_uri: Annotated[str, typer.Option(help="MLflow tracking URI.")] = "sqlite:///mlflow.db",
    tracking: Annotated[bool, typer.Option(help="Log the iterations to MLflow.")] = True,
    json_path: JsonOption = None,
    envelope: Annotated[
        bool,
        typer.Option(
            help="Train on the campaign's operating envelope (the manifest's gap, amplitude, "
            "frequency ratio, damping, fs/f_n and noise, widened 10 %) instead of the "
            "config's whole sweep (a new loop only)."
        ),
    ] = False,
    operating_points: Annotated[
        bool,
        typer.Option(
            help="Train at the campaign's own operating points (each manifest row's gap, "
            "amplitude, frequency ratio, damping, fs/f_n and noise, jittered 5 %; beta over "
            "the sweep) in every iteration (a new loop only; by default from the iteration "
            "that adds a contact law that is not a linear spring)."
        ),
    ] = False,
    sweep: Annotated[
        bool,
        typer.Option(
            help="Train over the config's whole sweep in every iteration, even after a "
            "contact law that is not a linear spring is added (a new loop only)."
        ),
    ] = False,
) -> None:
    """Iterate: diagnose, add the missing effects to the simulator, retrain, re-evaluate."""
    from stiffnet.effects.registry import parse_effect_option
    from stiffnet.inputs import bounded_count
    from stiffnet.measurement.loop import check_n_trajectories, run_loop

    family = _loop_family(family, model_family)
    check_n_trajectories(n_trajectories)
    bounded_count(max_epochs, "--max-epochs", 1, 1000)
    given = [parse_effect_option(t) for t in add_effect or []]
    diag = _read_json(diagnosis, "diagnosis")
    out, console, write_json = _io()
    if envelope and operating_points:
        from stiffnet.errors import StiffnetError

        raise StiffnetError("give one of --envelope and --operating-points (the operating "
                            "points already lie inside the envelope)")  # fmt: skip
    if sweep and operating_points:
        from stiffnet.errors import StiffnetError

        raise StiffnetError("give one of --sweep and --operating-points")
    camp, cfg = _load(campaign, config)
    if envelope:
        from stiffnet.measurement.envelope import campaign_envelope

        cfg = campaign_envelope(cfg, camp.rows)
    overrides = {"max_epochs": max_epochs} if max_epochs else None
    console.print(f"loop on {campaign}: {iterations} new iteration(s)")
    assumed = assumed_natural_frequency(camp)
    if assumed:
        console.print(f"[yellow]warning:[/] {assumed}")
    with _progress():
        res = run_loop(
            camp,
            cfg,
            state,
            iterations=iterations,
            add_effects=given,
            diagnosis=diag,
            family=family,
            n_trajectories=n_trajectories,
            spread=spread,
            tracking_uri=tracking_uri if tracking else None,
            train_overrides=overrides,
            seed=seed,
            candidates=list(effect) if effect else None,
            world=_loop_world(operating_points, sweep or envelope),
            keep_data=keep_data,
        )
    out.print(loop_table(res, campaign))
    if res["stopped"]:
        out.print(res["stopped"])
    out.print(f"state in {res['out']}; chart {res['chart']}")
    if res["iterations"]:
        out.print(f"latest model: {res['iterations'][-1]['model']} (stiffnet predict --model)")
    write_json(json_path, res)


def _loop_family(family: str | None, model_family: str | None) -> str | None:
    """The family `loop` trains: --family, or the deprecated --model (a file everywhere
    else: a note says so), checked against the registry."""
    from stiffnet.errors import StiffnetError
    from stiffnet.measurement.loop import check_family

    if model_family is not None:
        if family is not None and family != model_family:
            raise StiffnetError(f"--model {model_family} and --family {family} disagree")
        _io()[1].print("note: `loop --model` is deprecated (it is a file elsewhere): use --family")
        family = model_family
    if family is not None:
        check_family(family)
    return family


def _loop_world(operating_points: bool, sweep: bool) -> str | None:
    """The loop's ``world`` from the CLI's flags (None: a new loop's default, ``auto``;
    the envelope is a sweep)."""
    if operating_points:
        return "operating_points"
    return "sweep" if sweep else None


def loop_table(res: dict[str, Any], campaign: Any) -> Any:
    """The loop's iterations as a table: effects added, the metrics, model version, time."""
    from rich.table import Table

    table = Table(title=f"loop on {campaign} ({res['family']}, {res['seconds']:.0f} s this run)")
    cols = ("discrepancy", "accuracy", "beta_mape", "simulation_accuracy", "simulation_beta_mape",
            "reading_accuracy", "restoring_force_agreement")  # fmt: skip
    for col in ("iteration", "effects added", "trained on", "discrepancy", "accuracy",
                "beta MAPE", "accuracy by simulation", "beta MAPE by simulation",
                "reading accuracy", "agreement (restoring force)", "model version",
                "s"):  # fmt: skip
        table.add_column(col)
    for it in res["iterations"]:
        vals = [it["metrics"].get(k) for k in cols]
        table.add_row(
            str(it["index"]),
            ", ".join(
                a["name"]
                + "".join(
                    f" {k}={a['params'][k]:.3g}"
                    for k in a["fitted"] or a["params"]
                    if isinstance(a["params"].get(k), int | float)
                )
                for a in it["added"]
            )
            or "–",
            _trained_on(it, res),
            *("–" if v is None else f"{v:.3g}" for v in vals),
            str(it.get("model_version") or "–"),
            f"{it['seconds']['total']:.0f}",
        )  # fmt: skip
    return table


def _trained_on(it: dict[str, Any], res: dict[str, Any]) -> str:
    """An iteration's training world and size, e.g. ``points x400`` (older states kept
    only the loop's world)."""
    world = it.get("world") or res.get("world") or "sweep"
    n = it.get("n_trajectories") or res.get("n_trajectories")
    name = {"operating_points": "points", "sweep": "sweep"}.get(world, world)
    return f"{name} x{n}" if n else name


def report(
    campaign: CampaignArg,
    out_path: Annotated[Path, typer.Option("--out", help="HTML file to write.")] = Path(
        "report.html"
    ),
    model: Annotated[Path | None, typer.Option(help="ONNX model for evaluate.")] = None,
    config: ConfigOpt = None,
    diagnosis: Annotated[
        Path | None, typer.Option(help="Use this `diagnose --json` result instead of running it.")
    ] = None,
    loop_json: Annotated[
        Path | None, typer.Option("--loop", help="Include a `loop --json` result.")
    ] = None,
    run_diagnose: Annotated[
        bool, typer.Option("--diagnose/--no-diagnose", help="Run diagnose when not given.")
    ] = True,
    json_path: JsonOption = None,
) -> None:
    """One self-contained HTML page with the evaluate, compare and diagnose tables and plots."""
    from stiffnet.measurement.compare import compare_campaign, config_effects, config_settings
    from stiffnet.measurement.diagnose import diagnose_campaign
    from stiffnet.measurement.evaluate import evaluate_campaign
    from stiffnet.measurement.report import render_report, report_provenance, write_report
    from stiffnet.measurement.report_words import Units

    out, _, write_json = _io()
    diag = _read_json(diagnosis, "diagnosis")  # the given results are checked before any work
    loop_result = _read_json(loop_json, "loop")
    camp, cfg = _load(campaign, config)
    effects, settings = config_effects(cfg), config_settings(cfg)
    stages = 2 + int(diag is None and run_diagnose)
    with _progress(), progress_task("report stages", stages) as bar:
        bar.update(note="compare")
        # one simulation of the campaign: the discrepancy's gives evaluate its impact regimes
        cmp = compare_campaign(camp, effects, settings, contact=True)
        bar.advance(note="evaluate")
        # a field campaign (no beta) is reported too: the readings side by side
        ev = evaluate_campaign(camp, str(model) if model else None, effects, require_beta=False,
                               settings=settings, contact=cmp.contact)  # fmt: skip
        if diag is None and run_diagnose:
            bar.advance(note="diagnose")
            diag = diagnose_campaign(camp, effects)
        bar.advance()
    if diag is not None:  # its values in this campaign's units (docs/campaign.md)
        from stiffnet.measurement.report_units import with_physical_units

        diag = with_physical_units(diag, camp.rows)
    read = DEFAULT_SIM_CONFIG if DEFAULT_SIM_CONFIG.is_file() else None
    prov = report_provenance(
        camp, out_path, model, config, diagnosis, loop_json, run_diagnose, json_path, read
    )
    page = render_report(
        f"stiffnet: model versus measurement, {camp.folder.name}",
        ev,
        cmp,
        diag,
        loop_result,
        prov,
        Units.of(camp.rows),
    )
    write_report(out_path, page)
    out.print(f"report written to {out_path}")
    write_json(
        json_path,
        {
            "report": str(out_path),
            "discrepancy": cmp.result["discrepancy"],
            "missing_effect": diag["missing_effect"] if diag else None,
            "provenance": prov,
        },
    )


def register(app: typer.Typer) -> None:
    """Add ``evaluate``, ``compare``, ``diagnose``, ``loop`` and ``report`` to the app."""
    from stiffnet.cli.console import user_errors

    for fn in (evaluate, compare, diagnose, loop, report):
        app.command(fn.__name__)(user_errors(fn))

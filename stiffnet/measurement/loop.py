"""One iteration of the measure-diagnose-fix loop: add an effect, retrain, re-evaluate.

``run_loop`` takes a campaign, the current simulator config and the name of an
effect (with its fitted parameters from a diagnose result, or fitted now):

1. **before**: a dataset from the current config, a model trained on it
   (GBM by default), evaluated on the campaign; the simulator-measurement
   discrepancy of the current config;
2. **after**: the config plus the effect with its fitted parameters and a
   spread of +-``spread`` (relative, clipped to the declared ranges) drawn per
   trajectory, a dataset of the same size and seed, a model trained the same
   way, evaluated on the campaign; the discrepancy with the fitted values.

Before and after are trained alike (same size, seed and training config), so
the difference is the effect alone, not the amount of data. Each is an MLflow
run in the campaign's experiment (``campaign-<folder name>``; tracking URI
``sqlite:///mlflow.db`` by default) with the learned and geometric metrics
and the discrepancy; the training runs themselves are not tracked (their
metrics are on simulated test windows). The error-versus-iteration chart is
written as a PNG and logged with the after run.
"""

from __future__ import annotations

import time
from pathlib import Path
from typing import Any

from stiffnet.campaign import Campaign
from stiffnet.campaign.simulate import DEFAULT_SEED
from stiffnet.config.sim import EffectSpec, SimulationConfig
from stiffnet.effects.registry import effect_class
from stiffnet.errors import StiffnetError
from stiffnet.io_utils import finish_run_folder, output_lock, start_run_folder
from stiffnet.measurement.compare import compare_campaign, config_effects, config_settings
from stiffnet.measurement.fitting import fit_effect
from stiffnet.measurement.target import CampaignTarget, measured_statistics
from stiffnet.progress import task as progress_task

DEFAULT_SPREAD = 0.25


def spread_params(
    name: str, params: dict[str, float], fitted: list[str], spread: float
) -> dict[str, float | list[float]]:
    """Fitted parameters as ``[p (1 - s), p (1 + s)]`` ranges inside the declared ranges."""
    table = {r["name"]: r for r in effect_class(name).parameter_table()}
    out: dict[str, float | list[float]] = {}
    for k, v in params.items():
        if k in fitted and spread > 0 and v != 0:
            lo, hi = table[k]["range"]
            a, b = sorted((v * (1 - spread), v * (1 + spread)))
            out[k] = [max(a, lo), min(b, hi)]
        else:
            out[k] = float(v)
    return out


def config_with_effect(
    cfg: SimulationConfig, name: str, params: dict[str, Any]
) -> SimulationConfig:
    """A copy of ``cfg`` with the effect added (replacing one of the same name)."""
    cls_name = effect_class(name).name
    effects = [e for e in cfg.effects if effect_class(e.name).name != cls_name]
    effects.append(EffectSpec(name=name, params=params))
    return cfg.model_copy(update={"effects": effects})


def _train_and_evaluate(
    cfg: SimulationConfig,
    campaign: Campaign,
    work: Path,
    label: str,
    model: str,
    train_overrides: dict[str, Any] | None,
) -> dict[str, Any]:
    from stiffnet.config import validate_config
    from stiffnet.config.train import TrainConfig
    from stiffnet.dataset.generate import generate_dataset, shard_sizes
    from stiffnet.measurement.evaluate import evaluate_campaign
    from training.train import train

    t0 = time.perf_counter()
    data = work / f"data-{label}"
    with progress_task(f"simulating shards ({label})", len(shard_sizes(cfg))) as bar:
        generate_dataset(cfg, data, overwrite=True, progress=lambda done, _: bar.update(done))
    t_data = time.perf_counter() - t0
    from stiffnet.config import load_yaml
    from stiffnet.shipped import default_config

    default = default_config(f"train/{model}.yaml")

    raw = load_yaml(default) if default.is_file() else {"model": model}
    raw.update(train_overrides or {})
    raw["tracking"] = False
    tcfg = validate_config(TrainConfig, raw, str(default))
    summary = train(data, tcfg, work / f"model-{label}", progress=None)
    t_train = time.perf_counter() - t0 - t_data
    ev = evaluate_campaign(campaign, summary["paths"]["onnx"], config_effects(cfg))
    return {
        "evaluation": ev,
        "model_path": summary["paths"]["onnx"],
        "seconds": {
            "dataset": round(t_data, 2),
            "train": round(t_train, 2),
            "total": round(time.perf_counter() - t0, 2),
        },
    }


def _log_mlflow(
    uri: str,
    experiment: str,
    name: str,
    params: dict[str, Any],
    metrics: dict[str, float],
    artifacts: list[Path],
) -> str:
    import math

    import mlflow

    from training.tracking import _artifact_location, _clean_key

    mlflow.set_tracking_uri(uri)
    client = mlflow.MlflowClient(uri)
    if client.get_experiment_by_name(experiment) is None:
        client.create_experiment(experiment, artifact_location=_artifact_location(uri))
    mlflow.set_experiment(experiment)
    with mlflow.start_run(run_name=name, tags={"stiffnet.loop": name}) as run:
        mlflow.log_params({_clean_key(k): str(v)[:500] for k, v in params.items()})
        mlflow.log_metrics(
            {
                _clean_key(k): float(v)
                for k, v in metrics.items()
                if v is not None and math.isfinite(v)
            }
        )
        for a in artifacts:
            mlflow.log_artifact(str(a), artifact_path="figures")
        return run.info.run_id


def _flat(ev: dict[str, Any], discrepancy: float) -> dict[str, float | None]:
    m = ev["metrics"]
    return {
        "accuracy": m["learned"]["accuracy"],
        "macro_f1": m["learned"]["macro_f1"],
        "beta_mape": m["learned"]["beta_mape"],
        "geometric_accuracy": m["geometric"]["accuracy"],
        "geometric_beta_mape": m["geometric"]["beta_mape"],
        "discrepancy": discrepancy,
    }


#: ``kind`` in the marker (``stiffnet-run.json``) of a loop's output folder.
LOOP_KIND = "stiffnet-loop"
#: Fewest trajectories per generated dataset: every class in training and in test.
MIN_TRAJECTORIES = 50


def check_n_trajectories(n: int | None) -> None:
    """Refuse a dataset size too small to split into training and test trajectories."""
    if n is not None and not MIN_TRAJECTORIES <= n <= 10_000_000:
        raise StiffnetError(
            f"--n-trajectories must be {MIN_TRAJECTORIES}..10000000 (each dataset is split into "
            f"training and test trajectories of every class), got {n}"
        )


def run_loop(
    campaign: Campaign,
    cfg: SimulationConfig,
    effect: str,
    out_dir: str | Path,
    diagnosis: dict[str, Any] | None = None,
    n_trajectories: int | None = None,
    spread: float = DEFAULT_SPREAD,
    model: str = "gbm",
    tracking_uri: str | None = "sqlite:///mlflow.db",
    train_overrides: dict[str, Any] | None = None,
    seed: int = DEFAULT_SEED,
) -> dict[str, Any]:
    """One loop iteration (see the module notes).

    Parameters
    ----------
    campaign : Campaign
    cfg : SimulationConfig
        The current simulator config (its ``n_trajectories`` is replaced).
    effect : str
        Effect to add (canonical name or ``module:Class``).
    out_dir : str or Path
        Folder for datasets, models and the chart.
    diagnosis : dict, optional
        A :func:`~stiffnet.measurement.diagnose.diagnose_campaign` result holding
        the effect's fit; without it (or without the effect in it) it is fitted now.
    n_trajectories : int, optional
        Trajectories of each generated dataset (default: the config's, 2000 in
        ``configs/sim/default.yaml``: one iteration takes about 3 minutes on two
        cores, see ``docs/measurement_loop.md``).
    spread : float
        Relative half-width of the parameter ranges around the fitted values.
    model : {"gbm", "cnn"}
    tracking_uri : str or None
        MLflow URI; None disables tracking.
    train_overrides : dict, optional
        TrainConfig fields overriding ``configs/train/MODEL.yaml``.
    seed : int
        Common-random-number seed of the discrepancy simulations.

    Returns
    -------
    dict
        ``before`` and ``after`` (each ``accuracy``, ``beta_mape``,
        ``discrepancy``, ``run_id``, ...), ``effect``, ``params``, ``chart``,
        ``seconds``.
    """

    if model not in ("gbm", "cnn"):
        raise StiffnetError(f"model {model!r} is not available: use gbm or cnn")
    check_n_trajectories(n_trajectories)
    out = Path(out_dir)
    with output_lock(out):  # one loop per folder; a killed run's files are never mixed in
        start_run_folder(out, LOOP_KIND)
        result = _iterate(campaign, cfg, effect, out, diagnosis, n_trajectories, spread, model,
                          tracking_uri, train_overrides, seed)  # fmt: skip
        result["out"] = str(out.resolve())
        finish_run_folder(out, LOOP_KIND)
    return result


def _iterate(
    campaign: Campaign,
    cfg: SimulationConfig,
    effect: str,
    out: Path,
    diagnosis: dict[str, Any] | None,
    n_trajectories: int | None,
    spread: float,
    model: str,
    tracking_uri: str | None,
    train_overrides: dict[str, Any] | None,
    seed: int,
) -> dict[str, Any]:
    from stiffnet.measurement.plots import loop_figure

    t0 = time.perf_counter()
    if n_trajectories is not None:
        cfg = cfg.model_copy(update={"n_trajectories": int(n_trajectories)})
    base_cfg = cfg
    fit = None
    if diagnosis is not None:
        fit = next((r for r in diagnosis.get("ranking", []) if r["effect"] == effect), None)
    stages = progress_task("loop stages", 4 if fit is not None else 5)
    with stages as bar:
        if fit is None:
            bar.update(note=f"fitting {effect}")
            measured, lengths, _ = measured_statistics(campaign)
            target = CampaignTarget(
                list(campaign.rows), measured, lengths, config_effects(base_cfg), seed
            )
            fit = fit_effect(target, effect)
            bar.advance()
        params = {k: float(v) for k, v in fit["params"].items()}
        fitted = list(fit.get("fitted", params))
        spread_p = spread_params(effect, params, fitted, spread)
        new_cfg = config_with_effect(base_cfg, effect, spread_p)
        fixed_cfg = config_with_effect(base_cfg, effect, params)

        settings = config_settings(base_cfg)
        bar.update(note="discrepancy before")
        d_before = compare_campaign(campaign, config_effects(base_cfg), settings, seed)
        bar.advance(note=f"discrepancy with {effect}")
        d_after = compare_campaign(campaign, config_effects(fixed_cfg), settings, seed)
        bar.advance(note="dataset + model before")
        before = _train_and_evaluate(base_cfg, campaign, out, "before", model, train_overrides)
        bar.advance(note=f"dataset + model with {effect}")
        after = _train_and_evaluate(new_cfg, campaign, out, "after", model, train_overrides)
        bar.advance()

    iterations = [
        {"label": "before", **_flat(before["evaluation"], d_before.result["discrepancy"])},
        {"label": f"+{effect}", **_flat(after["evaluation"], d_after.result["discrepancy"])},
    ]
    chart = loop_figure(iterations, out / "loop_error.png")
    result: dict[str, Any] = {
        "campaign": str(campaign.folder),
        "effect": effect,
        "params": params,
        "spread": spread,
        "config_effects": [e.model_dump() for e in new_cfg.effects],
        "n_trajectories": int(base_cfg.n_trajectories),
        "model": model,
        "chart": str(chart),
    }
    experiment = f"campaign-{campaign.folder.name}"
    for key, it, run in (("before", iterations[0], before), ("after", iterations[1], after)):
        run_id = None
        if tracking_uri:
            run_id = _log_mlflow(
                tracking_uri,
                experiment,
                key,
                {
                    "iteration": 0 if key == "before" else 1,
                    "effect": "" if key == "before" else effect,
                    "params": params if key == "after" else {},
                    "n_trajectories": base_cfg.n_trajectories,
                    "model": model,
                },
                {k: v for k, v in it.items() if k != "label"},
                [chart] if key == "after" else [],
            )
        result[key] = {
            **{k: v for k, v in it.items() if k != "label"},
            "run_id": run_id,
            "model_path": run["model_path"],
            "seconds": run["seconds"],
            "recordings": run["evaluation"]["recordings"],
        }
    result["experiment"] = experiment if tracking_uri else None
    result["seconds"] = round(time.perf_counter() - t0, 2)
    return result

"""The measure-diagnose-fix loop, iterated: add the missing effects, retrain, re-evaluate.

``run_loop`` keeps a **state folder** (``state.json`` and one ``iter-NNN/`` folder
per iteration) so that a rerun continues from the last finished iteration:

* **iteration 0** is the starting simulator config (``configs/sim/ideal.yaml``
  by default) with a model trained on it the same way the later ones are;
* **iteration k** diagnoses the campaign
  (:func:`~stiffnet.measurement.diagnose.diagnose_campaign`, from the starting
  config with the effects added so far among the candidates, so that they are
  refitted jointly with the new ones; or takes the effects the user names), adds
  *every* selected effect (and updates the earlier ones) with its joint fitted values
  as a prior centred on the fit (``[p (1 - s), p (1 + s)]``, ``s`` = ``spread``,
  clipped to the effect's declared ranges; a sensor chain the diagnosis fitted through a
  contact its learned law replaces is centred on the restoring-force evidence's chain
  instead, :func:`with_evidence_chain`), writes ``iter-k/config.yaml`` (a
  :class:`~stiffnet.config.sim.SimulationConfig`, loadable by ``stiffnet simulate
  --config``), generates a dataset from it, retrains the family (CNN by default,
  GBM the fast option; every iteration from scratch with the same size, seed and
  training settings, so the change between iterations is the physics alone),
  evaluates the campaign and measures the simulator-measurement discrepancy with
  the effects at their fitted values.

Each iteration is a nested MLflow run under one parent run of the loop (its id is
kept in the state), with the ONNX model and card as its logged model, registered
in the Model Registry under the campaign's name (one version per iteration). The
error-versus-iteration chart (``loop_error.png``) covers all iterations.

Where each dataset is drawn (``world``): by default (``"auto"``) over the starting
config's sweep while every contact law of the iteration's config is a linear spring and
dashpot, and at the campaign's own operating points
(:mod:`stiffnet.measurement.operating_points`) from the iteration that adds a law that is
not (a learned law with a knee, a power or Hunt-Crossley term; any effect's
``nonlinear_contact``): an impact's shape then depends on how hard the stop is hit, and
on the example two-stage campaign a GBM trained over the sweep read 0.625 of the
recordings in class (β MAPE 0.21) where one trained at its points read 0.875-1.0
(0.09-0.14; docs/measurement_loop.md, "Training at the campaign's operating points").
``"sweep"`` (``loop --sweep``) and ``"operating_points"`` (``loop --operating-points``)
fix the world for every iteration. Each iteration records the world it used and why.

Every iteration evaluates the same recordings with a new model, and the restoring-force
check's sensor-chain and high-pass corner fits do not depend on the model: they are kept
in the state folder (``restoring_force_fits.pkl``,
:func:`~stiffnet.restoring_force.kept_fits.fits_kept`, keyed by each fit's inputs and the
method's code) and fitted once per loop, not once per iteration; the readings are the same.

The error of an iteration: the discrepancy and the agreement of the learned model
with the restoring-force cross-check always; with β in the manifest, also the
accuracy and the β MAPE.
"""

from __future__ import annotations

import shutil
import time
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

from pydantic import BaseModel, ConfigDict, Field

from stiffnet.campaign import Campaign, LoadedCampaign
from stiffnet.campaign.simulate import DEFAULT_SEED
from stiffnet.config.sim import EffectSpec, SimulationConfig
from stiffnet.effects.base import Effect
from stiffnet.effects.learned_contact import LearnedContact
from stiffnet.effects.registry import effect_class
from stiffnet.effects.sensor_dynamics import SensorDynamics
from stiffnet.errors import StiffnetError
from stiffnet.io_utils import RUN_MARKER, output_lock, sha256_file, write_json_atomic
from stiffnet.measurement.compare import compare_campaign, config_effects, config_settings
from stiffnet.measurement.learned_law import replaced_by, with_learned_law
from stiffnet.measurement.operating_points import TRAJECTORIES
from stiffnet.progress import task as progress_task
from stiffnet.restoring_force.kept_fits import fits_kept

#: ``kind`` in the marker (``stiffnet-run.json``) of a loop's state folder.
LOOP_KIND = "stiffnet-loop"
#: The state file in the state folder.
STATE_FILE = "state.json"
#: The restoring-force fits the iterations share (:mod:`stiffnet.restoring_force.kept_fits`).
KEPT_FITS_FILE = "restoring_force_fits.pkl"
STATE_VERSION = 1
DEFAULT_SPREAD = 0.25
#: How the loop's world takes a diagnosed sensor chain (:class:`LoopChainSettings`).
LOOP_CHAIN_CONFIG = "loop_chain.yaml"
#: Trajectories per generated dataset over the sweep (1000: one CNN iteration within 15
#: minutes on two cores, see docs/measurement_loop.md).
DEFAULT_TRAJECTORIES = 1000
#: Trajectories per dataset at the operating points, unless the user gives a number
#: (``configs/operating_points.yaml``'s ``trajectories``): the retrained model alone reaches
#: the campaign's accuracy with it, where 400 left it limited by its data
#: (docs/measurement_loop.md, "The loop's model alone: its dataset's size").
OPERATING_POINT_TRAJECTORIES = TRAJECTORIES
#: Fewest trajectories per generated dataset: every class in training and in test.
MIN_TRAJECTORIES = 50
#: How a model trained behind the campaign's own fitted sensor chain reads a record
#: (:func:`serving.chain_undo.chain_to_undo`): only the stages outside its priors divided
#: out. The predictor's default divides out every identified stage, which puts a record
#: outside the world of a model that learned to read through that chain: held-out
#: two-stage campaign behind a 240 Hz mount, iteration-1 GBM 0.500 / β MAPE 0.180 with the
#: chain undone (β >= 60 read 35 % low), as recorded 0.82 / 0.21 of 17 it read both ways
#: (docs/measurement_loop.md, "The loop's model reads through its own chain").
FITTED_CHAIN_UNDO = "outside_priors"
#: Where the datasets' trajectories are drawn: chosen per iteration by its contact law
#: (``auto``, see the module notes), over the starting config's sweep, or at the campaign's
#: own operating points (:mod:`stiffnet.measurement.operating_points`).
WORLDS = ("auto", "sweep", "operating_points")
#: What each iteration's record keeps of a recording's evaluation (the state stays small).
RECORDING_COLUMNS = (
    "recording", "beta", "class", "beta_estimate", "restoring_force_beta",
    "restoring_force_agreement", "error", "simulation_class", "simulation_beta",
    "simulation_reproduced", "simulation_alarm", "reading_method", "reading_class",
    "reading_beta",
)  # fmt: skip


def check_n_trajectories(n: int | None) -> None:
    """Refuse a dataset size too small to split into training and test trajectories."""
    if n is not None and not MIN_TRAJECTORIES <= n <= 10_000_000:
        raise StiffnetError(
            f"--n-trajectories must be {MIN_TRAJECTORIES}..10000000 (each dataset is split into "
            f"training and test trajectories of every class), got {n}"
        )


def check_family(family: str) -> None:
    """Refuse a model family the loop cannot train (the registry, :mod:`training.families`)."""
    from training.families import get_family

    get_family(family)


def _default_family() -> str:
    from training.families import default_family

    return default_family("loop").name


def default_state_dir(campaign_folder: str | Path) -> Path:
    """``<campaign>-loop`` beside the campaign; ``runs/loop-<name>`` for a campaign shipped
    inside stiffnet's checkout (the examples), so a default never writes into shipped files."""
    folder = Path(campaign_folder).resolve()
    checkout = Path(__file__).resolve().parents[2]
    if folder.is_relative_to(checkout) and not folder.is_relative_to(checkout / "runs"):
        return Path("runs") / f"loop-{folder.name}"
    return folder.with_name(f"{folder.name}-loop")


def spread_params(
    name: str,
    params: dict[str, float],
    fitted: list[str],
    spread: float,
    intervals: dict[str, list[float]] | None = None,
) -> dict[str, float | list[float]]:
    """Fitted parameters as ``[p (1 - s), p (1 + s)]`` ranges inside the declared ranges,
    and inside a parameter's measured interval where ``intervals`` gives one (the range
    always holds ``p``)."""
    table = {r["name"]: r for r in effect_class(name).parameter_table()}
    out: dict[str, float | list[float]] = {}
    for k, v in params.items():
        if isinstance(v, list):  # a range given by the user stays as it is
            out[k] = [float(x) for x in v]
        elif k in fitted and spread > 0 and v != 0 and table.get(k, {}).get("range"):
            lo, hi = table[k]["range"]
            a, b = sorted((v * (1 - spread), v * (1 + spread)))
            a, b = max(a, lo), min(b, hi)
            if k in (intervals or {}):
                a, b = min(max(a, intervals[k][0]), v), max(min(b, intervals[k][1]), v)
            out[k] = [a, b] if a < b else float(v)
        else:
            out[k] = float(v)
    return out


def config_with_effects(
    cfg: SimulationConfig, added: list[tuple[str, dict[str, Any]]]
) -> SimulationConfig:
    """A copy of ``cfg`` with the effects added (each replacing one of the same class)."""
    effects = list(cfg.effects)
    for name, params in added:
        cls_name = effect_class(name).name
        effects = [e for e in effects if effect_class(e.name).name != cls_name]
        effects.append(EffectSpec(name=name, params=params))
    return cfg.model_copy(update={"effects": effects})


def write_config_yaml(cfg: SimulationConfig, path: Path, header: str) -> SimulationConfig:
    """Write ``cfg`` as YAML (atomically) and read it back through the pydantic model."""
    import yaml

    from stiffnet.config import load_config
    from stiffnet.io_utils import write_bytes_atomic

    body = yaml.safe_dump(cfg.model_dump(mode="json"), sort_keys=False, default_flow_style=None)
    text = "".join(f"# {line}\n" for line in header.splitlines()) + body
    write_bytes_atomic(path, text.encode())
    back = load_config(SimulationConfig, path)
    if back != cfg:  # pragma: no cover - a field that does not survive YAML
        raise StiffnetError(f"{path}: the written config does not read back identically")
    return back


# ---------------------------------------------------------------- state folder


def _open_state(folder: Path, campaign: Campaign, settings: dict[str, Any]) -> dict[str, Any]:
    """The state of an earlier loop on this campaign, or a new one (refusing foreign folders)."""
    import json

    marker, state_path = folder / RUN_MARKER, folder / STATE_FILE
    if folder.is_dir() and any(folder.iterdir()):
        try:
            kind = json.loads(marker.read_text()).get("kind")
            state = json.loads(state_path.read_text())
        except (OSError, ValueError, AttributeError):
            kind, state = None, None
        if kind != LOOP_KIND or not isinstance(state, dict):
            raise StiffnetError(
                f"{folder}: folder exists and is not a loop state folder (no {RUN_MARKER} and "
                f"{STATE_FILE}): choose another --state folder"
            )
        if state.get("manifest_sha256") != settings["manifest_sha256"]:
            raise StiffnetError(
                f"{folder}: the state belongs to another campaign ({state.get('campaign')}); "
                "choose another --state folder"
            )
        for key in ("family", "n_trajectories", "spread", "seed", "train_overrides", "world"):
            if settings.get(key) is not None and settings[key] != state.get(key):
                had = "the default" if state.get(key) is None else repr(state.get(key))
                raise StiffnetError(
                    f"{folder}: the loop was started with {key} {had}, not "
                    f"{settings[key]!r}; resume with the same settings or choose another --state"
                )
        return state
    folder.mkdir(parents=True, exist_ok=True)
    write_json_atomic(marker, {"kind": LOOP_KIND, "status": "running"})
    state = {
        "kind": "stiffnet-loop-state",
        "version": STATE_VERSION,
        "campaign": str(campaign.folder.resolve()),
        "iterations": [],
        "parent_run_id": None,
        "stopped": None,
        **settings,
    }
    write_json_atomic(state_path, state)
    return state


def _save_state(folder: Path, state: dict[str, Any]) -> None:
    write_json_atomic(folder / STATE_FILE, state)


# ---------------------------------------------------------------- one iteration


def _train_config(family: str, overrides: dict[str, Any] | None) -> Any:
    from stiffnet.config import load_yaml, validate_config
    from stiffnet.shipped import default_config
    from training.config import TrainConfig
    from training.families import get_family

    path = default_config(f"train/{family}.yaml")
    raw = load_yaml(path) if path.is_file() else {"model": family}
    section = get_family(family).config.model_fields
    # the family's loop settings (smaller datasets than the shipped model's) under the
    # user's; a user's key of the family's section (max_epochs) goes into the section
    user = {family: {}}
    for key, value in (overrides or {}).items():
        if key in section and key not in TrainConfig.model_fields:
            user[family][key] = value
        else:
            user[key] = value
    for layer in ({family: get_family(family).loop_settings}, user):
        for key, value in layer.items():
            if isinstance(value, dict) and isinstance(raw.get(key), dict):
                raw[key] = {**raw[key], **value}
            else:
                raw[key] = value
    raw["tracking"] = False  # the loop logs its own run per iteration
    return validate_config(TrainConfig, raw, str(path))


def cpu_seconds() -> float:
    """CPU seconds of this process and its finished children (user + system): what an
    iteration's phase costs on a shared machine, where its wall time is mostly waiting."""
    import resource

    own, kids = (
        resource.getrusage(resource.RUSAGE_SELF),
        resource.getrusage(resource.RUSAGE_CHILDREN),
    )
    return own.ru_utime + own.ru_stime + kids.ru_utime + kids.ru_stime


def _train(
    cfg: SimulationConfig,
    work: Path,
    family: str,
    overrides: dict[str, Any] | None,
    keep_data: bool,
    rows: list[Any] | None = None,
    orbits: list[Any] | None = None,
) -> dict[str, Any]:
    """Generate the iteration's dataset (over ``cfg``'s sweep, or at the ``rows``'
    operating points, held on their recordings' ``orbits`` where given) and train the
    family on it."""
    from stiffnet.dataset.generate import generate_dataset, shard_sizes
    from stiffnet.measurement.operating_points import (
        operating_point_configs,
        operating_point_dataset,
    )
    from training.train import train

    tcfg = _train_config(family, overrides)
    t0, c0 = time.perf_counter(), cpu_seconds()
    data = work / "data"
    shards = len(operating_point_configs(cfg, rows)) if rows else len(shard_sizes(cfg))
    with progress_task("simulating shards", shards) as bar:
        if rows:
            operating_point_dataset(cfg, rows, data, progress=lambda done, _: bar.update(done),
                                    orbits=orbits)  # fmt: skip
        else:
            generate_dataset(cfg, data, overwrite=True, progress=lambda done, _: bar.update(done))
    t_data, c_data = time.perf_counter() - t0, cpu_seconds() - c0
    summary = train(data, tcfg, work / "model", progress=None)
    t_train, c_train = time.perf_counter() - t0 - t_data, cpu_seconds() - c0 - c_data
    shutil.copyfile(data / "card.json", work / "data_card.json")
    if not keep_data:
        shutil.rmtree(data, ignore_errors=True)
    return {
        "onnx": summary["paths"]["onnx"],
        "card": summary["paths"]["card"],
        # the model's test metrics (named alike for every family) and the geometric method's
        "train_metrics": {
            f"train/{k}": v
            for k, v in summary["metrics"].items()
            if k.removeprefix("geometric/") in ("accuracy", "macro_f1", "beta_mape")
        },
        "epochs": summary.get("epochs"),
        "seconds": {"dataset": round(t_data, 2), "train": round(t_train, 2)},
        "cpu_seconds": {"dataset": round(c_data, 2), "train": round(c_train, 2)},
    }


def iteration_metrics(evaluation: dict[str, Any], discrepancy: float | None) -> dict[str, Any]:
    """The numbers of one iteration: discrepancy and cross-check agreement always, accuracy
    and β MAPE of the learned model and the geometric method where the manifest has β."""
    m = evaluation["metrics"]
    rows = evaluation["recordings"]
    geo = [r["agreement"] for r in rows if r.get("agreement") is not None]
    return {
        "discrepancy": discrepancy,
        "restoring_force_agreement": m["restoring_force"].get("agreement_with_learned"),
        "geometric_agreement": sum(map(bool, geo)) / len(geo) if geo else None,
        "accuracy": m["learned"]["accuracy"],
        "macro_f1": m["learned"]["macro_f1"],
        "beta_mape": m["learned"]["beta_mape"],
        "geometric_accuracy": m["geometric"]["accuracy"],
        "geometric_beta_mape": m["geometric"]["beta_mape"],
        "alarm_rate": m["learned"].get("alarm_rate"),
        **simulation_metrics(m),
    }


#: The reading by simulation's numbers an iteration keeps (``metrics.simulation`` and
#: ``metrics.reading`` of the evaluation, :mod:`stiffnet.measurement.simulation_reading`).
SIMULATION_METRICS = {
    "simulation": ("accuracy", "beta_mape", "interval_coverage", "reproduced_share", "alarms"),
    "reading": ("accuracy", "beta_mape", "from_simulation"),
}


def simulation_metrics(metrics: dict[str, Any]) -> dict[str, Any]:
    """``simulation_accuracy``, ``reading_accuracy``, ... where the evaluation has them."""
    return {
        f"{method}_{k}": metrics[method].get(k)
        for method, keys in SIMULATION_METRICS.items()
        if method in metrics
        for k in keys
    }


#: What an iteration keeps of its diagnosis (the full result is in ``iter-k/diagnosis.json``).
DIAGNOSIS_SUMMARY = ("baseline_discrepancy", "residual_discrepancy", "noise_floor", "verdict",
                     "explained_fraction", "missing_effects", "summary", "seconds")  # fmt: skip


def diagnosis_summary(diagnosis: dict[str, Any]) -> dict[str, Any]:
    """The verdict and numbers of a diagnosis that the loop's state keeps."""
    return {k: diagnosis.get(k) for k in DIAGNOSIS_SUMMARY}


def _effects_to_add(
    campaign: Campaign,
    start_cfg: SimulationConfig,
    current: list[str],
    given: list[tuple[str, dict[str, Any]]],
    model_path: str,
    seed: int,
    candidates: list[str] | None,
    inclination: bool,
) -> tuple[list[dict[str, Any]], dict[str, Any] | None]:
    """(effects, diagnosis result): the given ones (fitted when given without values), else
    every effect the diagnosis selects, with its joint fitted values.

    The diagnosis starts from the *starting* config and has the effects the loop added
    before (``current``) among its candidates: so they are refitted jointly with the new
    ones (a value fitted alone in an earlier iteration, biased by an effect not yet in
    the model, never blocks the next one), and the iteration takes every joint value.
    """
    from stiffnet.measurement.diagnose import PROPOSED_ONLY, diagnose_campaign

    base = config_effects(start_cfg)
    if given and all(params for _, params in given):
        return [{"name": n, "params": p, "fitted": [], "source": "given"} for n, p in given], None
    # a learned law in the model is not refitted blind from its class defaults: the
    # diagnosis's discovery proposes it again, refined around its discovered values
    proposed = [n for n in current if n in PROPOSED_ONLY and n not in (candidates or [])]
    names = [n for n, _ in given] or (
        None
        if candidates is None
        else list(dict.fromkeys([*candidates, *(n for n in current if n not in proposed)]))
    )
    shipped = None if names is None else [n for n in names if ":" not in n]
    users = [n for n in (names or current) if ":" in n]
    diag = diagnose_campaign(
        campaign,
        base,
        effects=shipped,
        user_effects=users,
        seed=seed,
        inclination=inclination,
        model_path=model_path,
    )
    by_name = {r["effect"]: r for r in diag["ranking"]}
    if given:  # the user's choice: added even where the diagnosis would not select it
        out = []
        for n, p in given:
            fit = by_name.get(n, {})
            params = p or {
                k: float(v)
                for k, v in (diag["fitted_params"].get(n) or fit.get("params") or {}).items()
            }
            out.append(
                {
                    "name": n,
                    "params": params,
                    "fitted": [] if p else list(fit.get("fitted") or params),
                    "source": "given",
                }
            )
        return out, diag
    out = []
    for n in diag["missing_effects"]:
        params = {k: float(v) for k, v in diag["fitted_params"][n].items()}
        fitted = list(by_name.get(n, {}).get("fitted") or params)
        out.append({"name": n, "params": params, "fitted": fitted, "source": "diagnosis"})
    return with_learned_law(out, diag), diag


def _iteration(
    k: int,
    campaign: Campaign,
    state: dict[str, Any],
    folder: Path,
    start_cfg: SimulationConfig,
    added: list[dict[str, Any]],
    diagnosis: dict[str, Any] | None,
    keep_data: bool,
    bar: Any,
) -> dict[str, Any]:
    from stiffnet.measurement.evaluate import evaluate_campaign
    from stiffnet.measurement.operating_points import HOLD_ORBITS, measured_orbits

    t0, c0 = time.perf_counter(), cpu_seconds()
    work = folder / f"iter-{k:03d}"
    if work.exists():  # an interrupted attempt: its files are not part of the state
        shutil.rmtree(work)
    work.mkdir(parents=True)
    prev = state["iterations"][-1]["effects"] if state["iterations"] else []
    effects = carried_effects(prev, added)
    # the model at the fitted values; its effects include the starting config's own (a
    # user's --config with a nonlinear law decides the world too)
    fixed_cfg = config_with_effects(start_cfg, [(e["name"], e["params"]) for e in effects])
    world, why = dataset_world(state.get("world", "sweep"), config_effects(fixed_cfg))
    n = state["n_trajectories"] or (
        OPERATING_POINT_TRAJECTORIES if world == "operating_points" else DEFAULT_TRAJECTORIES
    )
    ops = world == "operating_points"
    names = ", ".join(f"{e['name']}" for e in added) or "none (starting config)"
    world_cfg = _prior_config(start_cfg.model_copy(update={"n_trajectories": n}), effects,
                              state["spread"])  # fmt: skip
    train_cfg = write_config_yaml(
        with_analog_chain(world_cfg),
        work / "config.yaml",
        f"stiffnet loop on {campaign.folder.name}, iteration {k}: added {names}\n"
        f"fitted values +-{state['spread']:.0%} (prior centred on the fit); "
        "stiffnet simulate --config this file"
        + ("\ntrained at the campaign's operating points (the sweep's columns per manifest row)"
           if ops else ""),
    )  # fmt: skip
    bar.update(note=f"iteration {k}: dataset + {state['family']} training")
    trained = _train(
        train_cfg, work, state["family"], iteration_train_overrides(state, effects), keep_data,
        list(campaign.rows) if ops else None,
        measured_orbits(campaign) if ops and HOLD_ORBITS else None,
    )  # fmt: skip
    bar.update(note=f"iteration {k}: evaluation and discrepancy")
    c_eval = cpu_seconds()
    # one simulation of the campaign for the discrepancy and the evaluation's impact regime
    cmp = compare_campaign(
        campaign, config_effects(fixed_cfg), config_settings(fixed_cfg), state["seed"],
        contact=True,
    )  # fmt: skip
    evaluation = evaluate_campaign(
        campaign, trained["onnx"], config_effects(fixed_cfg), require_beta=False,
        settings=config_settings(fixed_cfg), contact=cmp.contact,
    )  # fmt: skip
    metrics = iteration_metrics(evaluation, cmp.result["discrepancy"])
    write_json_atomic(work / "evaluation.json", evaluation)
    if diagnosis is not None:
        write_json_atomic(work / "diagnosis.json", diagnosis)
    return {
        "index": k,
        "label": _label(k, added, prev),
        "added": added,
        "effects": effects,
        "config": str(work / "config.yaml"),
        "model": trained["onnx"],
        "card": trained["card"],
        "world": world,
        "world_reason": why,
        "n_trajectories": n,
        "metrics": metrics,
        "train_metrics": trained["train_metrics"],
        "diagnosis": diagnosis_summary(diagnosis) if diagnosis is not None else None,
        "recordings": [{c: r.get(c) for c in RECORDING_COLUMNS} for r in evaluation["recordings"]],
        "seconds": {**trained["seconds"], "total": round(time.perf_counter() - t0, 2)},
        # the evaluation's restoring-force checks and the discrepancy's simulation
        "cpu_seconds": {
            **trained["cpu_seconds"],
            "evaluation": round(cpu_seconds() - c_eval, 2),
            "total": round(cpu_seconds() - c0, 2),
        },
    }


def iteration_train_overrides(
    state: dict[str, Any], effects: list[dict[str, Any]]
) -> dict[str, Any]:
    """The iteration's training settings: the user's, over :data:`FITTED_CHAIN_UNDO` where
    the world holds a sensor chain the loop fitted to the campaign (``effects``)."""
    chain = any(effect_class(e["name"]).name == "sensor_dynamics" for e in effects)
    return {**({"undo_chain": FITTED_CHAIN_UNDO} if chain else {}),
            **(state["train_overrides"] or {})}  # fmt: skip


def carried_effects(
    prev: list[dict[str, Any]], added: list[dict[str, Any]]
) -> list[dict[str, Any]]:
    """The next iteration's effects: the previous ones, less those an added effect replaces
    (the same effect refitted, or one it supersedes), then the added ones at their fit."""
    gone = {effect_class(a["name"]).name for a in added} | replaced_by(added)
    return [e for e in prev if effect_class(e["name"]).name not in gone] + [
        {
            "name": a["name"],
            "params": refit_params(prev, a),
            "fitted": a["fitted"],
            **({"intervals": a["intervals"]} if a.get("intervals") else {}),
        }
        for a in added
    ]


def _prior_config(
    base: SimulationConfig, effects: list[dict[str, Any]], spread: float
) -> SimulationConfig:
    """The training world's config: each effect as a prior around its fitted values."""
    return config_with_effects(
        base,
        [
            (
                e["name"],
                spread_params(e["name"], e["params"], e["fitted"], spread, e.get("intervals")),
            )
            for e in effects
        ],
    )


def dataset_world(world: str, effects: Sequence[Effect]) -> tuple[str, str]:
    """Where an iteration's dataset is drawn, ``"sweep"`` or ``"operating_points"``, and why.

    Parameters
    ----------
    world : {"auto", "sweep", "operating_points"}
        The loop's setting; ``"auto"`` picks the operating points when one of ``effects``
        (the iteration's config's, built) makes the contact law nonlinear
        (:attr:`~stiffnet.effects.base.DynamicsEffect.nonlinear_contact`).
    """
    if world != "auto":
        return world, f"the loop's world is {world}"
    nonlinear = [
        e.name or type(e).__name__ for e in effects if getattr(e, "nonlinear_contact", False)
    ]
    if nonlinear:
        return "operating_points", (
            f"{', '.join(nonlinear)}: a contact law that is not a linear spring (an impact's "
            "shape depends on how hard it hits), trained at the campaign's operating points"
        )
    return "sweep", "every contact law is a linear spring and dashpot: the config's sweep"


def refit_params(prev: list[dict[str, Any]], added: dict[str, Any]) -> dict[str, Any]:
    """An added effect's values: a refit of an effect already in the model keeps every value
    of the previous iteration that the refit does not set (a learned law's reference
    penetration, preload and face are discovered, not fitted: never the class defaults)."""
    cls = effect_class(added["name"]).name
    old = next((e["params"] for e in prev if effect_class(e["name"]).name == cls), {})
    return {**old, **added["params"]}


def _label(k: int, added: list[dict[str, Any]], prev: list[dict[str, Any]]) -> str:
    """``start``, ``+new+new`` and, for effects already there and refitted, ``(refit x)``."""
    if k == 0:
        return "start"
    had = {effect_class(e["name"]).name for e in prev}
    new = [a["name"] for a in added if effect_class(a["name"]).name not in had]
    refit = [a["name"] for a in added if effect_class(a["name"]).name in had]
    return "+".join(["", *new]) + (f" (refit {', '.join(refit)})" if refit else "")


def _track(state: dict[str, Any], it: dict[str, Any], chart: Path) -> None:
    """The iteration's nested MLflow run, its logged and registered model (training.tracking)."""
    from training.tracking import log_child_run, log_parent_artifact, parent_run

    uri, experiment = state["tracking_uri"], state["experiment"]
    state["parent_run_id"] = parent_run(
        uri,
        experiment,
        state.get("parent_run_id"),
        f"loop {state['registered_model']}",
        tags={"stiffnet.loop": state["registered_model"], "stiffnet.family": state["family"]},
    )
    params: dict[str, Any] = {
        "iteration": it["index"],
        "family": state["family"],
        "n_trajectories": it["n_trajectories"],
        "spread": state["spread"],
        "world": it["world"],
        "added": ",".join(a["name"] for a in it["added"]) or "none",
        "effects": ",".join(e["name"] for e in it["effects"]) or "none",
    }
    for e in it["effects"]:
        params.update({f"{e['name']}.{p}": v for p, v in e["params"].items()})
    logged = log_child_run(
        tracking_uri=uri,
        experiment=experiment,
        parent_run_id=state["parent_run_id"],
        name=f"iteration {it['index']}",
        step=it["index"],
        params=params,
        metrics={**it["metrics"], **it["train_metrics"]},
        tags={"stiffnet.loop": state["registered_model"], "stiffnet.iteration": str(it["index"])},
        artifacts=[it["config"], Path(it["config"]).parent / "evaluation.json"],
        onnx_model=it["model"],
        registered_model=state["registered_model"],
    )
    it.update(
        {
            "run_id": logged["run_id"],
            "model_uri": logged["model_uri"],
            "model_version": logged["model_version"],
        }
    )
    log_parent_artifact(uri, state["parent_run_id"], chart)


def _chart(folder: Path, state: dict[str, Any]) -> Path:
    from stiffnet.measurement.plots import loop_figure

    return loop_figure(
        [{"label": f"{it['index']}: {it['label']}", **it["metrics"]} for it in state["iterations"]],
        folder / "loop_error.png",
    )


def run_loop(
    campaign: Campaign,
    cfg: SimulationConfig,
    state_dir: str | Path | None = None,
    iterations: int = 1,
    add_effects: list[tuple[str, dict[str, Any]]] | None = None,
    diagnosis: dict[str, Any] | None = None,
    family: str | None = None,
    n_trajectories: int | None = None,
    spread: float | None = None,
    tracking_uri: str | None = "sqlite:///mlflow.db",
    train_overrides: dict[str, Any] | None = None,
    seed: int | None = None,
    candidates: list[str] | None = None,
    inclination: bool = False,
    keep_data: bool = False,
    world: str | None = None,
) -> dict[str, Any]:
    """Run ``iterations`` more loop iterations on the state in ``state_dir`` (see the module notes).

    Parameters
    ----------
    campaign : Campaign
    cfg : SimulationConfig
        The starting simulator config (used when the state is new).
    state_dir : str or Path, optional
        The state folder (default :func:`default_state_dir`); an existing one resumes.
    iterations : int
        New iterations after the last finished one (iteration 0, the start, is added
        first when the state is new and does not count).
    add_effects : list of (name, params), optional
        Effects the first new iteration adds instead of the diagnosed ones; empty
        ``params`` are fitted (by the diagnosis restricted to those effects).
    diagnosis : dict, optional
        A ``diagnose --json`` result against the last iteration's config, used by the
        first new iteration instead of diagnosing again.
    family : str, optional
        A registered model family (:mod:`training.families`). Default: the state's;
        for a new loop the family whose ``defaults`` name ``loop`` (the shipped one).
    n_trajectories : int, optional
        Trajectories per dataset (default :data:`DEFAULT_TRAJECTORIES` over the sweep,
        :data:`OPERATING_POINT_TRAJECTORIES` at the operating points).
    spread : float, optional
        Relative half-width of the prior around each fitted value (default 0.25).
    tracking_uri : str or None
        MLflow store; None disables tracking.
    train_overrides : dict, optional
        (Kept in the state: a resumed loop trains as it started.)
        TrainConfig fields over ``configs/train/FAMILY.yaml`` and the family's ``loop_settings``.
    seed : int, optional
        Common-random-number seed of the diagnosis and the discrepancy.
    candidates : list of str, optional
        Candidate effects of the diagnosis (default: every library effect).
    inclination : bool
        Include the inclination statistics in the diagnosis (slower).
    keep_data : bool
        Keep each iteration's dataset (by default only its card).
    world : {"auto", "sweep", "operating_points"}, optional
        Where the iterations' datasets are drawn (kept in the state): ``"auto"`` (the
        default for a new loop) per iteration by its contact law (:func:`dataset_world`),
        over the starting config's sweep, or at the campaign's operating points
        (:func:`~stiffnet.measurement.operating_points.operating_point_dataset`: each
        manifest row's gap, forcing, damping, fs/f_n and noise, jittered, β over the
        sweep).

    Returns
    -------
    dict
        ``iterations`` (each ``index``, ``label``, ``added``, ``effects``, ``config``,
        ``model``, ``metrics``, ``run_id``, ``model_version``, ``seconds``, ...),
        ``before`` / ``after`` (metrics of the first and the last), ``chart``,
        ``stopped`` (why no effect was added, or None), ``out`` (the state folder).
    """
    # the recordings, their statistics and predictions are read and computed once for all
    # iterations (a LoadedCampaign is shared by diagnose, evaluate and compare)
    campaign = LoadedCampaign.of(campaign)
    _check_arguments(family, n_trajectories, iterations, spread, world)
    folder = Path(state_dir) if state_dir is not None else default_state_dir(campaign.folder)
    settings = {
        "family": family,
        "n_trajectories": n_trajectories,
        "spread": spread,
        "seed": seed,
        "train_overrides": train_overrides,
        "world": world,
        "manifest_sha256": sha256_file(campaign.manifest_path),
    }
    t0 = time.perf_counter()
    with output_lock(folder):
        state = _start_state(folder, campaign, settings, cfg, tracking_uri)
        start_cfg = SimulationConfig.model_validate(state["start_config"])
        todo = iterations + (0 if state["iterations"] else 1)
        write_json_atomic(folder / RUN_MARKER, {"kind": LOOP_KIND, "status": "running"})
        with (
            progress_task("loop iterations", todo) as bar,
            fits_kept(folder / KEPT_FITS_FILE) as fits,
        ):
            for _ in range(todo):
                k = len(state["iterations"])
                added: list[dict[str, Any]] = []
                diag_result = None
                t_diag = time.perf_counter()
                if k > 0:
                    bar.update(note=f"iteration {k}: diagnosis")
                    given = (diagnosis, list(add_effects or []))
                    added, diag_result = _next_effects(
                        campaign, state, start_cfg, given, candidates, inclination
                    )
                    # a chain's low-pass fitted where its search ends is none
                    added = without_lowpass_at_top(added, min(r.fs_hz for r in campaign.rows))
                    # and, where configs/loop_chain.yaml says so, a high-pass no map reads
                    added = without_unread_highpass(added, diag_result)
                    diagnosis, add_effects = None, None  # the first new iteration only
                    if _stop_when_nothing_new(state, k, added, diag_result):
                        break
                diag_s = round(time.perf_counter() - t_diag, 2) if k > 0 else 0.0
                it = _iteration(
                    k, campaign, state, folder, start_cfg, added, diag_result, keep_data, bar
                )
                _record_iteration(folder, state, it, diag_s, tracking_uri)
                fits.save()  # an interrupted loop resumes with them
                bar.advance()
        chart = _chart(folder, state) if state["iterations"] else None
        _save_state(folder, state)
        write_json_atomic(folder / RUN_MARKER, {"kind": LOOP_KIND, "status": "complete"})
    return _loop_result(state, folder, chart, tracking_uri, time.perf_counter() - t0)


def _check_arguments(
    family: str | None,
    n_trajectories: int | None,
    iterations: int,
    spread: float | None,
    world: str | None = None,
) -> None:
    """One clear line for a loop argument out of range, before any work."""
    if family is not None:
        check_family(family)
    check_n_trajectories(n_trajectories)
    if not 0 <= iterations <= 100:
        raise StiffnetError(f"--iterations must be 0..100, got {iterations}")
    if spread is not None and not 0 <= spread < 1:
        raise StiffnetError(f"--spread must be in [0, 1), got {spread}")
    if world is not None and world not in WORLDS:
        raise StiffnetError(f"the training world must be one of {', '.join(WORLDS)}, got {world}")


def _start_state(
    folder: Path,
    campaign: Campaign,
    settings: dict[str, Any],
    cfg: SimulationConfig,
    tracking_uri: str | None,
) -> dict[str, Any]:
    """The state to continue: resumed, or new with its settings' defaults filled in."""
    state = _open_state(folder, campaign, settings)
    if not state["iterations"]:
        state.update(
            family=settings["family"] or _default_family(),
            # None: the world's default, per iteration (the world may change with the law)
            n_trajectories=settings["n_trajectories"],
            spread=DEFAULT_SPREAD if settings["spread"] is None else settings["spread"],
            seed=DEFAULT_SEED if settings["seed"] is None else settings["seed"],
            world=settings["world"] or "auto",
            start_config=cfg.model_dump(mode="json"),
            tracking_uri=tracking_uri,
            experiment=f"campaign-{campaign.folder.name}",
            registered_model=campaign.folder.name,
        )
    state["tracking_uri"] = tracking_uri
    state["stopped"] = None
    return state


def _next_effects(
    campaign: Campaign,
    state: dict[str, Any],
    start_cfg: SimulationConfig,
    given: tuple[dict[str, Any] | None, list[tuple[str, dict[str, Any]]]],
    candidates: list[str] | None,
    inclination: bool,
) -> tuple[list[dict[str, Any]], dict[str, Any] | None]:
    """What the next iteration adds: a given diagnosis's selection, else the effects the
    user names (fitted when without values) or the diagnosis selects."""
    diagnosis, add_effects = given
    last = state["iterations"][-1]
    current = [e["name"] for e in last["effects"]]

    def discrepancy(effects: list[dict[str, Any]]) -> float:
        return chain_discrepancy(campaign, start_cfg, effects, state["seed"])

    if diagnosis is not None and not add_effects:
        return with_evidence_chain(
            *with_chain_intervals(*with_law_intervals(*_from_diagnosis(diagnosis))), discrepancy
        )
    return with_evidence_chain(*with_chain_intervals(*with_law_intervals(*_effects_to_add(
        campaign, start_cfg, current, add_effects, last["model"], state["seed"], candidates,
        inclination,
    ))), discrepancy)  # fmt: skip


def chain_discrepancy(
    campaign: Campaign, start_cfg: SimulationConfig, effects: list[dict[str, Any]], seed: int
) -> float:
    """The campaign's discrepancy with ``effects`` at their values (one simulation of every
    row, :func:`~stiffnet.measurement.compare.compare_campaign`)."""
    cfg = config_with_effects(start_cfg, [(e["name"], e["params"]) for e in effects])
    return float(
        compare_campaign(campaign, config_effects(cfg), config_settings(cfg), seed).result[
            "discrepancy"
        ]
    )


def with_law_intervals(
    added: list[dict[str, Any]], diag: dict[str, Any] | None
) -> tuple[list[dict[str, Any]], dict[str, Any] | None]:
    """A discovered law's prior no wider than the discovery's intervals (bootstrap over
    impacts, widened by its misfit): ``intervals`` on the law's entry, for its fitted values.

    Measured (docs/measurement_loop.md, "Training at the campaign's operating points"): the
    blanket ±25 % on a two-stage law's knee and stage ratio blurs the classes more than the
    campaign's data allow; at its discovered values the retrained model classes every
    recording of the campaign."""
    law = ((diag or {}).get("learned_law") or {}).get("law") or {}
    measured = law.get("intervals") or {}
    for a in added:
        if a["name"] == LearnedContact.name and a.get("source") == "diagnosis" and measured:
            a["intervals"] = {
                k: [float(x) for x in measured[k]] for k in a["fitted"] if k in measured
            }
    return added, diag


#: The chain's parameters the restoring-force evidence reads on each recording with an
#: interval: the mounted resonance (its low-pass and high-pass are what a contact the library
#: lacks bends, :data:`OPTIONAL_STAGES`).
EVIDENCE_INTERVAL_PARAMS = ("resonance_hz", "resonance_damping")


def with_chain_intervals(
    added: list[dict[str, Any]], diag: dict[str, Any] | None
) -> tuple[list[dict[str, Any]], dict[str, Any] | None]:
    """A diagnosed sensor chain's resonance prior no wider than the restoring-force evidence
    reads it: ``intervals`` on the chain's entry, each the union of the recordings' intervals
    of :data:`EVIDENCE_INTERVAL_PARAMS` (the prior still holds the fit,
    :func:`spread_params`).

    The blanket ±25 % spreads the mount over a band the recordings rule out, and the model
    then reads β from a contact's spike blurred by mounts the campaign does not have.
    Measured (docs/measurement_loop.md, "A low-pass at the top of its search"): on the
    independent rig's two-stage campaign behind a 240 Hz ζ 0.04 mount the evidence read
    238.96-239.68 Hz and ζ 0.020-0.041 on its fitted recordings, the fit 240.4 Hz / 0.039;
    the loop's GBM alone (no low-pass, :func:`without_lowpass_at_top`) 0.875 / β MAPE 0.059
    with the ±25 % prior (180-300 Hz), 0.917 / 0.060 with the evidence's (the misses: both
    β 15, on the class edge)."""
    per = ((diag or {}).get("restoring_force") or {}).get("per_recording") or []
    read = [((r.get("sensor") or {}).get("intervals") or {}) for r in per]
    measured = {}
    for k in EVIDENCE_INTERVAL_PARAMS:
        spans = [v[k] for v in read if isinstance(v.get(k), list | tuple) and len(v[k]) == 2]
        if spans:
            measured[k] = [float(min(lo for lo, _ in spans)), float(max(hi for _, hi in spans))]
    for a in added:
        if effect_class(a["name"]).name == SensorDynamics.name and a.get("source") == "diagnosis":
            chain = {k: v for k, v in measured.items() if k in a["fitted"]}
            if chain:
                a["intervals"] = {**(a.get("intervals") or {}), **chain}
    return added, diag


def with_evidence_chain(
    added: list[dict[str, Any]],
    diag: dict[str, Any] | None,
    discrepancy: Callable[[list[dict[str, Any]]], float],
) -> tuple[list[dict[str, Any]], dict[str, Any] | None]:
    """A diagnosed sensor chain taken from the restoring-force evidence where the simulation
    fit read it through a contact law the iteration replaces, its stages chosen by the
    campaign's discrepancy.

    ``diagnose`` fits ``sensor_dynamics`` by simulation with the library's contact in the
    model; when the contact-law discovery then replaces that contact (a two-stage or power
    law), the chain's values are conditional on a contact now known wrong: the fit bends
    the mount to mimic the missing stiffening. The restoring-force evidence reads the chain
    on each recording's own force-state map, whatever the law. Where its recordings confirm
    one shared chain (``chain_fitted_on``; not ``chain_refuted``) with a mounted resonance,
    the candidates of :func:`evidence_chain_candidates` (the simulation fit, the evidence's
    chain, and that chain without its high-pass, its low-pass or both) are each simulated
    with the iteration's other effects at their values (``discrepancy(added)``, the loop's
    :func:`chain_discrepancy`), and the least discrepancy's is the world's chain, the prior
    then centred on it. The entry keeps the simulation fit (``simulation_fit``), every
    candidate's discrepancy (``chain_choice``) and where the chain came from (``origin``).
    Where the diagnosis refitted its chain with the learned law in place
    (:func:`~stiffnet.measurement.learned_law.with_refitted_chain`), that refit is the fit.

    Measured (docs/measurement_loop.md, "The loop's world takes the chain the evidence
    reads"): on the independent rig's two-stage campaign behind a 240 Hz mount (no other
    stage) the fit read 180.8 Hz / zeta 0.065 with a 248 Hz low-pass and a 0.67 Hz
    high-pass, the evidence 238.1 / 0.040 with a 258 Hz low-pass and a 0.24 Hz high-pass;
    discrepancy at the learned law 104.2 (fit), 46.7 (evidence), 1.6 (less the high-pass),
    1.1 (less both), 1.07 (the rig's own chain); at the loop's seed 104.5, 53.0, 5.9, 9.0,
    and the loop's reading went from 0.750 / beta MAPE 0.183 to 0.917 / 0.140. A chain the
    user gives (``source`` ``given``) is never replaced.
    """
    from stiffnet.restoring_force.chain import shared_chain_sheet

    evidence = (diag or {}).get("restoring_force") or {}
    sheet = shared_chain_sheet(evidence.get("sensor"))
    law_replaces = any(
        a["name"] == LearnedContact.name and a.get("source") == "diagnosis" and a.get("replaces")
        for a in added
    )
    if (
        not law_replaces
        or not sheet
        or not sheet.get("resonance_hz")
        or not evidence.get("chain_fitted_on")
        or evidence.get("chain_refuted")
    ):
        return added, diag
    for a in added:
        if effect_class(a["name"]).name != "sensor_dynamics" or a.get("source") != "diagnosis":
            continue
        fit = dict(a["params"])
        scored = []
        for name, params in evidence_chain_candidates(fit, sheet):
            a["params"] = params
            scored.append((discrepancy(added), name, params))
        best = min(scored, key=lambda t: t[0])
        a["params"] = best[2]
        a["simulation_fit"] = fit
        a["chain_choice"] = [{"chain": n, "discrepancy": round(d, 4)} for d, n, _ in scored]
        # the fit may be the diagnosis's refit with the learned law (its own origin kept)
        a["origin"] = (a.get("origin", SIMULATION_FIT) if best[1] == SIMULATION_FIT
                       else "restoring-force chain")  # fmt: skip
    return added, diag


class LoopChainSettings(BaseModel):
    """A diagnosed sensor chain in the loop's world (``configs/loop_chain.yaml``).

    Attributes
    ----------
    lowpass_top_fraction : float
        A low-pass corner fitted at or above this fraction of the top of its search (the
        campaign's lowest ``0.45 fs``, where the simulator skips the stage) is read as no
        low-pass (:func:`without_lowpass_at_top`).
    analog_world : bool
        Simulate the world's analog sensor chain on the motion sampled faster than the
        logger, as the diagnosis fitted it (:func:`with_analog_chain`).
    highpass_from_evidence : bool
        A diagnosed high-pass that the restoring-force evidence's pooled chain lacks is not
        in the world (:func:`without_unread_highpass`).
    """

    model_config = ConfigDict(extra="forbid")

    lowpass_top_fraction: float = Field(0.9, gt=0.0, le=1.0)
    analog_world: bool = False
    highpass_from_evidence: bool = False


def loop_chain_settings() -> LoopChainSettings:
    """The shipped settings (``configs/loop_chain.yaml``), else the defaults."""
    from stiffnet.config import shipped_settings

    return shipped_settings(LoopChainSettings, LOOP_CHAIN_CONFIG)


def with_analog_chain(cfg: SimulationConfig, on: bool | None = None) -> SimulationConfig:
    """``cfg`` with its solver oversampled where its world holds an analog effect (a sensor
    chain): the dataset then filters the motion at
    :func:`~stiffnet.campaign.simulate.oversampling` times the logger's rate and samples the
    output, as the campaign's simulations do (:func:`stiffnet.dataset.generate.measured`).

    The diagnosis fits the chain on such simulations; a world that filters the logger's
    samples instead is another chain (a mount's ring a few samples long, a 1 kHz record's
    response near Nyquist). ``on``: default ``configs/loop_chain.yaml``'s ``analog_world``.

    Measured (docs/measurement_loop.md, "The loop's analog world"; the loop's GBM, one
    iteration, with :func:`without_unread_highpass`): the independent rig's Hunt-Crossley
    campaign behind a 260 Hz mount 0.833 / beta MAPE 0.068 -> 0.917 / 0.030 (dataset seed 1
    0.875 / 0.036; its hardest-hit point, read 13-37 % high at the logger's rate, read right);
    its two-stage campaign behind 240 Hz 0.917 / 0.060 -> 0.833 / 0.047 (seed 1 0.958 / 0.073
    -> 0.833 / 0.059: beta 61 and 37 read 6-15 % low).
    """
    from stiffnet.campaign.simulate import oversampling

    on = loop_chain_settings().analog_world if on is None else on
    k = oversampling(config_effects(cfg)) if on else 1
    if k == 1 or cfg.solver.oversampled == k:
        return cfg
    return cfg.model_copy(update={"solver": cfg.solver.model_copy(update={"oversampled": k})})


def without_unread_highpass(
    added: list[dict[str, Any]], diag: dict[str, Any] | None, on: bool | None = None
) -> list[dict[str, Any]]:
    """The diagnosed sensor chains of ``added`` without a high-pass that the restoring-force
    evidence does not read (``highpass_hz`` 0, no longer fitted; the fit's corner kept as
    ``highpass_unread``).

    The evidence reads the chain on each recording's own force-state map and pools a stage
    only where half its recordings show it (``restoring_force.sensor``); a corner a tenth of
    a hertz or so that the campaign's simulation fit keeps for a small gain in discrepancy
    then lies in no recording's map. In the world it is not small: a first-order high-pass
    adds a term in the velocity, ``w_h / w`` of the forcing's swing with its phase, to every
    window, and the windows' inclination features read it. Without evidence (no pooled
    chain) the fit stands; a chain the user gives is never changed. ``on``: default
    ``configs/loop_chain.yaml``'s ``highpass_from_evidence``.

    Measured (docs/measurement_loop.md, "The loop's analog world"): the independent rig's
    Hunt-Crossley campaign behind a 260 Hz mount (no high-pass): the fit 0.306 Hz, no
    recording's map reads one; the loop's GBM in the oversampled world read beta 7 % low
    (0.833 / MAPE 0.071), without the high-pass 2 % (0.917 / 0.029; dataset seed 1: 0.0 %,
    0.875 / 0.030); the start-up transient is not the cause (a lead-in leaves 0.833 / 0.074).
    """
    pooled = ((diag or {}).get("restoring_force") or {}).get("sensor")
    if not (loop_chain_settings().highpass_from_evidence if on is None else on) or not pooled:
        return added
    if pooled.get("highpass_hz"):
        return added
    out = []
    for a in added:
        diagnosed = effect_class(a["name"]).name == SensorDynamics.name and (
            a.get("source") == "diagnosis"
        )
        corner = float(a["params"].get("highpass_hz") or 0.0) if diagnosed else 0.0
        if corner == 0.0:
            out.append(a)
            continue
        out.append({**a, "params": {**a["params"], "highpass_hz": 0.0},
                    "fitted": [k for k in a["fitted"] if k != "highpass_hz"],
                    "highpass_unread": corner})  # fmt: skip
    return out


def without_lowpass_at_top(
    added: list[dict[str, Any]], fs_hz_min: float, fraction: float | None = None
) -> list[dict[str, Any]]:
    """The diagnosed sensor chains of ``added`` with a low-pass fitted at the top of its
    search taken out (``lowpass_hz`` 0, no longer fitted; the fit's corner kept as
    ``lowpass_at_top``).

    A chain's low-pass corner is searched up to the campaign's lowest ``0.45 fs``
    (:meth:`~stiffnet.effects.sensor_dynamics.SensorDynamics.observed_fit_space`), where the
    simulator skips the stage: a fit that ends near there asks for as little low-pass as the
    search allows, i.e. none. Kept, the stage still filters the campaign's faster records
    and, spread about the fit, every record of the loop's world, which then reads a sharper
    record as a stiffer contact. ``fraction``: default ``configs/loop_chain.yaml``'s.

    Measured (docs/measurement_loop.md, "A low-pass at the top of its search"): the
    independent rig's two-stage campaign behind a 240 Hz mount (no low-pass; rates 1-2 kHz)
    had its chain refitted with the learned law at 439 Hz (top 450 Hz); the loop's GBM
    (1,600 trajectories) read beta 8 % high (median), 0.833 / MAPE 0.092 alone; the same
    world without the low-pass 0.875 / 0.059 (2 %), the campaign's discrepancy 2.57 -> 2.50.
    """
    limit = (loop_chain_settings().lowpass_top_fraction if fraction is None else fraction) * (
        SensorDynamics.campaign_fit_space(fs_hz_min).free[0].high
    )
    out = []
    for a in added:
        diagnosed = effect_class(a["name"]).name == SensorDynamics.name and (
            a.get("source") == "diagnosis"
        )  # a chain the user gives is never changed
        corner = float(a["params"].get("lowpass_hz") or 0.0) if diagnosed else 0.0
        if corner < limit:
            out.append(a)
            continue
        out.append({**a, "params": {**a["params"], "lowpass_hz": 0.0},
                    "fitted": [k for k in a["fitted"] if k != "lowpass_hz"],
                    "lowpass_at_top": corner})  # fmt: skip
    return out


#: The candidate chain that is the diagnosis's own simulation fit.
SIMULATION_FIT = "simulation fit"
#: Stages of the evidence's chain that its recordings read least consistently (a high-pass
#: corner profiled by the contact law, a low-pass a stiffening contact can stand for): each
#: candidate world without them too, so the campaign's discrepancy decides whether it holds.
OPTIONAL_STAGES = (("highpass_hz",), ("lowpass_hz",), ("highpass_hz", "lowpass_hz"))


def evidence_chain_candidates(
    fit: dict[str, float], sheet: dict[str, float]
) -> list[tuple[str, dict[str, float]]]:
    """The chains :func:`with_evidence_chain` scores: the simulation fit, the evidence's
    chain (its stages over the fit's), and the evidence's without each optional stage it has
    (:data:`OPTIONAL_STAGES`, disabled at 0)."""
    evidence = {**fit, **sheet}
    out = [(SIMULATION_FIT, fit), ("evidence", evidence)]
    for stages in OPTIONAL_STAGES:
        if all(evidence.get(k) for k in stages):
            out.append((f"evidence less {' and '.join(stages)}",
                        {**evidence, **dict.fromkeys(stages, 0.0)}))  # fmt: skip
    return out


def _stop_when_nothing_new(
    state: dict[str, Any], k: int, added: list[dict[str, Any]], diag: dict[str, Any] | None
) -> bool:
    """Rule: the loop stops when the diagnosis adds no effect the model lacks (it says why)."""
    current = [e["name"] for e in state["iterations"][-1]["effects"]]
    classes = {effect_class(n).name for n in current}
    nothing_new = all(
        a["source"] == "diagnosis" and effect_class(a["name"]).name in classes for a in added
    )
    if nothing_new:
        state["stopped_diagnosis"] = diagnosis_summary(diag or {})
        state["stopped"] = (
            f"iteration {k}: the diagnosis adds no effect beyond "
            f"{', '.join(current) or 'the starting config'} (verdict "
            f"{(diag or {}).get('verdict')}); nothing left to iterate"
        )
    return nothing_new


def _record_iteration(
    folder: Path, state: dict[str, Any], it: dict[str, Any], diag_s: float, tracking_uri: str | None
) -> None:
    """A finished iteration into the state (with its diagnosis's time), chart and tracking."""
    it["seconds"]["diagnosis"] = diag_s  # the iteration's wall time includes it
    it["seconds"]["total"] = round(it["seconds"]["total"] + diag_s, 2)
    state["iterations"].append(it)
    chart = _chart(folder, state)
    if tracking_uri:
        _track(state, it, chart)
    _save_state(folder, state)


def _loop_result(
    state: dict[str, Any], folder: Path, chart: Path | None, tracking_uri: str | None, sec: float
) -> dict[str, Any]:
    """``run_loop``'s summary of the state."""
    its = state["iterations"]
    return {
        "campaign": state["campaign"],
        "family": state["family"],
        "n_trajectories": state["n_trajectories"],
        "spread": state["spread"],
        "world": state.get("world", "sweep"),
        "iterations": its,
        "before": {**its[0]["metrics"], "run_id": its[0].get("run_id")} if its else {},
        "after": {**its[-1]["metrics"], "run_id": its[-1].get("run_id")} if its else {},
        "effect": ", ".join(e["name"] for e in its[-1]["effects"]) if its else "",
        "stopped": state["stopped"],
        "stopped_diagnosis": state.get("stopped_diagnosis") if state["stopped"] else None,
        "experiment": state["experiment"] if tracking_uri else None,
        "parent_run_id": state.get("parent_run_id") if tracking_uri else None,
        "registered_model": state["registered_model"] if tracking_uri else None,
        "chart": str(chart) if chart else None,
        "out": str(folder.resolve()),
        "seconds": round(sec, 2),
    }


def _from_diagnosis(diagnosis: dict[str, Any]) -> tuple[list[dict[str, Any]], dict[str, Any]]:
    """The selected effects of a given ``diagnose --json`` result."""
    by_name = {r["effect"]: r for r in diagnosis.get("ranking", [])}
    names = diagnosis.get("missing_effects")
    if names is None:  # an older result: the single named effect
        names = [diagnosis["missing_effect"]] if diagnosis.get("missing_effect") else []
    fitted_params = diagnosis.get("fitted_params") or {}
    added = []
    for n in names:
        params = fitted_params.get(n) or by_name.get(n, {}).get("params") or {}
        params = {k: float(v) for k, v in params.items()}
        added.append(
            {
                "name": n,
                "params": params,
                "fitted": list(by_name.get(n, {}).get("fitted") or params),
                "source": "diagnosis",
            }
        )
    return with_learned_law(added, diagnosis), diagnosis

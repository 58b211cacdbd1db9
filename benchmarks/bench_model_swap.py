"""The shipped learned model against a candidate, through the real predictor, set by set.

The question before a retrained model replaces ``models/cnn.onnx``: is it better behind
sensor chains, and no worse on the ideal and in-prior sets? Two parts:

* **Recordings** (24 per set, ``--n``), each model through
  :meth:`serving.predictor.Predictor.predict` (windows, ONNX model, restoring-force
  cross-check, alarm): ``benchmarks/bench_crosscheck.py``'s sets at its seeds (``ideal 2%``,
  ``sensor_chains``, ``sensor_chains+1000`` = its seed + 1000, ``rig_chains``,
  ``rig_chains_damped``) and ``benchmarks/bench_alarm.py``'s (the robustness sets ``ideal``,
  ``contact_damping``, ``hertz_contact``, ``sensor_dynamics``, ``damping_and_sensor``; the
  independent rig's ``rig_ideal``, ``rig_kv``, ``rig_two_stage``, ``rig_hc``). Per set:
  accuracy over the contact recordings, beta MAPE, 90 % interval coverage, alarms, wrong and
  silent (wrong class, no alarm), silent (wrong class or beta outside the interval, no
  alarm: bench_crosscheck's count), alarms on right answers.
* **A simulated dataset** (``--dataset DIR``, e.g. the independent calibration set of
  models/README.md): every window through each model, aggregated per trajectory as the
  predictor does (:func:`training.uncertainty_calibration.trajectory_table`), by where the
  trajectory's sensor chain lies: none, inside the narrow prior the models before issue 24
  trained on (resonance >= 15 f_n, low-pass >= 0.15 fs, high-pass <= 2 Hz), or only in the
  widened one. Coverage there uses each model's own recording quantile.

``--undo chain`` (also ``resonance``, ``outside_priors``) adds each model reading the record
with the chain the restoring-force check identified undone (:mod:`serving.chain_undo`);
``--sheet`` adds the rig chain sets with each recording's true chain as its data sheet
(:func:`rig_data_sheets`: what a lab that read its accelerometer's calibration sheet gives).
``--pooled`` adds each model reading every campaign through the chain pooled from its
recordings' identified chains, as ``evaluate`` and ``predict-batch`` do
(:mod:`serving.campaign_chain`; a set without campaigns counts as one, so the guard is
measured on the sets whose chain is drawn per recording). Campaign sets: ``rig_campaigns``
and ``rig_campaigns_damped`` (:func:`campaign_rig_set`: the independent rig, one lab chain
and one rate per campaign of 6; ``NAME+1000``, the same drawn at its seed + 1000). Per set
also the restoring-force accuracy (a refusal counts wrong) and its refusals, the interval's
median width (its high over its low) and the recordings the ``chain_class`` alarm fired on.
``--spread-off`` adds each undo mode with the interval's chain spread off
(:mod:`serving.chain_spread`: the model read through the fitted chain alone, as before it), a
column 'NAME undo=MODE spread off', for before -> after on the same cache.

The restoring-force check does not depend on the model and costs most of a prediction: it
runs once per recording and is kept under ``--cache`` (with the simulated recordings), so a
second model, or a second run, reuses it. Run::

    OMP_NUM_THREADS=1 python benchmarks/bench_model_swap.py --model shipped=models/cnn.onnx \\
        --model new=RUN/cnn.onnx --cache /tmp/stiffnet_swap --json swap.json \\
        [--dataset CALIBRATION_SET]
"""

from __future__ import annotations

import argparse
import copy
import hashlib
import json
import pickle
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
for _p in (ROOT, ROOT / "benchmarks", ROOT / "tests"):
    sys.path.insert(0, str(_p))

import bench_alarm as ba  # noqa: E402  (its sets; imports bench_robustness)
import bench_crosscheck as bc  # noqa: E402

import serving.predictor as sp  # noqa: E402
from serving.chain_spread import ChainSpreadConfig  # noqa: E402
from stiffnet.io_utils import write_json_atomic  # noqa: E402

CROSSCHECK_SETS = ["ideal 2%", "sensor_chains", "sensor_chains+1000", "rig_chains",
                   "rig_chains_damped"]  # fmt: skip
#: Campaign sets: the independent rig as labs run it, one accelerometer (one chain drawn from
#: bench_crosscheck's LAB_SENSOR_PRIOR) and one logger rate per campaign of CAMPAIGN_SIZE
#: recordings (the rig_chains sets draw a chain and a rate per recording: no campaign there).
CAMPAIGN_SETS = {"rig_campaigns": None, "rig_campaigns_damped": "kelvin_voigt"}
CAMPAIGN_SIZE = 6
ALARM_SETS = ["ideal", "contact_damping", "hertz_contact", "sensor_dynamics",
              "damping_and_sensor", "rig_ideal", "rig_kv", "rig_two_stage", "rig_hc"]  # fmt: skip

#: The per-trajectory fields of a TrajectoryTable a stratum selects.
ROW_FIELDS = ("trajectory", "label", "beta", "pred", "log_beta", "scale")
SET_COLUMNS = [("accuracy", "accuracy"), ("beta MAPE", "beta_mape"), ("coverage", "coverage"),
               ("alarms", "alarms"), ("wrong & silent", "wrong_silent"), ("silent", "silent"),
               ("alarms on right", "alarms_on_right"), ("width (hi/lo)", "width"),
               ("chain_class", "chain_class"), ("RF accuracy", "rf_accuracy"),
               ("RF refusals", "rf_refusals")]  # fmt: skip
DATASET_COLUMNS = [("n", "n"), ("accuracy", "accuracy"), ("beta MAPE", "beta_mape"),
                   ("median APE", "median_ape"), ("coverage", "coverage"),
                   ("alarm rate", "alarm_rate")]  # fmt: skip


class CachedRestoringForce:
    """The predictor's restoring-force check, computed once per recording (its samples'
    bytes, rates and sensor sheet) and copied out, so every model reads the same check."""

    def __init__(self, check: Any) -> None:
        self.check = check
        self.results: dict[tuple, dict] = {}

    def __call__(self, a: np.ndarray, fs: float, fn: float, sensor: dict | None,
                 *args: Any, **kwargs: Any) -> dict:  # fmt: skip
        # the rest (the card's stage ratio, a chain fitted regardless) is part of the key: a
        # model with a learned two-stage law reads beta in its own sense; the keywords' values
        # follow the positional ones, as the caches written when they were positional hold
        digest = hashlib.sha1(np.ascontiguousarray(a).tobytes()).hexdigest()
        rest = repr((*args, *kwargs.values()))
        key = (digest, float(fs), float(fn), json.dumps(sensor, sort_keys=True), rest)
        if key not in self.results:
            self.results[key] = self.check(a, fs, fn, sensor, *args, **kwargs)
        return copy.deepcopy(self.results[key])


def set_recordings(name: str, n: int, cache: Path) -> list[dict[str, Any]]:
    """The set's recordings (``accel``, ``fs_hz``, ``fn_hz``, ``beta``, ``class``), cached."""
    path = cache / "data" / f"{name.replace(' ', '_')}-{n}.pkl"
    if path.is_file():
        return with_rig_damping(name, pickle.loads(path.read_bytes()))
    if name.split("+")[0] in CAMPAIGN_SETS:
        base, _, offset = name.partition("+")
        recs = campaign_rig_set(base, n, 20261129 + int(offset or 0))
    elif name in CROSSCHECK_SETS:
        base = name.split("+")[0]
        seed = 20261123 + [*bc.SETS, *bc.RIG_SETS].index(base) + (1000 if "+" in name else 0)
        simulate = bc.simulate_rig_set if base in bc.RIG_SETS else bc.simulate_set
        rows, fs, beta, contact, _ = simulate(base, n, seed)
        recs = [dict(accel=np.asarray(a), fs_hz=float(f), fn_hz=bc.FN_HZ, beta=float(b),
                     **{"class": bc.class_of(float(b)) if c else "no_contact"})
                for a, f, b, c in zip(rows, fs, beta, contact, strict=True)]  # fmt: skip
    elif name in ba.RIG_SETS:
        recs = ba.rig_recordings(name, n, cache / "data" / "rig")
    else:
        cfg = ba.br.set_configs(ba.br.DEFAULT_SETS)[name][0]
        cfg = cfg.model_copy(update={"n_trajectories": n, "shard_size": n})
        recs = ba.br.recordings(cfg, cache / "data" / f"{name}-{n}")
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_bytes(pickle.dumps(recs))
    return with_rig_damping(name, recs)


def with_rig_damping(name: str, recs: list[dict[str, Any]]) -> list[dict[str, Any]]:
    """A campaign set's recordings with the rig's ``damping_ratio``, the value its manifest
    carries (``independent_rig.write_campaign`` writes the rig's own; caches written before
    the key lack it), as a lab's campaign gives it to the campaign chain's high-pass corner."""
    if name.split("+")[0] not in CAMPAIGN_SETS:
        return recs
    from independent_rig import RigRun

    return [{"damping_ratio": RigRun.damping_ratio, **r} for r in recs]


def campaign_rig_set(name: str, n: int, seed: int = 20261129) -> list[dict[str, Any]]:
    """`n` recordings of the independent rig in campaigns of :data:`CAMPAIGN_SIZE`: per
    campaign one lab chain and one rate (1-4 kHz), per recording beta (stratified by class),
    gap 1-2.5 mm and, on the damped set, a Kelvin-Voigt contact of zeta 0-0.3; 3 s, 2 % noise.
    Each recording carries its ``campaign`` index and true ``chain``."""
    from independent_rig import RigRun, record

    rng = np.random.default_rng(seed + list(CAMPAIGN_SETS).index(name))
    edges = [(lo, hi) for _, lo, hi in bc.CLASSES]
    n_campaigns = -(-n // CAMPAIGN_SIZE)
    fs = np.exp(rng.uniform(np.log(1000.0), np.log(4000.0), n_campaigns))
    _, chains = bc.prior_sensor_chain(np.zeros((n_campaigns, 1)), fs, rng, bc.LAB_SENSOR_PRIOR)
    recs = []
    for i in range(n):
        k = i // CAMPAIGN_SIZE
        beta = float(rng.uniform(*edges[i % len(edges)]))
        run = RigRun(recording=f"{name}_{i}.csv", beta=beta, fs_hz=float(fs[k]), duration_s=3.0,
                     gap_mm=float(rng.uniform(1.0, 2.5)), contact=CAMPAIGN_SETS[name],
                     contact_zeta=float(rng.uniform(0.0, 0.3)), sensor=chains[k])  # fmt: skip
        recs.append(dict(accel=np.asarray(record(run, seed=seed + i)[1]), fs_hz=float(fs[k]),
                         fn_hz=bc.FN_HZ, beta=beta, campaign=k, chain=chains[k],
                         **{"class": bc.class_of(beta)}))  # fmt: skip
    return recs


def rig_data_sheets(name: str, n: int) -> list[dict[str, float]]:
    """The true sensor chain of each recording of a bench_crosscheck rig set, as the data sheet
    a lab would give (drawn again from the set's seed, as
    :func:`bench_crosscheck.simulate_rig_set` draws it before simulating)."""
    seed = 20261123 + [*bc.SETS, *bc.RIG_SETS].index(name)
    rng = np.random.default_rng(seed)
    rng.uniform(0.0, 1.0, n)  # beta (stratified by class: one uniform draw each)
    fs = np.exp(rng.uniform(np.log(1000.0), np.log(4000.0), n))
    _, chains = bc.prior_sensor_chain(np.zeros((n, 1)), fs, rng, bc.LAB_SENSOR_PRIOR)
    keys = ("resonance_hz", "resonance_damping", "lowpass_hz", "lowpass_order", "highpass_hz")
    return [{k: float(c[k]) for k in keys} for c in chains]


def predict_set(
    pred: sp.Predictor,
    recs: list[dict[str, Any]],
    sheets: list[dict | None] | None = None,
    fitted: bool = False,
) -> list[dict[str, Any]]:
    """Each recording's class, beta, interval, alarm, restoring-force class and sensor chain
    (and CPU seconds) from `pred` (with its data sheet where `sheets` are given; `fitted`:
    the sheets are a campaign's pooled fits, the predictor's ``sensor_fitted``)."""
    out = []
    for i, r in enumerate(recs):
        t = time.process_time()
        res = pred.predict(r["accel"], r["fs_hz"], natural_frequency_hz=r["fn_hz"],
                           sensor=sheets[i] if sheets else None,
                           sensor_fitted=fitted and bool(sheets))  # fmt: skip
        out.append(dict(cls=res["class"], beta=res["beta"], interval=res["beta_interval"],
                        flag=bool(res["ood_flag"]), fired=(res["alarm"] or {}).get("fired", []),
                        rf_cls=res.get("restoring_force_class"),
                        rf=res.get("restoring_force"),
                        sensor=(res.get("restoring_force") or {}).get("sensor"),
                        readings=res.get("chain_readings"),
                        cpu_s=time.process_time() - t))  # fmt: skip
    return out


def campaigns_of(recs: list[dict[str, Any]]) -> dict[int, list[int]]:
    """Recording indices by campaign (a set without ``campaign`` keys is one campaign)."""
    groups: dict[int, list[int]] = {}
    for i, r in enumerate(recs):
        groups.setdefault(int(r.get("campaign", 0)), []).append(i)
    return groups


def pooled_predictions(
    pred: sp.Predictor, recs: list[dict[str, Any]], got: list[dict[str, Any]], say: Any
) -> tuple[list[dict[str, Any]], list[dict[str, Any]]]:
    """Each campaign's recordings read through the chain pooled from `got`'s identified chains
    (fitted regardless of the gate where too few identified one: ``identify_regardless``)
    and kept where confirmed, except on a recording whose own contact law it reads much worse
    (:mod:`serving.campaign_chain`, as ``evaluate`` and ``predict-batch`` do), else `got`'s;
    and each campaign's decision with its true chain."""
    from serving.campaign_chain import (
        confirmed,
        contact_r2_through,
        free_damping_through,
        identify_regardless,
        profiled_campaign_chain,
        reads_alone,
    )
    from serving.checks import checked_recording

    def identify(i: int) -> dict | None:  # the check with the chain always fitted
        r = recs[i]
        a = checked_recording(r["accel"], r["fs_hz"], r["fn_hz"], pred.window_periods, "")[0]
        return sp.restoring_force_check(a, r["fs_hz"], r["fn_hz"], None, pred.stage_ratio,
                                        fit_chain=True,
                                        penetration_dissipation=pred.penetration_dissipation,
                                        ).get("sensor")  # fmt: skip

    # the corner profile's readings, kept with the checks (the bench's cache) where it is on
    store = getattr(sp.restoring_force_check, "results", {})

    def contact_r2(i: int, sheet: dict, refused_as_unexplained: bool = False) -> float | None:
        r = recs[i]
        digest = hashlib.sha1(np.ascontiguousarray(r["accel"]).tobytes()).hexdigest()
        tag = "read_r2_through" if refused_as_unexplained else "contact_r2_through"
        key = (digest, float(r["fs_hz"]), float(r["fn_hz"]), json.dumps(sheet, sort_keys=True),
               tag)  # fmt: skip
        if key not in store:
            store[key] = {"contact_r2": contact_r2_through(r["accel"], r["fs_hz"], r["fn_hz"],
                                                           pred, sheet,
                                                           refused_as_unexplained)}  # fmt: skip
        return store[key]["contact_r2"]

    def free_damping(i: int, sheet: dict) -> float | None:
        r = recs[i]
        digest = hashlib.sha1(np.ascontiguousarray(r["accel"]).tobytes()).hexdigest()
        key = (digest, float(r["fs_hz"]), float(r["fn_hz"]), json.dumps(sheet, sort_keys=True),
               "free_damping_through")  # fmt: skip
        if key not in store:
            zeta = free_damping_through(r["accel"], r["fs_hz"], r["fn_hz"], pred, sheet)
            store[key] = {"free_damping": zeta}
        return store[key]["free_damping"]

    out = list(got)
    decisions = []
    for k, idx in campaigns_of(recs).items():
        chain, sensors = identify_regardless([got[i]["sensor"] for i in idx],
                                             [str(i) for i in idx], None,
                                             lambda j, idx=idx: identify(idx[j]))  # fmt: skip
        chain = profiled_campaign_chain(
            chain, sensors,
            lambda j, sheet, refused=False, idx=idx: contact_r2(idx[j], sheet, refused),
            lambda j, sheet, idx=idx: free_damping(idx[j], sheet),
            lambda idx=idx: [recs[i]["fn_hz"] for i in idx],
            [recs[i].get("damping_ratio") for i in idx],
        )  # fmt: skip
        if chain["pooled"]:
            again = predict_set(pred, [recs[i] for i in idx], [chain["sensor"]] * len(idx),
                                fitted=True)  # fmt: skip
            chain = confirmed(chain, [got[i]["rf"] for i in idx], [a["rf"] for a in again])
            if chain["pooled"]:
                for i, a in zip(idx, again, strict=True):
                    out[i] = got[i] if reads_alone(got[i]["rf"], a["rf"]) else a
        decisions.append({"campaign": k, "true": recs[idx[0]].get("chain"), **chain})
        say(f"  campaign {k}: {chain['reason']}; pooled {chain['sensor']}; "
            f"true {recs[idx[0]].get('chain')}")  # fmt: skip
    return out, decisions


def score(recs: list[dict[str, Any]], got: list[dict[str, Any]]) -> dict[str, Any]:
    """Accuracy, MAPE, coverage (contact recordings), alarms and silent failures of a set."""
    truth = np.array([r["class"] for r in recs])
    contact = truth != "no_contact"
    wrong = np.array([g["cls"] for g in got]) != truth
    flag = np.array([g["flag"] for g in got], dtype=bool)
    inside = np.ones(len(recs), dtype=bool)
    ape = []
    for i, (r, g) in enumerate(zip(recs, got, strict=True)):
        if contact[i]:
            iv = g["interval"]
            inside[i] = bool(iv and iv[0] <= r["beta"] <= iv[1])
            if g["beta"] is not None:
                ape.append(abs(g["beta"] / r["beta"] - 1))
    return {
        "n": len(recs),
        "n_contact": int(contact.sum()),
        "accuracy": float((~wrong[contact]).mean()) if contact.any() else float("nan"),
        "beta_mape": float(np.mean(ape)) if ape else float("nan"),
        "coverage": float(inside[contact].mean()) if contact.any() else float("nan"),
        "alarms": int(flag.sum()),
        "wrong": int(wrong.sum()),
        "wrong_silent": int((wrong & ~flag).sum()),
        "silent": int(((wrong | ~inside) & ~flag).sum()),
        "alarms_on_right": int((flag & ~wrong & inside).sum()),
        # the restoring-force cross-check: a refusal (no class) counts as wrong
        "rf_accuracy": float(
            np.mean(
                [
                    g["rf_cls"] == r["class"]
                    for r, g in zip(recs, got, strict=True)
                    if r["class"] != "no_contact"
                ]
            )
        )
        if contact.any()
        else float("nan"),
        "rf_refusals": int(sum(g["rf_cls"] is None for g in got)),
        "cpu_s_per_recording": float(np.mean([g["cpu_s"] for g in got])),
        "width": interval_width(recs, got),
        "chain_class": int(sum("chain_class" in g["fired"] for g in got)),
    }


def interval_width(recs: list[dict[str, Any]], got: list[dict[str, Any]]) -> float:
    """Median over the contact recordings with an interval of its high over its low."""
    ratios = [g["interval"][1] / g["interval"][0] for r, g in zip(recs, got, strict=True)
              if r["class"] != "no_contact" and g["interval"]]  # fmt: skip
    return float(np.median(ratios)) if ratios else float("nan")


def recordings_part(models: dict[str, sp.Predictor], sets: list[str], n: int, cache: Path,
                    say: Any, sheet: bool = False,
                    pooled: bool = False) -> dict[str, dict[str, Any]]:  # fmt: skip
    """Every set through every model (the restoring-force check cached per set on disk); with
    `sheet`, the rig chain sets also with each recording's true chain as its data sheet; with
    `pooled`, every set also with each campaign's pooled chain as its recordings' data sheet
    (a column 'NAME + campaign chain'; the decisions under ``_campaigns``)."""
    cached = CachedRestoringForce(sp.restoring_force_check)
    sp.restoring_force_check = cached  # the predictor module calls it by this name
    table: dict[str, dict[str, Any]] = {}
    try:
        for name in sets:
            recs = set_recordings(name, n, cache)
            rf_path = cache / "restoring_force" / f"{name.replace(' ', '_')}-{n}.pkl"
            cached.results = pickle.loads(rf_path.read_bytes()) if rf_path.is_file() else {}
            sheets = rig_data_sheets(name, n) if sheet and name in bc.RIG_SETS else None
            if sheet and name.split("+")[0] in CAMPAIGN_SETS:
                sheets = [{k: float(v) for k, v in r["chain"].items()} for r in recs]
            runs = [(m, pred, None) for m, pred in models.items()]
            runs += [(f"{m} + data sheet", pred, sheets) for m, pred in models.items() if sheets]
            for m, pred, sheets_m in runs:
                got = predict_set(pred, recs, sheets_m)
                _row(table, name, m, score(recs, got), say)
                table[name].setdefault("_recordings", {})[m] = _recording_rows(name, recs, got)
                if pooled and sheets_m is None:
                    again, decisions = pooled_predictions(pred, recs, got, say)
                    table[name].setdefault("_campaigns", {})[m] = decisions
                    _row(table, name, f"{m} + campaign chain", score(recs, again), say)
                    table[name]["_recordings"][f"{m} + campaign chain"] = _recording_rows(
                        name, recs, again, decisions
                    )
            rf_path.parent.mkdir(parents=True, exist_ok=True)
            rf_path.write_bytes(pickle.dumps(cached.results))
    finally:
        sp.restoring_force_check = cached.check
    return table


def _row(table: dict, name: str, m: str, s: dict[str, Any], say: Any) -> None:
    table.setdefault(name, {})[m] = s
    say(f"{name} / {m}: accuracy {s['accuracy']:.2f}, MAPE {s['beta_mape']:.3f}, "
        f"coverage {s['coverage']:.2f}, alarms {s['alarms']}, wrong and silent "
        f"{s['wrong_silent']}, silent {s['silent']}; restoring force {s['rf_accuracy']:.2f}, "
        f"refusals {s['rf_refusals']}")  # fmt: skip


def chain_strata(ds: Any, trajectories: np.ndarray) -> dict[str, np.ndarray]:
    """Masks over `trajectories`: no sensor, a chain in the narrow prior, a widened one."""
    traj = ds.column("trajectory")
    first = np.array([np.flatnonzero(traj == t)[0] for t in trajectories])

    def col(key: str) -> np.ndarray:
        return np.asarray(ds.column(key), dtype=np.float64)[first]

    active = col("effect.sensor_dynamics.active").astype(bool)
    res = col("effect.sensor_dynamics.resonance_hz") / col("natural_frequency_hz")
    lowpass = col("effect.sensor_dynamics.lowpass_hz") / col("fs_hz")
    highpass = col("effect.sensor_dynamics.highpass_hz")
    narrow = (res >= 15) & (lowpass >= 0.15) & (highpass <= 2.0)
    return {
        "all": np.ones(len(first), dtype=bool),
        "no sensor": ~active,
        "chain in the narrow prior": active & narrow,
        "chain widened": active & ~narrow,
        "low-pass < 0.15 fs": active & (lowpass < 0.15),
        "resonance < 15 f_n": active & (res < 15),
        "high-pass > 2 Hz": active & (highpass > 2.0),
    }


def dataset_part(paths: dict[str, Path], data: Path) -> dict[str, dict[str, Any]]:
    """Each model on the dataset's trajectories, by stratum (accuracy, MAPE, median APE,
    coverage with the model's own quantile, alarm rate)."""
    from dataclasses import replace

    from stiffnet.dataset.store import load_dataset
    from stiffnet.uncertainty.alarm import load_alarm
    from training.recalibrate import model_outputs
    from training.uncertainty_calibration import trajectory_metrics, trajectory_table

    ds = load_dataset(data)
    out: dict[str, dict[str, Any]] = {}
    for m, path in paths.items():
        meta = json.loads(path.with_suffix(".card.json").read_text())["metadata"]
        alarm = load_alarm(path.with_suffix(".alarm.npz"))
        table = trajectory_table(ds.column("trajectory"), ds.column("label"), ds.column("beta"),
                                 model_outputs(path, ds, meta), alarm)  # fmt: skip
        q = float(meta["conformal_quantile_recording"])
        for name, mask in chain_strata(ds, table.trajectory).items():
            rows = {k: getattr(table, k)[mask] for k in ROW_FIELDS}
            checks = {k: np.asarray(v)[mask] for k, v in table.checks.items()}
            sub = replace(table, **rows, checks=checks)
            r = trajectory_metrics(sub, q, alarm)
            ok = (sub.label != 0) & np.isfinite(sub.log_beta)
            r["median_ape"] = float(np.median(np.abs(np.exp(sub.log_beta[ok]) / sub.beta[ok] - 1)))
            out.setdefault(name, {})[m] = r
    return out


def markdown(table: dict[str, dict[str, Any]], columns: list[tuple[str, str]]) -> str:
    """One row per set and model."""
    lines = ["| set | model | " + " | ".join(c for c, _ in columns) + " |",
             "| --- | --- |" + " ---: |" * len(columns)]  # fmt: skip
    for name, models in table.items():
        for m, s in models.items():
            if m.startswith("_"):
                continue
            cells = [f"{s.get(k, float('nan')):.3g}" if isinstance(s.get(k), float)
                     else str(s.get(k)) for _, k in columns]  # fmt: skip
            lines.append(f"| {name} | {m} | " + " | ".join(cells) + " |")
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--model", action="append", required=True, metavar="NAME=PATH.onnx")
    ap.add_argument("--sets", nargs="*", default=CROSSCHECK_SETS + ALARM_SETS)
    ap.add_argument("--n", type=int, default=24, help="recordings per set")
    ap.add_argument("--cache", type=Path, default=Path("/tmp/stiffnet_model_swap"))
    ap.add_argument("--dataset", type=Path, help="also score a simulated dataset by stratum")
    ap.add_argument("--json", type=Path, help="also write the numbers here")
    ap.add_argument(
        "--sheet",
        action="store_true",
        help="also the rig chain sets with each recording's true chain as its data "
        "sheet (a column 'NAME + data sheet')",
    )
    ap.add_argument("--undo", nargs="*", default=[], choices=sp.UNDO_MODES[1:],
                    help="also each model reading the record with its identified chain undone "
                    "(serving.chain_undo), a column 'NAME undo=MODE' per mode")  # fmt: skip
    ap.add_argument("--pooled", action="store_true",
                    help="also each model with every campaign's pooled chain as its recordings' "
                    "data sheet (serving.campaign_chain; a set without campaigns is one), a "
                    "column 'NAME + campaign chain'")  # fmt: skip
    ap.add_argument("--spread-off", action="store_true",
                    help="also each undo mode with the interval's chain spread off "
                    "(serving.chain_spread: the model's reading through the fitted chain "
                    "alone), a column 'NAME undo=MODE spread off'")  # fmt: skip
    args = ap.parse_args(argv)
    paths = {k: Path(v) for k, v in (m.split("=", 1) for m in args.model)}
    # every rig law of bench_alarm (rig_sensor: a lab mount) reads as its default sets do
    known = CROSSCHECK_SETS + ALARM_SETS + [s for s in ba.RIG_SETS if s not in ALARM_SETS]
    known += list(CAMPAIGN_SETS)
    known += [f"{k}+1000" for k in CAMPAIGN_SETS]
    unknown = set(args.sets) - set(known)
    if unknown:
        ap.error(f"unknown sets {sorted(unknown)}; choose from {known}")
    models = {k: sp.Predictor.load(v, undo_chain="off") for k, v in paths.items()}
    off = ChainSpreadConfig(enabled=False)
    for mode in args.undo:
        models.update({f"{k} undo={mode}": sp.Predictor.load(v, undo_chain=mode)
                       for k, v in paths.items()})  # fmt: skip
        if args.spread_off:
            models.update({f"{k} undo={mode} spread off": sp.Predictor.load(
                v, undo_chain=mode, chain_spread=off) for k, v in paths.items()})  # fmt: skip
    t0 = time.perf_counter()

    def say(msg: str) -> None:
        print(f"[{time.perf_counter() - t0:.0f} s] {msg}", file=sys.stderr, flush=True)

    result: dict[str, Any] = {"models": {k: str(v) for k, v in paths.items()}}
    result["sets"] = recordings_part(models, args.sets, args.n, args.cache, say, args.sheet,
                                     args.pooled)  # fmt: skip
    print(markdown(result["sets"], SET_COLUMNS))
    if args.dataset:
        result["dataset"] = dataset_part(paths, args.dataset)
        print()
        print(markdown(result["dataset"], DATASET_COLUMNS))
    if args.json:
        write_json_atomic(args.json, result)
    return 0


def _recording_rows(
    name: str,
    recs: list[dict[str, Any]],
    got: list[dict[str, Any]],
    decisions: list[dict[str, Any]] | None = None,
) -> list[dict[str, Any]]:
    """One row per recording of set `name`: its campaign, true beta, class and chain, the
    model's reading, the restoring-force reading (class, beta, interval, refusal reason, the
    chain it used) and, with `decisions`, its campaign's pooled chain and decision."""
    by_campaign = {d["campaign"]: d for d in decisions or []}
    rows = []
    for i, (r, g) in enumerate(zip(recs, got, strict=True)):
        rf = g.get("rf") or {}
        d = by_campaign.get(int(r.get("campaign", 0)))
        rows.append({
            "recording": i, "set": name, "campaign": r.get("campaign"),
            "beta_true": r["beta"], "class_true": r["class"], "chain_true": r.get("chain"),
            "class": g["cls"], "beta": g["beta"], "interval": g["interval"],
            "alarm": g["flag"], "fired": g["fired"],
            "rf_class": g["rf_cls"], "rf_beta": rf.get("beta"),
            "rf_interval": rf.get("beta_interval"), "rf_reason": rf.get("reason"),
            "rf_sensor": g.get("sensor"),
            "pooled": None if d is None else {k: d.get(k) for k in ("pooled", "sensor", "reason")},
        })  # fmt: skip
    return rows


if __name__ == "__main__":
    raise SystemExit(main())

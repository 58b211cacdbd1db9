"""Robustness of the shipped models on rigs with physical effects.

For each test set of ``benchmarks/configs/robustness_sets.yaml`` (the ideal world
plus one effect in the upper half of its training prior, two at once, and
contact laws the effect library lacks, written as user effects in
``tests/unknown_contact_laws.py``), every trajectory is one *recording* (8
consecutive windows, 128 natural periods) and goes through the real predictor
(:class:`serving.predictor.Predictor`: windows, ONNX model, aggregation,
per-recording interval, alarm). Per set and model the table gives:

* class accuracy and beta MAPE (contact recordings the model calls contact);
* interval coverage: the fraction of contact recordings whose true beta lies in
  the reported interval (a missing interval counts as a miss);
* alarm rate, and the alarm rate on the recordings whose class is wrong;
* silent failures: recordings with a wrong class or a beta outside its interval and
  no alarm (the failures a user is not warned of).

Alarm rate and silent failures are given with all the predictor's checks, in
brackets with the model's own checks only (without the restoring-force checks: the
interval contradiction, the identified sensor chain outside the model's priors and
the unseen contact law), and in their own columns without the unseen-contact-law
check (``contact_law``, :mod:`stiffnet.uncertainty.unseen_law`): its before and after.

Models are ``NAME=PATH`` pairs (``--model``); each is loaded with its own alarm
reference / OOD reference as the predictor finds them. The older models trained
on the ideal world are scored by pointing ``--model`` at a
copy: ``git show 7d10b2e:models/cnn.onnx > old/cnn.onnx`` (and its
``cnn.card.json`` and ``ood_reference.json``).

Run::

    OMP_NUM_THREADS=1 python benchmarks/bench_robustness.py \\
        --model cnn=models/cnn.onnx --model gbm=models/gbm.onnx \\
        --model cnn_ideal=old/cnn.onnx --data /tmp/robustness --out /tmp/robustness.json

``--data`` caches the simulated sets (simulated once, reused by reruns);
``--quick`` uses 12 recordings per set.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from collections import Counter
from pathlib import Path
from typing import Any

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "benchmarks"))

from bench_models import _merge, say  # noqa: E402  (the test-set config merge, progress)

from serving.predictor import Predictor  # noqa: E402
from stiffnet.config import load_yaml, validate_config  # noqa: E402
from stiffnet.config.sim import SimulationConfig  # noqa: E402
from stiffnet.dataset.generate import generate_dataset  # noqa: E402
from stiffnet.dataset.store import CARD, load_dataset  # noqa: E402
from stiffnet.effects.registry import register_plugin  # noqa: E402
from stiffnet.io_utils import write_json_atomic  # noqa: E402

# the user effects of the sets: a plugin file, named as the configs name it
register_plugin(ROOT / "tests" / "unknown_contact_laws.py", "unknown_contact_laws")

DEFAULT_SETS = ROOT / "benchmarks" / "configs" / "robustness_sets.yaml"
#: The issue's target for sets inside the priors: the 90 % interval covers >= 88 %.
COVERAGE_TARGET = 0.88


def set_configs(path: Path, quick: bool = False) -> dict[str, tuple[SimulationConfig, bool]]:
    """Each set's simulation config and whether it lies inside the training priors."""
    spec = load_yaml(path)
    base = _merge(load_yaml(ROOT / spec["base"]), spec.get("common") or {})
    out = {}
    for name, s in spec["sets"].items():
        data = _merge(base, {"effects": s.get("effects") or []})
        if "n_trajectories" in s:
            data["n_trajectories"] = data["shard_size"] = int(s["n_trajectories"])
        if quick:
            data["n_trajectories"] = data["shard_size"] = 12
        out[name] = (validate_config(SimulationConfig, data, f"{path}:{name}"), bool(
            s.get("inside_priors", False)))  # fmt: skip
    return out


def recordings(cfg: SimulationConfig, folder: Path) -> list[dict[str, Any]]:
    """Simulate (or reuse) the set and join each trajectory's windows into one recording."""
    card = folder / CARD
    cached = json.loads(card.read_text()).get("config") if card.is_file() else None
    if cached != cfg.model_dump(mode="json"):  # missing, or simulated from another config
        generate_dataset(cfg, folder, overwrite=True)
    ds = load_dataset(folder)
    traj = ds.column("trajectory")
    windows = ds.windows()
    out = []
    for t in np.unique(traj):
        rows = np.flatnonzero(traj == t)
        rows = rows[np.argsort(ds.column("window")[rows])]
        out.append(
            {
                "accel": np.concatenate([np.asarray(windows[i], np.float64) for i in rows]),
                "fs_hz": float(ds.column("fs_hz")[rows[0]]),
                "fn_hz": float(ds.column("natural_frequency_hz")[rows[0]]),
                "beta": float(ds.column("beta")[rows[0]]),
                "class": Counter(ds.column("class")[rows].tolist()).most_common(1)[0][0],
            }
        )  # fmt: skip
    return out


def score(pred: Predictor, recs: list[dict[str, Any]]) -> dict[str, Any]:
    """Accuracy, beta MAPE, coverage, alarm rates of one model on one set."""
    right, flags, model_flags, misses, covered, ape, width = [], [], [], [], [], [], []
    no_law_flags = []
    t0 = time.perf_counter()
    for r in recs:
        res = pred.predict(r["accel"], r["fs_hz"], natural_frequency_hz=r["fn_hz"])
        ok = res["class"] == r["class"]
        right.append(ok)
        flags.append(bool(res["ood_flag"]))
        fired = (res["alarm"] or {}).get("fired", [])
        model_flags.append(
            any(f not in ("restoring_force", "sensor", "contact_law") for f in fired)
        )
        no_law_flags.append(any(f != "contact_law" for f in fired))
        miss = not ok
        if r["class"] != "no_contact":
            iv = res["beta_interval"]
            inside = bool(iv and iv[0] <= r["beta"] <= iv[1])
            covered.append(inside)
            miss = miss or not inside
            if iv:
                width.append(iv[1] / iv[0])
            if res["beta"] is not None:
                ape.append(abs(res["beta"] - r["beta"]) / r["beta"])
        misses.append(miss)
    right_a, flags_a, model_a = np.array(right), np.array(flags), np.array(model_flags)
    wrong, miss_a = ~right_a, np.array(misses)
    no_law = np.array(no_law_flags)
    return {
        "n": len(recs),
        "accuracy": float(right_a.mean()),
        "beta_mape": float(np.mean(ape)) if ape else None,
        "coverage": float(np.mean(covered)) if covered else None,
        "interval_ratio_median": float(np.median(width)) if width else None,
        "alarm_rate": float(flags_a.mean()),
        "alarm_rate_wrong": float(flags_a[wrong].mean()) if wrong.any() else None,
        "n_wrong": int(wrong.sum()),
        # without the restoring-force check (the model's own checks only)
        "alarm_rate_model_checks": float(model_a.mean()),
        # a wrong class or a beta outside its interval, with no alarm: the failures a
        # user is not warned of, with all checks and with the model's own checks only
        "silent_failure_rate": float((miss_a & ~flags_a).mean()),
        "silent_failure_rate_model_checks": float((miss_a & ~model_a).mean()),
        # without the unseen-contact-law check: its before
        "alarm_rate_without_law_check": float(no_law.mean()),
        "silent_failure_rate_without_law_check": float((miss_a & ~no_law).mean()),
        "silent_wrong_class": int((wrong & ~flags_a).sum()),
        "silent_wrong_class_without_law_check": int((wrong & ~no_law).sum()),
        "ms_per_recording": 1e3 * (time.perf_counter() - t0) / max(1, len(recs)),
    }


def markdown(result: dict[str, Any]) -> str:
    """One row per set and model."""

    def f(v: Any, pct: bool = False) -> str:
        if v is None:
            return "-"
        return f"{100 * v:.0f} %" if pct else f"{v:.3f}"

    lines = [
        f"(!): coverage under the {COVERAGE_TARGET:.0%} target on a set inside the priors",
        "",
        "| set | inside priors | model | accuracy | beta MAPE | coverage (90 %) | "
        "alarm rate | alarm on wrong (n wrong) | silent failures | "
        "without contact_law: alarm rate / silent failures | wrong class, no alarm: "
        "before -> after contact_law |",
        "|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    for name, s in result["sets"].items():
        for model, m in s["models"].items():
            short = s["inside_priors"] and (m["coverage"] or 0) < COVERAGE_TARGET
            lines.append(
                f"| {name} | {'yes' if s['inside_priors'] else 'no'} | {model} | "
                f"{f(m['accuracy'])} | {f(m['beta_mape'])} | {f(m['coverage'])}"
                f"{' (!)' if short else ''} | "
                f"{f(m['alarm_rate'], True)} ({f(m.get('alarm_rate_model_checks'), True)}) | "
                f"{f(m['alarm_rate_wrong'], True)} ({m['n_wrong']}) | "
                f"{f(m.get('silent_failure_rate'), True)} "
                f"({f(m.get('silent_failure_rate_model_checks'), True)}) | "
                f"{f(m.get('alarm_rate_without_law_check'), True)} / "
                f"{f(m.get('silent_failure_rate_without_law_check'), True)} | "
                f"{m.get('silent_wrong_class_without_law_check', '-')} -> "
                f"{m.get('silent_wrong_class', '-')} of {m['n']} |"
            )
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--model", action="append", default=[], help="NAME=PATH of an ONNX model")
    ap.add_argument("--sets", type=Path, default=DEFAULT_SETS)
    ap.add_argument("--only", action="append", default=[], help="run only these sets")
    ap.add_argument("--data", type=Path, default=Path("/tmp/stiffnet_robustness"))
    ap.add_argument("--out", type=Path, default=None, help="JSON result")
    ap.add_argument("--quick", action="store_true")
    args = ap.parse_args(argv)
    models = dict(m.split("=", 1) for m in args.model) or {"cnn": str(ROOT / "models/cnn.onnx")}
    preds = {name: Predictor.load(path) for name, path in models.items()}
    result: dict[str, Any] = {"models": models, "sets": {}}
    for name, (cfg, inside) in set_configs(args.sets, args.quick).items():
        if args.only and name not in args.only:
            continue
        t0 = time.perf_counter()
        recs = recordings(cfg, args.data / (name + ("-quick" if args.quick else "")))
        say(f"{name}: {len(recs)} recordings ({time.perf_counter() - t0:.0f} s)")
        entry = {"inside_priors": inside, "models": {}}
        for model, pred in preds.items():
            entry["models"][model] = m = score(pred, recs)
            say(f"  {model}: " + ", ".join(f"{k} {v:.3g}" for k, v in m.items()
                                          if isinstance(v, float)))  # fmt: skip
        result["sets"][name] = entry
    table = markdown(result)
    print(table)
    if args.out:
        write_json_atomic(args.out, {**result, "table": table})
    return 0


if __name__ == "__main__":
    raise SystemExit(main())

"""The class from the beta head near a class edge: how often the heads disagree, who is right,
and the rule's effect, before -> after, per set and model family.

Each recording goes once through the real predictor (:class:`serving.predictor.Predictor`:
windows, ONNX model, restoring-force cross-check, alarm) with the class head deciding
("before"). "After" is :func:`stiffnet.uncertainty.class_decision.decide_class` applied to
the same outputs with the family's rule (``configs/class_decision.yaml``, or
``--max-head-probability FAMILY=P``), and the alarm's ``restoring_force_class`` check
recomputed for the answered class (every other check reads what the class does not change;
``class_beta`` compares the two heads). Beta, its interval and MAPE do not move.

Sets: ``benchmarks/bench_alarm.py``'s (the robustness sets and the independent rig's laws),
``benchmarks/bench_crosscheck.py``'s chain sets and ideal sets (their seeds). Per set and
model: disagreements on neighbouring classes (class head right / beta head right / neither),
accuracy, wrong and silent (no alarm) and alarms, before -> after. Prints Markdown with the
machine's load::

    OMP_NUM_THREADS=1 python benchmarks/bench_class_decision.py --sets ideal rig_ideal \\
        "ideal 2%" rig_chains --models cnn gbm [--max-head-probability gbm=1.0] [--json out]

``--data`` caches the simulated recordings (the independent rig's take ~10 s each).
"""

from __future__ import annotations

import argparse
import hashlib
import math
import os
import pickle
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path[:0] = [str(ROOT), str(ROOT / "benchmarks"), str(ROOT / "tests")]

import bench_alarm as ba  # noqa: E402
import bench_crosscheck as bc  # noqa: E402
import bench_robustness as br  # noqa: E402

import serving.predictor as sp  # noqa: E402
from stiffnet.io_utils import write_json_atomic  # noqa: E402
from stiffnet.uncertainty import RecordingEstimate  # noqa: E402
from stiffnet.uncertainty.alarm_verdict import (  # noqa: E402
    RESTORING_FORCE_CLASS_THRESHOLD,
    restoring_force_class_share,
)
from stiffnet.uncertainty.class_decision import FamilyRule, decide_class, family_rule  # noqa: E402


def recordings(name: str, n: int, data: Path) -> list[dict[str, Any]]:
    """The set's recordings: ``accel``, ``fs_hz``, ``fn_hz``, ``beta``, ``class``."""
    if name in ba.RIG_SETS:
        return ba.rig_recordings(name, n, data / "rig")
    if name in bc.SETS or name in bc.RIG_SETS:
        cache = data / f"crosscheck-{name.replace(' ', '_').replace('%', '')}-{n}.pkl"
        if cache.is_file():
            rows, fs, beta, contact, _ = pickle.loads(cache.read_bytes())
        else:
            seed = 20261123 + [*bc.SETS, *bc.RIG_SETS].index(name)  # bench_crosscheck's
            sim = bc.simulate_rig_set if name in bc.RIG_SETS else bc.simulate_set
            rows, fs, beta, contact, chains = sim(name, n, seed)
            data.mkdir(parents=True, exist_ok=True)
            cache.write_bytes(pickle.dumps((rows, fs, beta, contact, chains)))
        return [dict(accel=a, fs_hz=float(f), fn_hz=bc.FN_HZ, beta=float(b),
                     **{"class": bc.class_of(float(b)) if c else "no_contact"})
                for a, f, b, c in zip(rows, fs, beta, contact, strict=True)]  # fmt: skip
    cfg = br.set_configs(br.DEFAULT_SETS)[name][0]
    cfg = cfg.model_copy(update={"n_trajectories": n, "shard_size": n})
    return br.recordings(cfg, data / f"{name}-{n}")


def _shared_restoring_force() -> None:
    """The restoring-force check once per recording, whichever model asks (it reads no model)."""
    memo: dict[tuple, dict] = {}
    check = sp.restoring_force_check

    def once(a, fs, fn, sensor=None):
        key = (hashlib.sha1(np.ascontiguousarray(a).tobytes()).hexdigest(), fs, fn, repr(sensor))
        if key not in memo:
            memo.clear()
            memo[key] = check(a, fs, fn, sensor)
        return memo[key]

    sp.restoring_force_check = once


def after(pred: sp.Predictor, res: dict[str, Any], rule: FamilyRule | None) -> tuple[str, bool]:
    """The class the rule answers for a result the class head answered, and the alarm's flag."""
    names, edges = pred.class_names, pred.metadata.get("class_edges")
    p = np.array([res["probabilities"][c] for c in names])
    lb = math.log(res["beta"]) if res["beta"] else None
    est = RecordingEstimate(p, int(np.argmax(p)), lb, None, res["n_windows"])
    cls = names[decide_class(est, names, edges, rule).label]
    fired = [f for f in (res["alarm"] or {}).get("fired", []) if f != "restoring_force_class"]
    share = restoring_force_class_share(cls, res["restoring_force"] or {}, names, edges)
    if share is not None and share > RESTORING_FORCE_CLASS_THRESHOLD:
        fired.append("restoring_force_class")
    return cls, bool(fired)


def score(pred: sp.Predictor, recs: list[dict], rule: FamilyRule | None) -> dict[str, Any]:
    """Disagreements and who is right; accuracy, silent and alarms before -> after."""
    rows, t0 = [], time.process_time()
    for r in recs:
        res = pred.predict(r["accel"], r["fs_hz"], natural_frequency_hz=r["fn_hz"])
        cls, flag = after(pred, res, rule)
        head, truth = res["class"], r["class"]
        beta_cls = cls if cls != head else None
        rows.append((head == truth, cls == truth, bool(res["ood_flag"]), flag, beta_cls, truth,
                     res["beta"], r["beta"]))  # fmt: skip
    hb, ha = np.array([x[0] for x in rows]), np.array([x[1] for x in rows])
    fb, fa = np.array([x[2] for x in rows]), np.array([x[3] for x in rows])
    changed = [x for x in rows if x[4] is not None]
    ape = [abs(x[6] / x[7] - 1) for x in rows if x[6] and x[5] != "no_contact"]
    return {
        "n": len(rows),
        "changed": len(changed),
        "changed_class_head_right": sum(x[0] for x in changed),
        "changed_beta_head_right": sum(x[1] for x in changed),
        "accuracy_before": float(hb.mean()),
        "accuracy_after": float(ha.mean()),
        "silent_before": int((~hb & ~fb).sum()),
        "silent_after": int((~ha & ~fa).sum()),
        "alarms_before": int(fb.sum()),
        "alarms_after": int(fa.sum()),
        "beta_mape": float(np.mean(ape)) if ape else None,
        "cpu_s_per_recording": (time.process_time() - t0) / max(1, len(rows)),
    }


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sets", nargs="*", default=["ideal", "rig_ideal", "ideal 2%",
                    "sensor_chains", "rig_chains", "rig_chains_damped"])  # fmt: skip
    ap.add_argument("--models", nargs="*", default=["cnn", "gbm"])
    ap.add_argument("--max-head-probability", action="append", default=[], metavar="FAMILY=P",
                    help="the family's rule instead of the shipped one")  # fmt: skip
    ap.add_argument("--n", type=int, default=24)
    ap.add_argument("--data", type=Path, default=Path("/tmp/stiffnet_bench_class_decision"))
    ap.add_argument("--json", type=Path, default=None)
    args = ap.parse_args(argv)
    given = {k: FamilyRule(max_head_probability=float(v))
             for k, v in (kv.split("=", 1) for kv in args.max_head_probability)}  # fmt: skip
    _shared_restoring_force()
    sp.family_rule = lambda kind: None  # "before": the class head decides
    preds = {m: sp.Predictor.load(ROOT / "models" / f"{m}.onnx") for m in args.models}
    rules = {m: given.get(p.kind, family_rule(p.kind)) for m, p in preds.items()}
    print(f"rules: { {m: (r.max_head_probability if r else None) for m, r in rules.items()} }")
    print("| set | model | n | changed (class head right / beta head right) | accuracy | "
          "wrong & silent | alarms | beta MAPE | load |")  # fmt: skip
    print("| --- | --- | ---: | --- | --- | --- | --- | ---: | ---: |")
    out: dict[str, Any] = {}
    for name in args.sets:
        recs = recordings(name, args.n, args.data)
        for m, pred in preds.items():
            s = out.setdefault(name, {})[m] = score(pred, recs, rules[m])
            print(f"| {name} | {m} | {s['n']} | {s['changed']} ({s['changed_class_head_right']} "
                  f"/ {s['changed_beta_head_right']}) | {s['accuracy_before']:.3f} -> "
                  f"{s['accuracy_after']:.3f} | {s['silent_before']} -> {s['silent_after']} | "
                  f"{s['alarms_before']} -> {s['alarms_after']} | {s['beta_mape']:.3f} | "
                  f"{os.getloadavg()[0]:.1f} |", flush=True)  # fmt: skip
    if args.json:
        used = {m: r.model_dump() if r else None for m, r in rules.items()}
        write_json_atomic(args.json, {"rules": used, "sets": out})
    return 0


if __name__ == "__main__":
    raise SystemExit(main())

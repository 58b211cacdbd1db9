"""A model's answers, its restoring-force check and its alarms on a campaign, per recording.

What ``stiffnet evaluate`` reads through the predictor (the campaign's pooled sensor chain
and the campaign-level ``campaign_law`` decision included), without the reading by
simulation: per recording the model's class and beta, the check's beta, interval and
whether it covers the manifest's, the checks that fired and the ``contact_law`` reasons;
then the honesty figures: right answers flagged, wrong answers without an alarm, how many
answers' beta intervals (widened where flagged) cover the truth, the check's coverage, accuracy
and beta MAPE, and the CPU seconds.

Run (a campaign with ``beta`` in its manifest; ``shipped`` for the predictor's default)::

    OMP_NUM_THREADS=1 PYTHONPATH=. python benchmarks/bench_check_alarms.py CAMPAIGN MODEL \\
        --json OUT.json
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from serving.predictor import Predictor  # noqa: E402
from stiffnet.campaign.loaded import memo  # noqa: E402
from stiffnet.campaign.manifest import load_campaign  # noqa: E402
from stiffnet.measurement.evaluate import campaign_predictions  # noqa: E402
from stiffnet.measurement.metrics import true_class  # noqa: E402
from stiffnet.uncertainty.campaign_law import campaign_law_alarms  # noqa: E402
from stiffnet.uncertainty.unseen_law import trained_law_kinds, unseen_law_reasons  # noqa: E402

RESTORING_FORCE_CHECKS = {"restoring_force", "restoring_force_class"}


def recording_row(row: Any, result: dict[str, Any], seen: frozenset[str]) -> dict[str, Any]:
    """One recording: the truth, the model's answer, the check and the alarm."""
    rf = result.get("restoring_force") or {}
    alarm = result.get("alarm") or {}
    iv = rf.get("beta_interval")
    return {
        "recording": row.recording,
        "beta": row.beta,
        "true_class": true_class(row.beta, True),
        "class": result.get("class"),
        "beta_estimate": result.get("beta"),
        "beta_interval": result.get("beta_interval"),
        "check_beta": rf.get("beta"),
        "check_interval": iv,
        "check_class": rf.get("class"),
        "covers": None if not iv else bool(iv[0] <= row.beta <= iv[1]),
        "fired": list(alarm.get("fired") or []),
        "flag": bool(alarm.get("flag")),
        "scores": alarm.get("scores"),
        "contact_law": unseen_law_reasons(rf, seen=seen) if rf.get("class") else None,
        "hunt_crossley": rf.get("hunt_crossley"),
    }


def summary(rows: list[dict[str, Any]]) -> dict[str, Any]:
    """The honesty figures of a campaign's rows (:func:`recording_row`)."""
    right = [r for r in rows if r["class"] == r["true_class"]]
    wrong = [r for r in rows if r["class"] != r["true_class"]]
    read = [r for r in rows if r["check_beta"]]
    return {
        "n": len(rows),
        "right": len(right),
        "right_flagged": sum(r["flag"] for r in right),
        "right_flagged_by_the_check": sum(
            bool(RESTORING_FORCE_CHECKS & set(r["fired"])) for r in right
        ),  # fmt: skip
        "right_flagged_by_contact_law_alone": sum(r["fired"] == ["contact_law"] for r in right),
        "wrong": len(wrong),
        "wrong_silent": sum(not r["flag"] for r in wrong),
        "contact_law_fired": sum("contact_law" in r["fired"] for r in rows),
        "answer_covers": sum(
            bool(r["beta_interval"]) and r["beta_interval"][0] <= r["beta"] <= r["beta_interval"][1]
            for r in rows
        ),  # fmt: skip
        "check_covers": sum(bool(r["covers"]) for r in rows),
        "check_read": len(read),
        "check_accuracy": sum(r["check_class"] == r["true_class"] for r in rows) / len(rows),
        "check_beta_mape": sum(abs(r["check_beta"] / r["beta"] - 1) for r in read)
        / max(len(read), 1),
    }


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("campaign", type=Path)
    ap.add_argument("model", help="ONNX model, or 'shipped' for the predictor's default")
    ap.add_argument("--json", type=Path, help="write the rows and the summary here")
    args = ap.parse_args()
    model = None if args.model == "shipped" else args.model
    campaign = load_campaign(args.campaign)
    t0 = time.process_time()
    results, _ = campaign_predictions(campaign, model)
    results, law = campaign_law_alarms(results)
    cpu = time.process_time() - t0
    predictor = memo(campaign, ("predictor", model), lambda: Predictor.load(model))
    seen = trained_law_kinds((predictor.model.card.get("data") or {}).get("priors"))
    rows = [recording_row(row, res, seen) for row, res in zip(campaign.rows, results, strict=True)]
    print("| recording | beta | model | check (interval) | fired |")
    print("|---|---|---|---|---|")
    for r in rows:
        iv = r["check_interval"] or [float("nan")] * 2
        mark = "" if r["class"] == r["true_class"] else " **wrong**"
        model_read = f"{r['beta_estimate'] or float('nan'):.1f} {r['class']}{mark}"
        check = f"{r['check_beta'] or float('nan'):.1f} ({iv[0]:.1f}-{iv[1]:.1f})"
        check += "" if r["covers"] else " misses"
        print(f"| {r['recording']} | {r['beta']:g} | {model_read} | {check} | "
              f"{', '.join(r['fired'])} |")  # fmt: skip
    out = {**summary(rows), "campaign_law_flag": law.get("flag"), "cpu_s": round(cpu, 1)}
    print(json.dumps(out))
    if args.json:
        args.json.write_text(json.dumps({"summary": out, "campaign_law": law, "rows": rows},
                                        indent=1, default=str))  # fmt: skip


if __name__ == "__main__":
    main()

"""Beta by simulation beside the learned model on a campaign: learned vs simulation vs reading.

``evaluate_campaign`` with the reading by simulation (:mod:`stiffnet.measurement.simulated_beta`)
against the given law, one line per recording (the learned class, beta, interval and alarm;
the simulation's, its least discrepancy over the floor it is judged against and whether it
reproduces the recording; the disjoint-interval alarm; where the reading came from), then
each method's metrics and the simulation's CPU seconds. A missing campaign folder named
after an independent-rig law (``ideal``, ``two_stage``, ``hunt_crossley``, ``power_law``) is
written first with :func:`bench_loop_iteration.rig_runs` (24 recordings, 3 s, 2 % noise).

    OMP_NUM_THREADS=1 PYTHONPATH=.:tests:benchmarks python benchmarks/bench_simulated_beta.py \\
        CAMPAIGN --model iter-001/model/gbm.onnx \\
        --law '{"knee": 0.249, "knee_ratio": 2.436, "reference_penetration": 0.54}'
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path[:0] = [str(ROOT), str(ROOT / "tests"), str(ROOT / "benchmarks")]

from stiffnet.campaign import LoadedCampaign, load_campaign  # noqa: E402
from stiffnet.effects.learned_contact import LearnedContact  # noqa: E402
from stiffnet.measurement.evaluate import evaluate_campaign  # noqa: E402


def _f(x: float | None) -> str:
    return "-" if x is None else f"{x:.1f}"


def recording_line(r: dict) -> str:
    """One recording: learned, simulation, alarm and reading (WRONG: not the true class)."""
    li = r["beta_interval"] or [None, None]
    si = r["simulation_beta_interval"] or [None, None]
    wrong = {k: " WRONG" if r[k] != r["true_class"] else ""
             for k in ("class", "simulation_class", "reading_class")}  # fmt: skip
    return (f"{r['recording']} b={r['beta']:g} | learned {r['class']} {_f(r['beta_estimate'])} "
            f"[{_f(li[0])},{_f(li[1])}] ood={r['ood']}{wrong['class']} | simulation "
            f"{r['simulation_class']} {_f(r['simulation_beta'])} [{_f(si[0])},{_f(si[1])}] "
            f"x{_f(r['simulation_floor_ratio'])} reproduced={r['simulation_reproduced']}"
            f"{wrong['simulation_class']} alarm={r['simulation_alarm']} | reading "
            f"{r.get('reading_method')}{wrong['reading_class']}")  # fmt: skip


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("campaign", type=Path)
    ap.add_argument("--model", default=None, help="ONNX model (default: the shipped CNN)")
    ap.add_argument("--law", default="{}", help="LearnedContact parameters as JSON ({}: linear)")
    ap.add_argument("--json", type=Path, default=None, help="write the evaluation here")
    args = ap.parse_args()
    if not (args.campaign / "manifest.csv").is_file():
        from bench_loop_iteration import rig_runs
        from independent_rig import write_campaign

        write_campaign(args.campaign, rig_runs(args.campaign.name))
    camp = LoadedCampaign.of(load_campaign(args.campaign))
    law = json.loads(args.law)
    c0 = time.process_time()
    ev = evaluate_campaign(camp, args.model, [LearnedContact(**law)] if law else [])
    cpu = time.process_time() - c0
    if args.json:
        args.json.write_text(json.dumps(ev, default=str))
    for r in ev["recordings"]:
        print(recording_line(r))
    for k in ("learned", "simulation", "reading"):
        m = ev["metrics"].get(k, {})
        print(k, {a: round(b, 3) if isinstance(b, float) else b for a, b in m.items()})
    print(f"simulation CPU s {ev['simulation'].get('cpu_seconds')}; evaluate CPU {cpu:.1f} s, "
          f"load {os.getloadavg()[0]:.1f}")  # fmt: skip


if __name__ == "__main__":
    main()

"""The unseen-contact-law alarm of the shipped model, before and after a threshold change.

Sets of 24 recordings (``--n``) go through the real predictor
(:class:`serving.predictor.Predictor`: windows, ONNX model, restoring-force cross-check,
alarm):

* the robustness sets of ``benchmarks/configs/robustness_sets.yaml``
  (:mod:`bench_robustness`: the training world's laws, sensor chains, and the laws of
  ``tests/unknown_contact_laws.py``);
* the independent rig (``tests/independent_rig.py``: solve_ivp in SI units), 8 s at 1 kHz,
  beta log-uniform 8-90, forcing 0.95-1.1 f_n, noise 1-3 %, seed 7: no contact law
  (``rig_ideal``), Kelvin-Voigt zeta 0.2-0.4 (``rig_kv``), Hunt-Crossley lambda 8-25 s/m
  (``rig_hc``), two-stage knee 0.2 mm ratio 3 (``rig_two_stage``), power law n = 2
  (``rig_power``), the stop at the tip of a cantilever (mass 0.3 m, first mode 10 f_n, two
  modes; ``rig_beam``); laws in pairs: the same rig behind a mounted accelerometer
  (resonance 237 Hz = 25 f_n, damping 0.05, high-pass 1 Hz; ``LAB_MOUNT``) with no contact
  law (``rig_sensor``), Hunt-Crossley (``rig_hc_sensor``) or two-stage
  (``rig_two_stage_sensor``).

Each recording's details keep the model's readings through the other chains a fitted one
allows (``chain_readings``: what ``chain_class`` judged). Per set: wrong classes; wrong
classes without any alarm ("silent") and alarms, before ->
after; and the set read as one rig's campaign (``evaluate`` and ``predict-batch`` on a
campaign folder: :mod:`stiffnet.uncertainty.campaign_law`): on how many recordings the law
was read and on how many a counted check fired (``contact_law``, ``restraint_dynamics``,
``contact_duration``: the campaign rule's ``law_checks``), whether
the campaign is flagged (every recording then has ``campaign_law`` fired), wrong and silent
and alarms after it. "After" is the
predictor as shipped; "before" is the same prediction with the ``contact_law`` check's
reasons recomputed (:func:`stiffnet.uncertainty.unseen_law.unseen_law_reasons`) under the
thresholds of ``--before KEY=VALUE`` (default: the soft first stage rule off,
``onset_toe_min=inf``; ``stage_min_gain=inf`` turns the stage rule off,
``contact_damping_ratio_max=inf`` the damping ceiling,
``fast_chain_contact_min_ratio=inf`` the fitted chain's pulse against the law,
``release_ring_max_side=-inf`` a ringing release's hold on the exponent and curvature), and
``reference_penetration`` recomputed under them too (it reads the exponent), every other
check as it fired
(``restraint_dynamics`` included: a change of it is measured against a run of the code
before it).

Run::

    OMP_NUM_THREADS=1 python benchmarks/bench_alarm.py --data /tmp/bench_alarm \\
        --out /tmp/bench_alarm.json

``--data`` caches the simulated recordings (the independent rig's take ~10 s each).
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "benchmarks"))
sys.path.insert(0, str(ROOT / "tests"))

import bench_robustness as br  # noqa: E402  (the robustness sets and their recordings)
import independent_rig as rig  # noqa: E402

from serving.predictor import Predictor  # noqa: E402
from serving.verdict import model_facts  # noqa: E402
from stiffnet.io_utils import write_json_atomic  # noqa: E402
from stiffnet.measurement.metrics import true_class  # noqa: E402
from stiffnet.uncertainty.campaign_law import campaign_law_alarms  # noqa: E402
from stiffnet.uncertainty.reference_penetration import (  # noqa: E402
    REFERENCE_PENETRATION,
    reference_penetration_settings,
    reference_penetration_share,
)
from stiffnet.uncertainty.unseen_law import unseen_law_reasons, unseen_law_thresholds  # noqa: E402

ROBUSTNESS_SETS = ["ideal", "contact_damping", "hertz_contact", "sensor_dynamics",
                   "damping_and_sensor", "bilinear_contact", "hunt_crossley_contact",
                   "power_law_contact"]  # fmt: skip
#: A lab's mounted accelerometer: resonance 237 Hz (25 f_n), damping 0.05, high-pass 1 Hz.
LAB_MOUNT = {"resonance_hz": 237.0, "resonance_damping": 0.05, "highpass_hz": 1.0}
_TWO_STAGE = {"contact": "two_stage", "knee_mm": 0.2, "stage_ratio": 3.0}
#: The independent rig's contact laws (RigRun keywords; a draw's zeta / lambda where named).
RIG_SETS: dict[str, dict[str, Any]] = {
    "rig_ideal": {},
    "rig_kv": {"contact": "kelvin_voigt"},
    "rig_hc": {"contact": "hunt_crossley"},
    "rig_two_stage": _TWO_STAGE,
    "rig_power": {"contact": "power_law", "power_exponent": 2.0},
    "rig_beam": {"contact": "beam"},
    # laws in pairs: a mounted accelerometer (resonance 25 f_n, high-pass 1 Hz) alone, the
    # training world's, and behind two laws it lacks
    "rig_sensor": {"sensor": LAB_MOUNT},
    "rig_hc_sensor": {"contact": "hunt_crossley", "sensor": LAB_MOUNT},
    "rig_two_stage_sensor": {**_TWO_STAGE, "sensor": LAB_MOUNT},
}
RIG_SEED = 7


def rig_draws(n: int, seed: int = RIG_SEED) -> list[dict[str, float]]:
    """The independent rig's operating points (the same for every law)."""
    rng = np.random.default_rng(seed)
    return [
        dict(
            beta=float(np.exp(rng.uniform(np.log(8), np.log(90)))),
            ratio=float(rng.uniform(0.95, 1.1)),
            noise=float(rng.uniform(0.01, 0.03)),
            zeta=float(rng.uniform(0.2, 0.4)),
            lam=float(rng.uniform(8, 25)),
        )  # fmt: skip
        for _ in range(n)
    ]


def rig_recordings(name: str, n: int, folder: Path, seed: int = RIG_SEED) -> list[dict[str, Any]]:
    """The independent rig's recordings of one law, draws and noise from `seed` (cached as
    ``folder/<name>_<i>.npy``)."""
    folder.mkdir(parents=True, exist_ok=True)
    out = []
    for i, d in enumerate(rig_draws(n, seed)):
        kw = dict(RIG_SETS[name])
        if kw.get("contact") == "kelvin_voigt":
            kw["contact_zeta"] = d["zeta"]
        if kw.get("contact") == "hunt_crossley":
            kw["hc_lambda_s_per_m"] = d["lam"]
        run = rig.RigRun(recording=f"{name}_{i}.csv", beta=d["beta"], noise=d["noise"],
                         forcing_frequency_hz=9.48 * d["ratio"], duration_s=8.0, **kw)  # fmt: skip
        cache = folder / f"{name}_{i}.npy"
        if cache.is_file():
            accel = np.load(cache)
        else:
            accel = rig.record(run, seed=seed)[1]
            np.save(cache, accel)
        out.append(dict(accel=accel, fs_hz=run.fs_hz, fn_hz=run.natural_frequency_hz,
                        beta=run.beta, **{"class": true_class(run.beta, True)}))  # fmt: skip
    return out


def score(pred: Predictor, recs: list[dict[str, Any]], before: Any) -> dict[str, Any]:
    """Wrong, wrong and silent, alarms: before (thresholds `before`) and after (as shipped);
    ``recordings``: each recording's classes, β, alarm and restoring-force check."""
    wrong, after, prior, details, t0 = [], [], [], [], time.process_time()
    facts = model_facts(pred)
    results = []
    for r in recs:
        res = pred.predict(r["accel"], r["fs_hz"], natural_frequency_hz=r["fn_hz"])
        results.append(res)
        fired = (res["alarm"] or {}).get("fired", [])
        others = any(f not in ("contact_law", REFERENCE_PENETRATION) for f in fired)
        rf = res.get("restoring_force") or {}
        judged = any(rf.get(k) is not None for k in ("exponent", "dissipation_gain", "law_shape"))
        wrong.append(res["class"] != r["class"])
        after.append(bool(res["ood_flag"]))
        # reference_penetration reads the exponent as the contact_law check does: recomputed
        share = reference_penetration_share(res["class"], rf, facts["priors"], pred.class_names,
                                            pred.metadata.get("class_edges"), before)  # fmt: skip
        at_reference = (
            share is not None and share > reference_penetration_settings().outside_share_min
        )
        prior.append(others or at_reference or (judged and bool(unseen_law_reasons(rf, before))))
        details.append({"class": res["class"], "true_class": r["class"], "beta": res["beta"],
                        "true_beta": r["beta"], "beta_interval": res["beta_interval"],
                        "fired": fired, "scores": (res["alarm"] or {}).get("scores"),
                        "probabilities": res.get("probabilities"),
                        "geometric_class": (res.get("geometric") or {}).get("class"),
                        "chain_undone": res.get("chain_undone"),
                        "chain_readings": res.get("chain_readings"),
                        "restoring_force": rf})  # fmt: skip
    w, a, b = np.array(wrong), np.array(after), np.array(prior)
    flagged, campaign = campaign_law_alarms(results)  # the set read as one rig's campaign
    c = np.array([bool(res["ood_flag"]) for res in flagged])
    return {
        "n": len(recs),
        "wrong": int(w.sum()),
        "silent_before": int((w & ~b).sum()),
        "silent_after": int((w & ~a).sum()),
        "alarms_before": int(b.sum()),
        "alarms_after": int(a.sum()),
        "alarms_on_right": int((a & ~w).sum()),
        "campaign_law": campaign,
        "silent_campaign": int((w & ~c).sum()),
        "alarms_campaign": int(c.sum()),
        "cpu_s_per_recording": (time.process_time() - t0) / max(1, len(recs)),
        "recordings": details,
    }


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--model", type=Path, default=ROOT / "models" / "cnn.onnx")
    ap.add_argument("--sets", nargs="*", default=ROBUSTNESS_SETS + list(RIG_SETS))
    ap.add_argument("--n", type=int, default=24)
    ap.add_argument("--before", action="append", default=[], metavar="KEY=VALUE",
                    help="a threshold of configs/alarm/unseen_law.yaml for 'before'")  # fmt: skip
    ap.add_argument("--seed-offset", type=int, default=0,
                    help="fresh draws: added to the rig's and robustness sets' seeds")  # fmt: skip
    ap.add_argument("--data", type=Path, default=Path("/tmp/stiffnet_bench_alarm"))
    ap.add_argument("--out", type=Path, default=None, help="JSON result")
    args = ap.parse_args(argv)
    shipped = unseen_law_thresholds()
    changes = dict(kv.split("=", 1) for kv in args.before) or {"onset_toe_min": "inf"}
    before = shipped.model_copy(update={k: float(v) for k, v in changes.items()})
    pred = Predictor.load(str(args.model))
    configs = br.set_configs(br.DEFAULT_SETS)
    rows = {}
    print("| set | n | wrong | wrong & silent, before -> after | alarms, before -> after "
          "| alarms on right answers | as a campaign: a law check fired / law read, wrong & "
          "silent, alarms |")  # fmt: skip
    print("| --- | ---: | ---: | ---: | ---: | ---: | ---: |")
    for name in args.sets:
        if name in RIG_SETS:
            seed, tag = (
                RIG_SEED + args.seed_offset,
                f"-s{args.seed_offset}" * bool(args.seed_offset),
            )
            recs = rig_recordings(name, args.n, args.data / f"rig{tag}", seed)
        else:
            cfg = configs[name][0]
            cfg = cfg.model_copy(update={"n_trajectories": args.n, "shard_size": args.n,
                                         "seed": cfg.seed + args.seed_offset})  # fmt: skip
            recs = br.recordings(cfg, args.data / f"{name}-{args.n}-s{cfg.seed}")
        s = rows[name] = score(pred, recs, before)
        print(f"| {name} | {s['n']} | {s['wrong']} | {s['silent_before']} -> {s['silent_after']}"
              f" | {s['alarms_before']} -> {s['alarms_after']} | {s['alarms_on_right']} | "
              f"{s['campaign_law']['n_fired']} / {s['campaign_law']['n_judged']}"
              f"{' (flagged)' * s['campaign_law']['flag']}, {s['silent_campaign']}, "
              f"{s['alarms_campaign']} |", flush=True)  # fmt: skip
        if args.out:  # after every set: a long run's finished sets are kept
            write_json_atomic(args.out, {"before": changes, "sets": rows})
    return 0


if __name__ == "__main__":
    raise SystemExit(main())

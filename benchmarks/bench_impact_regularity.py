"""How much the impacts of one record differ: the leverage a time-invariance test of an
identified sensor chain would have (docs/crosscheck.md, "A chain the rig does not have").

A sensor chain is linear and time-invariant and shapes every impact's pulse alike; a
stiffening contact law reshapes the pulse with the impact's velocity. Telling the two apart
within one record needs impacts that differ. Two readings:

* ``truth``: the independent rig's draws (:func:`bench_alarm.rig_draws`, the two-stage law;
  the mount does not change the motion) integrated without noise at 20 kHz
  (:func:`independent_rig.simulate`): each impact's peak acceleration, its coefficient of
  variation over the impacts and the peak penetration in knees;
* ``maps``: the restoring-force map as the predictor reads it
  (:meth:`serving.predictor.Predictor.predict`; the estimate it runs is recorded), per
  impact (a run of samples past the fitted onset, one sample either side): the impulse (the
  pulse's area, which a chain of unit DC gain keeps), the peak force, the deepest
  penetration, the fitted law's misfit over the peak force and the pulse's second moment;
  per recording their spreads, the slope of ln peak force on ln depth (1 where the depths
  differ through a linear law, 0 where the map's level wanders) and Spearman's rank
  correlations of the misfit with the depth and with the impulse, and of the second moment
  with the impulse (printed for the recordings whose impulse CV exceeds
  :data:`VARIED_IMPULSE_CV`: those whose impacts differ).

Run::

    OMP_NUM_THREADS=1 python benchmarks/bench_impact_regularity.py --data DIR \\
        --truth-offsets 0 1000 2000 --out /tmp/impact_regularity.json
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np
from scipy import signal, stats

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "benchmarks"))
sys.path.insert(0, str(ROOT / "tests"))

import bench_alarm as ba  # noqa: E402  (the sets and their cached recordings)
import bench_robustness as br  # noqa: E402
import independent_rig as rig  # noqa: E402

import serving.restoring_force_check as rfc  # noqa: E402
from serving.predictor import Predictor  # noqa: E402
from stiffnet.io_utils import write_json_atomic  # noqa: E402
from stiffnet.restoring_force.contact_law import contact_force  # noqa: E402
from stiffnet.uncertainty.law_shape import impact_runs  # noqa: E402

DEFAULT_SETS = ["rig_two_stage", "rig_ideal", "rig_sensor", "rig_two_stage_sensor",
                "sensor_dynamics", "damping_and_sensor"]  # fmt: skip
#: An impulse CV above which a recording's impacts count as differing (the rig's maps read
#: 0.1-0.5 % on impacts that are identical).
VARIED_IMPULSE_CV = 0.05
#: The truth's sampling rate: the contact's peak resolved to a few per cent of its duration.
TRUTH_FS_HZ = 20000.0


def rig_truth(offset: int, n: int) -> list[dict[str, float]]:
    """Per draw of the rig's two-stage law: impacts, the peak acceleration's CV over them
    and the median peak penetration over the knee (noise-free, :data:`TRUTH_FS_HZ`)."""
    out = []
    for d in ba.rig_draws(n, ba.RIG_SEED + offset):
        run = rig.RigRun(recording="truth.csv", beta=d["beta"], noise=0.0,
                         forcing_frequency_hz=9.48 * d["ratio"], duration_s=8.0,
                         fs_hz=TRUTH_FS_HZ, **ba._TWO_STAGE)  # fmt: skip
        _, acc = rig.simulate(run)
        spikes = -acc if abs(acc.min()) > abs(acc.max()) else acc
        half_period = int(TRUTH_FS_HZ / run.forcing_frequency_hz / 2)
        peaks, _ = signal.find_peaks(spikes, height=0.5 * spikes.max(), distance=half_period)
        top = spikes[peaks]
        # the contact force per unit mass at the deepest point, read back to a penetration
        k, knee, ratio = run.beta * run.omega_n**2, run.knee_mm * 1e-3, run.stage_ratio
        depth = np.where(top <= k * knee, top / k, (top + (ratio - 1) * k * knee) / (ratio * k))
        out.append({"beta": run.beta, "n_impacts": int(peaks.size),
                    "peak_cv": float(np.std(top) / np.mean(top)),
                    "depth_over_knee": float(np.median(depth) / knee)})  # fmt: skip
    return out


def impact_readings(r: Any) -> np.ndarray:
    """Per impact of a restoring-force result `r`: impulse, peak force, depth, misfit over
    the peak force and the pulse's second moment (samples squared), one row each."""
    law = r.law
    d = r.displacement - law.onset
    fit = contact_force(r.displacement, r.velocity, law.stiffness, law.onset, law.damping,
                        law.exponent, law.reference_penetration)  # fmt: skip
    rows = []
    for run in impact_runs(d):
        s = slice(max(run[0] - 1, 0), run[-1] + 2)
        f = r.force[s]
        area, peak = float(f.sum()), float(f.max())
        t = np.arange(f.size, dtype=float)
        mean = float(f @ t / area)
        misfit = float(np.sqrt(np.mean((f - fit[s]) ** 2)) / peak)
        rows.append((area, peak, float(d[run].max()), misfit, float(f @ (t - mean) ** 2 / area)))
    return np.array(rows)


def spread(rows: np.ndarray) -> dict[str, float]:
    """One recording's spreads over its impacts (:func:`impact_readings`)."""
    area, peak, depth, misfit, width2 = rows.T
    return {
        "impulse_cv": float(np.std(area) / np.mean(area)),
        "peak_cv": float(np.std(peak) / np.mean(peak)),
        "depth_p90_p10": float(np.percentile(depth, 90) / np.percentile(depth, 10)),
        "peak_on_depth": float(np.polyfit(np.log(depth), np.log(peak), 1)[0]),
        "misfit_depth_rank": float(stats.spearmanr(depth, misfit)[0]),
        "misfit_impulse_rank": float(stats.spearmanr(area, misfit)[0]),
        "width2_impulse_rank": float(stats.spearmanr(area, width2)[0]),
        "width2_cv": float(np.std(width2) / abs(np.mean(width2))),
    }


def map_readings(pred: Predictor, recs: list[dict[str, Any]]) -> list[dict[str, Any]]:
    """Per recording: the answer (wrong, silent), the chain undone and :func:`spread`."""
    seen: list[Any] = []
    estimate = rfc.restoring_force_estimate

    def recorded(*args: Any, **kw: Any) -> Any:
        result = estimate(*args, **kw)
        if kw.get("impact_onsets"):  # the predictor's cross-check, not a chain's re-read
            seen.append(result)
        return result

    out = []
    rfc.restoring_force_estimate = recorded
    try:
        for i, rec in enumerate(recs):
            seen.clear()
            res = pred.predict(rec["accel"], rec["fs_hz"], natural_frequency_hz=rec["fn_hz"])
            wrong = res["class"] != rec["class"]
            sensor = (res.get("restoring_force") or {}).get("sensor")
            item = {"i": i, "wrong": wrong, "silent": wrong and not res["ood_flag"],
                    "chain_undone": bool(sensor and sensor.get("applied"))}  # fmt: skip
            r = seen[-1] if seen else None
            if r is not None and r.ok and r.law is not None:
                rows = impact_readings(r)
                if len(rows) >= 4:
                    item.update(spread(rows))
            out.append(item)
    finally:
        rfc.restoring_force_estimate = estimate
    return out


def _span(values: list[float]) -> str:
    v = np.array(values)
    return f"{v.min():.3f}-{v.max():.3f} ({np.median(v):.3f})"


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--model", type=Path, default=ROOT / "models" / "cnn.onnx")
    ap.add_argument("--sets", nargs="*", default=DEFAULT_SETS)
    ap.add_argument("--n", type=int, default=24)
    ap.add_argument("--seed-offset", type=int, default=0)
    ap.add_argument("--truth-offsets", nargs="*", type=int, default=[],
                    help="the rig's draws at these offsets, integrated noise-free")  # fmt: skip
    ap.add_argument("--data", type=Path, default=Path("/tmp/stiffnet_bench_alarm"))
    ap.add_argument("--out", type=Path, default=None, help="JSON result")
    args = ap.parse_args(argv)
    result: dict[str, Any] = {"truth": {}, "maps": {}}
    for offset in args.truth_offsets:
        t0 = time.process_time()
        truth = result["truth"][offset] = rig_truth(offset, args.n)
        print(f"truth, offset {offset}: impacts {min(t['n_impacts'] for t in truth)}-"
              f"{max(t['n_impacts'] for t in truth)}, peak CV at most "
              f"{max(t['peak_cv'] for t in truth):.1e}, depth "
              f"{_span([t['depth_over_knee'] for t in truth])} knees, "
              f"{time.process_time() - t0:.0f} s CPU", flush=True)  # fmt: skip
    pred = Predictor.load(str(args.model)) if args.sets else None
    configs = br.set_configs(br.DEFAULT_SETS)
    keys = ["impulse_cv", "peak_cv", "depth_p90_p10", "peak_on_depth", "misfit_depth_rank"]
    print("| set | group | n | " + " | ".join(keys) + " |")
    for name in args.sets:
        t0 = time.process_time()
        if name in ba.RIG_SETS:
            tag = f"-s{args.seed_offset}" * bool(args.seed_offset)
            recs = ba.rig_recordings(name, args.n, args.data / f"rig{tag}",
                                     ba.RIG_SEED + args.seed_offset)  # fmt: skip
        else:
            cfg = configs[name][0]
            cfg = cfg.model_copy(update={"n_trajectories": args.n, "shard_size": args.n,
                                         "seed": cfg.seed + args.seed_offset})  # fmt: skip
            recs = br.recordings(cfg, args.data / f"{name}-{args.n}-s{cfg.seed}")
        items = result["maps"][name] = map_readings(pred, recs)
        for chain in (False, True):
            group = [it for it in items if "impulse_cv" in it and it["chain_undone"] is chain]
            if group:
                silent = sum(it["silent"] for it in group)
                cells = " | ".join(_span([it[k] for it in group]) for k in keys)
                print(f"| {name} | {'chain undone' if chain else 'no chain'} ({silent} silent) "
                      f"| {len(group)} | {cells} |", flush=True)  # fmt: skip
        varied = [it for it in items if it.get("impulse_cv", 0.0) > VARIED_IMPULSE_CV]
        for chain in (False, True):
            group = [it for it in varied if it["chain_undone"] is chain]
            if group:
                print(f"  {name}, impulse CV > {VARIED_IMPULSE_CV}, "
                      f"{'chain undone' if chain else 'no chain'}: {len(group)}, Spearman "
                      f"(misfit, impulse) {_span([it['misfit_impulse_rank'] for it in group])}, "
                      f"(width², impulse) {_span([it['width2_impulse_rank'] for it in group])}",
                      flush=True)  # fmt: skip
        print(f"  {name}: {time.process_time() - t0:.0f} s CPU", flush=True)
        if args.out:
            write_json_atomic(args.out, result)
    if args.out:
        write_json_atomic(args.out, result)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())

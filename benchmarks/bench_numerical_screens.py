"""Benchmark the numerical-engine effects' design screens of a diagnosis's second step.

The campaign of ``bench_diagnose.py`` (24 recordings, contact damping 0.25 and a 237 Hz
resonance hidden); the model holds the sensor chain the diagnosis selects first (237.05 Hz,
zeta 0.0297, high-pass 1.06 Hz), as in its step 2. For each numerical-engine candidate
(Hertz contact, restraint mass, dry friction) its design is taken exactly as
:func:`stiffnet.measurement.fitting.fit_effect` builds it, then screened on the design's
recordings (:meth:`~stiffnet.measurement.target.CampaignTarget.per_recording_points`)
with each settings variant, in one process, the variants alternated ``--repeats`` times:
CPU seconds (``time.process_time``), the objective of every design point and the point
each variant picks: the chain's standard lead-in (1.5 s) against the screen's
(:func:`stiffnet.campaign.simulate.screen_lead_in_seconds`, 0.48 s). Both draw the same
white noise (drawn for the record's samples only), so the objectives differ by the lead-in
alone: the record starts earlier on the orbit, its motion settled a little less (within the
screen's tolerance), and the chain's start-up is left at that tolerance.

Run from the repository root::

    OMP_NUM_THREADS=1 PYTHONPATH=. python benchmarks/bench_numerical_screens.py [--rows 24]
"""

from __future__ import annotations

import argparse
import os
import tempfile
import time
from pathlib import Path

import numpy as np
from bench_diagnose import campaign

from stiffnet.campaign import load_campaign
from stiffnet.campaign.simulate import FIT_SETTINGS_NUMERICAL
from stiffnet.effects.registry import effect_class
from stiffnet.measurement import fitting
from stiffnet.measurement.fitting import objective_value, screen_settings
from stiffnet.measurement.nuisance import resolve_rows
from stiffnet.measurement.target import CampaignTarget, measured_statistics

CANDIDATES = ("hertz_contact", "restraint_mass", "dry_friction")
SENSOR = {"resonance_hz": 237.05, "resonance_damping": 0.0297, "highpass_hz": 1.06,
          "lowpass_hz": 0.0, "lowpass_order": 2.0}  # fmt: skip


def designs(target: CampaignTarget, fixed: list) -> dict[str, tuple]:
    """Each candidate's (searched target, model, points) as ``fit_effect`` would screen them."""
    out = {}

    def capture(target_, name, fixed_, space, design, settings, off, t0):
        n = len(target_.rows)
        idx = np.unique(
            np.round(np.linspace(0, n - 1, min(n, fitting.SUBSET_NUMERICAL))).astype(int)
        )
        searched = target_ if idx.size == n else target_.subset(idx)
        out[name] = (searched, [*target_.base_effects, *fixed_], [space.params(u) for u in design])
        return {}

    real = fitting._fit_design
    fitting._fit_design = capture
    try:
        for name in CANDIDATES:
            fitting._fit_effect(target, name, fixed, None, None, np.zeros(len(target.rows)), ())
    finally:
        fitting._fit_design = real
    return out


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--rows", type=int, default=24)
    ap.add_argument("--duration", type=float, default=6.0)
    ap.add_argument("--repeats", type=int, default=2)
    args = ap.parse_args()
    variants = {
        "standard lead-in": screen_settings(FIT_SETTINGS_NUMERICAL),
        "screen lead-in": screen_settings(FIT_SETTINGS_NUMERICAL, short_lead_in=True),
    }
    with tempfile.TemporaryDirectory() as d:
        camp = load_campaign(campaign(Path(d), args.duration, args.rows))
        rows, _ = resolve_rows(camp)
        measured, lengths, _ = measured_statistics(camp, rows, False)
        target = CampaignTarget(rows, measured, lengths, [], inclination=False)
        fixed = [effect_class("sensor_dynamics")(**SENSOR)]
        cases = designs(target, fixed)
        load0 = os.getloadavg()[0]
        cpu = {(c, v): [] for c in cases for v in variants}
        values = {}
        for _ in range(args.repeats):
            for c, (searched, model, points) in cases.items():
                for v, settings in variants.items():
                    searched.known.clear()
                    t = time.process_time()
                    pers = searched.per_recording_points(
                        model, c, points, settings, inclination=False, oversample=False
                    )
                    cpu[(c, v)].append(time.process_time() - t)
                    values[(c, v)] = [objective_value(p, searched.weights) for p in pers]
        load1 = os.getloadavg()[0]
    print(f"load average {load0:.2f} -> {load1:.2f}; {args.rows} recordings x "
          f"{args.duration:g} s, {args.repeats} repeats alternated")  # fmt: skip
    print("| candidate | variant | CPU s (each run) | objective per design point | pick |")
    print("|---|---|---|---|---|")
    for (c, v), secs in cpu.items():
        vals = values[(c, v)]
        print(f"| {c} | {v} | {' / '.join(f'{s:.2f}' for s in secs)} | "
              f"{' '.join(f'{x:.3f}' for x in vals)} | {int(np.argmin(vals))} |")  # fmt: skip
    for v in variants:
        total = sum(min(cpu[(c, v)]) for c in cases)
        print(f"{v}: {total:.2f} s CPU for the three screens (fastest run of each)")


if __name__ == "__main__":
    main()

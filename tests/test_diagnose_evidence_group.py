"""The restoring-force evidence's chain and contact law fitted as one step of the diagnosis.

A damped contact behind a mounted sensor chain: neither effect passes alone (the chain with
the contact left elastic rings far harder than the recordings; the damping without the chain
explains a sixth of the excess), so a forward selection stops with nothing while the pair
the evidence identifies brings the model to the floor.
"""

from __future__ import annotations

import csv

import pytest

from stiffnet.campaign import load_campaign, simulate_campaign
from stiffnet.measurement.diagnose import diagnose_campaign, evidence_group

CHAIN = {"sensor": {"resonance_hz": 210.0, "lowpass_hz": 320.0}}


def test_evidence_group_is_the_chain_with_the_contact_it_supports():
    both = ["contact_damping", "sensor_dynamics", "forcing_harmonics"]
    assert evidence_group({**CHAIN, "supports": ["contact_damping"]}, both) == [
        "sensor_dynamics",
        "contact_damping",
    ]
    # no chain identified, no supported contact, or a member not a candidate: no group
    assert evidence_group({"sensor": None, "supports": ["contact_damping"]}, both) == []
    assert evidence_group({"sensor": {"resonance_hz": None}, "supports": ["contact_damping"]},
                          both) == []  # fmt: skip
    assert evidence_group({**CHAIN, "supports": []}, both) == []
    assert evidence_group({**CHAIN, "supports": ["hertz_contact"]}, both) == []
    assert evidence_group({**CHAIN, "supports": ["contact_damping"]}, ["contact_damping"]) == []
    assert evidence_group(None, both) == []


# the independent rig's campaign a at six of its operating points (model units): beta 81 at
# a 0.5 mm gap is the recording whose free-flight harmonics the chain alone sends 200
# tolerances off
ROWS = [
    ("p0.csv", 1000, 1.04958, 1.89937, 2.8, 13),
    ("p1.csv", 1000, 0.95042, 1.0006, 0.5, 81),
    ("p2.csv", 1250, 1.0, 1.19959, 1.2, 60),
    ("p3.csv", 1250, 1.10021, 1.89983, 2.0, 17),
    ("p4.csv", 1500, 0.97996, 1.49957, 1.6, 10),
    ("p6.csv", 2000, 1.02004, 1.29902, 0.9, 37),
]


@pytest.mark.slow  # a diagnosis with the restoring-force evidence (about 15 CPU s)
def test_damped_contact_behind_a_mounted_chain_is_explained_by_the_pair(tmp_path):
    manifest = tmp_path / "manifest.csv"
    with open(manifest, "w", encoding="utf-8", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(["recording", "fs_hz", "natural_frequency_hz", "frequency_ratio", "amplitude",
                    "gap", "damping_ratio", "beta", "duration_s", "noise"])  # fmt: skip
        for name, fs, ratio, amp, gap, beta in ROWS:
            w.writerow([name, fs, 9.48, ratio, amp, gap, 0.02, beta, 3, 0.02])
    chain = ("sensor_dynamics:resonance_hz=210,resonance_damping=0.05,highpass_hz=0,"
             "lowpass_hz=320,lowpass_order=4")  # fmt: skip
    camp = simulate_campaign(
        manifest, tmp_path / "c", ["contact_damping:damping_ratio=0.15", chain], seed=0
    )
    d = diagnose_campaign(
        load_campaign(camp), effects=["contact_damping", "sensor_dynamics"], inclination=False
    )
    alone = [s for s in d["selection"] if s["effect"] in ("contact_damping", "sensor_dynamics")]
    assert alone and not any(s["significant"] for s in alone)  # neither passes alone
    assert sorted(d["missing_effects"]) == ["contact_damping", "sensor_dynamics"]
    assert d["verdict"] == "explained" and d["explained_fraction"] > 0.95
    (group,) = [s for s in d["selection"] if s.get("proposed_by")]
    assert group["effects"] == ["sensor_dynamics", "contact_damping"] and group["significant"]
    fitted = d["fitted_params"]
    assert fitted["contact_damping"]["damping_ratio"] == pytest.approx(0.15, rel=0.1)
    assert fitted["sensor_dynamics"]["resonance_hz"] == pytest.approx(210.0, rel=0.03)
    by_name = {r["effect"]: r for r in d["ranking"]}
    assert by_name["contact_damping"]["selected_with"] == ["sensor_dynamics"]
    assert by_name["sensor_dynamics"]["selected_with"] == ["contact_damping"]

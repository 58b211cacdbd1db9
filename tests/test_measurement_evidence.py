"""Restoring-force evidence beside diagnose's fits: rules and a simulated damped campaign."""

from pathlib import Path

import numpy as np
import pytest

from stiffnet.campaign import load_campaign, read_manifest, simulate_campaign, write_manifest
from stiffnet.measurement.evidence import contact_evidence, restitution, restoring_force_evidence

ROOT = Path(__file__).resolve().parents[1]


def test_restitution_of_a_kelvin_voigt_contact():
    assert restitution(0.0) == 1.0
    assert restitution(0.5) == pytest.approx(np.exp(-np.pi * 0.5 / np.sqrt(0.75)))
    assert restitution(1.0) == 0.0


def _rec(zeta, p, ok=True):
    return {"recording": "r", "ok": ok, "contact_damping_ratio": zeta, "exponent": p}


def test_evidence_rules_name_dissipation_and_stiffening():
    damped = contact_evidence([_rec(0.3, 1.0), _rec(0.25, 1.0), _rec(0.2, 1.05)])
    assert damped["supports"] == ["contact_damping"]
    assert damped["contact_damping_ratio"] == pytest.approx(0.25)
    assert "supports contact_damping" in damped["summary"]
    hertz = contact_evidence([_rec(0.0, 1.5), _rec(0.01, 1.4), _rec(0.0, 1.6, ok=False)])
    assert hertz["supports"] == ["hertz_contact"] and hertz["answered"] == 2
    ideal = contact_evidence([_rec(0.01, 1.0), _rec(0.0, 1.0)])
    assert ideal["supports"] == [] and "no dissipation" in ideal["summary"]
    few = contact_evidence([_rec(0.3, 1.0), _rec(None, None, ok=False)])
    assert few["supports"] == [] and "too few" in few["summary"]


@pytest.mark.parametrize("zeta", [0.0, 0.25])
def test_evidence_on_a_simulated_campaign(tmp_path, zeta):
    """The hidden-effect manifest's 8 rows: dissipation named only when the contact has it."""
    effects = [f"contact_damping:damping_ratio={zeta}"] if zeta else []
    rows = read_manifest(ROOT / "examples" / "hidden_effect_manifest.csv")
    manifest = write_manifest(
        tmp_path / "m.csv", [r.model_copy(update={"duration_s": 2.0}) for r in rows]
    )
    camp = load_campaign(simulate_campaign(manifest, tmp_path / "c", effects, seed=0))
    ev = restoring_force_evidence(camp, camp.rows)
    assert ev["answered"] >= 6
    if zeta:
        assert ev["supports"] == ["contact_damping"]
        assert ev["contact_damping_ratio"] == pytest.approx(zeta, abs=0.08)
    else:
        assert "contact_damping" not in ev["supports"]
        assert ev["contact_damping_ratio"] < 0.05


def test_the_chain_is_fitted_on_a_few_recordings_spread_over_the_campaign():
    from stiffnet.measurement.evidence import _spread
    from stiffnet.restoring_force.chain import shared_chain_sheet

    assert _spread(list(range(24)), 3) == [0, 12, 23]
    assert _spread([1, 4, 6, 9], 3) == [1, 6, 9]
    assert _spread([2, 5], 3) == [2, 5]
    # a shared chain becomes a data sheet with a whole low-pass order; no stage to undo: none
    shared = {"n": 3, "resonance_hz": 237.0, "resonance_damping": 0.03, "lowpass_hz": 150.0,
              "lowpass_order": 1.5, "highpass_hz": None}  # fmt: skip
    sheet = {"resonance_hz": 237.0, "resonance_damping": 0.03, "lowpass_hz": 150.0,
             "lowpass_order": 2.0, "highpass_hz": 0.0}  # fmt: skip
    assert shared_chain_sheet(shared) == sheet
    assert (
        shared_chain_sheet({"n": 3, "resonance_hz": None, "lowpass_hz": None, "highpass_hz": 1.0})
        is None
    )
    assert shared_chain_sheet(None) is None


@pytest.mark.slow
def test_one_accelerometer_chain_fitted_on_three_recordings_is_undone_on_the_rest(tmp_path):
    """5 recordings through a 237 Hz accelerometer resonance and a damped contact: the chain
    is fitted on 3 of them, the other 2 are read through the chain those share, and the
    evidence says so; the contact damping and the chain are still read."""
    from campaign_helpers import short_manifest

    from stiffnet.measurement.evidence import contact_law_per_recording

    hidden = ["contact_damping:damping_ratio=0.25",
              "sensor_dynamics:resonance_hz=237,resonance_damping=0.03,lowpass_hz=0"]  # fmt: skip
    camp = load_campaign(simulate_campaign(short_manifest(tmp_path, 5, "2"), tmp_path / "c",
                                           hidden, seed=0))  # fmt: skip
    per = contact_law_per_recording(camp, camp.rows)
    shared = [p for p in per if p.get("chain_shared")]
    names = [r.recording for r in camp.rows]
    assert [p["recording"] for p in shared] == [names[1], names[3]]
    assert all(p["chain_fitted_on"] == [names[0], names[2], names[4]] for p in shared)
    assert all(p["sensor"]["source"] == "data sheet" for p in shared)
    assert all(p["sensor"]["source"] == "fitted" for p in per if not p.get("chain_shared"))
    assert shared[0]["sensor"]["resonance_hz"] == pytest.approx(237.0, rel=0.01)
    ev = contact_evidence(per)
    assert ev["sensor"]["n"] == 5  # one vote per recording
    assert ev["sensor"]["resonance_hz"] == pytest.approx(237.0, rel=0.01)
    assert ev["chain_fitted_on"] == [names[0], names[2], names[4]]
    assert (
        "fitted on 3 of them" in ev["summary"]
        and "undone as shared on the other 2" in ev["summary"]
    )
    assert ev["supports"] == ["contact_damping"] and ev["answered"] >= 4
    assert ev["contact_damping_ratio"] == pytest.approx(0.25, abs=0.08)


def _as_recorded(row) -> dict:
    """A stand-in reading as recorded: no samples for the shared chain's rule to judge."""
    return {"recording": row.recording, "ok": True, "contact_r2": 0.9, "exponent": 1.0,
            "contact_damping_ratio": 0.2, "sensor": None}  # fmt: skip


def _stand_in_readings(evidence, monkeypatch, shared_r2: dict, calls: list):
    """Stand-in readings: a fitted chain explains 0.97 of every recording's law; through the
    shared chain, row `i` explains ``shared_r2.get(i, 0.99)`` (None: refused)."""
    chain = {"resonance_hz": 237.0, "resonance_damping": 0.03, "source": "fitted"}

    def reading(item):
        rec, row, sheet = item
        if sheet == evidence.AS_RECORDED:  # the shared chain's rule reads the rest as recorded
            return _as_recorded(row)
        calls.append((rec, sheet is not None))
        if sheet is None:  # the chain fitted on this recording
            return {"recording": row.recording, "ok": True, "contact_r2": 0.97, "exponent": 1.0,
                    "contact_damping_ratio": 0.2, "sensor": dict(chain)}  # fmt: skip
        r2 = shared_r2.get(rec, 0.99)
        return {"recording": row.recording, "ok": r2 is not None, "contact_r2": r2,
                "contact_damping_ratio": 0.2, "exponent": 1.0,
                "sensor": {**sheet, "source": "data sheet"}}  # fmt: skip

    monkeypatch.setattr(evidence, "_contact_law_task", reading)


def test_a_recording_the_shared_chain_leaves_poorly_explained_gets_its_own_chain(monkeypatch):
    """The rule on stand-in readings: 6 rows, the chain fitted on rows 0, 2 and 5; the shared
    chain reads those three at R² 0.5 (their own: 0.97), so it is not theirs: of the others
    read through it, the one whose law explains 0.6 and the refused one are read again with
    their own chain fitted; a row with its own sheet keeps it."""
    from types import SimpleNamespace

    from stiffnet.measurement import evidence

    calls = []
    _stand_in_readings(evidence, monkeypatch, {0: 0.5, 2: 0.5, 5: 0.5, 3: 0.6, 4: None}, calls)
    rows = [SimpleNamespace(recording=f"r{i}", sensor_sheet=lambda: None) for i in range(6)]
    rows.append(
        SimpleNamespace(
            recording="own", sensor_sheet=lambda: {"resonance_hz": 300.0, "resonance_damping": 0.05}
        )
    )
    camp = SimpleNamespace(recording=lambda i: i)
    per = evidence.contact_law_per_recording(camp, rows)
    shared = [p["recording"] for p in per if p.get("chain_shared")]
    assert shared == ["r1"]  # r3 (law explains 0.6) and r4 (refused) read again
    assert per[1]["chain_fitted_on"] == ["r0", "r2", "r3", "r4", "r5"]
    assert per[1]["chain_shortfall"] == pytest.approx(0.97 - 0.5)
    assert [rec for rec, with_sheet in calls if not with_sheet] == [0, 2, 5, 3, 4]
    assert [rec for rec, with_sheet in calls if with_sheet] == [1, 3, 4, 6, 0, 2, 5]
    assert per[6]["sensor"]["resonance_hz"] == 300.0
    assert all(per[i]["contact_r2"] == 0.97 for i in (0, 3, 4, 5))
    ev = evidence.contact_evidence(per)
    assert ev["sensor"]["n"] == 7  # one vote per recording, the shared chain's copy included


def test_a_chain_confirmed_on_its_own_recordings_is_kept_where_a_recording_reads_poorly(
    monkeypatch,
):
    """The same rows, the shared chain reading the three it was fitted on at 0.99 (their own
    0.97; one of them refused through it does not outvote the other two): it is the
    campaign's chain, so a recording it reads poorly (0.6, refused) is poor whatever chain is
    undone, and no chain is fitted on it."""
    from types import SimpleNamespace

    from stiffnet.measurement import evidence

    calls = []
    _stand_in_readings(evidence, monkeypatch, {5: None, 3: 0.6, 4: None}, calls)
    rows = [SimpleNamespace(recording=f"r{i}", sensor_sheet=lambda: None) for i in range(6)]
    per = evidence.contact_law_per_recording(SimpleNamespace(recording=lambda i: i), rows)
    assert [rec for rec, with_sheet in calls if not with_sheet] == [0, 2, 5]
    assert [p["recording"] for p in per if p.get("chain_shared")] == ["r1", "r3", "r4"]
    assert per[3]["contact_r2"] == 0.6 and not per[4]["ok"]
    assert per[1]["chain_fitted_on"] == ["r0", "r2", "r5"]
    assert per[1]["chain_shortfall"] == pytest.approx(0.97 - 0.99)
    assert evidence.contact_evidence(per)["answered"] == 5


def test_a_second_round_of_chain_fits_where_the_first_three_share_no_stage(monkeypatch):
    """8 rows; the first round (rows 0, 4, 7) reads a resonance, a low-pass and nothing (as
    fast contacts do): no stage shared, so 3 more are fitted (rows 1, 3, 6, all with the
    resonance: 4 of 6 share it) and the last 2 are read through it."""
    from types import SimpleNamespace

    from stiffnet.measurement import evidence

    resonance = {"resonance_hz": 237.0, "resonance_damping": 0.03, "source": "fitted"}
    own = {0: resonance, 4: {"lowpass_hz": 280.0, "lowpass_order": 4, "source": "fitted"},
           7: {"source": "fitted"}}  # fmt: skip
    fitted = []

    def reading(item):
        rec, row, sheet = item
        if sheet == evidence.AS_RECORDED:
            return _as_recorded(row)
        if sheet is None:
            fitted.append(rec)
        chain = own.get(rec, resonance) if sheet is None else {**sheet, "source": "data sheet"}
        return {"recording": row.recording, "ok": True, "contact_r2": 0.97, "exponent": 1.0,
                "contact_damping_ratio": 0.2, "sensor": chain}  # fmt: skip

    monkeypatch.setattr(evidence, "_contact_law_task", reading)
    rows = [SimpleNamespace(recording=f"r{i}", sensor_sheet=lambda: None) for i in range(8)]
    per = evidence.contact_law_per_recording(SimpleNamespace(recording=lambda i: i), rows)
    assert fitted == [0, 4, 7, 1, 3, 6]
    assert [p["recording"] for p in per if p.get("chain_shared")] == ["r2", "r5"]
    assert per[2]["sensor"]["resonance_hz"] == 237.0 and not per[2]["sensor"]["lowpass_hz"]


def _impacts(noise: float, seed: int):
    """Force-state samples of 8 half-sine impacts, the force a power of the penetration plus
    white noise of `noise` (what no static function of the state explains)."""
    from stiffnet.discovery.samples import ContactSamples

    t = np.tile(np.linspace(0.05, np.pi - 0.05, 40), 8)
    x, v = np.sin(t), np.cos(t)
    f = x**1.6 + noise * np.random.default_rng(seed).standard_normal(t.size)
    return ContactSamples("r", x, v, f, np.repeat(np.arange(1, 9), 40), 0.0, 1.0)


def _chain_rule_readings(evidence, monkeypatch, own_noise: float, shared_noise: float):
    """Stand-in readings of 8 rows with their samples: a chain fitted on rows 0, 4 and 7,
    kept by row 7 only; through the shared chain the force carries `shared_noise`, as read
    alone (row 7 through its own chain, the others as recorded) `own_noise`."""
    chain = {"lowpass_hz": 135.0, "lowpass_order": 2, "source": "fitted"}

    def reading(item):
        rec, row, sheet = item
        out = {"recording": row.recording, "ok": True, "contact_r2": 0.99,
               "contact_damping_ratio": 0.0, "exponent": 1.0, "sensor": None}  # fmt: skip
        if sheet is None:  # its own chain fitted: applied on every one, kept by row 7
            kept = rec == 7
            out.update(sensor={**chain, "applied": True}, _kept=kept, exponent=1.1 if kept else 1.7,
                       _samples=_impacts(own_noise, rec))  # fmt: skip
        elif sheet == evidence.AS_RECORDED:
            out.update(exponent=1.7, _samples=_impacts(own_noise, rec))
        else:
            out.update(sensor={**sheet, "source": "data sheet", "applied": True}, exponent=1.05,
                       _samples=_impacts(shared_noise, 100 + rec))  # fmt: skip
        return out

    monkeypatch.setattr(evidence, "_contact_law_task", reading)


def test_a_shared_chain_the_records_refute_is_no_sensors_and_they_are_read_as_recorded(
    monkeypatch,
):
    """The discovery's rule on the evidence (stand-in readings): the shared chain, undone on
    every row, leaves ten times the unexplained force of the rows' own readings and one of
    the three fitted rows kept its chain: every row is read as recorded (the exponent of the
    rows as recorded, 1.7, not the shared chain's 1.05), the chains still seed
    sensor_dynamics as before (identified, not undone), and the summary says why. On main the shared
    chain was undone on the five others."""
    from types import SimpleNamespace

    from stiffnet.measurement import evidence

    _chain_rule_readings(evidence, monkeypatch, own_noise=0.01, shared_noise=0.1)
    rows = [SimpleNamespace(recording=f"r{i}", sensor_sheet=lambda: None) for i in range(8)]
    per = evidence.contact_law_per_recording(SimpleNamespace(recording=lambda i: i), rows)
    assert not any(p.get("chain_shared") for p in per)
    assert all(p["chain_refuted"]["fitted_on"] == ["r0", "r4", "r7"] for p in per)
    assert all(p["exponent"] == 1.7 for p in per)
    # the chains stay as identified, not undone: sensor_dynamics' start, one vote per row
    assert all(p["sensor"]["applied"] is False for p in per)
    assert [p["sensor"]["source"] for p in per].count("fitted") == 3
    assert all(not any(k.startswith("_") for k in p) for p in per)  # samples stay inside
    ev = evidence.contact_evidence(per)
    assert ev["exponent"] == 1.7 and ev["supports"] == ["hertz_contact"]
    assert ev["sensor"]["lowpass_hz"] == 135.0 and ev["sensor"]["n"] == 8
    assert ev["chain_refuted"]["chain"]["lowpass_hz"] == 135.0
    unexplained = ev["chain_refuted"]["unexplained_shared"] / ev["chain_refuted"]["unexplained_own"]
    assert unexplained > 10
    assert "read as recorded" in ev["summary"] and "135 Hz low-pass" in ev["summary"]


def test_a_shared_chain_that_reads_the_records_better_stays(monkeypatch):
    """The mirror case: through the shared chain the force is the clean function of the state
    and as read alone it is not: the shared chain is undone on the five others, as before."""
    from types import SimpleNamespace

    from stiffnet.measurement import evidence

    _chain_rule_readings(evidence, monkeypatch, own_noise=0.1, shared_noise=0.01)
    rows = [SimpleNamespace(recording=f"r{i}", sensor_sheet=lambda: None) for i in range(8)]
    per = evidence.contact_law_per_recording(SimpleNamespace(recording=lambda i: i), rows)
    assert [p["recording"] for p in per if p.get("chain_shared")] == ["r1", "r2", "r3", "r5", "r6"]
    assert not any(p.get("chain_refuted") for p in per)
    assert all(not any(k.startswith("_") for k in p) for p in per)
    assert "undone as shared on the other 5" in evidence.contact_evidence(per)["summary"]

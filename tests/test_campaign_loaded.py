"""One campaign object through compare -> diagnose -> evaluate: each recording read once,
the predictor run once per recording and model."""

from __future__ import annotations

import pytest
from campaign_helpers import without_beta

from stiffnet.campaign import (
    LoadedCampaign,
    ManifestRow,
    load_campaign,
    simulate_campaign,
    write_manifest,
)
from stiffnet.measurement.compare import compare_campaign
from stiffnet.measurement.diagnose import diagnose_campaign
from stiffnet.measurement.evaluate import evaluate_campaign


@pytest.fixture(scope="module")
def campaign(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("loaded")
    rows = [
        ManifestRow(recording=f"recordings/r{b}.csv", fs_hz=1000, natural_frequency_hz=9.48,
                    frequency_ratio=w, amplitude=1.9, gap=e, damping_ratio=0.02, beta=b,
                    duration_s=2.0, noise=0.02)
        for b, w, e in ((10, 1.05, 2.8), (25, 1.1, 2.0), (45, 1.08, 2.4))
    ]  # fmt: skip
    write_manifest(tmp / "plan.csv", rows)
    camp = simulate_campaign(tmp / "plan.csv", tmp / "c", [])
    return camp, without_beta(camp, tmp / "field")


def _count_predictions(monkeypatch):
    from serving.predictor import Predictor

    calls = []
    original = Predictor.predict

    def counting(self, *a, **k):
        calls.append(k.get("source"))
        return original(self, *a, **k)

    monkeypatch.setattr(Predictor, "predict", counting)
    return calls


def test_each_recording_is_read_once_and_predicted_once(campaign, monkeypatch):
    calls = _count_predictions(monkeypatch)
    camp = LoadedCampaign.of(load_campaign(campaign[0]))
    assert LoadedCampaign.of(camp) is camp
    compare_campaign(camp)
    diagnose_campaign(camp, effects=[])
    evaluate_campaign(camp)
    evaluate_campaign(camp)
    assert camp.reads == len(camp.rows)
    assert sorted(calls) == sorted(r.recording for r in camp.rows)  # the predictor ran once


def test_field_campaign_shares_the_predictor_between_diagnose_and_evaluate(campaign, monkeypatch):
    calls = _count_predictions(monkeypatch)
    camp = LoadedCampaign.of(load_campaign(campaign[1]))
    d = diagnose_campaign(camp, effects=[])  # β of each recording from the model's estimate
    assert d["nuisances"]["estimated"]["beta"]
    evaluate_campaign(camp, require_beta=False)
    assert camp.reads == len(camp.rows)
    assert len(calls) == len(camp.rows)


def test_a_plain_campaign_gives_the_same_diagnosis(campaign):
    plain = diagnose_campaign(load_campaign(campaign[0]), effects=[])
    loaded = diagnose_campaign(LoadedCampaign.of(load_campaign(campaign[0])), effects=[])
    for key in ("baseline_per_recording", "noise_floor_per_recording", "verdict"):
        assert plain[key] == loaded[key]


def test_analog_effects_are_simulated_faster_with_a_lead_in():
    """A mounted sensor is analog: its campaign simulation runs at 8x the logger's rate and
    drops a lead-in long enough for the high-pass to settle (7 time constants)."""
    import math

    from stiffnet.campaign.simulate import ANALOG_OVERSAMPLING, lead_in_seconds, oversampling
    from stiffnet.effects.registry import effect_class

    sensor = effect_class("sensor_dynamics")
    assert oversampling([]) == 1 and lead_in_seconds([]) == 0.0
    assert oversampling([effect_class("contact_damping")()]) == 1
    assert oversampling([sensor()]) == ANALOG_OVERSAMPLING == 8
    assert lead_in_seconds([sensor(highpass_hz=0.0)]) == pytest.approx(0.1)
    assert lead_in_seconds([sensor(highpass_hz=0.1)]) == pytest.approx(7 / (2 * math.pi * 0.1))

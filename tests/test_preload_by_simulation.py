"""A restraint's preload, found by simulating the campaign where the maps cannot resolve it.

The campaigns are the example manifest's eight rows simulated with a user effect of
``tests/unknown_contact_laws.py`` (a power law, n = 2, secant beta at 0.5 mm, with and
without a compression before first touch) and written in g, so model lengths are mm and
the user's law is ``learned_contact`` with ``d_r`` 0.5 and ``preload`` its compression.
"""

from __future__ import annotations

import numpy as np
import pytest
import unknown_contact_laws as laws
from test_learned_law_diagnose import batch_campaign

from stiffnet.discovery.law import DiscoveredLaw
from stiffnet.effects.learned_contact import LearnedContact, learned_contact_force
from stiffnet.measurement.noise_floor import noise_floor, recording_floors
from stiffnet.measurement.preload_by_simulation import preload_applies, preload_by_simulation
from stiffnet.measurement.target import FIT_SETTINGS_NUMERICAL, CampaignTarget, measured_statistics

#: The law as the maps read it: the user's power law, no preload.
POWER = {"exponent": 2.0, "reference_penetration": 0.5}


def test_a_preload_is_swept_only_on_a_law_without_one_or_a_face():
    assert preload_applies(POWER)
    assert not preload_applies({**POWER, "preload": 0.05})
    assert not preload_applies({**POWER, "face_mass": 0.3})


def test_a_power_laws_preload_is_the_restraints_compression():
    """``learned_contact``'s preload is a compression before touch: the user's preloaded power
    law ``k_p (delta + pre)**n`` is the learned law with d_r = d0, the same numbers, and the law
    reports the step at touch, keeps its preload when referred to the manifest's beta and
    writes the compression into its equation."""
    d, v = np.linspace(-0.1, 0.9, 11), np.zeros(11)
    user = laws.PreloadedPowerLawContact(exponent=2.0, d0=0.5, pre=0.1)
    batch = type("B", (), {"beta": np.full(11, 30.0)})()
    expected = np.where(d > 0, user.elastic_contact(d, user.params.model_dump(), batch), 0.0)
    learned = learned_contact_force(d, v, 30.0, {**LearnedContact().params.model_dump(),
                                                 **POWER, "preload": 0.1})  # fmt: skip
    np.testing.assert_allclose(learned, expected, rtol=1e-12)
    law = DiscoveredLaw(("power",), {**LearnedContact().params.model_dump(), **POWER, "knee": 0.0},
                        {}, ("a", "b"), (30.0, 60.0), (None, None), (1.0, 1.0), 0.99, 0.98,
                        (), new_terms=("power",)).with_preload(0.1)  # fmt: skip
    assert law.terms == ("power", "preload") and law.new_terms == ("power", "preload")
    assert law.coefficient("preload", 30.0) == pytest.approx(30.0 * 0.5 * 0.2**2)
    assert "0.5 ((delta + 0.1)/0.5)^2" in law.equation and "compressed" in law.words
    referred = law.referred_to([60.0, 120.0])  # the secant at another penetration
    assert referred.params["preload"] == 0.1
    assert referred.params["reference_penetration"] != 0.5


def _scored(folder, effects):
    camp = batch_campaign(folder, effects, noise=0.03, duration_s=2.0)
    rows = list(camp.rows)
    measured, lengths, signals = measured_statistics(camp, rows, False)
    target = CampaignTarget(rows, measured, lengths, [], 0, False)
    settings = FIT_SETTINGS_NUMERICAL
    at_law = np.asarray(target.per_recording([LearnedContact(**POWER)], settings))
    info = noise_floor(signals, rows, settings.periods, False)
    floor = recording_floors(info, signals, rows, settings.periods)
    return preload_by_simulation(target, rows, [], POWER, at_law, floor, settings)


@pytest.mark.slow
def test_a_preload_the_maps_miss_is_found_by_simulation_and_none_on_a_plain_power_law(tmp_path):
    """A power law set 0.15 mm into its stop (the force at touch 9 % of the secant's at d0)
    simulated with the law the maps read (its exponent, no preload): the sweep names the
    preload within 15 % and it passes the tests of an effect; on the same power law without a
    preload the sweep's best point is refused."""
    found = _scored(tmp_path / "pre", [laws.PreloadedPowerLawContact(exponent=2.0, d0=0.5,
                                                                     pre=0.15)])  # fmt: skip
    assert found["significant"], found["significance"]
    assert found["preload"] == pytest.approx(0.15, rel=0.15)
    assert found["objective_preload"] < found["objective_law"]
    plain = _scored(tmp_path / "plain", [laws.PowerLawContact(exponent=2.0, d0=0.5)])
    assert not plain["significant"], plain

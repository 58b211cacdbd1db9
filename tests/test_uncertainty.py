"""Recording-level aggregation, per-trajectory conformal intervals and the alarm."""

import numpy as np
import pytest

from stiffnet.errors import StiffnetError
from stiffnet.uncertainty import aggregate_windows, conformal_quantile, normalized_scores
from stiffnet.uncertainty.alarm import (
    AlarmReference,
    calibrate_thresholds,
    fit_embedding_reference,
    load_alarm,
    recording_checks,
    save_alarm,
)


def test_aggregate_windows_scale_is_model_plus_disagreement():
    proba = np.array([[0.0, 1.0], [0.0, 1.0], [0.0, 1.0], [0.9, 0.1]])
    lb = np.array([1.0, 2.0, 3.0, 50.0])  # the last window says no contact: left out
    est = aggregate_windows(proba, lb, np.full(4, np.log(0.5)), no_contact=0)
    assert est.label == 1 and est.log_beta == pytest.approx(2.0)
    assert est.scale == pytest.approx(np.sqrt(0.25 + 2.0 / 3.0))
    assert est.probabilities == pytest.approx([0.225, 0.775])
    nc = aggregate_windows(np.array([[0.8, 0.2], [0.7, 0.3]]), np.zeros(2), None, 0)
    assert nc.label == 0 and nc.log_beta is None and nc.scale is None
    # without a scale output the model's own part is 1
    assert aggregate_windows(proba[:2], lb[:2], None, 0).scale == pytest.approx(np.sqrt(1.25))


def _synthetic_model(n_traj, rng, windows=4):
    """Trajectories whose windows share an error (correlated), of a known per-trajectory size."""
    y = rng.uniform(np.log(5), np.log(100), n_traj)
    s = rng.uniform(0.02, 0.3, n_traj)  # how hard each trajectory is; the model knows it
    bias = rng.normal(0, 1, n_traj) * s
    win = y[:, None] + bias[:, None] + rng.normal(0, 0.3, (n_traj, windows)) * s[:, None]
    return y, s, win


def test_per_trajectory_normalised_conformal_covers_new_recordings():
    rng = np.random.default_rng(0)
    y, s, win = _synthetic_model(600, rng)
    proba = np.tile([0.0, 1.0], (4, 1))
    est = [
        aggregate_windows(proba, w, np.log(si) * np.ones(4), 0)
        for w, si in zip(win, s, strict=True)
    ]
    q = conformal_quantile(
        normalized_scores([e.log_beta for e in est], [e.scale for e in est], y), 0.9
    )
    y2, s2, win2 = _synthetic_model(6000, rng, windows=8)  # longer recordings than training
    est2 = [aggregate_windows(np.tile([0.0, 1.0], (8, 1)), w, np.log(si) * np.ones(8), 0)
            for w, si in zip(win2, s2, strict=True)]  # fmt: skip
    covered = [abs(e.log_beta - t) <= q * e.scale for e, t in zip(est2, y2, strict=True)]
    assert 0.88 <= np.mean(covered) <= 0.94
    # wide where the model is unsure, narrow where it is sure
    half = np.array([q * e.scale for e in est2])
    assert np.median(half[s2 > 0.25]) > 3 * np.median(half[s2 < 0.05])
    # and it holds on the hard recordings too, where one width for all under-covers
    hard = s2 > 0.25
    assert np.mean(np.array(covered)[hard]) >= 0.85
    q_win = conformal_quantile((win - y[:, None]).ravel(), 0.9)
    fixed = np.array([abs(e.log_beta - t) <= q_win for e, t in zip(est2, y2, strict=True)])
    assert fixed[hard].mean() < 0.8


def test_conformal_quantile_rank_and_guards():
    assert conformal_quantile(np.arange(1, 10), 0.9) == 9.0  # ceil(10 * 0.9) = 9th of 9
    assert conformal_quantile(np.arange(1, 5), 0.9) == np.inf
    with pytest.raises(ValueError):
        conformal_quantile([1.0], 1.5)
    with pytest.raises(ValueError):
        normalized_scores([0.0], [0.0], [1.0])


def test_thresholds_flag_at_most_the_target_in_distribution():
    rng = np.random.default_rng(1)
    cal = {"a": rng.normal(size=2000), "b": rng.exponential(size=2000)}
    cal["b"][:100] = np.nan  # a check that does not apply to some units
    th, rate = calibrate_thresholds(cal, 0.05)
    assert 0.04 <= rate <= 0.05
    fresh_a, fresh_b = rng.normal(size=20000), rng.exponential(size=20000)
    fresh = np.mean((fresh_a > th["a"]) | (fresh_b > th["b"]))
    assert fresh == pytest.approx(0.05, abs=0.01)


def test_embedding_alarm_flags_far_recordings_and_round_trips(tmp_path):
    rng = np.random.default_rng(2)
    train = rng.normal(size=(3000, 6)) * [1, 2, 3, 1, 1, 5] + 10
    emb, center, scale = fit_embedding_reference(train, 1000, rng)
    ref = AlarmReference(thresholds={}, embeddings=emb, center=center, scale=scale, k=10)
    inside = rng.normal(size=(400, 6)) * [1, 2, 3, 1, 1, 5] + 10
    est = aggregate_windows(np.tile([0.0, 1.0], (1, 1)), np.zeros(1), None, 0)
    cal = {"embedding": ref.embedding_scores(inside)}
    ref.thresholds, _ = calibrate_thresholds(cal, 0.04)
    far = inside[:4] + [0, 0, 0, 8, 0, 0]  # 8 standard deviations off in one direction
    hit = ref.evaluate(recording_checks(est, ref.embedding_scores(far)))
    assert hit["flag"] and hit["fired"] == ["embedding"]
    ok = ref.evaluate(recording_checks(est, ref.embedding_scores(inside[:4])))
    assert not ok["flag"]

    path = tmp_path / "m.alarm.npz"
    save_alarm(path, ref)
    back = load_alarm(path)
    assert back.thresholds == ref.thresholds
    np.testing.assert_allclose(back.embedding_scores(far), ref.embedding_scores(far))
    (tmp_path / "x.npz").write_bytes(b"not a zip")
    with pytest.raises(StiffnetError, match="not a readable alarm reference") as info:
        load_alarm(tmp_path / "x.npz")
    assert "\n" not in str(info.value)


NAMES, EDGES = ["no_contact", "soft", "medium", "hard", "very_hard"], [5, 15, 35, 60, 100]


def test_restoring_force_class_share_is_the_log_share_outside_the_models_class():
    from stiffnet.uncertainty.alarm_verdict import restoring_force_class_share as share

    rf = {"class": "medium", "beta_interval": [31.6, 35.3], "contact_r2": 0.997}
    # hard (35-60) against [31.6, 35.3]: only log(35.3 / 35) of log(35.3 / 31.6) inside
    outside = 1 - np.log(35.3 / 35) / np.log(35.3 / 31.6)
    assert share("hard", rf, NAMES, EDGES) == pytest.approx(outside)
    assert share("medium", rf, NAMES, EDGES) == pytest.approx(1 - outside)  # the sliver above 35
    assert share("very_hard", rf, NAMES, EDGES) == 1.0
    # the outer classes are open-ended: an interval beyond 100 is inside very_hard
    assert share("very_hard", {**rf, "beta_interval": [90.0, 130.0]}, NAMES, EDGES) == 0.0
    assert share("soft", {**rf, "beta_interval": [3.0, 12.0]}, NAMES, EDGES) == 0.0
    # no evidence: a loose fit, a refusal, no contact either side, edges of other classes
    assert share("hard", {**rf, "contact_r2": 0.9}, NAMES, EDGES) is None
    assert share("hard", {**rf, "class": None}, NAMES, EDGES) is None
    assert share("no_contact", rf, NAMES, EDGES) is None
    assert share("hard", {**rf, "class": "no_contact"}, NAMES, EDGES) is None
    assert share("hard", rf, NAMES, EDGES[:-1]) is None


def test_a_class_both_readings_leave_open_toward_the_checks_class_is_flagged():
    """The Hunt-Crossley loop's two silent misses: beta 15 read 13.5 soft [12.0, 15.1] against
    the check's [14.0, 26.8] (0.89 of it medium, below the 0.9 of restoring_force_class), and
    beta 61 read 57.2 hard [51.5, 63.5] against [52.7, 70.4] (0.55 very hard)."""
    from serving.verdict import rule_checks

    model = {"class_names": NAMES, "class_edges": EDGES, "priors": None}
    quiet = {"flag": False, "fired": [], "scores": {}, "thresholds": {}}

    def fired(cls, interval, check):
        rf = {"class": "x", "beta_interval": check, "contact_r2": 0.99, "beta": 1.0}
        return rule_checks(quiet, cls, interval, rf, model, 1000.0, 9.48)["fired"]

    assert fired("soft", [12.0, 15.1], [14.0, 26.8]) == ["class_contested"]
    assert fired("hard", [51.5, 63.5], [52.7, 70.4]) == ["class_contested"]
    # the model's interval stays inside its class: it excludes the other class on its own
    assert fired("soft", [12.0, 14.9], [14.0, 26.8]) == []
    # most of the check's interval in the model's class (a right beta 55 read 55.8 [51.4,
    # 60.6] against [50.3, 68.8]: 0.44 outside), or inside it
    assert fired("hard", [51.4, 60.6], [50.3, 68.8]) == []
    assert fired("hard", [45.0, 62.0], [46.0, 58.0]) == []
    # wholly outside: restoring_force_class's (and the disjoint intervals' restoring_force)
    assert fired("soft", [12.0, 15.1], [16.0, 26.8]) == ["restoring_force", "restoring_force_class",
                                                         "class_contested"]  # fmt: skip
    # a loose fit is no evidence
    rf = {"class": "medium", "beta_interval": [14.0, 26.8], "contact_r2": 0.9, "beta": 1.0}
    assert rule_checks(quiet, "soft", [12.0, 15.1], rf, model, 1e3, 9.48)["fired"] == []


def test_a_class_near_an_edge_no_close_reading_confirms_is_flagged():
    """contact_damping's draw 15 of the robustness benchmark, wrong and silent before the check:
    beta 16.0 (medium) read 15.6 soft [9.9, 25.1], the cross-check's law explaining 91 % of
    the contact force (< 0.95: no evidence either way). 0.55 of the model's interval (in log
    beta) lies above 15, beyond the shipped 0.35: class_unverified fires. The same answer with
    a close-fitting reading, or an interval inside its class, stays quiet."""
    from serving.verdict import rule_checks
    from stiffnet.uncertainty.unverified_class import (
        CLASS_UNVERIFIED,
        unverified_class_settings,
        unverified_class_share,
    )

    model = {"class_names": NAMES, "class_edges": EDGES, "priors": None}
    quiet = {"flag": False, "fired": [], "scores": {}, "thresholds": {}}
    loose = {"class": "soft", "beta": 3.85, "beta_interval": [2.62, 5.67], "contact_r2": 0.91}
    share = unverified_class_share("soft", [9.9, 25.1], loose, NAMES, EDGES)
    assert share == pytest.approx(np.log(25.1 / 15) / np.log(25.1 / 9.9))
    assert unverified_class_settings().outside_share_min == 0.35
    res = rule_checks(quiet, "soft", [9.9, 25.1], loose, model, 1000.0, 9.48)
    assert res["fired"] == [CLASS_UNVERIFIED] and res["flag"]
    assert "the model's guess alone" in res["message"]
    # a refusal confirms nothing either
    refused = {"class": None, "beta": None, "beta_interval": None, "reason": "no meaningful fit"}
    assert rule_checks(quiet, "soft", [9.9, 25.1], refused, model, 1e3, 9.48)["fired"] == [
        CLASS_UNVERIFIED
    ]
    # below the threshold: 0.30 of damping_and_sensor's draw 22, medium [17.1, 47.3] (wrong),
    # is not beyond it (the calibration draws' right answers set it)
    assert unverified_class_share("medium", [17.1, 47.3], loose, NAMES, EDGES) < 0.35
    assert rule_checks(quiet, "medium", [17.1, 47.3], loose, model, 1e3, 9.48)["fired"] == []
    # a close reading in the model's class confirms it; the checks comparing the two readings
    # judge a close one (class_contested, restoring_force_class), this one does not apply
    close = {"class": "soft", "beta": 12.0, "beta_interval": [10.0, 14.0], "contact_r2": 0.99}
    res = rule_checks(quiet, "soft", [9.9, 25.1], close, model, 1e3, 9.48)
    assert res["fired"] == [] and CLASS_UNVERIFIED not in res["scores"]
    # an ideal rig's answer: the interval inside its class, nothing to confirm
    assert rule_checks(quiet, "soft", [8.0, 14.0], loose, model, 1e3, 9.48)["fired"] == []
    # no class range to judge
    assert unverified_class_share("no_contact", [1.0, 2.0], loose, NAMES, EDGES) is None


def test_both_physical_readings_on_one_side_outvote_a_class_the_model_leaves_open():
    """The rule on analytic inputs: it applies only where the geometric and the
    restoring-force classes lie on one side of the class answered, and scores the share (in
    log beta) of the model's interval outside its class."""
    from stiffnet.uncertainty.outvoted_class import (
        outvoted_class_settings,
        outvoted_class_share,
        readings_side,
    )

    names = NAMES[1:]
    assert readings_side("hard", ["medium", "soft"], names) == -1
    assert readings_side("soft", ["medium", "very_hard"], names) == 1
    assert readings_side("hard", ["medium", "very_hard"], names) == 0  # split
    assert readings_side("hard", ["medium", "hard"], names) == 0  # one agrees with the model
    assert readings_side("hard", ["medium", None], names) == 0  # a refusal
    assert readings_side("hard", ["medium", "no_contact"], names) == 0

    rf = {"class": "medium", "beta": 20.0, "beta_interval": [12.0, 33.0], "contact_r2": 0.8}
    # [20, 80] read hard (35-60): log(35/20) below, log(80/60) above, over log(80/20)
    share = outvoted_class_share("hard", [20.0, 80.0], "soft", rf, NAMES, EDGES)
    assert share == pytest.approx((np.log(35 / 20) + np.log(80 / 60)) / np.log(4))
    # an interval inside its class: the model placed beta there on its own
    assert outvoted_class_share("hard", [40.0, 55.0], "soft", rf, NAMES, EDGES) == 0.0
    # harder readings: only the part above the class counts (medium [30, 40]: 35-40)
    hard_rf = {**rf, "class": "very_hard"}
    share = outvoted_class_share("medium", [30.0, 40.0], "hard", hard_rf, NAMES, EDGES)
    assert share == pytest.approx(np.log(40 / 35) / np.log(40 / 30))
    # no vote: readings split, one missing or agreeing with the model, no interval
    assert outvoted_class_share("hard", [20.0, 80.0], "very_hard", rf, NAMES, EDGES) is None
    assert outvoted_class_share("hard", [20.0, 80.0], None, rf, NAMES, EDGES) is None
    assert outvoted_class_share("medium", [20.0, 80.0], "soft", rf, NAMES, EDGES) is None
    assert outvoted_class_share("hard", None, "soft", rf, NAMES, EDGES) is None
    assert outvoted_class_share("no_contact", [1.0, 2.0], "soft", rf, NAMES, EDGES) is None
    assert outvoted_class_share("hard", [20.0, 80.0], "soft", rf, NAMES, EDGES[:-1]) is None
    assert outvoted_class_settings().outside_share_min == 0.05


def test_an_answer_both_physical_readings_place_in_a_softer_class_is_flagged():
    """damping_and_sensor's draw 20 of the robustness benchmark (a damped contact behind a
    sensor chain), wrong and silent before the check: beta 27.4 (medium) read 43.1 hard
    [31.3, 59.5]; the geometric cross-check medium, the restoring-force one medium 33.3
    [22.3, 49.7] at R2 0.91 (a loose fit: the comparing checks do not apply, and 0.17 of the
    model's interval outside hard is under class_unverified's 0.35). Both physical readings
    lie below hard and the model's interval leaves hard: class_outvoted fires. A right answer
    the readings split on, or whose interval stays inside its class, stays quiet."""
    from serving.verdict import rule_checks
    from stiffnet.uncertainty.outvoted_class import CLASS_OUTVOTED

    model = {"class_names": NAMES, "class_edges": EDGES, "priors": None}
    quiet = {"flag": False, "fired": [], "scores": {}, "thresholds": {}}
    rf = {"class": "medium", "beta": 33.3, "beta_interval": [22.3, 49.7], "contact_r2": 0.91}
    res = rule_checks(quiet, "hard", [31.3, 59.5], rf, model, 1e3, 9.48, geometric_class="medium")
    assert res["fired"] == [CLASS_OUTVOTED] and res["flag"]
    assert res["scores"][CLASS_OUTVOTED] == pytest.approx(np.log(35 / 31.3) / np.log(59.5 / 31.3))
    assert "against both readings" in res["message"]
    # without the geometric reading (the log's points) the check does not apply
    res = rule_checks(quiet, "hard", [31.3, 59.5], rf, model, 1e3, 9.48)
    assert res["fired"] == [] and CLASS_OUTVOTED not in res["scores"]
    # the geometric reading hard (with the model): no vote, quiet
    res = rule_checks(quiet, "hard", [31.3, 59.5], rf, model, 1e3, 9.48, geometric_class="hard")
    assert res["fired"] == []
    # damping_and_sensor's draw 18 at seed offset 2000, right: beta 91.7 read 90.2 very_hard
    # [70.0, 117.1], both readings hard (39.7 [8.0, 210] at R2 0.59): the interval stays in
    # very_hard, the model placed beta there on its own
    loose = {"class": "hard", "beta": 39.7, "beta_interval": [8.0, 210.0], "contact_r2": 0.59}
    res = rule_checks(quiet, "very_hard", [70.0, 117.1], loose, model, 1e3, 9.48,
                      geometric_class="hard")  # fmt: skip
    assert res["fired"] == [] and res["scores"][CLASS_OUTVOTED] == 0.0


#: The shipped models' training world, the parts the reference_penetration check reads
#: (the card's ``data.priors``): forcing amplitude and the Hertz contact's reference penetration.
HERTZ_WORLD = {
    "sweep": {"amplitude": [0.2, 2.0]},
    "effects": [{"name": "hertz_contact", "probability": 0.12,
                 "params": {"reference_penetration": [0.1, 2.0]}}],
}  # fmt: skip


def _hertz_check(interval, exponent=1.48, r2=0.9996, scale=0.227):
    return {"class": "hard", "beta": float(np.sqrt(interval[0] * interval[1])),
            "beta_interval": interval, "exponent": exponent, "contact_r2": r2,
            "penetration_over_table": scale}  # fmt: skip


def test_a_hertz_class_the_record_does_not_determine_is_flagged():
    """hertz_contact's draw 0 of the robustness benchmark, wrong and silent before the check:
    beta 86.1 (delta_ref 0.49) read 51.8 hard [42.5, 63.2], the cross-check 42.9 [37.1, 49.6]
    at exponent 1.48, R2 0.9996, its median peak penetration 0.227 of the table's amplitude
    (0.119 model lengths at the draw's a = 0.526: both read the secant there). Over the training
    world's delta_ref 0.1-2.0 and a 0.2-2.0 the record allows beta from
    37.1 (0.1 / (0.227 x 2.0))^0.48 to 49.6 (2.0 / (0.227 x 0.2))^0.48, 0.81 of it outside
    hard: the check fires and the flagged interval spans it, 86.1 included."""
    from serving.verdict import rule_checks, widened_interval
    from stiffnet.uncertainty.reference_penetration import (
        REFERENCE_PENETRATION,
        reference_penetration_settings,
        reference_penetration_share,
        reference_penetration_span,
    )

    model = {"class_names": NAMES, "class_edges": EDGES, "priors": HERTZ_WORLD}
    quiet = {"flag": False, "fired": [], "scores": {}, "thresholds": {}}
    rf = _hertz_check([37.1, 49.6])
    lo, hi = reference_penetration_span(rf, HERTZ_WORLD)
    assert lo == pytest.approx(37.1 * (0.1 / (0.227 * 2.0)) ** 0.48)
    assert hi == pytest.approx(49.6 * (2.0 / (0.227 * 0.2)) ** 0.48)
    share = reference_penetration_share("hard", rf, HERTZ_WORLD, NAMES, EDGES)
    assert share == pytest.approx(1 - np.log(60 / 35) / np.log(hi / lo))
    assert share > reference_penetration_settings().outside_share_min == 0.5
    res = rule_checks(quiet, "hard", [42.5, 63.2], rf, model, 872.2, 9.48)
    assert res["fired"] == [REFERENCE_PENETRATION] and res["flag"]
    assert "reference penetration the record does not carry" in res["message"]
    wide, said = widened_interval([42.5, 63.2], rf, model)
    assert wide == pytest.approx([lo, hi]) and wide[0] < 86.1 < wide[1]
    assert "reference penetrations" in said
    # a stiff Hertz contact whose span lies mostly above 60 (the open top class): draw 11,
    # beta 91.4 read very_hard, the check [63.2, 104.4] at 0.21 of the table's amplitude
    stiff = _hertz_check([63.2, 104.4], exponent=1.52, scale=0.21)
    assert reference_penetration_share("very_hard", stiff, HERTZ_WORLD, NAMES, EDGES) < 0.5
    assert rule_checks(quiet, "very_hard", [88.8, 123.2], stiff, model, 681.6, 9.48)["fired"] == []
    # not a clearly nonlinear law: linear, below the Hertz band (1.3), or a loose fit (< 0.98)
    for kw in ({"exponent": 1.0}, {"exponent": 1.25}, {"r2": 0.97}):
        assert reference_penetration_span(_hertz_check([37.1, 49.6], **kw), HERTZ_WORLD) is None
    # a training world without Hertz contacts (the contact_law check judges the law there), or
    # without a forcing amplitude to place the penetration in model lengths
    no_hertz = {"sweep": {"amplitude": [0.2, 2.0]}, "effects": []}
    assert reference_penetration_span(rf, no_hertz) is None
    assert reference_penetration_span(rf, {**HERTZ_WORLD, "sweep": {}}) is None
    assert reference_penetration_span({**rf, "penetration_over_table": None}, HERTZ_WORLD) is None
    assert reference_penetration_share("no_contact", rf, HERTZ_WORLD, NAMES, EDGES) is None
    # known to the model's world at one reference penetration and one amplitude, the span is
    # the check's own interval
    exact = {"sweep": {"amplitude": 0.524}, "effects": [
        {"name": "hertz_contact", "params": {"reference_penetration": 0.119}}]}  # fmt: skip
    assert reference_penetration_span(rf, exact) == pytest.approx([37.1, 49.6], rel=0.01)


def test_a_hertz_reading_through_a_chain_left_on_the_map_does_not_flag_the_class():
    """sensor_dynamics' draw 22 (bench_alarm, seed offset 0): a linear contact, beta 10.1,
    behind a chain of the priors (resonance 202 Hz, low-pass 198 Hz order 4, high-pass 1.69 Hz)
    answered soft, right. The cross-check undid a chain (high-pass 2.5 Hz) but the record
    excludes neither of the priors' 91 Hz low-passes; with an onset per impact the map read
    exponent 2.05 (R2 0.982, gain 0.31 over the linear law), 0.175 of the table's amplitude.
    That exponent is partly the low-pass's, so no reference penetration is read from it:
    before, the check fired at a share of 0.63 and this right answer carried an alarm."""
    from serving.verdict import rule_checks
    from stiffnet.uncertainty.reference_penetration import (
        REFERENCE_PENETRATION,
        reference_penetration_span,
    )

    model = {"class_names": NAMES, "class_edges": EDGES, "priors": HERTZ_WORLD}
    quiet = {"flag": False, "fired": [], "scores": {}, "thresholds": {}}
    lowpasses = [{"order": 2, "hz": 90.84}, {"order": 4, "hz": 90.84}]
    sensor = {
        "applied": True,
        "resonance_hz": None,
        "highpass_hz": 2.5,
        "lowpass_not_excluded": lowpasses,
    }
    onsets = {"exponent": 2.045, "r2": 0.982, "linear_r2": 0.974}
    rf = {**_hertz_check([5.07, 12.01], exponent=1.003, r2=0.905, scale=0.175),
          "class": "soft", "beta": 7.90, "impact_onsets": onsets,
          "contact_damping_ratio": 0.0, "sensor": sensor}  # fmt: skip
    assert reference_penetration_span(rf, HERTZ_WORLD) is None
    res = rule_checks(quiet, "soft", [1.37, 825.7], rf, model, 718.1, 9.48)
    assert REFERENCE_PENETRATION not in res["fired"] and "91 Hz" in res["exponent_unread"]
    # the same map with the low-pass resolved reads as a power law: the class is a convention
    bare = {**rf, "sensor": {**sensor, "lowpass_not_excluded": []}}
    lo, hi = reference_penetration_span(bare, HERTZ_WORLD)
    assert lo < 5 and hi > 15
    fired = rule_checks(quiet, "soft", [1.37, 825.7], bare, model, 718.1, 9.48)["fired"]
    assert REFERENCE_PENETRATION in fired


def test_an_exponent_read_with_an_onset_per_impact_counts_where_the_law_does_not():
    """Recorded numbers of bench_alarm's offset-0 draws. power_law_contact draw 14 (exponent
    2.06 drawn, beta 56.1 read very_hard, wrong and silent before): the law with one onset
    reads p 1.10 at R2 0.944, which does not count; with an onset per impact p 2.09 at R2
    0.996, removing 0.86 of the misfit of the linear law with the same onsets, on a contact
    damped 0.08: outside both training bands, the contact_law check fires. contact_damping
    draw 19 (a linear Kelvin-Voigt contact, zeta 0.26 drawn, 0.36 fitted, R2 0.740 with one
    onset) reads p 1.64 at R2 0.986 per impact: the damping ceiling leaves it out."""
    from stiffnet.uncertainty.unseen_law import (
        exponent_reading,
        impact_onset_gain,
        stiffening_reasons,
        unseen_law_thresholds,
    )

    t = unseen_law_thresholds()
    power = {
        "exponent": 1.1038,
        "contact_r2": 0.94373,
        "contact_damping_ratio": 0.0768,
        "impact_onsets": {"exponent": 2.0935, "r2": 0.99629, "linear_r2": 0.97349},
    }
    assert impact_onset_gain(0.99629, 0.97349) == pytest.approx(1 - 0.00371 / 0.02651)
    p, r2, how = exponent_reading(power, t)
    assert (p, r2, how) == (2.0935, 0.99629, "an onset per impact")
    assert "2.09 (R2 0.996, an onset per impact)" in stiffening_reasons(power, t)[0]
    # the law's own reading counts first where it fits closely
    close = {**power, "exponent": 1.05, "contact_r2": 0.985}
    assert exponent_reading(close, t) == (1.05, 0.985, "the law")
    assert stiffening_reasons(close, t) == []
    # each condition of the per-impact reading
    for change in ({"r2": 0.975}, {"linear_r2": 0.9955}):
        loose = {**power, "impact_onsets": {**power["impact_onsets"], **change}}
        assert exponent_reading(loose, t) is None
    damped = {
        "exponent": 1.0,
        "contact_r2": 0.740,
        "contact_damping_ratio": 0.3590,
        "impact_onsets": {"exponent": 1.6359, "r2": 0.98594, "linear_r2": 0.70115},
    }
    assert exponent_reading(damped, t) is None and stiffening_reasons(damped, t) == []
    assert exponent_reading({**power, "impact_onsets": None}, t) is None
    off = t.model_copy(update={"impact_onset_min_r2": float("inf")})
    assert exponent_reading(power, off) is None


def test_contact_duration_excess_fires_beyond_twice_the_half_period():
    from stiffnet.uncertainty.alarm_verdict import (
        ALARM_WORDS,
        contact_duration_excess,
        with_restoring_force_checks,
    )

    assert contact_duration_excess({"duration_ratio": 2.2, "contact_r2": 0.988}) == (
        pytest.approx(np.log(1.1))
    )
    assert contact_duration_excess({"duration_ratio": 1.2, "contact_r2": 0.99}) < 0
    assert contact_duration_excess({"duration_ratio": 3.0, "contact_r2": 0.6}) is None
    assert contact_duration_excess({"duration_ratio": None, "contact_r2": 0.99}) is None
    quiet = {
        "flag": False,
        "fired": [],
        "scores": {"embedding": 1.0},
        "thresholds": {"embedding": 3.0},
    }
    refused = {"class": None, "beta_interval": None, "contact_r2": 0.988, "duration_ratio": 2.2}
    out = with_restoring_force_checks(quiet, "hard", refused, NAMES, EDGES)
    assert out["flag"] and out["fired"] == ["contact_duration"]
    assert ALARM_WORDS["contact_duration"] in out["message"]
    assert quiet["fired"] == [] and "contact_duration" not in quiet["scores"]  # not mutated
    agree = {"class": "hard", "beta_interval": [40.0, 50.0], "contact_r2": 0.99,
             "duration_ratio": 1.1}  # fmt: skip
    calm = with_restoring_force_checks(quiet, "hard", agree, NAMES, EDGES)
    assert not calm["flag"] and calm["scores"]["restoring_force_class"] == 0.0
    wrong = with_restoring_force_checks(quiet, "very_hard", agree, NAMES, EDGES)
    assert wrong["fired"] == ["restoring_force_class"]


def test_interval_behind_alarm_spans_a_close_restoring_force_interval():
    from stiffnet.uncertainty.conformal import interval_behind_alarm

    assert interval_behind_alarm([44.8, 84.0], [28.0, 33.0], 0.99, 0.95) == [28.0, 84.0]
    assert interval_behind_alarm([44.8, 84.0], [50.0, 90.0], 0.99, 0.95) == [44.8, 90.0]
    assert interval_behind_alarm([44.8, 84.0], [50.0, 60.0], 0.99, 0.95) == [44.8, 84.0]
    # a loose contact-law fit, a refusal or no model interval: the model's interval stands
    assert interval_behind_alarm([44.8, 84.0], [28.0, 33.0], 0.9, 0.95) == [44.8, 84.0]
    assert interval_behind_alarm([44.8, 84.0], None, None, 0.95) == [44.8, 84.0]
    assert interval_behind_alarm(None, [28.0, 33.0], 0.99, 0.95) is None


def test_an_unapplied_lowpass_far_below_the_prior_fires_the_sensor_fit_check():
    from stiffnet.uncertainty.alarm_verdict import unapplied_lowpass_excess, with_sensor_fit_check

    priors = {"effects": [{"name": "sensor_dynamics", "relative": {
        "lowpass_hz": {"per": "sampling_rate", "range": [0.15, 0.45]}}}]}  # fmt: skip
    fit = {"lowpass_hz": 57.7, "lowpass_order": 3, "applied": False}
    # 0.10 fs of a 718 Hz recording is 71.8 Hz: log(71.8 / 57.7) beyond it
    assert unapplied_lowpass_excess(fit, priors, 718.0) == pytest.approx(np.log(71.8 / 57.7))
    assert unapplied_lowpass_excess({**fit, "lowpass_hz": 80.0}, priors, 718.0) < 0
    assert unapplied_lowpass_excess({**fit, "applied": True}, priors, 718.0) is None
    assert unapplied_lowpass_excess({**fit, "lowpass_hz": None}, priors, 718.0) is None
    assert unapplied_lowpass_excess(fit, {"effects": []}, 718.0) is None
    assert unapplied_lowpass_excess(None, priors, 718.0) is None
    out = with_sensor_fit_check(None, fit, priors, 718.0)
    assert out["flag"] and out["fired"] == ["sensor_fit"]
    assert with_sensor_fit_check(None, {**fit, "applied": True}, priors, 718.0) is None


def test_a_refusal_for_the_sensor_fires_the_chain_refusal_check_outside_the_prior():
    from stiffnet.restoring_force.band import smoothed_contact_refusal
    from stiffnet.restoring_force.chain import SensorChain, identifiability
    from stiffnet.uncertainty.alarm_verdict import (
        SENSOR_REFUSAL_WORDS,
        UNFITTED_LOWPASS_SCORE,
        chain_refusal_excess,
        with_chain_refusal_check,
    )

    priors = {"effects": [{"name": "sensor_dynamics", "relative": {
        "lowpass_hz": {"per": "sampling_rate", "range": [0.15, 0.45]}}}]}  # fmt: skip
    # the refusals the cross-check writes for its sensor's band carry the words the rule reads
    said = identifiability(SensorChain(lowpass_hz=54.0, lowpass_order=3, contact_hz=93.0))
    assert SENSOR_REFUSAL_WORDS in said
    # a rounded pulse per period (even and odd harmonics) and no impact: smoothed away
    w = 2 * np.pi * np.arange(64 * 60) / 64
    noise = 1e-4 * np.random.default_rng(0).standard_normal(w.size)
    smooth = np.sin(w) + 0.3 * np.maximum(np.sin(w), 0) ** 4 + noise
    assert SENSOR_REFUSAL_WORDS in smoothed_contact_refusal(smooth, 64.0, 576.0, 9.48, 5.0)
    fitted = {"beta": None, "reason": said, "sensor": {"lowpass_hz": 54.0, "applied": True}}
    # 0.15 fs of a 1812 Hz recording is 271.8 Hz: the fitted 54 Hz lies log(271.8 / 54) below
    assert chain_refusal_excess(fitted, priors, 1812.0) == pytest.approx(np.log(271.8 / 54.0))
    # a low-pass inside the prior: the model was calibrated behind such chains
    assert chain_refusal_excess(fitted, priors, 300.0) < 0
    unfitted = {"beta": None, "reason": "... so beta is not identifiable from this sensor"}
    assert chain_refusal_excess(unfitted, priors, 578.0) == UNFITTED_LOWPASS_SCORE > 0
    # not a refusal for the sensor, an answer, or no prior to judge by: the check does not apply
    assert chain_refusal_excess({**fitted, "reason": "no contact"}, priors, 1812.0) is None
    assert chain_refusal_excess({**fitted, "beta": 40.0}, priors, 1812.0) is None
    assert chain_refusal_excess(fitted, {"effects": []}, 1812.0) is None
    quiet = {"flag": False, "fired": [], "scores": {}, "thresholds": {}}
    out = with_chain_refusal_check(quiet, unfitted, priors, 578.0)
    assert out["flag"] and out["fired"] == ["chain_refusal"] and "UNRELIABLE" in out["message"]
    assert not with_chain_refusal_check(quiet, fitted, priors, 300.0)["flag"]
    assert quiet["fired"] == []  # not mutated


def test_a_hertz_reading_without_a_chain_is_flagged_and_says_a_data_sheet_would_tell():
    """hertz_contact's draw 0 through rule_checks, as read (no sensor chain): the
    reference_penetration alarm fires and the alarm says that a low-pass near the contact reads
    as this exponent; with a chain undone the note goes (the exponent is read through it)."""
    from serving.verdict import rule_checks
    from stiffnet.uncertainty.reference_penetration import REFERENCE_PENETRATION

    model = {"class_names": NAMES, "class_edges": EDGES, "priors": HERTZ_WORLD}
    quiet = {"flag": False, "fired": [], "scores": {}, "thresholds": {}}
    rf = _hertz_check([37.1, 49.6])
    res = rule_checks(quiet, "hard", [42.5, 63.2], rf, model, 872.2, 9.48)
    assert REFERENCE_PENETRATION in res["fired"]
    assert "--sensor" in res["exponent_chain_unknown"]
    undone = {**rf, "sensor": {"applied": True, "lowpass_not_excluded": []}}
    res = rule_checks(quiet, "hard", [42.5, 63.2], undone, model, 872.2, 9.48)
    assert REFERENCE_PENETRATION in res["fired"] and "exponent_chain_unknown" not in res


def test_a_hertz_reading_through_a_ringing_low_pass_is_no_reference_penetration():
    """sensor_dynamics' draw 20 (bench_alarm offset 0): a linear contact behind a 140 Hz
    low-pass read as Hertz (1.59, R2 0.997) with no chain undone, its force pulling after the
    release (-27.8 free-flight scatters). The exponent is the chain's: no span; with the
    thresholds that count a chain's exponent (the benchmark's "before"), the span is read."""
    from stiffnet.uncertainty.reference_penetration import reference_penetration_span
    from stiffnet.uncertainty.unseen_law import unseen_law_thresholds

    rf = {**_hertz_check([25.3, 29.9], exponent=1.59, r2=0.997),
          "law_shape": {"toe_least_side": -27.8}}  # fmt: skip
    assert reference_penetration_span(rf, HERTZ_WORLD) is None
    counted = unseen_law_thresholds().model_copy(update={"exponent_through_left_chain": True})
    assert reference_penetration_span(rf, HERTZ_WORLD, counted) is not None
    quiet = {**rf, "law_shape": {"toe_least_side": -0.5}}  # an unseen law's side: read
    assert reference_penetration_span(quiet, HERTZ_WORLD) is not None


def _power_result(cls, interval, rf_interval, exponent, scale):
    """A result on the rig's power law (n 1.6, beta the secant at 0.4 mm): the model's class
    and interval, the cross-check's band, exponent and median peak depth over the table."""
    rf = {"beta": float(np.sqrt(rf_interval[0] * rf_interval[1])), "beta_interval": rf_interval,
          "exponent": exponent, "contact_r2": 0.998, "penetration_over_table": scale}  # fmt: skip
    return {"class": cls, "beta_interval": interval, "ood_flag": False,
            "alarm": {"flag": False, "fired": [], "scores": {}, "thresholds": {}},
            "restoring_force": rf}  # fmt: skip


def test_a_stiffening_contact_is_judged_over_the_depths_its_campaign_reaches():
    """The rig's power law behind a 250 Hz low-pass (s43, shipped CNN): beta 50 read 92.3
    very_hard [74.7, 113.9], the cross-check 103 (exponent 1.52, band [81.9, 157]) at a depth
    of 0.593 x a = 1.90, 1.13 model lengths: wrong and silent, the training world's references
    leaving 0.29 of their span outside very_hard. The campaign's impacts reach 0.094 (beta 34,
    a = 1.00) to 1.26 model lengths (beta 25, a = 1.90): over those references the record
    allows 22.3-167, and the answer's interval spanning them lies 0.49 outside its class: the
    check fires and 50 is inside. A right very_hard answer (beta 84, read 92.3 [63.3, 119],
    the cross-check 126 at 0.34 x 1.90) is widened (its span leaves the class) but not
    flagged (0.16 outside)."""
    from stiffnet.uncertainty.reference_penetration import (
        CAMPAIGN_REFERENCE,
        campaign_reference_decision,
    )

    model = {"class_names": NAMES, "class_edges": EDGES}
    results = [
        _power_result("very_hard", [74.7, 113.9], [81.9, 157.3], 1.523, 0.5931),
        _power_result("hard", [7.8, 364.9], [11.35, 23.35], 1.589, 0.0937),
        _power_result("hard", [10.6, 345.4], [42.06, 81.57], 1.532, 0.6635),
        _power_result("very_hard", [63.3, 118.7], [104.2, 179.4], 1.422, 0.34),
    ]
    amplitudes = [1.899, 1.001, 1.899, 1.899]
    out, decision = campaign_reference_decision(results, amplitudes, model)
    assert decision["references"] == pytest.approx([0.0938, 1.260], rel=1e-2)
    silent, right = out[0], out[3]
    assert CAMPAIGN_REFERENCE in silent["alarm"]["fired"] and silent["ood_flag"]
    assert decision["shares"][0] == pytest.approx(0.49, abs=0.02)
    assert silent["beta_interval"][0] < 50.0 < silent["beta_interval"][1]
    assert "reference penetrations this campaign's impacts reach" in silent["warnings"][-1]
    assert not right["alarm"]["flag"] and decision["shares"][3] < 0.35
    assert right["beta_interval"][0] < 60.0 and results[3]["beta_interval"] == [63.3, 118.7]
    # no forcing amplitudes, a linear law, or one depth read: no references, nothing judged
    for amps, res in (([None] * 4, results),
                      (amplitudes, [{**r, "restoring_force": {**r["restoring_force"],
                                                               "exponent": 1.02}}
                                    for r in results]),
                      (amplitudes[:1], results[:1])):  # fmt: skip
        same, d = campaign_reference_decision(res, amps, model)
        assert d["references"] is None and same == res

"""A mount's resonance behind a campaign's pooled low-pass, shown by a minority of the chain
fits (serving/campaign_chain.py, :func:`campaign_resonance_minority`), and the campaign read
the same way by ``predict-batch`` as by ``evaluate`` (serving/batch_prediction.py).

The stand-in readers carry what the independent rig's campaign behind a 280 Hz zeta 0.03 mount
and a 120 Hz 4th-order low-pass gave (/work/scratch/s43/chain24 probes): its recordings' fits
showed a low-pass alone at 111-134 Hz, three (fitted regardless of the gate) the resonance at
281-287 Hz with their low-pass at 120.7-121.8 Hz, one a spurious 136 Hz ring beside a 170 Hz
order-2 low-pass; the contact laws explained 0.83-0.99 of the force through the pooled 126.7 Hz
low-pass alone, 0.98-1.0 through a resonance fit's chain.
"""

from __future__ import annotations

import pytest

from serving.campaign_chain import campaign_resonance_minority, profiled_campaign_chain


def fitted(lowpass_hz, order=4, resonance_hz=None, damping=None) -> dict:
    """A chain as the check reports a fitted one."""
    return {"resonance_hz": resonance_hz, "resonance_damping": damping, "lowpass_hz": lowpass_hz,
            "lowpass_order": order, "highpass_hz": 0.0, "source": "fitted", "applied": True,
            "intervals": {}}  # fmt: skip


N = 12
#: the gate fitted the even recordings (a low-pass alone, one a spurious ring) and spared the
#: odd ones; fitted regardless, recordings 3 and 7 show the mount
GATED = [fitted(126.0 + i) if i % 2 == 0 else None for i in range(N)]
GATED[4] = fitted(170.3, 2, 136.0, 0.079)
REGARDLESS = {3: fitted(120.7, 4, 281.6, 0.028), 7: fitted(121.8, 4, 287.3, 0.029)}
POOLED = {"pooled": True, "n": N, "n_identified": 6, "stages": {},
          "reason": "one sensor chain (low-pass) pooled",
          "sensor": {"resonance_hz": 0.0, "resonance_damping": 0.0, "lowpass_hz": 126.7,
                     "lowpass_order": 4.0, "highpass_hz": "auto"}}  # fmt: skip


def mount_reader(log):
    """The contact laws' R²: high through a chain with the rig's mount, lower without it."""

    def contact_r2(i, sheet, refused_as_unexplained=False):
        log.append((i, dict(sheet)))
        res = sheet.get("resonance_hz") or 0.0
        if 270.0 < res < 300.0:
            return 0.999 if abs(sheet["lowpass_hz"] - 121.0) < 2.0 else 0.95
        return 0.93 if res else 0.97

    return contact_r2


def test_a_resonance_a_minority_of_fits_show_behind_the_lowpass_is_kept_with_its_lowpass():
    log, fitted_on = [], []

    def identify(i):
        fitted_on.append(i)
        return REGARDLESS.get(i)

    out = campaign_resonance_minority(POOLED, GATED, mount_reader(log), None, identify)
    assert fitted_on == [i for i in range(N) if i % 2]  # the gate's spared recordings only
    sheet = out["sensor"]
    assert 280.0 < sheet["resonance_hz"] < 288.0 and sheet["resonance_damping"] < 0.035
    assert sheet["lowpass_hz"] == pytest.approx(121.0, abs=1.0)  # the fit's own, not the pool's
    assert sheet["lowpass_order"] == 4 and sheet["highpass_hz"] == "auto"
    stage = out["stages"]["resonance_hz"]
    assert stage["kept"] and stage["fitted"] == [136.0, 281.6, 287.3]
    assert "kept" in out["reason"] and "3 chain fit(s)" in out["reason"]


def test_a_spurious_ring_that_reads_the_laws_worse_is_not_kept():
    log = []
    out = campaign_resonance_minority(POOLED, GATED, mount_reader(log), None, lambda i: None)
    assert out["sensor"] == POOLED["sensor"]
    assert out["stages"]["resonance_hz"]["kept"] is False
    assert "not kept" in out["reason"]


@pytest.mark.parametrize(
    "sensor",
    [
        None,  # nothing pooled
        {"resonance_hz": 220.0, "resonance_damping": 0.05, "lowpass_hz": 0.0,
         "lowpass_order": 0.0, "highpass_hz": "auto"},  # a pooled mount: profiled elsewhere
    ],
)  # fmt: skip
def test_a_pool_without_a_lowpass_or_with_a_mount_is_returned_as_it_is(sensor):
    chain = {**POOLED, "pooled": sensor is not None, "sensor": sensor}
    asked = []
    out = campaign_resonance_minority(chain, GATED, mount_reader(asked), None, asked.append)
    assert out is chain and asked == []


def test_the_campaigns_profiles_fit_the_spared_recordings_for_a_resonance():
    """:func:`profiled_campaign_chain` passes its `identify` on (``evaluate`` and
    ``predict-batch`` both give it theirs)."""
    log = []
    out = profiled_campaign_chain(POOLED, GATED, mount_reader(log), lambda i, s: None,
                                  lambda: [9.48] * N, [None] * N, None, None,
                                  REGARDLESS.get)  # fmt: skip
    assert out["stages"]["resonance_hz"]["kept"]


def test_predict_batch_pools_the_campaign_with_the_readers_evaluate_uses(monkeypatch):
    """``predict-batch``'s pooling gets the dissipation readers and the chain fitted
    regardless of the gate, as ``evaluate``'s does: one campaign, one reading."""
    import pyarrow as pa

    import serving.batch_prediction as bp

    got = {}

    def profiled(chain, sensors, contact_r2, free_damping, fns, dampings, sheets,
                 dissipation=None, identify=None):  # fmt: skip
        got.update(dissipation=dissipation, identify=identify)
        return chain

    monkeypatch.setattr(bp, "profiled_campaign_chain", profiled)
    monkeypatch.setattr(bp, "identify_regardless", lambda s, n, sh, f: ({"pooled": False}, s))
    table = pa.table({"sensor": [None, None]})
    settings = [(1000.0, 9.48, None, None, None, None)] * 2
    bp._campaign_chain(table, ["a.csv", "b.csv"], settings, object())
    assert got["dissipation"] is not None and len(got["dissipation"]) == 3
    assert callable(got["identify"])


def test_a_part_read_through_the_pooled_chain_passes_the_dissipation_on(monkeypatch, tmp_path):
    import serving.batch_prediction as bp
    from stiffnet.errors import StiffnetError

    calls = []

    def predict(file, **kwargs):
        calls.append(kwargs["penetration_dissipation"])
        raise StiffnetError("stand-in")

    monkeypatch.setattr(bp, "predict_recording", predict)
    monkeypatch.setattr(bp, "_predictor", lambda path, sha: None)
    job = bp.PartJob(0, ("a.csv", "b.csv"), ("a.csv", "b.csv"), str(tmp_path), "m", "sha",
                     ("soft",), 1000.0, 9.48, "fp", settings=((1000.0, 9.48, None, None, None,
                     {"lowpass_hz": 120.0}), (1000.0, 9.48, None, None, None, None)),
                     campaign_chain=(True, False), penetration_dissipation=True)  # fmt: skip
    bp.predict_part(job)
    assert calls == [True, None]  # only the recording read through the pooled chain


def test_behind_a_completed_chain_the_campaign_profiles_its_own_highpass_corner():
    """The recordings' own corners were fitted behind chains without the mount: where the
    campaign completed the chain, the corner is profiled over its contact laws (here best
    near no corner: the grid's lowest), not left to each recording."""
    from serving.campaign_chain import campaign_highpass

    sheet = {**POOLED["sensor"], "resonance_hz": 285.5, "resonance_damping": 0.03,
             "lowpass_hz": 120.6}  # fmt: skip

    def r2(i, at, refused_as_unexplained=False):
        return 0.999 - 0.001 * at["highpass_hz"]

    left = {**POOLED, "sensor": sheet}
    assert campaign_highpass(left, r2, [9.48] * N) is left  # each recording's own, as before
    out = campaign_highpass({**left, "completed_stage": "resonance_hz"}, r2, [9.48] * N)
    assert out["sensor"]["highpass_hz"] == pytest.approx(0.0948, rel=0.05)
    assert out["stages"]["highpass_hz"]["pooled_median"] is None

"""With workers, the single fits that need nothing of the restoring-force evidence run while it
is read (``diagnose._Run.submit_early``, below the evidence's Dask priority), and the
diagnosis is the one computed in-process, every field of it."""

from __future__ import annotations

import threading
import time

import pytest
from campaign_helpers import short_manifest

pytest.importorskip("distributed")

from stiffnet.campaign import load_campaign, simulate_campaign  # noqa: E402
from stiffnet.distributed.cluster import local_cluster  # noqa: E402
from stiffnet.effects.registry import CANONICAL  # noqa: E402
from stiffnet.measurement import diagnose  # noqa: E402

CANDIDATES = ["contact_damping", "adc", "sensor_dynamics"]
#: How long the evidence's wrapper waits for a fit task to reach the scheduler.
WAIT_S = 60.0


def _without_seconds(value):
    if isinstance(value, dict):
        return {
            k: _without_seconds(v) for k, v in value.items() if k not in ("seconds", "cpu_seconds")
        }
    if isinstance(value, list):
        return [_without_seconds(v) for v in value]
    return value


def _fit_tasks(dask_scheduler) -> list[str]:
    return [str(k) for k in dask_scheduler.tasks if str(k).startswith("_fit_task")]


def test_reads_evidence_names_the_fits_that_start_from_the_measurement():
    # sensor_dynamics starts from the evidence's shared chain, forcing_harmonics from the
    # free flights' lines (both read through CampaignTarget.observed); the others not
    assert {n for n in CANONICAL if diagnose.reads_evidence(n)} == {
        "sensor_dynamics",
        "forcing_harmonics",
    }


@pytest.mark.slow  # two diagnoses of a 4-recording campaign, one on a LocalCluster
def test_fits_beside_the_evidence_give_the_in_process_diagnosis(tmp_path, monkeypatch):
    hidden = ["contact_damping:damping_ratio=0.25"]
    path = simulate_campaign(short_manifest(tmp_path, 4, "2"), tmp_path / "c", hidden, seed=0)
    here = diagnose.diagnose_campaign(load_campaign(path), effects=CANDIDATES, inclination=False)

    evidence = diagnose.restoring_force_evidence
    seen: dict[str, list[str]] = {}

    def watched(campaign, rows, client=None):
        out = evidence(campaign, rows, client)
        # the early fits are submitted once the nuisances are profiled, the evidence
        # meanwhile on its thread: they reach the scheduler before it returns
        end = time.monotonic() + WAIT_S
        while time.monotonic() < end and not seen.get("fits"):
            seen["fits"] = client.run_on_scheduler(_fit_tasks)
            time.sleep(0.05)
        seen["thread"] = [threading.current_thread().name]
        return out

    monkeypatch.setattr(diagnose, "restoring_force_evidence", watched)
    with local_cluster(2) as cluster:
        there = diagnose.diagnose_campaign(
            load_campaign(path), effects=CANDIDATES, inclination=False,
            scheduler=cluster.scheduler_address,
        )  # fmt: skip
    assert seen["fits"], "no single fit ran beside the evidence"
    assert seen["thread"] != [threading.main_thread().name]
    assert _without_seconds(there) == _without_seconds(here)
    assert "contact_damping" in there["missing_effects"]


def test_fit_tasks_go_longest_first_by_their_planned_evaluations(tmp_path):
    """The numerical-engine fits first, then the closed-form ones by the budget their fit
    starts with (design, global stage, refinement), the largest first; the budget is the
    one fit_effect spends within."""
    from types import SimpleNamespace

    from stiffnet.measurement.fitting import (
        DEFAULT_BUDGET_NUMERICAL,
        REFINE_EVALUATIONS,
        fit_effect,
        planned_evaluations,
    )
    from stiffnet.measurement.target import CampaignTarget, measured_statistics

    path = simulate_campaign(short_manifest(tmp_path, 2, "2"), tmp_path / "c", [], seed=0)
    camp = load_campaign(path)
    measured, lengths, _ = measured_statistics(camp, camp.rows, False)
    target = CampaignTarget(list(camp.rows), measured, lengths, [], inclination=False)
    # one parameter: a 9-point design, then the bounded Brent's refinement
    assert planned_evaluations(target, "contact_damping") == 9 + REFINE_EVALUATIONS[1]
    assert planned_evaluations(target, "hertz_contact") == DEFAULT_BUDGET_NUMERICAL
    plans = {n: planned_evaluations(target, n) for n in ("gap_drift", "adc", "colored_noise")}
    fit = fit_effect(target, "gap_drift")
    assert 0 < fit["evaluations"] <= plans["gap_drift"]

    run = SimpleNamespace(target=target, budget=None, budget_numerical=None)
    names = ["contact_damping", "adc", "hertz_contact", "gap_drift", "colored_noise"]
    order, items = diagnose._Run._items(run, names, [])
    closed = sorted(
        [n for n in names if n != "hertz_contact"],
        key=lambda n: -(9 + REFINE_EVALUATIONS[1] if n == "contact_damping" else plans[n]),
    )
    assert order == ["hertz_contact", *closed]
    assert [item[1] for item in items] == order

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

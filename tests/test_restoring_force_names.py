"""One name for the restoring-force estimate: results written under the earlier names
("physical_*", "restoring_force_evidence") are still read, under today's names."""

import json

from stiffnet.cli.measurement import _read_json, diagnosis_lines


def _write(path, data):
    path.write_text(json.dumps(data))
    return path


def test_an_earlier_diagnosis_is_read_under_todays_key(tmp_path):
    old = {"baseline_discrepancy": 1.0, "ranking": [], "missing_effect": None,
           "verdict": "explained", "summary": "s",
           "restoring_force_evidence": {"summary": "the contact dissipates"}}  # fmt: skip
    data = _read_json(_write(tmp_path / "d.json", old), "diagnosis")
    assert "restoring_force_evidence" not in data
    assert data["restoring_force"] == {"summary": "the contact dissipates"}
    assert "the contact dissipates" in diagnosis_lines(data)


def test_todays_key_wins_over_an_earlier_one(tmp_path):
    both = {"baseline_discrepancy": 1.0, "ranking": [], "missing_effect": None,
            "restoring_force_evidence": {"summary": "old"},
            "restoring_force": {"summary": "new"}}  # fmt: skip
    data = _read_json(_write(tmp_path / "d.json", both), "diagnosis")
    assert data["restoring_force"] == {"summary": "new"} and len(data) == 4


def test_an_earlier_loops_rows_are_renamed(tmp_path):
    row = {"recording": "a.csv", "physical_beta": 30.0, "physical_agreement": True}
    old = {"before": {"recordings": [row]}, "after": {},
           "iterations": [{"recordings": [row], "physical": 1}]}  # fmt: skip
    data = _read_json(_write(tmp_path / "l.json", old), "loop")
    for rows in (data["before"]["recordings"], data["iterations"][0]["recordings"]):
        assert rows == [{"recording": "a.csv", "restoring_force_beta": 30.0,
                         "restoring_force_agreement": True}]  # fmt: skip
    assert data["iterations"][0]["physical"] == 1  # only the estimate's own keys are renamed

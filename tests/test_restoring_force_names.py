"""One name for the restoring-force estimate: results written under the earlier names
("physical_*", "restoring_force_evidence") are still read, under today's names."""

import json
import re
from pathlib import Path

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


#: The earlier names of the restoring-force estimate in code: a key read with ``.get`` under
#: an old name would silently give None.
_EARLIER_NAME = re.compile(
    r"\bphysical_(beta|class|agreement|reason|gap|check|interval|every)|[\"']physical[\"']"
    r"|\bPhysicalCheck\b|\bserving\.physical\b|[\"']restoring_force_evidence[\"']"
)


def test_no_module_uses_the_earlier_names():
    """Library and benchmarks (the tests feed earlier keys on purpose)."""
    root = Path(__file__).resolve().parents[1]
    found = [
        f"{path.relative_to(root)}:{i}: {line.strip()}"
        for folder in ("stiffnet", "serving", "training", "benchmarks")
        for path in sorted((root / folder).rglob("*.py"))
        for i, line in enumerate(path.read_text(encoding="utf-8").splitlines(), 1)
        if _EARLIER_NAME.search(line)
        and "_EARLIER" not in line  # the reader of earlier results maps them
        and not line.lstrip().startswith("#")
    ]
    assert not found, "use the restoring_force names:\n" + "\n".join(found)

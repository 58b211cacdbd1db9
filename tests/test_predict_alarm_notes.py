"""``stiffnet predict``'s table prints the alarm's notes the JSON carries.

An exponent read through an unknown chain, or not read at all, is said in
``alarm["exponent_chain_unknown"]`` / ``alarm["exponent_unread"]``; a person reading the
table needs them as much as a program reading the JSON.
"""

from __future__ import annotations

import io
from pathlib import Path

import pytest
from rich.console import Console

from serving.predictor import Predictor
from stiffnet.cli.predict import ALARM_NOTES, result_tables

EXAMPLE = Path(__file__).resolve().parents[1] / "examples" / "recordings" / "impact_beta45.csv"


@pytest.fixture(scope="module")
def result():
    return Predictor.load().predict_file(EXAMPLE, natural_frequency_hz=9.48)


def _printed(result) -> str:
    console = Console(width=200, record=True, file=io.StringIO())
    for part in result_tables(result, "example"):
        console.print(part)
    return console.export_text()


@pytest.mark.parametrize("key", ALARM_NOTES)
def test_each_alarm_note_is_printed(result, key):
    note = f"the note of {key}: what would resolve it"
    alarm = {**result["alarm"], key: note}
    text = _printed({**result, "alarm": alarm})
    assert "alarm note" in text and note in text


def test_no_note_no_row(result):
    alarm = {k: v for k, v in result["alarm"].items() if k not in ALARM_NOTES}
    assert "alarm note" not in _printed({**result, "alarm": alarm})

"""A campaign manifest's ``sensor`` column: the chain's data sheet, read like ``--sensor``.

The recording comes from the independent solve_ivp rig (tests/independent_rig.py) through
an analog 4th-order low-pass at 30 Hz, below its contact's frequency: given as a data sheet,
the restoring-force estimate must refuse beta in one line naming that low-pass.
"""

from __future__ import annotations

import numpy as np
import pytest

from stiffnet.campaign import load_campaign, read_manifest, write_manifest
from stiffnet.errors import StiffnetError
from stiffnet.measurement.evidence import contact_law_per_recording
from tests.independent_rig import RigRun, record

FN = 9.48
FS = 2000.0


def write(folder, header: str, lines: list[str]):
    folder.mkdir(exist_ok=True)
    (folder / "manifest.csv").write_text(header + "\n" + "\n".join(lines) + "\n")
    return folder / "manifest.csv"


def test_sensor_cell_is_the_cli_data_sheet(tmp_path):
    lines = ["a.csv,2000,lowpass_hz=30;lowpass_order=4",
             'b.csv,2000,"resonance_hz=400,resonance_damping=0.05"', "c.csv,2000,"]  # fmt: skip
    path = write(tmp_path, "recording,fs_hz,sensor", lines)
    rows = read_manifest(path)
    assert rows[0].sensor_sheet() == {"lowpass_hz": 30.0, "lowpass_order": 4.0}
    assert rows[1].sensor_sheet() == {"resonance_hz": 400.0, "resonance_damping": 0.05}
    assert rows[2].sensor is None and rows[2].sensor_sheet() is None
    again = read_manifest(write_manifest(tmp_path / "again.csv", rows))
    assert [r.sensor_sheet() for r in again] == [r.sensor_sheet() for r in rows]


@pytest.mark.parametrize(
    "cell, words",
    [
        ("lowpass=30", "unknown sensor key(s) lowpass"),
        ("lowpass_hz", "'lowpass_hz' is not KEY=VALUE"),
        ("lowpass_hz=fast", "lowpass_hz = 'fast' is not a number"),
        ("resonance_hz=400;resonance_damping=3", "resonance_damping = 3 is outside"),
        ("lowpass_hz=30;lowpass_order=2.5", "lowpass_order must be an integer"),
    ],
)
def test_a_bad_sensor_cell_is_one_line_naming_the_row(tmp_path, cell, words):
    path = write(tmp_path, "recording,fs_hz,sensor", ["a.csv,2000,", f"b.csv,2000,{cell}"])
    with pytest.raises(StiffnetError) as err:
        read_manifest(path)
    msg = str(err.value)
    assert msg.startswith(f"{path}: line 3, column sensor: data sheet: ") and words in msg, msg
    assert "\n" not in msg


def test_the_campaign_uses_the_data_sheet_and_skips_the_fit(tmp_path):
    """Independent rig, a damped contact through a 30 Hz 4th-order low-pass: the row with the
    data sheet is refused in one line naming it; the row without is read without a sheet."""
    run = RigRun(recording="r.csv", beta=30.0, fs_hz=FS, duration_s=3.0,
                 contact="kelvin_voigt", contact_zeta=0.15,
                 sensor={"lowpass_hz": 30.0, "lowpass_order": 4, "oversample": 8})  # fmt: skip
    t, acc = record(run, seed=3)
    for name in ("given.csv", "fitted.csv"):
        np.savetxt(tmp_path / name, np.column_stack([t, acc]), delimiter=",", header="t,accel",
                   comments="")  # fmt: skip
    lines = [f"given.csv,{FS},{FN},lowpass_hz=30;lowpass_order=4", f"fitted.csv,{FS},{FN},"]
    write(tmp_path, "recording,fs_hz,natural_frequency_hz,sensor", lines)
    campaign = load_campaign(tmp_path)
    given, fitted = contact_law_per_recording(campaign, campaign.rows)
    assert given["sensor"]["source"] == "data sheet" and given["sensor"]["lowpass_hz"] == 30.0
    assert not given["ok"]
    assert given["reason"].startswith("the low-pass at 30 Hz is below the contact's frequency")
    assert (fitted["sensor"] or {}).get("source") != "data sheet"  # the row without: no sheet
    assert not fitted["reason"].startswith("the low-pass at 30 Hz")

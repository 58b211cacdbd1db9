"""bench_diagnose's --timeline: each stage's CPU goes to the process that spent it (this one or
its workers), and a worker that exits takes none of it back."""

from __future__ import annotations

import subprocess
import sys
import time
from pathlib import Path
from types import SimpleNamespace

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "benchmarks"))
from stage_timeline import PERIOD_S, StageTimeline  # noqa: E402

BURN = "import time\nt = time.process_time()\nwhile time.process_time() - t < {s}: pass\n"


def _burn_here(seconds: float) -> None:
    t = time.process_time()
    while time.process_time() - t < seconds:
        pass


def _burn_in_a_child(seconds: float) -> None:
    subprocess.run([sys.executable, "-c", BURN.format(s=seconds)], check=True)
    time.sleep(0.5)  # sampled after the child is gone


def test_the_stages_split_this_process_from_its_workers():
    work = SimpleNamespace(here=_burn_here, child=_burn_in_a_child)
    timeline = StageTimeline()
    timeline.label(work, "here", lambda s: "alone")
    timeline.label(work, "child", lambda s: "on a worker")
    with timeline:
        work.here(0.6)
        work.child(0.8)
    stages = {s: (wall, own, kids) for s, wall, own, kids in timeline.stages()}
    # an interval goes to the stage running at its start, so a stage may take up to one
    # sampling period of the next one's CPU
    _, own, kids = stages["alone"]
    assert own > 0.4 and kids < PERIOD_S + 0.05
    _, own, kids = stages["on a worker"]
    # the child's CPU, kept after it exited (a live sum would fall back to 0 in the stage)
    assert kids > 0.5 and own < 0.3
    assert "| on a worker |" in timeline.table()

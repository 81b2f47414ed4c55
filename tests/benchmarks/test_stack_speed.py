"""stack_speed.py's reading of the simulator's log: the rounds per sync time of a lockstep run."""
from __future__ import annotations

from pathlib import Path


def test_rounds_per_sync_time_come_from_the_last_count_the_simulator_logged(load_benchmark, tmp_path: Path) -> None:
    stack_speed = load_benchmark("stack_speed")
    logs = tmp_path / "logs"
    logs.mkdir()
    assert stack_speed.rounds_per_sync_time(tmp_path) is None  # no simulator log
    (logs / "simulator-1.log").write_text(
        "[INFO] [1.0] [simulator]: real-time factor 4.2x (as fast as possible), t = 40.0 s; "
        "lockstep: 1000 steps, 1500 rounds with 3 participant(s)\n"
        "[INFO] [2.0] [simulator]: lockstep: 'pppbot_eval' leaves (so far: 1900 steps, 2300 rounds)\n")
    assert stack_speed.rounds_per_sync_time(tmp_path) == 1.21  # the whole run, counted as the evaluation left
    (logs / "simulator-1.log").write_text("[INFO] [1.0] [simulator]: lockstep: 'pppbot_eval' joins\n")
    assert stack_speed.rounds_per_sync_time(tmp_path) is None

"""soak.py's figures from its samples: RSS growth per sim hour after the warm-up (a fitted line, in
MB and in % of the RSS the warm-up ended with), descriptor growth and CPU share."""
from __future__ import annotations

import csv
import os
import re
import subprocess
import sys
import time

import pytest


def test_growth_fits_the_samples_after_the_warm_up(load_benchmark) -> None:
    soak = load_benchmark("soak")
    ticks = soak.TICKS
    samples = []
    for minute in range(0, 61, 5):
        # 100 MB growing 10 MB per sim hour after a warm-up of 10 min that doubled it from 50 MB;
        # a descriptor leaked every 20 min; half a core (the wall runs at 2x: 30 wall s per sim minute).
        rss = 50.0 + 5.0 * minute if minute <= 10 else 100.0 + 10.0 * (minute - 10) / 60
        samples.append((minute * 60.0, minute * 30.0, {"navigation": {
            "rss_mb": rss, "cpu_ticks": 0.5 * ticks * minute * 30.0, "fds": 18 + minute // 20}}))
    (name, figures), = soak.growth(samples, warmup_s=600.0).items()
    assert name == "navigation"
    assert figures["rss_mb_at_warmup"] == 100.0 and figures["rss_growth_mb_per_sim_hour"] == pytest.approx(10.0)
    assert figures["rss_growth_pct_per_sim_hour"] == pytest.approx(10.0)
    assert figures["fd_growth"] == 3 - 0 and figures["cpu_pct"] == pytest.approx(50.0)
    with pytest.raises(SystemExit, match="only 2 samples after the warm-up"):
        soak.growth(samples[:3], warmup_s=300.0)


GROWING = """
import sys, time
from pppbot_common.process import trace_memory_if_asked
trace_memory_if_asked("grower")
kept = []
print("ready", flush=True)
for line in sys.stdin:  # each line: keep 1000 more lists, then say so
    kept.extend([[n] for n in range(1000)])
    print("grown", flush=True)
"""


def test_traced_processes_write_snapshots_on_a_signal_and_the_growth_names_its_line(load_benchmark, tmp_path,
                                                                                       monkeypatch) -> None:
    soak = load_benchmark("soak")
    proc_stats = load_benchmark("proc_stats")
    monkeypatch.setenv("PPPBOT_TRACE_MEMORY", str(tmp_path))
    child = subprocess.Popen([sys.executable, "-c", GROWING], stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True)
    try:
        assert child.stdout is not None and child.stdin is not None
        assert child.stdout.readline() == "ready\n"
        assert proc_stats.catches(child.pid, soak.MEMORY_SNAPSHOT_SIGNAL)
        for _ in range(2):  # a snapshot, 1000 lists more, another snapshot
            child.send_signal(soak.MEMORY_SNAPSHOT_SIGNAL)
            child.stdin.write("grow\n")
            child.stdin.flush()
            assert child.stdout.readline() == "grown\n"  # the handler ran before the line was read
    finally:
        child.kill()
        child.wait()
    deadline = time.monotonic() + 30
    while len(list(tmp_path.glob("*.tracemalloc"))) < 2 and time.monotonic() < deadline:
        time.sleep(0.05)
    assert sorted(p.name for p in tmp_path.glob("*.tracemalloc")) == [f"grower-{child.pid}-000.tracemalloc",
                                                                      f"grower-{child.pid}-001.tracemalloc"]
    (name, lines), = soak.memory_growth(tmp_path).items()
    assert name == f"grower-{child.pid}"
    # First, the line that keeps the lists: 1000 of them and their numbers.
    grown = re.match(r"\+(\d+) KB in \+(\d+) blocks: <string>:8\b", lines[0])
    assert grown is not None and int(grown[1]) >= 50 and int(grown[2]) >= 1000, lines


def test_a_progress_bar_on_a_terminal_reads_as_one_line_per_redraw(load_benchmark) -> None:
    """soak.py gives the eval a terminal, so its bar is redrawn (sim time and all) every 0.2 s."""
    soak = load_benchmark("soak")
    terminal, their_end = os.openpty()
    writer = subprocess.Popen([sys.executable, "-c", (
        "import sys\nfor t in (1.5, 2.0, 2.5): sys.stderr.write(f'\\reval [##..] sim {t:6.1f} s\\033[K')\n"
        "sys.stderr.write('\\ndone\\n')")], stderr=their_end)
    os.close(their_end)
    lines = list(soak.terminal_lines(terminal))
    assert writer.wait() == 0
    assert [float(t) for line in lines for t in soak.SIM_TIME.findall(line)] == [1.5, 2.0, 2.5]
    assert lines[-1] == "done"


def test_samples_are_written_as_csv_a_row_per_process(load_benchmark, tmp_path) -> None:
    soak = load_benchmark("soak")
    samples = [(60.0 * m, 100.0 + 20.0 * m, {"navigation": {"rss_mb": 190.0 + m, "cpu_ticks": 7.0 * m, "fds": 31},
                                             "simulator": {"rss_mb": 130.5, "cpu_ticks": 3.0 * m, "fds": 20}})
               for m in range(3)]
    soak.write_samples(samples, tmp_path / "s.csv")
    rows = list(csv.DictReader((tmp_path / "s.csv").open()))
    assert [(r["sim_s"], r["wall_s"], r["process"], float(r["rss_mb"])) for r in rows][-2:] == [
        ("120.0", "40.0", "navigation", 192.0), ("120.0", "40.0", "simulator", 130.5)]
    assert len(rows) == 6 and {r["fds"] for r in rows} == {"31", "20"}


def test_a_failed_runs_tail_keeps_its_last_words_before_a_bar_redrawn_unchanged(load_benchmark) -> None:
    soak = load_benchmark("soak")
    tail: list[str] = []
    for line in ["[ERROR] [eval]: no ground truth for 30 s", *["eval [##..] sim 124.3 s"] * 100, "[INFO] done"]:
        tail = soak.kept_tail(tail, line, keep=3)
    assert tail == ["[ERROR] [eval]: no ground truth for 30 s", "eval [##..] sim 124.3 s", "[INFO] done"]

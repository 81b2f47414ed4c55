"""A process tree's processes, their names, CPU, memory and open files, from /proc (for the
benchmarks that watch a running stack: stack_speed, soak)."""
from __future__ import annotations

import os
from pathlib import Path

from pppbot_common.process import process_tree

TICKS = os.sysconf("SC_CLK_TCK")


def children(root: int) -> list[int]:
    """``root``'s descendants (pids), from /proc."""
    return process_tree(root)[1:]


def process_name(pid: int) -> str:
    try:
        argv = Path(f"/proc/{pid}/cmdline").read_bytes().split(b"\0")
    except OSError:
        return "?"
    words = [a.decode(errors="replace") for a in argv if a]
    for word in words:
        if word.startswith("/") and "/lib/pppbot_" in word:
            return Path(word).name
    if any("pppbot_bringup.cli" in w for w in words):
        return "eval" if "eval" in words else "launch_sim"
    return Path(words[0]).name if words else "?"


def cpu_ticks(pid: int) -> int:
    try:
        fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    except OSError:
        return 0
    return int(fields[11]) + int(fields[12])


def memory_mb(pid: int, file: str, key: str) -> float:
    try:
        for line in Path(f"/proc/{pid}/{file}").read_text().splitlines():
            if line.startswith(key):
                return int(line.split()[1]) / 1024
    except OSError:
        pass
    return 0.0


def rss_mb(pid: int) -> float:
    return memory_mb(pid, "status", "VmRSS:")


def pss_mb(pid: int) -> float:
    """Proportional set size: the process's own pages plus its share of those it shares (Python,
    rclpy, Fast DDS, numpy are mapped once for all processes). Summed over processes, the
    memory they take together; a sum of RSS counts every shared page once per process."""
    return memory_mb(pid, "smaps_rollup", "Pss:")


def open_files(pid: int) -> int:
    """How many file descriptors ``pid`` has open (0 once it is gone)."""
    try:
        return len(os.listdir(f"/proc/{pid}/fd"))
    except OSError:
        return 0


def catches(pid: int, signum: int) -> bool:
    """Whether ``pid`` has a handler for ``signum`` (its ``SigCgt`` mask in /proc): a signal whose
    default is to end a process is only sent to one that takes it."""
    try:
        for line in Path(f"/proc/{pid}/status").read_text().splitlines():
            if line.startswith("SigCgt:"):
                return bool(int(line.split()[1], 16) >> (signum - 1) & 1)
    except OSError:
        pass
    return False

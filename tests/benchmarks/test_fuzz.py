"""``benchmarks/fuzz.py``: every parser of users' files survives a short coverage-guided fuzz
(atheris, from its seed corpus, a fixed libFuzzer seed and number of inputs), and every input
the fuzzer ever found (``tests/data/fuzz/findings/<target>-<hash>``) is refused with the
parser's own message naming the file."""
from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
FINDINGS = ROOT / "tests" / "data" / "fuzz" / "findings"
#: Inputs per target in ``make test`` (the benchmark runs for minutes).
RUNS = 300


@pytest.fixture(scope="module")
def targets(load_benchmark):
    return load_benchmark("fuzz_targets")


def test_every_target_has_seeds_and_every_finding_a_target(targets) -> None:
    for name in targets.TARGETS:
        assert any((targets.SEEDS / name).iterdir()), name
    assert {p.name.split("-", 1)[0] for p in FINDINGS.iterdir()} <= set(targets.TARGETS)


@pytest.mark.parametrize("finding", sorted(p.name for p in FINDINGS.iterdir()))
def test_each_input_the_fuzzer_found_is_refused_naming_the_file(finding: str, targets, tmp_path: Path) -> None:
    target = targets.TARGETS[finding.split("-", 1)[0]]
    target.prepare(tmp_path)
    message = targets.check_one(target, tmp_path, (FINDINGS / finding).read_bytes())
    assert message is not None and "Traceback" not in message  # refused, by the parser's own error


@pytest.mark.parametrize("name", ["urdf", "xacro", "sdf", "stl", "obj", "dae", "map_yaml", "map_pgm", "map_png",
                                  "params", "bag_metadata", "mcap", "carmen"])
def test_each_parser_survives_a_short_fuzz(name: str, tmp_path: Path) -> None:
    # An input slower than 10 s is a finding here (2 s in the benchmark: a loaded machine is slower).
    scratch = tmp_path / "tmp"  # the run's temporary files: none is left behind
    scratch.mkdir()
    done = subprocess.run([sys.executable, str(ROOT / "benchmarks" / "fuzz.py"), name, "--runs", str(RUNS),
                           "--timeout", "10", "--artifacts", str(tmp_path / "found")], capture_output=True, text=True,
                          timeout=600, check=False, env={**os.environ, "TMPDIR": str(scratch)})
    report = json.loads(done.stdout.strip().splitlines()[-1])
    (result,) = report["targets"]
    assert result["findings"] == 0 and done.returncode == 0, result.get("output")
    assert result["executions"] >= RUNS and list((tmp_path / "found").iterdir()) == []
    assert list(scratch.iterdir()) == []


def test_an_input_whose_plain_check_hangs_counts_as_reproduced(load_benchmark, monkeypatch) -> None:
    fuzz = load_benchmark("fuzz")
    asked: list[float] = []

    def hangs(command: list[str], **kwargs: object) -> None:
        asked.append(float(kwargs["timeout"]))  # type: ignore[arg-type]
        raise subprocess.TimeoutExpired(command, fuzz.REPRODUCE_TIMEOUT_S)

    monkeypatch.setattr(fuzz.subprocess, "run", hangs)
    assert fuzz._reproduces("map_yaml", b"image: x.pgm\n") is True
    assert asked == [fuzz.REPRODUCE_TIMEOUT_S]

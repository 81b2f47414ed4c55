"""Coverage-guided fuzzing of every parser of users' files, with atheris (libFuzzer for Python).

    ./pppbot env python benchmarks/fuzz.py                      # every target, 60 s each
    ./pppbot env python benchmarks/fuzz.py urdf sdf --seconds 600
    ./pppbot env python benchmarks/fuzz.py --runs 300           # what make test runs, per target

Each target (:mod:`fuzz_targets`: URDF, xacro, SDF, STL, OBJ, COLLADA, map YAML, PGM and PNG
map images, Nav2 parameter files, rosbag2 metadata and MCAP, CARMEN logs) runs in a process
of its own, starting from its seed corpus (``tests/data/fuzz/<target>/``, read only; what the
fuzzer adds goes to a scratch folder). A finding is: an exception other than the parser's own
error naming the file, an input that takes longer than ``--timeout`` (2 s), or a process over
``--rss-limit-mb`` (2048 MB). libFuzzer writes the input to ``--artifacts`` (``build/fuzz-artifacts``:
``<target>-crash-…``, ``-timeout-…``, ``-oom-…``) and the target's run ends; a fixed finding goes
to ``tests/data/fuzz/findings/<target>-<hash>``, which ``make test`` feeds to its parser.

Prints a line per target and, last, JSON: per target the executions, seconds, findings and
the artifacts written.
"""
from __future__ import annotations

import argparse
import json
import os
import re
import subprocess
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from fuzz_targets import ROOT, SEEDS, TARGETS, check_one  # noqa: E402 (the benchmarks folder is not a package)

_ARTEFACT = "fuzz: an exception of the instrumented code only (not reproduced uninstrumented): ignored"
#: The libFuzzer seed: the same inputs in the same order on every machine.
SEED = 1


def parse_arguments(argv: list[str] | None = None) -> argparse.Namespace:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("targets", nargs="*", default=[], metavar="TARGET",
                        help=f"which parsers (default: all of {', '.join(TARGETS)})")
    budget = parser.add_mutually_exclusive_group()
    budget.add_argument("--seconds", type=float, default=None, help="fuzzing time per target (default 60)")
    budget.add_argument("--runs", type=int, default=None, help="inputs per target instead of a time")
    parser.add_argument("--timeout", type=float, default=2.0, help="an input slower than this (s) is a finding")
    parser.add_argument("--rss-limit-mb", type=int, default=2048, help="a process bigger than this is a finding")
    parser.add_argument("--artifacts", type=Path, default=ROOT / "build" / "fuzz-artifacts",
                        help="where findings are written (default build/fuzz-artifacts)")
    parser.add_argument("--one", metavar="TARGET", help=argparse.SUPPRESS)  # the child process: one target
    args = parser.parse_args(argv)
    unknown = [t for t in args.targets if t not in TARGETS]
    if unknown:
        parser.error(f"unknown target(s) {', '.join(unknown)}; known: {', '.join(TARGETS)}")
    if args.seconds is None and args.runs is None:
        args.seconds = 60.0
    return args


#: The environment variable naming the fuzzing child's scratch folder (made and removed by its parent).
_SCRATCH = "PPPBOT_FUZZ_SCRATCH"


def _fuzz_one(name: str, libfuzzer_args: list[str]) -> None:
    """In the child: fuzz one target under libFuzzer (never returns)."""
    import atheris

    with atheris.instrument_imports(include=["pppbot_common", "pppbot_description", "pppbot_sim", "pppbot_bag",
                                             "pppbot_bringup", "xacro", "trimesh", "collada", "rosbags",
                                             "mcap", "PIL"]):
        import pppbot_bag.reader  # noqa: F401 (imported here to be instrumented)
        import pppbot_bringup.parameter_files  # noqa: F401
        import pppbot_common.maps  # noqa: F401
        import pppbot_description.xacro_model  # noqa: F401
        import pppbot_sim.meshes  # noqa: F401
        import pppbot_sim.sdf_world  # noqa: F401
    target = TARGETS[name]
    folder = Path(os.environ[_SCRATCH])  # the parent's: libFuzzer ends this process without cleaning up
    target.prepare(folder)

    def one_input(data: bytes) -> None:
        try:
            check_one(target, folder, data)
        except Exception:
            # Coverage instrumentation rewrites the libraries' bytecode, and once in a while that
            # alone breaks them (PyYAML's scanner did): a crash counts when it happens uninstrumented.
            if _reproduces(name, data):
                raise
            print(_ARTEFACT, flush=True)

    atheris.Setup([sys.argv[0], *libfuzzer_args], one_input)
    atheris.Fuzz()


#: Wall seconds a plain process may take to import a target and check one input: longer is a hang.
REPRODUCE_TIMEOUT_S = 120.0


def _reproduces(name: str, data: bytes) -> bool:
    """Whether ``data`` fails ``name``'s check in a plain (uninstrumented) process; a check that does
    not end within :data:`REPRODUCE_TIMEOUT_S` fails it too (a hang)."""
    with tempfile.NamedTemporaryFile(prefix=f"fuzz-{name}-") as file:
        file.write(data)
        file.flush()
        try:
            done = subprocess.run([sys.executable, __file__, "--reproduce", name, file.name], capture_output=True,
                                  check=False, timeout=REPRODUCE_TIMEOUT_S)
        except subprocess.TimeoutExpired:
            return True
    return done.returncode != 0


def run_target(name: str, args: argparse.Namespace) -> dict[str, object]:
    """Fuzz ``name`` in a child process; its executions, time and findings."""
    args.artifacts.mkdir(parents=True, exist_ok=True)
    before = set(args.artifacts.iterdir())
    with (tempfile.TemporaryDirectory(prefix=f"fuzz-corpus-{name}-") as corpus,
          tempfile.TemporaryDirectory(prefix=f"fuzz-{name}-") as scratch):
        flags = [corpus, str(SEEDS / name), f"-seed={SEED}", f"-timeout={max(1, round(args.timeout))}",
                 f"-rss_limit_mb={args.rss_limit_mb}", f"-artifact_prefix={args.artifacts.resolve()}/{name}-",
                 "-max_len=65536", "-print_final_stats=1"]
        flags.append(f"-runs={args.runs}" if args.runs is not None else f"-max_total_time={round(args.seconds)}")
        started = time.monotonic()
        done = subprocess.run([sys.executable, __file__, "--one", name, "--", *flags], capture_output=True,
                              text=True, env={**os.environ, "PYTHONHASHSEED": "0", _SCRATCH: scratch}, check=False)
        seconds = time.monotonic() - started
    log = "".join(line for line in (done.stdout + done.stderr).splitlines(keepends=True)
                  if not line.startswith(("INFO: Instrumenting", "WARNING: Failed to find function")))
    executed = re.findall(r"stat::number_of_executed_units: (\d+)", log)
    artifacts = sorted(str(p) for p in set(args.artifacts.iterdir()) - before)
    report = {"target": name, "what": TARGETS[name].what, "executions": int(executed[-1]) if executed else 0,
              "seconds": round(seconds, 1), "findings": len(artifacts) or int(done.returncode != 0),
              "artifacts": artifacts, "instrumentation_artefacts": log.count(_ARTEFACT),
              "exit_code": done.returncode}
    if done.returncode != 0:  # the Python exception (or libFuzzer's verdict) and how the run ended
        caught = re.search(r"=== Uncaught Python exception: ===.*?(?=\n==\d+== ERROR)", log, re.S)
        report["output"] = ((caught.group(0) + "\n") if caught else "") + log[-1500:]
    return report


def main(argv: list[str] | None = None) -> int:
    argv = sys.argv[1:] if argv is None else argv
    if argv[:1] == ["--one"]:
        _fuzz_one(argv[1], argv[3:])
    if argv[:1] == ["--reproduce"]:
        target = TARGETS[argv[1]]
        with tempfile.TemporaryDirectory(prefix=f"fuzz-{target.name}-") as folder:
            target.prepare(Path(folder))
            check_one(target, Path(folder), Path(argv[2]).read_bytes())  # raises (exit 1) when it reproduces
        return 0
    args = parse_arguments(argv)
    reports = []
    for name in args.targets or list(TARGETS):
        report = run_target(name, args)
        reports.append(report)
        print(f"{name}: {report['executions']} executions in {report['seconds']} s, {report['findings']} finding(s) "
              + " ".join(report["artifacts"]), flush=True)  # type: ignore[arg-type]
        if report["findings"]:
            print(report.get("output", ""), flush=True)
    budget = {"runs": args.runs} if args.runs is not None else {"seconds": args.seconds}
    print(json.dumps({"targets": reports, **budget, "timeout_s": args.timeout, "rss_limit_mb": args.rss_limit_mb,
                      "findings": sum(int(r["findings"]) for r in reports)}))  # type: ignore[call-overload]
    return 1 if any(r["findings"] for r in reports) else 0


if __name__ == "__main__":
    sys.exit(main())

"""No line of pppbot's code picks its log severity at run time: rclpy raises "Logger severity
cannot be changed between calls" when one call site logs at another severity than before. The
simulator died so when ppp_bot tipped over after it had been reported upright (the line
``(logger.info if upright else logger.error)(text)``)."""
from __future__ import annotations

import ast
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
SEVERITIES = {"debug", "info", "warning", "warn", "error", "fatal"}


def _severity_choice(node: ast.AST) -> bool:
    """``a.info if c else a.error`` (either branch a logger method)."""
    return isinstance(node, ast.IfExp) and any(
        isinstance(branch, ast.Attribute) and branch.attr in SEVERITIES for branch in (node.body, node.orelse))


def run_time_severities(source: str) -> list[int]:
    """The lines that call a logger method chosen at run time, or keep one in a name."""
    lines: list[int] = []
    for node in ast.walk(ast.parse(source)):
        chosen = node.func if isinstance(node, ast.Call) else node.value if isinstance(node, ast.Assign) else None
        if chosen is not None and _severity_choice(chosen):
            lines.append(chosen.lineno)
    return sorted(lines)


def test_the_check_finds_a_severity_chosen_at_run_time() -> None:
    assert run_time_severities("(log.info if ok else log.error)('x')\nlog.info('y')\n") == [1]
    assert run_time_severities("say = node.get_logger().warning if late else node.get_logger().info\n") == [1]
    assert run_time_severities("log.info('a' if ok else 'b')\n") == []


def test_no_package_picks_a_severity_at_run_time() -> None:
    found = []
    for path in sorted(ROOT.glob("pppbot_*/pppbot_*/**/*.py")):
        found += [f"{path.relative_to(ROOT)}:{line}" for line in run_time_severities(path.read_text())]
    assert found == []

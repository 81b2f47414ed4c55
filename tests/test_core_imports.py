"""Algorithm cores never import rclpy or ROS interface packages.

The rule (STYLE.md): in every pppbot package, only modules inside a ``ros``
subpackage are ROS adapters. Every other module is core and must not reach rclpy
or a message package, directly or through another pppbot module.
"""
from __future__ import annotations

import ast
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parent.parent
ROS_MODULES = ("rclpy", "rosidl_runtime_py", "launch", "launch_ros", "tf2_ros")
ROS_SUFFIXES = ("_msgs", "_srvs", "_interfaces")


def is_ros_module(name: str) -> bool:
    top = name.split(".", maxsplit=1)[0]
    return top in ROS_MODULES or top.endswith(ROS_SUFFIXES)


def project_modules() -> dict[str, Path]:
    """Dotted module name → file, for every module of every pppbot package."""
    modules = {}
    for package_xml in REPO.glob("pppbot_*/package.xml"):
        source = package_xml.parent / package_xml.parent.name
        for path in source.rglob("*.py"):
            parts = list(path.relative_to(source.parent).with_suffix("").parts)
            if parts[-1] == "__init__":
                parts.pop()
            modules[".".join(parts)] = path
    return modules


def imports_of(path: Path, module: str) -> set[str]:
    names: set[str] = set()
    package = module if path.name == "__init__.py" else module.rpartition(".")[0]
    for node in ast.walk(ast.parse(path.read_text(), str(path))):
        if isinstance(node, ast.Import):
            names.update(alias.name for alias in node.names)
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:
                anchor = package.split(".")
                anchor = anchor[: len(anchor) - (node.level - 1)]
                base = ".".join([*anchor, base] if base else anchor)
            names.add(base)
            names.update(f"{base}.{alias.name}" for alias in node.names)
    return names


def is_adapter(module: str) -> bool:
    return "ros" in module.split(".")[1:]


def ros_reach(modules: dict[str, Path]) -> dict[str, list[str]]:
    """For each module, one import chain that reaches ROS (empty if none): breadth first."""
    graph = {m: imports_of(p, m) for m, p in modules.items()}

    def project_target(name: str) -> str | None:
        for candidate in (name, name.rpartition(".")[0]):
            if candidate in graph:
                return candidate
        return None

    def chain(start: str) -> list[str]:
        parents: dict[str, str | None] = {start: None}
        queue = [start]
        while queue:
            module = queue.pop(0)
            for name in sorted(graph[module]):
                if is_ros_module(name):
                    path = [name, module]
                    while parents[path[-1]] is not None:
                        path.append(parents[path[-1]])  # type: ignore[arg-type]
                    return list(reversed(path))
                target = project_target(name)
                if target is not None and target not in parents:
                    parents[target] = module
                    queue.append(target)
        return []

    return {m: chain(m) for m in graph}


MODULES = project_modules()
CORES = sorted(m for m in MODULES if not is_adapter(m))


def test_rule_sees_the_packages():
    assert {m.split(".")[0] for m in MODULES} >= {
        "pppbot_common", "pppbot_description", "pppbot_sim", "pppbot_control",
        "pppbot_slam", "pppbot_nav", "pppbot_bag", "pppbot_bringup", "pppbot_eval", "pppbot_viz",
    }
    assert any(is_adapter(m) for m in MODULES), "no ros/ adapters found: the rule would be vacuous"


@pytest.fixture(scope="module")
def reach() -> dict[str, list[str]]:
    """Every module's chain to ROS, found once for all the parametrized tests (each parse of the
    whole project took a second)."""
    return ros_reach(MODULES)


@pytest.mark.parametrize("module", CORES)
def test_core_module_does_not_reach_ros(module, reach):
    chain = reach[module]
    assert not chain, f"core module {module} reaches ROS: {' -> '.join(chain)}"


def test_checker_catches_a_transitive_import(tmp_path):
    """The checker itself: a core importing an adapter is caught."""
    pkg = tmp_path / "pkg"
    (pkg / "ros").mkdir(parents=True)
    (pkg / "__init__.py").write_text("")
    (pkg / "ros" / "__init__.py").write_text("")
    (pkg / "ros" / "node.py").write_text("import rclpy\n")
    (pkg / "core.py").write_text("from .ros import node\n")
    modules = {"pkg": pkg / "__init__.py", "pkg.ros": pkg / "ros" / "__init__.py",
               "pkg.ros.node": pkg / "ros" / "node.py", "pkg.core": pkg / "core.py"}
    reach = ros_reach(modules)
    assert reach["pkg.core"] == ["pkg.core", "pkg.ros.node", "rclpy"]
    assert reach["pkg"] == []


def test_checker_follows_import_cycles(tmp_path):
    """a ↔ b in a cycle, b → c → rclpy: both a and b are caught."""
    files = {"pkg.a": "from pkg import b\n", "pkg.b": "from pkg import a\nfrom pkg import c\n",
             "pkg.c": "import rclpy\n"}
    modules = {}
    for name, text in files.items():
        path = tmp_path / f"{name.split('.')[1]}.py"
        path.write_text(text)
        modules[name] = path
    reach = ros_reach(modules)
    assert reach["pkg.a"] == ["pkg.a", "pkg.b", "pkg.c", "rclpy"]
    assert reach["pkg.b"][-1] == "rclpy"

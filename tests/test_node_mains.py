"""Every node module's ``main`` has one shape: ``main(args: list[str] | None = None) -> int``,
returning the exit code, and ``python -m`` runs it through ``sys.exit(main())``."""
from __future__ import annotations

import ast
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parent.parent


def node_mains() -> list[tuple[Path, ast.FunctionDef, ast.Module]]:
    found = []
    for path in sorted(REPO.glob("pppbot_*/pppbot_*/ros/*.py")):
        tree = ast.parse(path.read_text(), str(path))
        for node in tree.body:
            if isinstance(node, ast.FunctionDef) and node.name == "main" and node.args.args \
                    and ast.unparse(node.args.args[0].annotation or ast.Constant(None)) == "list[str] | None":
                found.append((path, node, tree))
    return found


MAINS = node_mains()


def test_the_nodes_are_found():
    names = {path.stem for path, _, _ in MAINS}
    assert {"amcl", "slam", "simulator", "navigator", "twist_mux", "map_server"} <= names


@pytest.mark.parametrize("path, main, tree", MAINS, ids=[str(p.relative_to(REPO)) for p, _, _ in MAINS])
def test_main_returns_the_exit_code_and_runs_as_a_module(path: Path, main: ast.FunctionDef, tree: ast.Module):
    assert main.returns is not None and ast.unparse(main.returns) == "int", f"{path}: main must return int"
    assert not any(isinstance(n, ast.Call) and ast.unparse(n.func) == "sys.exit" for n in ast.walk(main)), \
        f"{path}: main returns its code; sys.exit belongs to the caller"
    guards = [n for n in tree.body if isinstance(n, ast.If) and ast.unparse(n.test) == "__name__ == '__main__'"]
    assert guards and ast.unparse(guards[0].body[0]) == "sys.exit(main())", f"{path}: no `sys.exit(main())` guard"

"""The ``pppbot`` dispatcher finds its verbs through entry points, as ``ros2`` finds ``ros2 bag``."""
from __future__ import annotations

import importlib
from importlib.metadata import EntryPoint

import pytest

from pppbot_bringup import cli

#: ../shared/DESIGN.md's verbs, and the package that declares each.
DESIGN_VERBS = {"run": "pppbot_bringup", "topic": "pppbot_bringup", "teleop": "pppbot_bringup",
                "launch_sim": "pppbot_bringup", "eval": "pppbot_eval", "bag": "pppbot_bag",
                "nav": "pppbot_nav", "map_saver": "pppbot_nav",
                # issue 23's Foxglove bridge and live view on its own (DESIGN.md's table predates them)
                "foxglove": "pppbot_viz", "view": "pppbot_viz"}


def test_every_verb_comes_from_its_package_and_is_a_verb_module():
    verbs = cli.find_verbs()
    assert set(verbs) == set(DESIGN_VERBS)
    for verb, module_name in verbs.items():
        assert module_name.split(".")[0] == DESIGN_VERBS[verb], verb
        module = importlib.import_module(module_name)
        assert hasattr(module, "main_argv") or (hasattr(module, "add_arguments") and hasattr(module, "main")), verb


def test_help_lines_come_from_the_docstring_after_the_usage():
    assert cli.verb_help("pppbot_bag.cli") == (
        "record, play, inspect and reindex rosbag2 (MCAP) bags, like `ros2 bag`; "
        "and turn a real robot's CARMEN laser log into one.")
    assert cli.verb_help("pppbot_no_such.module") == "(pppbot_no_such.module is not installed)"


def points(*pairs: tuple[str, str]) -> list[EntryPoint]:
    return [EntryPoint(name, value, cli.VERB_GROUP) for name, value in pairs]


def test_a_verb_declared_by_two_packages_is_refused_naming_both(monkeypatch, capsys):
    monkeypatch.setattr(cli, "entry_points", lambda group: points(("bag", "pppbot_bag.cli"), ("bag", "other.bag")))
    with pytest.raises(cli.VerbConflict, match=r"verb 'bag' is declared twice: by pppbot_bag\.cli and by other\.bag"):
        cli.find_verbs()
    assert cli.main(["bag", "info"]) == 2
    assert "declared twice" in capsys.readouterr().err


def test_a_package_installed_twice_is_one_verb(monkeypatch):
    monkeypatch.setattr(cli, "entry_points", lambda group: points(("bag", "pppbot_bag.cli"), ("bag", "pppbot_bag.cli")))
    assert cli.find_verbs() == {"bag": "pppbot_bag.cli"}


def test_a_verb_of_a_new_package_is_dispatched(monkeypatch, capsys):
    # A package that declares `hello = pppbot_bag.cli` would get `pppbot hello` without touching the dispatcher.
    monkeypatch.setattr(cli, "entry_points", lambda group: points(("hello", "pppbot_bag.cli")))
    with pytest.raises(SystemExit):
        cli.main(["hello", "--help"])
    assert "usage: pppbot hello" in capsys.readouterr().out

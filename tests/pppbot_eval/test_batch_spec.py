"""A batch spec, expanded into runs and checked: products, world families, steps and their references."""
from __future__ import annotations

from pathlib import Path

import pytest

from pppbot_eval.batch import BatchSpecError, argv, filled, load_batch
from pppbot_eval.ros.batch_cli import eval_parser
from pppbot_eval.scenarios import Scenario
from pppbot_sim.wheel_slip import MAX_SLIP_STDDEV

SCENARIOS = [s.value for s in Scenario]
SHIPPED = Path(__file__).resolve().parents[2] / "benchmarks" / "batches"


def load(tmp_path: Path, text: str):
    path = tmp_path / "spec.yaml"
    path.write_text(text)
    return load_batch(path, eval_parser(), SCENARIOS, MAX_SLIP_STDDEV)


def test_lists_are_axes_and_the_runs_are_their_product(tmp_path):
    batch = load(tmp_path, """
out: here
defaults: {wheel-slip: 0.02}
runs:
  - scenario: navigation
    world: [maze, box_room]
    seed: [0, 1, 2]
    goals: 3
    start: [[0, 0, 0], [1, 0, 1.5]]
""")
    assert batch.out == Path("here")
    ids = [s.id for s in batch.steps]
    assert len(ids) == 2 * 3 * 2 == len(set(ids))
    assert ids[0] == "maze/seed=0,start=0_0_0/navigation" and ids[-1] == "box_room/seed=2,start=1_0_1.5/navigation"
    last = batch.steps[-1]
    assert dict(last.flags) == {"wheel_slip": 0.02, "seed": 2, "goals": 3, "start": [1, 0, 1.5]}
    assert argv(last, last.flags, eval_parser()) == ["navigation", "--wheel-slip", "0.02", "--seed", "2",
                                                     "--goals", "3", "--start", "1", "0", "1.5"]


def test_a_family_with_seeds_gives_generated_worlds_and_steps_take_earlier_reports(tmp_path):
    batch = load(tmp_path, """
runs:
  - name: suite
    world: {family: [maze, office], seed: [100, 101], small: true}
    seed: ${world.seed}
    lockstep: true
    steps:
      - scenario: slam
      - scenario: localization
        map: ${slam.map}
        map_pose: ${slam.start}
        global: false
""")
    assert len(batch.chains) == 4 and all(len(c.steps) == 2 for c in batch.chains)
    slam, localization = batch.chains[3].steps
    assert localization.id == "suite/office_small_101/localization" and slam.world.family == "office"
    flags = filled(localization, {"slam": {"map": "/m/map.yaml", "start": [1.0, 2.0, 0.5]}})
    assert flags == {"seed": 101, "lockstep": True, "map": "/m/map.yaml", "map_pose": [1.0, 2.0, 0.5],
                     "global_localization": False}
    assert argv(localization, flags, eval_parser()) == [
        "localization", "--seed", "101", "--lockstep", "--map", "/m/map.yaml", "--map-pose", "1.0", "2.0", "0.5"]
    with pytest.raises(KeyError, match=r"slam's report has no map \(route not finished\)"):
        filled(localization, {"slam": {"ok": False, "failure": "route not finished"}})


def test_a_seed_range_of_clutter_worlds_navigated_without_a_map(tmp_path):
    batch = load(tmp_path, """
runs:
  - scenario: navigation
    world: {family: clutter, seed: {first: 100, last: 199}}
    no-map: true
    goal: [[10, 0, 0], [9, 1, 0]]
""")
    assert len(batch.steps) == 200 and batch.steps[0].id == "clutter_100/goal=10_0_0/navigation"
    last = batch.steps[-1]
    assert last.world.seed == 199 and argv(last, last.flags, eval_parser()) == [
        "navigation", "--no-map", "--goal", "9", "1", "0"]


@pytest.mark.parametrize("text, message", [
    ("runs: []", r"'runs' must be a non-empty list"),
    ("runs:\n  - {scenario: fly}", r"scenario 'fly': one of map, drive"),
    ("runs:\n  - {scenario: slam, speeed: 0.3}", r"runs\[0\]: 'speeed' is not a flag of pppbot eval"),
    ("runs:\n  - {scenario: slam, world: {family: castle}}", r"world: .*castle.*maze"),
    ("runs:\n  - {scenario: slam, seed: []}", r"'seed' is an empty list"),
    ("runs:\n  - {scenario: slam, world: {family: maze, seed: {first: 3}}}", r"a range is \{first: A, last: B\}"),
    ("runs:\n  - {scenario: slam, no_map: true}", r"--no-map: only the navigation scenario takes it"),
    ("runs:\n  - steps: [{scenario: localization, map: '${slam.map}'}]", r"'slam' is not a step before this one"),
    ("runs:\n  - {scenario: slam, seed: 'x${world.seed}'}", r"a placeholder is the whole value"),
    ("runs:\n  - {scenario: slam, world: [maze, maze]}", r"two runs have the id 'maze/slam'"),
    ("runs:\n  - {scenario: slam, speed: fast}", r"runs\[0\]: run 'maze/slam': argument --speed: invalid float"),
    ("rns: []", r"unknown key\(s\) rns"),
    ("runs:\n  - {name: ../up, scenario: slam}", r"name '../up': letters, digits and _"),
    ("runs:\n  - {scenario: slam, lockstep: 'false'}", r"lockstep 'false': true or false"),
    ("runs:\n  - {scenario: slam, seed: '${world.seed}'}", r"only a generated world .* has a seed"),
    ("runs:\n  - {scenario: slam, wheel_slip: 5}", r"run 'maze/slam': --wheel-slip 5.*must be in"),
    ("runs:\n  - {scenario: localization, map: no_such.yaml}", r"map no_such.yaml: no such file"),
    ("runs:\n  - {scenario: map}", r"run 'maze/map': --map: the map scenario needs it"),
    ("runs:\n  - {scenario: slam, world: {family: []}}", r"world family \[\]: give at least one"),
    ("out: 5\nruns:\n  - {scenario: slam}", r"out 5: a folder name"),
    ("runs:\n  - steps: [{scenario: slam}, {scenario: slam}]", r"two steps are called 'slam'"),
])
def test_a_bad_spec_is_refused_naming_the_entry_and_key(tmp_path, text, message):
    with pytest.raises(BatchSpecError, match=message):
        load(tmp_path, text)


@pytest.mark.parametrize("spec", sorted(SHIPPED.glob("*.yaml")), ids=lambda p: p.stem)
def test_every_shipped_batch_spec_loads(spec: Path):
    batch = load_batch(spec, eval_parser(), SCENARIOS, MAX_SLIP_STDDEV)
    assert batch.steps and all(s.scenario in SCENARIOS for s in batch.steps)
    assert batch.out in (None, Path(f"eval_batch_{spec.stem}"))

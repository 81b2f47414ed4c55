"""A batch of evaluation runs: its spec file, checked and expanded into runs (``pppbot eval batch``).

A spec is YAML::

    out: eval_batch_nav              # the default of --out
    defaults: {wheel_slip: 0.01}     # flags every run gets (pppbot eval's flags, - or _)
    runs:
      - scenario: navigation
        world: [maze, box_room]      # a list is an axis: one run per value, the product of all axes
        seed: [0, 1, 2]
        goals: 3
      - name: autonomy               # optional: a prefix of the entry's run ids
        world: {family: [maze, office], seed: [100, 101]}   # generated worlds (small: true for small;
                                                            # seed: {first: 100, last: 199} a range)
        seed: ${world.seed}
        steps:                       # runs in order in one world; later ones take earlier reports' values
          - scenario: slam
          - scenario: localization
            map: ${slam.map}
            map_pose: ${slam.start}

Each run is one ``pppbot eval <scenario>`` with its report in ``<out>/<id>/``; the id is the
entry's name, the world, the axes' values (when an entry has axes besides the world) and the
step: ``autonomy/maze_100/localization``, ``box_room/seed=2,goals=3/navigation``. Flags that take three
numbers (``map_pose``, ``start``, ``initial_offset``, ``goal``) are an axis when given a list of
triples. ``${world.seed}``, ``${world.family}``, ``${world.name}`` and ``${<step>.<report key>}``
are filled in when the run starts. Every problem is one :class:`BatchSpecError` naming the file,
the entry and the key, before anything runs.
"""
from __future__ import annotations

import argparse
import itertools
import re
from collections.abc import Iterator, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from pppbot_common.errors import ArgumentError
from pppbot_common.param_files import load_yaml_file
from pppbot_eval.config import EvalConfig
from pppbot_eval.errors import BatchSpecError
from pppbot_sim.worldgen.families import WorldGenError, family_of, world_name

#: Flags that take three numbers: a list of triples is an axis of them.
TRIPLES = ("map_pose", "start", "initial_offset", "goal")
#: Flags that name a file, checked to exist before anything runs.
FILES = ("map", "route_file", "params_file")
#: Flags a spec cannot set: the batch sets them for every run.
RESERVED = ("out", "json", "scenario", "world")
#: ``${world.seed}``, ``${slam.map}``: a value filled in when the run starts.
PLACEHOLDER = re.compile(r"^\$\{(\w+)\.(\w+)\}$")
WORLD_KEYS = ("seed", "family", "name")
_ID_UNSAFE = re.compile(r"[^A-Za-z0-9_.=-]+")  # in one axis's part of an id
#: An entry's or a step's name: a part of run ids and of folder names.
NAME = re.compile(r"\w+")


@dataclass(frozen=True)
class World:
    """A run's world: a shipped name or a file (``source``, as ``--world`` takes it), or a generated
    one (``family`` and ``seed``; ``source`` is then its name)."""

    source: str
    family: str = ""
    seed: int | None = None
    small: bool = False

    @property
    def generated(self) -> bool:
        return bool(self.family)

    @property
    def name(self) -> str:
        """The world's name in run ids: a generated world's, a shipped world's, a file's stem."""
        return self.source if self.generated else Path(self.source).stem

    def value(self, key: str) -> Any:
        """``${world.<key>}``."""
        return {"seed": self.seed, "family": self.family or self.name, "name": self.name}[key]


@dataclass(frozen=True)
class Step:
    """One run: ``pppbot eval <scenario>`` with ``flags`` (placeholders still in) in ``world``."""

    id: str
    name: str
    scenario: str
    world: World
    flags: Mapping[str, Any]
    axes: Mapping[str, Any] = field(default_factory=dict)
    where: str = ""  # the spec file and entry it comes from, for messages


@dataclass(frozen=True)
class Chain:
    """Runs that go in order in one world (an entry's steps at one point of its axes)."""

    steps: tuple[Step, ...]


@dataclass(frozen=True)
class Batch:
    file: Path
    out: Path | None
    chains: tuple[Chain, ...]

    @property
    def steps(self) -> list[Step]:
        return [s for c in self.chains for s in c.steps]


def load_batch(path: Path, parser: argparse.ArgumentParser, scenarios: Sequence[str], max_wheel_slip: float) -> Batch:
    """The batch ``path`` describes, expanded and checked against ``parser`` (pppbot eval's flags, whose
    ``error`` raises instead of exiting) and the eval's own rules (:class:`EvalConfig`).

    Raises:
        BatchSpecError: the first problem, naming the file, entry and key.
    """
    spec = load_yaml_file(path, BatchSpecError)
    where = str(path)
    if not isinstance(spec, dict):
        raise BatchSpecError(f"{where}: a batch spec is a mapping with 'runs:' (and 'out:', 'defaults:')")
    unknown = set(spec) - {"out", "defaults", "runs"}
    if unknown:
        raise BatchSpecError(f"{where}: unknown key(s) {', '.join(sorted(map(str, unknown)))}; "
                             "a spec has out, defaults and runs")
    flags = _flag_names(parser)
    defaults = spec.get("defaults") or {}
    if not isinstance(defaults, dict):
        raise BatchSpecError(f"{where}: 'defaults' must be a mapping of flags to values")
    defaults = {_key(k, flags, f"{where}: defaults"): v for k, v in defaults.items()}
    runs = spec.get("runs")
    if not isinstance(runs, list) or not runs:
        raise BatchSpecError(f"{where}: 'runs' must be a non-empty list of entries")
    chains = [chain for i, entry in enumerate(runs)
              for chain in _entry(entry, defaults, flags, scenarios, f"{where}: runs[{i}]")]
    seen: set[str] = set()
    for chain in chains:
        for step in chain.steps:
            if step.id in seen:
                raise BatchSpecError(f"{where}: two runs have the id '{step.id}'; give the entries a 'name', the "
                                     "steps different names, or an axis's files different names")
            seen.add(step.id)
    out = spec.get("out")
    if out is not None and not isinstance(out, str):
        raise BatchSpecError(f"{where}: out {out!r}: a folder name")
    if not chains:
        raise BatchSpecError(f"{where}: the entries give no run")
    batch = Batch(path, Path(out) if out else None, tuple(chains))
    for step in batch.steps:
        check_flags(step, parser, max_wheel_slip)
    return batch


def _flag_names(parser: argparse.ArgumentParser) -> dict[str, argparse.Action]:
    return {a.dest: a for a in parser._actions if a.option_strings and a.dest not in RESERVED + ("help",)}


def _key(key: Any, flags: Mapping[str, argparse.Action], where: str) -> str:
    name = str(key).replace("-", "_")
    if name == "global":
        name = "global_localization"
    if name not in flags:
        raise BatchSpecError(f"{where}: '{key}' is not a flag of pppbot eval (it has "
                             f"{', '.join(sorted(flags))})")
    return name


def _axis(name: str, value: Any) -> list[Any] | None:
    """The values of an axis, or None when ``value`` is one value."""
    if name in TRIPLES:
        return list(value) if isinstance(value, list) and value and isinstance(value[0], list) else None
    return list(value) if isinstance(value, list) else None


def _entry(entry: Any, defaults: Mapping[str, Any], flags: Mapping[str, argparse.Action],
           scenarios: Sequence[str], where: str) -> Iterator[Chain]:
    if not isinstance(entry, dict):
        raise BatchSpecError(f"{where}: an entry is a mapping of flags (with 'scenario' or 'steps')")
    entry = dict(entry)
    name = str(entry.pop("name", "") or "")
    if name and not NAME.fullmatch(name):
        raise BatchSpecError(f"{where}: name {name!r}: letters, digits and _ (it names folders)")
    worlds = _worlds(entry.pop("world", "maze"), where)
    steps = _entry_steps(entry, where)
    shared = {**defaults, **{_key(k, flags, where): v for k, v in entry.items()}}
    axes = {k: axis for k, v in shared.items() if (axis := _axis(k, v)) is not None}
    for k, axis_values in axes.items():
        if not axis_values:
            raise BatchSpecError(f"{where}: '{k}' is an empty list: no run")
    parsed = [_step(s, flags, scenarios, f"{where}: steps[{i}]") for i, s in enumerate(steps)]
    names = [n for n, _, _ in parsed]
    if len(set(names)) != len(names):
        raise BatchSpecError(f"{where}: two steps are called '{max(names, key=names.count)}'; give one a 'name'")
    generated = all(w.generated for w in worlds)
    for i, (_, _, step_flags) in enumerate(parsed):
        for key, value in step_flags.items():
            _check_reference(value, names[:i], generated, f"{where}: steps[{i}]: {key}")
    for key, value in shared.items():
        if key not in axes:
            _check_reference(value, [], generated, f"{where}: {key}")
    for world in worlds:
        for point in itertools.product(*axes.values()):
            values = dict(zip(axes, point, strict=True))
            prefix = [p for p in (name, world.name, _axes_id(values)) if p]
            chain = []
            for step_name, scenario, step_flags in parsed:
                chain.append(Step("/".join([*prefix, step_name]), step_name, scenario, world,
                                  {**shared, **values, **step_flags}, values, where))
            yield Chain(tuple(chain))


def _entry_steps(entry: dict[str, Any], where: str) -> list[dict[str, Any]]:
    """An entry's ``steps``, or its one ``scenario`` as a step (taken out of ``entry``)."""
    steps = entry.pop("steps", None)
    if steps is None:
        if "scenario" not in entry:
            raise BatchSpecError(f"{where}: give 'scenario' (one run) or 'steps' (runs in order)")
        return [{"scenario": entry.pop("scenario")}]
    if "scenario" in entry:
        raise BatchSpecError(f"{where}: give 'scenario' or 'steps', not both")
    if not isinstance(steps, list) or not steps or not all(isinstance(s, dict) for s in steps):
        raise BatchSpecError(f"{where}: 'steps' must be a non-empty list of mappings with a 'scenario'")
    return steps


def _step(step: Mapping[str, Any], flags: Mapping[str, argparse.Action], scenarios: Sequence[str],
          where: str) -> tuple[str, str, dict[str, Any]]:
    step = dict(step)
    scenario = step.pop("scenario", None)
    if scenario not in scenarios:
        raise BatchSpecError(f"{where}: scenario {scenario!r}: one of {', '.join(scenarios)}")
    name = str(step.pop("name", scenario))
    if not NAME.fullmatch(name) or name == "world":
        raise BatchSpecError(f"{where}: name {name!r}: letters, digits and _, not 'world' (it names folders, and "
                             "${world.<key>} the world)")
    values = {_key(k, flags, where): v for k, v in step.items()}
    for key, value in values.items():
        if _axis(key, value) is not None:
            raise BatchSpecError(f"{where}: '{key}' is a list; axes go in the entry, not in a step")
    return name, str(scenario), values


def _check_reference(value: Any, earlier: Sequence[str], generated: bool, where: str) -> None:
    """A placeholder names the world (its seed only a generated world's) or an earlier step."""
    for item in value if isinstance(value, list) else [value]:
        match = PLACEHOLDER.match(item) if isinstance(item, str) else None
        if isinstance(item, str) and "${" in item and match is None:
            raise BatchSpecError(f"{where}: {item!r}: a placeholder is the whole value, '${{world.seed}}' or "
                                 "'${<step>.<report key>}'")
        if match is None:
            continue
        source, key = match.groups()
        if source == "world" and key not in WORLD_KEYS:
            raise BatchSpecError(f"{where}: {item!r}: the world has {', '.join(WORLD_KEYS)}")
        if source == "world" and key == "seed" and not generated:
            raise BatchSpecError(f"{where}: {item!r}: only a generated world ({{family: ..., seed: ...}}) has a seed")
        if source != "world" and source not in earlier:
            raise BatchSpecError(f"{where}: {item!r}: '{source}' is not a step before this one"
                                 + (f" (they are {', '.join(earlier)})" if earlier else ""))


def _seeds(value: Any, where: str) -> list[Any]:
    """A generated world's seeds: one, a list, or ``{first: A, last: B}`` (A to B inclusive)."""
    if isinstance(value, dict):
        first, last = value.get("first"), value.get("last")
        if set(value) != {"first", "last"} or not all(isinstance(v, int) and not isinstance(v, bool)
                                                       for v in (first, last)):
            raise BatchSpecError(f"{where}: world seed {value!r}: a range is {{first: A, last: B}}, two integers")
        return list(range(int(first), int(last) + 1))  # type: ignore[arg-type]  # checked above
    return value if isinstance(value, list) else [value]


def _worlds(value: Any, where: str) -> list[World]:
    if isinstance(value, str):
        return [World(value)]
    if isinstance(value, list) and value and all(isinstance(v, str) for v in value):
        return [World(v) for v in value]
    if isinstance(value, dict):
        unknown = set(value) - {"family", "seed", "small"}
        if unknown or "family" not in value:
            raise BatchSpecError(f"{where}: world: a generated world is {{family: ..., seed: ..., small: ...}}")
        names = value["family"] if isinstance(value["family"], list) else [value["family"]]
        seeds = _seeds(value.get("seed", 0), where)
        if not names:
            raise BatchSpecError(f"{where}: world family []: give at least one")
        if not isinstance(value.get("small", False), bool):
            raise BatchSpecError(f"{where}: world small {value['small']!r}: true or false")
        try:
            families = [family_of(str(n)).value for n in names]
        except WorldGenError as exc:
            raise BatchSpecError(f"{where}: world: {exc}") from None
        if not seeds or not all(isinstance(s, int) and not isinstance(s, bool) and s >= 0 for s in seeds):
            raise BatchSpecError(f"{where}: world seed {value.get('seed')!r}: non-negative integers")
        small = bool(value.get("small", False))
        return [World(world_name(family_of(f), s, small), f, s, small) for f in families for s in seeds]
    raise BatchSpecError(f"{where}: world {value!r}: a world name or file, a list of them, or "
                         "{family: ..., seed: ...}")


def _axes_id(values: Mapping[str, Any]) -> str:
    """``seed=2,params_file=my_dwb``: each axis and its value (a file by its stem)."""
    def text(v: Any) -> str:
        if isinstance(v, list):
            return "_".join(map(text, v))
        if isinstance(v, float):
            return f"{v:g}"
        return Path(v).stem if isinstance(v, str) and ("/" in v or v.endswith((".yaml", ".sdf"))) else str(v)
    return ",".join(_ID_UNSAFE.sub("-", f"{k}={text(v)}") for k, v in values.items())


def argv(step: Step, flags: Mapping[str, Any], parser: argparse.ArgumentParser) -> list[str]:
    """``pppbot eval``'s arguments for ``flags`` (placeholders filled in), without world and out."""
    actions = _flag_names(parser)
    args = [step.scenario]
    for key, value in flags.items():
        action = actions[key]
        option = action.option_strings[0]
        if isinstance(action, argparse.BooleanOptionalAction):
            args.append(option if value else f"--no-{option[2:]}")
        elif isinstance(action, argparse._StoreTrueAction):
            args += [option] if value else []
        elif isinstance(value, list):
            args += [option, *map(str, value)]
        else:
            args += [option, str(value)]
    return args


def check_flags(step: Step, parser: argparse.ArgumentParser, max_wheel_slip: float) -> None:
    """The flags without placeholders are pppbot eval's, each as its rules allow (types, choices,
    ranges, files that exist), before anything runs.

    Raises:
        BatchSpecError: naming the spec, the entry, the run and the flag.
    """
    known = {k: v for k, v in step.flags.items() if not _has_placeholder(v)}
    actions = _flag_names(parser)
    for key, value in known.items():
        switch = isinstance(actions[key], (argparse.BooleanOptionalAction, argparse._StoreTrueAction))
        if switch and not isinstance(value, bool):
            raise BatchSpecError(f"{step.where}: {key} {value!r}: true or false")
        if key in FILES and not Path(str(value)).is_file():
            raise BatchSpecError(f"{step.where}: {key} {value}: no such file")
    try:
        flags = parser.parse_args([*argv(step, known, parser), "--world", "maze"])
        if not any(_has_placeholder(v) for v in step.flags.values()):
            EvalConfig.from_flags(flags, max_wheel_slip)
    except (BatchSpecError, ArgumentError) as exc:
        raise BatchSpecError(f"{step.where}: run '{step.id}': {exc}") from None


def _has_placeholder(value: Any) -> bool:
    return any(isinstance(v, str) and "${" in v for v in (value if isinstance(value, list) else [value]))


def filled(step: Step, reports: Mapping[str, Mapping[str, Any]]) -> dict[str, Any]:
    """``step``'s flags with the placeholders filled in from the world and earlier steps' reports.

    Raises:
        KeyError: a report lacks the value (the message says which and why).
    """
    def value(item: Any) -> Any:
        match = PLACEHOLDER.match(item) if isinstance(item, str) else None
        if match is None:
            return item
        source, key = match.groups()
        if source == "world":
            return step.world.value(key)
        report = reports.get(source) or {}
        if report.get(key) is None:
            why = report.get("failure") or "no such key"
            raise KeyError(f"{item}: {source}'s report has no {key} ({why})")
        return report[key]
    return {k: [value(i) for i in v] if isinstance(v, list) else value(v) for k, v in step.flags.items()}

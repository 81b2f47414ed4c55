"""Which controllers a controller_manager switch activates and deactivates (ros2_control's rules).

A request names controllers to activate and to deactivate, with a strictness:

* ``STRICT``: any problem (an unknown name, a controller not loaded, a name in both lists, a
  command interface another active controller keeps) fails the whole switch, nothing changes;
* ``BEST_EFFORT``: the problems are skipped and the rest is switched; it fails only when every
  name of a non-empty list is unknown;
* ``AUTO`` / ``FORCE_AUTO`` resolve controller chains upstream; pppbot's controllers are never
  chained, so they act as ``STRICT`` here;
* 0 (unset) is read as ``BEST_EFFORT``, as ros2_control reads it (with a warning).

Activating an active controller or deactivating an inactive one is no change and no problem.
"""
from __future__ import annotations

import enum
from collections.abc import Mapping, Sequence
from dataclasses import dataclass


class Strictness(enum.IntEnum):
    UNSET = 0
    BEST_EFFORT = 1
    STRICT = 2
    AUTO = 3
    FORCE_AUTO = 4


class ControllerStatus(enum.Enum):
    """A loaded controller's lifecycle state, by ros2_control's label."""

    UNCONFIGURED = "unconfigured"
    INACTIVE = "inactive"
    ACTIVE = "active"
    FINALIZED = "finalized"


@dataclass(frozen=True)
class ControllerInfo:
    """What the switch needs to know of one loaded controller."""

    status: ControllerStatus
    command_interfaces: tuple[str, ...]  # e.g. ("left_wheel_joint/velocity", ...)


@dataclass(frozen=True)
class SwitchPlan:
    """The outcome: ``ok`` and which controllers change (in order), with the problems found."""

    ok: bool
    activate: tuple[str, ...]
    deactivate: tuple[str, ...]
    problems: tuple[str, ...]

    @property
    def message(self) -> str:
        changes = [f"activate {', '.join(self.activate)}"] if self.activate else []
        changes += [f"deactivate {', '.join(self.deactivate)}"] if self.deactivate else []
        text = "; ".join(changes) or "nothing to switch"
        return text + (f" ({'; '.join(self.problems)})" if self.problems else "")


def plan_switch(controllers: Mapping[str, ControllerInfo], activate: Sequence[str], deactivate: Sequence[str],
                strictness: int) -> SwitchPlan:
    """What a switch request does to ``controllers`` (by name).

    Raises:
        ValueError: ``strictness`` is none of :class:`Strictness`.
    """
    try:
        level = Strictness(strictness)
    except ValueError as exc:
        raise ValueError(f"strictness {strictness}: must be 1 (BEST_EFFORT), 2 (STRICT), 3 (AUTO) or "
                         "4 (FORCE_AUTO)") from exc
    strict = level not in (Strictness.UNSET, Strictness.BEST_EFFORT)
    problems: list[str] = []
    both = sorted(set(activate) & set(deactivate))
    if both:
        problems.append(f"{', '.join(both)} both to activate and to deactivate")
    unknown = [n for n in (*activate, *deactivate) if n not in controllers]
    if unknown:
        problems.append(f"{', '.join(unknown)} not loaded")
    if not strict:
        for names in (activate, deactivate):
            if names and all(n not in controllers for n in names):
                return SwitchPlan(False, (), (), tuple(problems))
    elif problems:
        return SwitchPlan(False, (), (), tuple(problems))
    off = tuple(n for n in dict.fromkeys(deactivate) if n in controllers and n not in both
                and controllers[n].status is ControllerStatus.ACTIVE)
    claimed = {interface: name for name, info in controllers.items()
               if info.status is ControllerStatus.ACTIVE and name not in off for interface in info.command_interfaces}
    on: list[str] = []
    for name in dict.fromkeys(activate):
        if name not in controllers or name in both or controllers[name].status is ControllerStatus.ACTIVE:
            continue
        taken = [f"{i} (held by {claimed[i]})" for i in controllers[name].command_interfaces if i in claimed]
        if taken:
            problems.append(f"{name} needs {', '.join(taken)}")
            if strict:
                return SwitchPlan(False, (), (), tuple(problems))
            continue
        claimed.update({i: name for i in controllers[name].command_interfaces})
        on.append(name)
    return SwitchPlan(True, tuple(on), off, tuple(problems))

"""Which topics a recording or a playback takes: ``ros2 bag``'s topic list, regex,
exclusions, hidden topics, and ``--remap``."""
from __future__ import annotations

import re
from dataclasses import dataclass, field

from pppbot_bag.errors import BagError


def compile_regex(pattern: str, option: str) -> re.Pattern[str] | None:
    """``pattern`` compiled, or None when empty.

    Raises:
        BagError: the pattern is not a valid regular expression (naming the option).
    """
    if not pattern:
        return None
    try:
        return re.compile(pattern)
    except re.error as exc:
        raise BagError(f"{option} '{pattern}' is not a valid regular expression: {exc}") from exc


def is_hidden(topic: str) -> bool:
    return any(part.startswith("_") for part in topic.split("/"))


def normalize_topic(name: str) -> str:
    """``scan`` → ``/scan`` (the recorder runs in the root namespace).

    Raises:
        BagError: not a valid topic name.
    """
    name = name.strip()
    if not name or not re.fullmatch(r"/?[A-Za-z_~{][\w/{}~]*", name) or "//" in name or name.endswith("/"):
        raise BagError(f"'{name}' is not a valid topic name")
    return name if name.startswith("/") else "/" + name


@dataclass(frozen=True)
class TopicSelection:
    """``all_topics`` or the named ``topics`` or ``regex`` matches (``re.fullmatch``, as
    rosbag2's std::regex_match), minus ``exclude_regex`` and ``exclude_topics``."""

    all_topics: bool = False
    topics: tuple[str, ...] = ()
    regex: re.Pattern[str] | None = None
    exclude_regex: re.Pattern[str] | None = None
    exclude_topics: tuple[str, ...] = ()
    include_hidden: bool = False

    def __post_init__(self) -> None:
        object.__setattr__(self, "topics", tuple(normalize_topic(t) for t in self.topics))
        object.__setattr__(self, "exclude_topics", tuple(normalize_topic(t) for t in self.exclude_topics))

    def matches(self, topic: str) -> bool:
        if topic in self.exclude_topics:
            return False
        if self.exclude_regex is not None and self.exclude_regex.fullmatch(topic):
            return False
        if topic in self.topics:
            return True  # named explicitly: hidden or not
        if self.regex is not None and self.regex.fullmatch(topic):
            return self.include_hidden or not is_hidden(topic)
        return self.all_topics and (self.include_hidden or not is_hidden(topic))

    @property
    def selects_anything(self) -> bool:
        return self.all_topics or bool(self.topics) or self.regex is not None


@dataclass(frozen=True)
class Remapping:
    """``--remap old:=new`` pairs."""

    pairs: dict[str, str] = field(default_factory=dict)

    @classmethod
    def parse(cls, items: list[str]) -> Remapping:
        """Raises: BagError for an item that is not ``old:=new`` with topic names."""
        pairs: dict[str, str] = {}
        for item in items:
            old, sep, new = item.partition(":=")
            if not sep:
                raise BagError(f"--remap '{item}' is not of the form old_topic:=new_topic")
            pairs[normalize_topic(old)] = normalize_topic(new)
        return cls(pairs)

    def __call__(self, topic: str) -> str:
        return self.pairs.get(topic, topic)

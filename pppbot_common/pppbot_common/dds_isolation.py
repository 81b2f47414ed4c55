"""A ROS_DOMAIN_ID of one's own, for tests and benchmarks, with DDS kept on this machine.

Each claim holds a lock file per domain in the temporary directory for as long as
the process lives (or a ``with`` block: a batch's run), so concurrent runs (a developer's
and CI's, a batch's workers) never share one.
"""
from __future__ import annotations

import contextlib
import fcntl
import os
import tempfile
from collections.abc import Iterator
from pathlib import Path
from typing import IO

from pppbot_common.dds_participants import LOCALHOST_PEERS, own_participants

# Linux domain IDs that map to valid DDS ports: 0-101 and 215-232. 0 is the default
# every ROS user runs in, so runs avoid it.
#: The largest domain ID whose DDS ports exist (Fast DDS: 7400 + 250 × domain + offsets < 65536).
MAX_DOMAIN_ID = 232
DOMAIN_IDS = [*range(1, 102), *range(215, MAX_DOMAIN_ID + 1)]
_held: list[IO[str]] = []


def domain_id_problem(value: str | None) -> str | None:
    """What is wrong with a ``ROS_DOMAIN_ID`` value (None: unset or fine)."""
    if value is None or value.strip() == "":
        return None
    try:
        domain = int(value)
    except ValueError:
        domain = -1
    if not 0 <= domain <= MAX_DOMAIN_ID:
        return (f"ROS_DOMAIN_ID={value!r} must be a whole number from 0 to {MAX_DOMAIN_ID} (DDS has no ports "
                "beyond that); 0-101 and 215-232 also keep clear of Linux's ephemeral ports")
    return None


def _try_claim(domain: int) -> IO[str] | None:
    """The lock file of ``domain``, locked (the claim), or None when another process holds it."""
    lock = open(Path(tempfile.gettempdir()) / f"pppbot-ros-domain-{domain}.lock", "w")  # noqa: SIM115
    try:
        fcntl.flock(lock, fcntl.LOCK_EX | fcntl.LOCK_NB)
    except BlockingIOError:
        lock.close()
        return None
    return lock


def _claim() -> tuple[int, IO[str]]:
    start = os.getpid() % len(DOMAIN_IDS)
    for i in range(len(DOMAIN_IDS)):
        domain = DOMAIN_IDS[(start + i) % len(DOMAIN_IDS)]
        lock = _try_claim(domain)
        if lock is not None:
            return domain, lock
    raise RuntimeError("every ROS domain ID is held by another pppbot run")


def claim_domain_id() -> int:
    """A domain ID no other claimant on this machine holds (held until this process ends).

    Raises:
        RuntimeError: every domain ID is taken.
    """
    domain, lock = _claim()
    _held.append(lock)  # held open (and locked) for the whole process: the lock is the claim
    return domain


@contextlib.contextmanager
def claimed_domain_id() -> Iterator[int]:
    """A domain ID no other claimant on this machine holds, for the ``with`` block (a batch's run:
    its child processes use it and it is free again after them).

    Raises:
        RuntimeError: every domain ID is taken.
    """
    domain, lock = _claim()
    try:
        yield domain
    finally:
        lock.close()  # closing the file lets the lock go


def isolate_dds() -> int:
    """Set this process's (and its children's) environment: own domain, localhost only."""
    domain = claim_domain_id()
    os.environ["ROS_DOMAIN_ID"] = str(domain)
    os.environ["ROS_AUTOMATIC_DISCOVERY_RANGE"] = "LOCALHOST"
    os.environ.pop("ROS_STATIC_PEERS", None)
    os.environ.pop("ROS_LOCALHOST_ONLY", None)
    return domain


def fresh_domain_if_crowded(limit: int = LOCALHOST_PEERS // 2) -> int | None:
    """When this process holds ``limit`` or more participants in its ``ROS_DOMAIN_ID`` (a test
    session's in-process contexts that rclpy has not let go yet), move it and its future children
    to a domain of their own (the new ID; None: nothing to do). New participants would otherwise
    get IDs past :data:`LOCALHOST_PEERS`, where they do not find each other."""
    domain = int(os.environ.get("ROS_DOMAIN_ID", "0") or 0)
    if own_participants(domain) < limit:
        return None
    new = claim_domain_id()
    os.environ["ROS_DOMAIN_ID"] = str(new)
    return new

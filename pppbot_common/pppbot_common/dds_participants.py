"""Which DDS participants of a ROS domain live on this machine, read from /proc (Linux) without
joining the domain: every Fast DDS participant binds its domain's metatraffic unicast port
``7400 + 250 × domain + 10 + 2 × participant_id``.

A new launch asks :func:`others_on_this_machine` whether anything besides itself and the
processes that started it takes part in its domain: with discovery kept on this machine, none
means no simulation can be running there, and it need not listen for one.
"""
from __future__ import annotations

import os
from pathlib import Path

#: The participant IDs a Fast DDS participant pings on localhost (rmw_fastrtps's
#: maxInitialPeersRange with ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST): two participants whose IDs
#: are both past it never discover each other.
LOCALHOST_PEERS = 32
#: participant IDs looked for (Fast DDS tries IDs upwards until a port is free)
_MAX_PARTICIPANT_ID = 120


def domain_ports(domain: int) -> dict[int, str] | None:
    """The metatraffic unicast ports bound in ``domain`` on this machine, each with its socket's
    inode; None where /proc has no UDP tables (not Linux)."""
    base = 7400 + 250 * domain + 10
    ports: dict[int, str] = {}
    found = False
    for table in ("/proc/self/net/udp", "/proc/self/net/udp6"):
        try:
            lines = Path(table).read_text().splitlines()[1:]
        except OSError:
            continue
        found = True
        for line in lines:
            fields = line.split()
            port = int(fields[1].rsplit(":", 1)[1], 16)
            if base <= port < base + 2 * _MAX_PARTICIPANT_ID and (port - base) % 2 == 0:
                ports[port] = fields[9]
    return ports if found else None


def participant_ids(domain: int) -> list[int]:
    """The participant IDs in use in ``domain`` on this machine, ascending (empty where /proc cannot
    tell): IDs past :data:`LOCALHOST_PEERS` are where discovery fails."""
    base = 7400 + 250 * domain + 10
    return sorted((port - base) // 2 for port in domain_ports(domain) or {})


def socket_inodes(pid: int | str = "self") -> set[str]:
    """The inodes of process ``pid``'s sockets (empty when its descriptors cannot be read)."""
    inodes: set[str] = set()
    try:
        descriptors = list(Path(f"/proc/{pid}/fd").iterdir())
    except OSError:
        return inodes
    for fd in descriptors:
        try:
            target = os.readlink(fd)
        except OSError:
            continue
        if target.startswith("socket:["):
            inodes.add(target[8:-1])
    return inodes


def own_participants(domain: int) -> int:
    """How many DDS participants this process holds in ``domain`` (0 where /proc has no such files)."""
    inodes = socket_inodes()
    return sum(inode in inodes for inode in (domain_ports(domain) or {}).values())


def ancestors(pid: int | None = None) -> list[int]:
    """``pid`` (default: this process) and the processes that started it, up to init."""
    chain = []
    current = os.getpid() if pid is None else pid
    while current > 1:
        chain.append(current)
        try:
            stat = Path(f"/proc/{current}/stat").read_text()
        except OSError:
            break
        current = int(stat.rsplit(")", 1)[1].split()[1])  # the field after the name (which may hold spaces)
    return chain


def others_on_this_machine(domain: int) -> int | None:
    """How many participants in ``domain`` on this machine are held by processes other than this
    one and those that started it (a test runner's or a script's own nodes are not another
    simulation); None where /proc cannot tell."""
    ports = domain_ports(domain)
    if ports is None:
        return None
    ours: set[str] = set()
    for pid in ancestors():
        ours |= socket_inodes(pid)
    return sum(inode not in ours for inode in ports.values())


def discovery_stays_on_this_machine(environ: dict[str, str] | None = None) -> bool:
    """Whether ROS 2 discovery reaches no other machine: ``ROS_AUTOMATIC_DISCOVERY_RANGE`` LOCALHOST
    or OFF (or Humble's ``ROS_LOCALHOST_ONLY=1`` with no range set), and no ``ROS_STATIC_PEERS``."""
    env = os.environ if environ is None else environ
    if env.get("ROS_STATIC_PEERS", "").strip():
        return False
    reach = env.get("ROS_AUTOMATIC_DISCOVERY_RANGE", "").strip().upper()
    if reach:
        return reach in ("LOCALHOST", "OFF")
    return env.get("ROS_LOCALHOST_ONLY", "") == "1"

"""Print the pinned lock of the running environment (used by `make lock`).

Lists only distributions that pip installed; the ROS wheels also ship egg-info
folders for their Python packages (action_msgs, rclpy, ...) that are not PyPI
distributions and must not be pinned.
"""
from __future__ import annotations

import importlib.metadata

HEADER = """\
# Full pinned lock of requirements.in, made by 'make lock' (a fresh venv's distributions).
# Setup installs exactly this; requirements.in lists the direct dependencies."""


def main() -> None:
    pins = set()
    for dist in importlib.metadata.distributions():
        if dist.read_text("INSTALLER") is None:
            continue
        name = dist.metadata["Name"].lower()
        if name == "pip":
            continue
        pins.add(f"{name}=={dist.version}")
    print(HEADER)
    print("\n".join(sorted(pins)))


if __name__ == "__main__":
    main()

"""pppbot's example plugin package: a planner, a DWB critic and a behaviour-tree node of a user's
own, registered in ``pyproject.toml``'s entry points and named in YAML by their type names."""

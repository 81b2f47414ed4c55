"""Global planning: a cost-aware grid A* with any-angle smoothing (Nav2's planner server's algorithms)."""

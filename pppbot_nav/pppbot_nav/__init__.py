"""Map server, map saver, AMCL, costmaps, planner, controller and navigator for ppp_bot (Nav2's role)."""

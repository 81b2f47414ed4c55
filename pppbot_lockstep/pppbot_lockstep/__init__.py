"""pppbot_lockstep: how pppbot's nodes run, and lockstep."""

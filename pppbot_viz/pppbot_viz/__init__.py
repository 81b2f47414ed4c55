"""pppbot_viz: the live view (rerun) and the Foxglove bridge."""

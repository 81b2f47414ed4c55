"""AMCL's core without ROS: motion models, laser models, the particle filter and the localizer."""

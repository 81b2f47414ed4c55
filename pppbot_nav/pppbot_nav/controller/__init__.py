"""Path following: Nav2's Regulated Pure Pursuit controller and its goal and progress checkers, without ROS."""

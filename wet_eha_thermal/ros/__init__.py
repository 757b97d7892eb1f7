"""Thin rclpy nodes over the estimator core and the simulated rig (the only ROS imports)."""

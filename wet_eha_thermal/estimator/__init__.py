"""Estimator core: samples in, estimates and alerts out (no ROS import)."""

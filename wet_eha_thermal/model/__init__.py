"""Pure-numerics thermal model of the wet EHA (no ROS import in this package)."""

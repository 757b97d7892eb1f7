"""Record runs to rosbag2-compatible MCAP files and read them back fast."""

"""PRVO planner: a per-robot ROS 2 node around a numpy core."""

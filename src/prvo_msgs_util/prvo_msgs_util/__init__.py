"""Conversions between ROS 2 messages and numpy arrays for the PRVO stack."""

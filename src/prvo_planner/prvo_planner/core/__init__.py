"""Numerical core of PRVO: plain numpy, no ROS imports."""

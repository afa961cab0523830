#!/bin/bash
# Source ROS 2 Jazzy and the prvo workspace, then run the given command.
set -e
source /opt/ros/jazzy/setup.bash
source /prvo/ros2_ws/install/setup.bash
exec "$@"

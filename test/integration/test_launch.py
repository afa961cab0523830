"""`ros2 launch prvo_sim scenario.launch.py scenario:=headon2` runs the team; one Ctrl-C stops it.

Runs where `launch` is importable (a ROS 2 install, or launch installed from its sources);
skipped elsewhere.
"""

import os
import signal

from nav_msgs.msg import Odometry
import numpy as np
import pytest

from prvo_msgs_util import GROUND_TRUTH, ODOM_QOS, robot_topic
from prvo_sim.scenario import find_scenario, load_scenario

pytestmark = pytest.mark.integration
pytest.importorskip('launch')

# What `ros2 launch PACKAGE FILE ARGUMENTS` does (ros2launch's launch_a_launch_file).
LAUNCHER = """
import sys
import launch
from ament_index_python.packages import get_package_share_directory
from launch.actions import IncludeLaunchDescription
from launch.launch_description_sources import AnyLaunchDescriptionSource

path = get_package_share_directory('prvo_sim') + '/launch/scenario.launch.py'
arguments = [argument.split(':=', 1) for argument in sys.argv[1:]]
service = launch.LaunchService(argv=sys.argv[1:], noninteractive=True)
service.include_launch_description(launch.LaunchDescription([IncludeLaunchDescription(
    AnyLaunchDescriptionSource(path), launch_arguments=arguments)]))
sys.exit(service.run())
"""


def test_launch_runs_the_scenario_and_stops_cleanly_on_one_ctrl_c(children, probe,
                                                                  python_executable, tmp_path):
    scenario = load_scenario(find_scenario('headon2'))
    launcher = tmp_path / 'launcher.py'
    launcher.write_text(LAUNCHER)
    process = children.start('launch', [python_executable, str(launcher), 'scenario:=headon2',
                                        'mode:=realtime'])
    progress = {}

    def keep(name, msg):
        position = np.array([msg.pose.pose.position.x, msg.pose.pose.position.y])
        start = next(robot.start for robot in scenario.robots if robot.name == name)
        goal = next(robot.goal for robot in scenario.robots if robot.name == name)
        # How much closer to its goal than at the start the robot is [m].
        progress[name] = np.linalg.norm(goal - start) - np.linalg.norm(goal - position)

    for robot in scenario.robots:
        probe.node.create_subscription(Odometry, robot_topic(robot.name, GROUND_TRUTH),
                                       lambda msg, name=robot.name: keep(name, msg), ODOM_QOS)
    probe.wait_until(lambda: process.poll() is not None or (
        len(progress) == len(scenario.robots) and min(progress.values()) > 0.5),
        timeout=120.0, what='every robot 0.5 m closer to its goal')
    assert process.poll() is None, children.output(process)
    # Ctrl-C in a terminal: SIGINT to every process of the group, launch and the nodes, and
    # launch passes it on to the nodes again.
    os.killpg(process.pid, signal.SIGINT)
    assert process.wait(timeout=60.0) == 0, children.output(process)
    output = children.output(process)
    assert 'Traceback' not in output and 'process has died' not in output, output
    # Every node, not only launch, ended with exit code 0.
    assert output.count('process has finished cleanly') == 1 + len(scenario.robots), output

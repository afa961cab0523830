"""A filter started from the Nav2-style parameter file, and the Nav2 stand-in node, live.

The shipped file is rewritten under a robot's namespace as nav2_bringup rewrites its parameter
file (the namespace as root key); the filter it starts must read the remapped topics of
docs/nav2.md and pass a free command on bit for bit.
"""

import pathlib
import threading

from geometry_msgs.msg import Twist
from nav_msgs.msg import Odometry
import numpy as np
import pytest
from rclpy.serialization import serialize_message
import yaml

from prvo_msgs_util import CMD_VEL_QOS, ODOM_QOS, make_odometry

pytestmark = pytest.mark.integration

PARAMS = (pathlib.Path(__file__).resolve().parents[2]
          / 'src/prvo_planner/config/nav2_prvo_params.yaml')
NOISE = 1e-4 * np.eye(2)


def _rewritten(tmp_path, namespace):
    """Return the shipped parameter file under NAMESPACE, as RewrittenYaml(root_key=) does."""
    document = yaml.safe_load(PARAMS.read_text())
    # Alone: no neighbour to wait for.
    document['prvo_filter']['ros__parameters']['neighbors'] = ['']
    path = tmp_path / f'{namespace}_prvo.yaml'
    path.write_text(yaml.safe_dump({namespace: document}))
    return path


def test_the_parameter_file_starts_a_filter_on_the_nav2_topics(children, probe,
                                                              ros2_executable, tmp_path):
    children.start('filter', [ros2_executable('prvo_planner', 'planner'), '--ros-args',
                              '-r', '__ns:=/robot_0', '-r', '__node:=prvo_filter',
                              '--params-file', str(_rewritten(tmp_path, 'robot_0'))])
    received = probe.record(Twist, '/robot_0/cmd_vel_prvo', CMD_VEL_QOS)
    state = probe.node.create_publisher(Odometry, '/robot_0/odometry/global', ODOM_QOS)
    upstream = probe.node.create_publisher(Twist, '/robot_0/cmd_vel_smoothed', CMD_VEL_QOS)
    probe.wait_until(lambda: probe.node.count_subscribers('/robot_0/cmd_vel_smoothed') > 0
                     and probe.node.count_publishers('/robot_0/cmd_vel_prvo') > 0, 60.0,
                     'the filter on cmd_vel_smoothed -> cmd_vel_prvo')
    probe.wait_until(lambda: probe.node.count_subscribers('/robot_0/odometry/global') > 0,
                     30.0, 'the filter reading odometry/global')
    def twist_of(linear, angular):
        twist = Twist()
        twist.linear.x, twist.linear.y = linear
        twist.angular.z = angular
        return twist

    stamps = iter(range(1, 10 ** 6))

    def send(twist):
        """Send a fresh state, then TWIST; return the filter's answer."""
        state.publish(make_odometry(0.05 * next(stamps), [1.0, 2.0], [0.0, 0.0], NOISE, NOISE,
                                    yaw=0.4))
        # The state first: the filter answers from it (a stale state is answered by zero).
        threading.Event().wait(0.2)
        count = len(received)
        upstream.publish(twist)
        probe.wait_until(lambda: len(received) > count, 15.0, 'the filtered twist')
        return received[count]

    # Until the filter holds the state (the first messages may go before the match).
    warm_up = twist_of((0.1, 0.0), 0.0)
    for _ in range(100):
        if serialize_message(send(warm_up)) == serialize_message(warm_up):
            break
    else:
        pytest.fail('no warm-up twist passed on')
    start = len(received)
    sent = []
    for linear, angular in (((0.3, 0.0), 0.7), ((0.0, 0.0), -1.1), ((-0.2, 0.0), 0.0)):
        twist = twist_of(linear, angular)
        sent.append(serialize_message(twist))
        send(twist)
    received = received[start:]
    assert [serialize_message(message) for message in received] == sent


def test_the_stand_in_answers_each_odometry_with_its_stamp(children, probe, ros2_executable):
    from geometry_msgs.msg import TwistStamped

    children.start('stand_in', [ros2_executable('prvo_sim', 'nav2_stand_in'), '--ros-args',
                                '-r', '__ns:=/robot_0', '-p', 'waypoints:=[4.0, 0.0]',
                                '-p', 'speed:=0.5', '-p', 'answer_odometry:=true',
                                '-p', 'enable_stamped_cmd_vel:=true'])
    received = probe.record(TwistStamped, '/robot_0/cmd_vel_smoothed', CMD_VEL_QOS)
    odometry = probe.node.create_publisher(Odometry, '/robot_0/odom', ODOM_QOS)
    probe.wait_until(lambda: probe.node.count_subscribers('/robot_0/odom') > 0, 60.0,
                     'the stand-in reading odom')
    for step in range(3):
        odometry.publish(make_odometry(0.1 * (step + 1), [0.0, 0.0], [0.0, 0.0], NOISE, NOISE))
        probe.wait_until(lambda step=step: len(received) > step, 15.0, 'the answer')
    assert [message.header.stamp.nanosec for message in received] == [
        100_000_000, 200_000_000, 300_000_000]
    assert all(message.twist.linear.x == 0.5 and message.header.frame_id == 'robot_0/base_link'
               for message in received)

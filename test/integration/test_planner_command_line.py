"""A running planner through what the ROS command line uses: parameter services and topics.

`ros2 param set/get/delete/dump` call a node's parameter services; `ros2 topic pub` publishes a
message with an empty header. Each test drives the planner the way those tools do.
"""

import threading
import time

from geometry_msgs.msg import PoseStamped, TwistStamped
from nav_msgs.msg import Odometry
import numpy as np
import pytest
from rcl_interfaces.msg import Log, Parameter, ParameterType, ParameterValue
from rcl_interfaces.srv import GetParameters, ListParameters, SetParameters
from rclpy.parameter import parameter_value_to_python
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy
import yaml

from prvo_msgs_util import (
    CMD_VEL_QOS,
    GOAL_QOS,
    ODOM_QOS,
    make_odometry,
    make_pose_stamped,
    robot_topic,
    stamp_to_seconds,
)

pytestmark = pytest.mark.integration

NODE = '/robot_0/planner'
LOGGER = 'robot_0.planner'
COVARIANCE = 1e-6 * np.eye(2)
# How /rosout is published (rcl's defaults): a late subscriber still gets the history.
ROSOUT_QOS = QoSProfile(depth=1000, reliability=ReliabilityPolicy.RELIABLE,
                        durability=DurabilityPolicy.TRANSIENT_LOCAL)


class LivePlanner:
    """A planner for robot_0 started with PARAMETERS ('-p' strings), driven through a probe."""

    def __init__(self, children, ros2_executable, probe, *ros_arguments, label='planner'):
        self.children = children
        self.probe = probe
        self.process = children.start(label, [
            ros2_executable('prvo_planner', 'planner'), '--ros-args', '-r', '__ns:=/robot_0',
            *ros_arguments])
        self._lock = threading.Lock()
        self.commands = {}
        self.logs = []
        node = probe.node
        node.create_subscription(TwistStamped, robot_topic('robot_0', 'cmd_vel'),
                                 self._on_cmd_vel, CMD_VEL_QOS)
        node.create_subscription(Log, '/rosout', self._on_log, ROSOUT_QOS)
        self.odometry = {robot: node.create_publisher(Odometry, robot_topic(robot, 'odom'),
                                                      ODOM_QOS)
                         for robot in ('robot_0', 'robot_1')}
        self.goal_pose = node.create_publisher(PoseStamped, robot_topic('robot_0', 'goal_pose'),
                                               GOAL_QOS)
        self.clients = {service: node.create_client(service, f'{NODE}/{name}') for service, name
                        in ((SetParameters, 'set_parameters'), (GetParameters, 'get_parameters'),
                            (ListParameters, 'list_parameters'))}
        self.wait(lambda: all(client.service_is_ready() for client in self.clients.values()),
                  'the parameter services')

    def _on_cmd_vel(self, msg):
        with self._lock:
            self.commands[round(stamp_to_seconds(msg.header.stamp), 6)] = np.array(
                [msg.twist.linear.x, msg.twist.linear.y])

    def _on_log(self, msg):
        if msg.name == LOGGER:
            with self._lock:
                self.logs.append(msg.msg)

    def wait(self, condition, what, timeout=30.0):
        """Wait until CONDITION(); fail with the planner's log if it exits or time runs out."""
        # Not the probe's wait_until: it holds the probe's lock, and CONDITION may call a service.
        deadline = time.monotonic() + timeout
        while not (condition() or self.process.poll() is not None):
            if time.monotonic() > deadline:
                raise AssertionError(f'{what} did not happen within {timeout} s; planner log:\n'
                                     f'{self.children.output(self.process)}')
            threading.Event().wait(0.05)
        assert self.process.poll() is None, (
            f'planner exited ({self.process.returncode}):\n{self.children.output(self.process)}')

    def call(self, service, request):
        """Return the answer of the planner's parameter SERVICE to REQUEST.

        Sent again if unanswered (`probe.call`): Fast DDS drops the answer to a request that
        reaches the planner before it has matched the probe's response reader ("failed to send
        response (timeout)" in the planner's log).
        """
        try:
            return self.probe.call(self.clients[service], request,
                                   f'the answer of {service.__name__}', timeout=30.0,
                                   resend_after=5.0)
        except TimeoutError as error:
            raise AssertionError(
                f'{error}; planner log:\n{self.children.output(self.process)}') from None

    def set(self, name, value):
        """Set parameter NAME to the ParameterValue VALUE; return the SetParametersResult."""
        return self.call(SetParameters, SetParameters.Request(
            parameters=[Parameter(name=name, value=value)])).results[0]

    def get(self, name):
        """Return parameter NAME's value as Python (lists for arrays, None when unset)."""
        value = self.call(GetParameters, GetParameters.Request(names=[name])).values[0]
        return parameter_value_to_python(value)

    def command_for(self, stamp, position):
        """Send robot_0's odometry at STAMP, POSITION; return the command that answers it."""
        self.wait(lambda: self.odometry['robot_0'].get_subscription_count() > 0,
                  'the planner subscribing to its odometry')
        self.odometry['robot_0'].publish(make_odometry(
            stamp, position, [0.0, 0.0], COVARIANCE, COVARIANCE,
            child_frame_id='robot_0/base_link'))
        self.wait(lambda: round(stamp, 6) in self.commands, f'the command for {stamp} s')
        with self._lock:
            return self.commands[round(stamp, 6)]

    def logged(self, text):
        """Return the planner's /rosout messages so far that contain TEXT."""
        with self._lock:
            return [line for line in self.logs if text in line]


@pytest.fixture
def live_planner(children, ros2_executable, probe):
    """Return a factory of `LivePlanner`s (positional arguments: ROS arguments)."""
    return lambda *arguments, **options: LivePlanner(children, ros2_executable, probe,
                                                     *arguments, **options)


def _double_array(values):
    # What `ros2 param set NODE goal "[2.0, -1.0]"` sends.
    return ParameterValue(type=ParameterType.PARAMETER_DOUBLE_ARRAY, double_array_value=values)


def _heading(velocity, target, position=(0.0, 0.0)):
    """Return the cosine between VELOCITY and the direction from POSITION to TARGET."""
    direction = np.asarray(target, dtype=float) - position
    return float(velocity @ direction / np.linalg.norm(velocity) / np.linalg.norm(direction))


def test_deleting_the_goal_is_refused_and_it_stays_settable(live_planner):
    """`ros2 param delete` sends a value of type NOT_SET; the goal must survive it."""
    planner = live_planner('-p', 'goal:=[1.0, 0.0]')
    refused = planner.set('goal', ParameterValue())
    assert not refused.successful and 'goal' in refused.reason, refused
    names = planner.call(ListParameters, ListParameters.Request()).result.names
    assert 'goal' in names
    assert planner.get('goal') == [1.0, 0.0]
    accepted = planner.set('goal', _double_array([2.0, -1.0]))
    assert accepted.successful, accepted.reason
    assert planner.get('goal') == [2.0, -1.0]
    assert _heading(planner.command_for(0.1, (0.0, 0.0)), (2.0, -1.0)) > 0.99


def test_a_goal_pose_is_kept_through_a_parameter_change_and_read_back(live_planner):
    planner = live_planner('-p', 'goal:=[-3.0, 0.0]')
    assert _heading(planner.command_for(0.1, (0.0, 0.0)), (-3.0, 0.0)) > 0.99

    def goal_read_back():
        # Published until taken: the probe's publisher may not have matched yet.
        planner.goal_pose.publish(make_pose_stamped(0.0, (2.0, -1.0)))
        return planner.get('goal') == [2.0, -1.0]

    planner.wait(goal_read_back, 'the goal parameter showing the goal_pose')
    accepted = planner.set('eta', ParameterValue(type=ParameterType.PARAMETER_DOUBLE,
                                                 double_value=0.85))
    assert accepted.successful, accepted.reason
    assert planner.get('goal') == [2.0, -1.0]
    assert _heading(planner.command_for(0.2, (0.0, 0.0)), (2.0, -1.0)) > 0.99


def test_a_goal_pose_without_a_frame_is_in_the_map_frame(live_planner):
    """`ros2 topic pub` without a header sends an empty frame_id, as cmd_vel may."""
    planner = live_planner('-p', 'goal:=[-3.0, 0.0]')
    stamp = [0.0]

    def heading_for_the_goal_pose():
        planner.goal_pose.publish(make_pose_stamped(0.0, (2.0, -1.0), frame_id=''))
        stamp[0] += 0.1
        return _heading(planner.command_for(stamp[0], (0.0, 0.0)), (2.0, -1.0)) > 0.99

    planner.wait(heading_for_the_goal_pose, 'a command towards the frameless goal_pose')
    assert not planner.logged('ignoring goal')


def test_dumped_parameters_load_back_with_params_file(live_planner, children, tmp_path):
    """A `ros2 param dump` file (unset parameters as null) starts the planner again."""
    planner = live_planner('-p', 'goal:=[1.0, 0.0]', '-p', 'eta:=0.9')
    names = sorted(planner.call(ListParameters, ListParameters.Request()).result.names)
    values = planner.call(GetParameters, GetParameters.Request(names=names)).values
    dumped = {name: parameter_value_to_python(value)
              for name, value in zip(names, values, strict=True)}
    assert dumped['neighbors'] is None
    dump = tmp_path / 'planner.yaml'
    dump.write_text(yaml.dump({NODE: {'ros__parameters': dumped}}, default_flow_style=False))
    assert 'neighbors: null' in dump.read_text()
    assert children.interrupt(planner.process) == 0

    reloaded = live_planner('--params-file', str(dump), label='reloaded')
    values = reloaded.call(GetParameters, GetParameters.Request(names=names)).values
    assert {name: parameter_value_to_python(value)
            for name, value in zip(names, values, strict=True)} == dumped
    assert _heading(reloaded.command_for(0.1, (0.0, 0.0)), (1.0, 0.0)) > 0.99


def test_arrival_is_logged_once_while_noise_moves_the_robot_about_its_goal(live_planner):
    planner = live_planner('-p', 'goal:=[1.0, 0.0]', '-p', 'goal_tolerance:=0.2')
    # In, out by less than twice the tolerance (noise), in, out far (left), in again; each for
    # three measurements a second apart, so that the tracked position follows.
    distances = [distance for distance in (0.05, 0.3, 0.05, 0.3, 0.05, 1.0, 0.05, 0.3, 0.05)
                 for _ in range(3)]
    for step, distance in enumerate(distances, start=1):
        planner.command_for(float(step), (1.0 - distance, 0.0))
    # The log goes out in order: once this line is in, every earlier one is.
    planner.goal_pose.publish(make_pose_stamped(0.0, (3.0, 0.0)))
    planner.wait(lambda: planner.logged('new goal'), 'the new goal logged')
    assert len(planner.logged('arrived')) == 2, planner.logs


def test_invalid_parameter_at_startup_is_logged_under_the_node_logger(children, ros2_executable):
    process = children.start('planner', [
        ros2_executable('prvo_planner', 'planner'), '--ros-args', '-r', '__ns:=/robot_0',
        '-p', 'eta:=1.5'])
    assert process.wait(timeout=30.0) == 2
    fatal = [line for line in children.output(process).splitlines() if '[FATAL]' in line]
    assert len(fatal) == 1 and f'[{LOGGER}]: invalid parameter' in fatal[0], fatal
    assert 'eta' in fatal[0], fatal


def test_a_neighbour_tracked_again_after_it_was_dropped_is_logged(live_planner):
    """A simulator restart: the neighbour falls silent, then comes back from time zero."""
    planner = live_planner('-p', 'goal:=[5.0, 0.0]', '-p', 'neighbors:=[robot_1]',
                           '-p', 'neighbor_timeout:=0.5')
    neighbour = planner.odometry['robot_1']
    planner.wait(lambda: neighbour.get_subscription_count() > 0, 'the neighbour subscription')
    for step in range(1, 4):
        neighbour.publish(make_odometry(100.0 + 0.1 * step, (0.0, 2.0), (0.0, 0.0),
                                        COVARIANCE, COVARIANCE))
    planner.wait(lambda: planner.logged('dropped neighbour robot_1'), 'the neighbour dropped')
    neighbour.publish(make_odometry(0.1, (0.0, 2.0), (0.0, 0.0), COVARIANCE, COVARIANCE))
    planner.wait(lambda: planner.logged('tracking robot_1 again'),
                 'the neighbour tracked again, logged')

"""A live planner fed by a probe: bad odometry, a silent neighbour, duplicates, shutdown."""

import signal
import threading

from geometry_msgs.msg import PolygonStamped, TwistStamped, Vector3Stamped
from nav_msgs.msg import Path
import numpy as np
import pytest
from rclpy.serialization import serialize_message

from prvo_msgs_util import (
    ANNOUNCEMENT_QOS,
    CMD_VEL_QOS,
    GOAL_QOS,
    MAX_PATH_POSES,
    ODOM_QOS,
    footprint_message,
    make_odometry,
    make_path,
    robot_topic,
    share_message,
    stamp_to_seconds,
)

pytestmark = pytest.mark.integration

ROBOTS = ('robot_0', 'robot_1', 'robot_2')
NOISE = 0.0025 * np.eye(2)


class FedPlanner:
    """A planner for robot_0 with neighbours robot_1 and robot_2, whose odometry a probe sends.

    With ANNOUNCE, the probe also announces the neighbours as planners do (radius 0.3, share
    0.5, from the start, latched): a planner waits for its listed neighbours' announcements
    before it plans.
    """

    def __init__(self, children, ros2_executable, probe, announce=True, **parameters):
        values = {'goal': '[5.0, 0.0]', 'neighbors': '[robot_1, robot_2]',
                  'sync_timeout': 0.3, 'neighbor_timeout': 3600.0}
        values.update(parameters)
        argv = [ros2_executable('prvo_planner', 'planner'), '--ros-args', '-r', '__ns:=/robot_0']
        for name, value in values.items():
            argv += ['-p', f'{name}:={value}']
        self.children = children
        self.process = children.start('planner', argv)
        self.probe = probe
        self._lock = threading.Lock()
        self.answers = []
        probe.node.create_subscription(
            TwistStamped, robot_topic('robot_0', 'cmd_vel'), self._on_cmd_vel, CMD_VEL_QOS)
        self.publishers = {robot: probe.node.create_publisher(
            type(make_odometry(0.0, [0, 0], [0, 0], NOISE, NOISE)), robot_topic(robot, 'odom'),
            ODOM_QOS) for robot in ROBOTS}
        if announce:
            for robot in ROBOTS[1:]:
                probe.node.create_publisher(
                    PolygonStamped, robot_topic(robot, 'footprint'), ANNOUNCEMENT_QOS).publish(
                    footprint_message(0.3, f'{robot}/base_link', 0.0))
                probe.node.create_publisher(
                    Vector3Stamped, robot_topic(robot, 'avoidance_share'),
                    ANNOUNCEMENT_QOS).publish(share_message(0.5, f'{robot}/base_link', 0.0))
        probe.wait_until(
            lambda: all(p.get_subscription_count() > 0 for p in self.publishers.values())
            or self.process.poll() is not None, timeout=60.0, what='the planner subscribing')
        assert self.process.poll() is None, children.output(self.process)

    def _on_cmd_vel(self, msg):
        with self._lock:
            self.answers.append(stamp_to_seconds(msg.header.stamp))

    def answered(self, stamp):
        """Return how many commands answered STAMP so far."""
        with self._lock:
            return sum(1 for answer in self.answers if abs(answer - stamp) < 1e-6)

    def send(self, robot, stamp, position=(0.0, 0.0), velocity=(0.5, 0.0), change=None):
        """Publish ROBOT's odometry at STAMP; CHANGE(msg) breaks it before it goes."""
        msg = make_odometry(stamp, position, velocity, NOISE, NOISE)
        if change is not None:
            change(msg)
        self.publishers[robot].publish(msg)

    def send_step(self, stamp, robots=ROBOTS):
        """Publish the neighbours' odometry at STAMP, then the robot's own."""
        for robot in sorted(robots, reverse=True):
            self.send(robot, stamp, position=(0.0, 2.0 * ROBOTS.index(robot)))

    def wait_answer(self, stamp, timeout=20.0):
        """Wait until a command answers STAMP; fail naming the planner's log otherwise."""
        try:
            self.probe.wait_until(lambda: self.answered(stamp) > 0
                                  or self.process.poll() is not None,
                                  timeout=timeout, what=f'the answer to stamp {stamp}')
        except TimeoutError as error:
            raise AssertionError(f'{error}; planner log:\n'
                                 f'{self.children.output(self.process)}') from None
        assert self.process.poll() is None, (
            f'planner exited ({self.process.returncode}):\n{self.children.output(self.process)}')


@pytest.fixture
def fed_planner(children, ros2_executable, probe):
    """Return a factory of `FedPlanner`s (keyword arguments: planner parameters)."""
    return lambda **parameters: FedPlanner(children, ros2_executable, probe, **parameters)


def _set_stamp(sec, nanosec=0):
    def setter(msg):
        msg.header.stamp.sec, msg.header.stamp.nanosec = sec, nanosec
    return setter


# name: (how the odometry is broken, what the planner logs about it, naming the topic after
# "odometry on "). Warnings are throttled per topic and kind: the wall-clock stamp is refused
# like the first one, within the same period, so it leaves no line of its own.
BAD_ODOMETRY = {
    'stamp at sec 2^31-1': (_set_stamp(2 ** 31 - 1, 999_999_999),
                            ': stamp 2147483648.000 s is more than 10 s after'),
    'wall-clock stamp': (_set_stamp(1_700_000_000), None),
    'position 1e308': (lambda m: setattr(m.pose.pose.position, 'x', 1.0e308),
                       ': pose.position is beyond 1e+06'),
    'velocity 1e4': (lambda m: setattr(m.twist.twist.linear, 'y', 1.0e4),
                     ': twist.linear is beyond 1000'),
    'variance 1e7': (lambda m: m.pose.covariance.__setitem__(0, 1.0e7),
                     ': pose.covariance has an x variance beyond 1e+06'),
    'stamp 0': (_set_stamp(0, 1), ': time jumped back from'),
}


@pytest.mark.parametrize('robot', ['robot_0', 'robot_1'])
def test_planner_survives_bad_odometry_and_keeps_answering(fed_planner, children, probe, robot):
    planner = fed_planner()
    topic = robot_topic(robot, 'odom')
    stamp = 100.0
    planner.send_step(stamp)
    planner.wait_answer(stamp)
    for name, (change, logged) in BAD_ODOMETRY.items():
        planner.send(robot, stamp + 0.05, change=change)
        if logged is not None:
            # Seen before the next odometry replaces it in the planner's queue of one.
            probe.wait_until(lambda logged=logged: f'on {topic}{logged}' in children.output(
                planner.process) or planner.process.poll() is not None, timeout=20.0,
                what=f'the planner handling {name}')
        stamp += 0.1
        planner.send_step(stamp)
        planner.wait_answer(stamp)
    output = children.output(planner.process)
    assert 'Traceback' not in output and 'Singular matrix' not in output, output


def test_each_own_odometry_is_answered_while_a_neighbour_is_silent(fed_planner):
    """Spaced wider than sync_timeout, every own odometry gets its answer before the next."""
    planner = fed_planner()
    planner.send_step(1.0)
    planner.wait_answer(1.0)
    for step in range(1, 8):
        stamp = 1.0 + 0.1 * step
        planner.send_step(stamp, robots=('robot_0', 'robot_1'))
        planner.wait_answer(stamp)


def test_own_odometry_faster_than_sync_timeout_still_gets_plans(fed_planner, probe):
    """A silent neighbour and odometry every 0.1 s with sync_timeout 0.5 s: plans still come.

    Re-arming the wait on every own odometry postponed every plan until the neighbour was
    dropped; here it never is (neighbor_timeout of an hour).
    """
    planner = fed_planner(sync_timeout=0.5)
    planner.send_step(1.0)
    planner.wait_answer(1.0)
    stamps = [1.0 + 0.1 * step for step in range(1, 31)]
    pace = threading.Event()
    for stamp in stamps:
        planner.send_step(stamp, robots=('robot_0', 'robot_1'))
        # Pacing the sender, not synchronising with the planner: 0.1 s between stamps.
        pace.wait(0.1)
    planner.wait_answer(stamps[-1])
    answered_during_silence = [stamp for stamp in stamps[:-1] if planner.answered(stamp)]
    # The wait runs out every 0.5 s of the 3 s: about five plans, never none.
    assert len(answered_during_silence) >= 2, answered_during_silence


def test_a_duplicate_odometry_stamp_is_answered_again_once(fed_planner):
    planner = fed_planner()
    planner.send_step(1.0)
    planner.wait_answer(1.0)
    planner.send('robot_0', 1.0)
    planner.probe.wait_until(lambda: planner.answered(1.0) == 2, timeout=20.0,
                             what='the re-sent answer to a duplicate')
    for _ in range(3):
        planner.send('robot_0', 1.0)
        # Nothing may answer a further copy; a wait that runs out is the expected outcome.
        with pytest.raises(TimeoutError):
            planner.probe.wait_until(lambda: planner.answered(1.0) > 2, timeout=0.5,
                                     what='a second re-send')
    planner.send_step(1.1)
    planner.wait_answer(1.1)
    # The answers come in order: all copies have been handled by now.
    assert planner.answered(1.0) == 2


def test_a_path_beyond_the_bound_is_ignored_keeping_the_path_in_force(fed_planner, children,
                                                                      probe):
    planner = fed_planner(preferred_source='path')
    publisher = probe.node.create_publisher(Path, robot_topic('robot_0', 'plan'), GOAL_QOS)
    probe.wait_until(lambda: publisher.get_subscription_count() > 0, timeout=60.0,
                     what='the planner subscribing its path')

    def logged(text):
        return text in children.output(planner.process) or planner.process.poll() is not None

    publisher.publish(make_path(0.0, [[0.0, 0.0], [5.0, 0.0]]))
    probe.wait_until(lambda: logged('following a path of 2 poses'), timeout=30.0,
                     what='the path followed')
    # Deserialized, 100,000 poses took 5 s of the control loop's thread, each time sent.
    count = 10 * MAX_PATH_POSES
    long_path = serialize_message(make_path(0.0, np.column_stack(
        [np.linspace(0.0, 5.0, count), np.zeros(count)])))
    publisher.publish(long_path)
    refusal = (f'ignoring path on /robot_0/plan (keeping the path in force): the path has '
               f'{count} poses, more than {MAX_PATH_POSES}')
    probe.wait_until(lambda: logged(refusal), timeout=30.0, what='the long path refused')
    planner.send_step(1.0)
    planner.wait_answer(1.0)
    assert f'following a path of {count}' not in children.output(planner.process)


@pytest.mark.parametrize('moment', ['warm-up', 'planning'])
@pytest.mark.parametrize('signal_number', [signal.SIGINT, signal.SIGTERM])
def test_shutdown_at_any_moment_is_quiet(children, ros2_executable, probe, fed_planner, moment,
                                         signal_number):
    if moment == 'warm-up':
        # Right after start: the node is being built or planning its warm-up encounter.
        process = children.start('planner', [
            ros2_executable('prvo_planner', 'planner'), '--ros-args', '-r', '__ns:=/robot_0',
            '-p', 'goal:=[1.0, 0.0]', '-p', 'num_directions:=4096'])
        probe.wait_until(lambda: 'planning for robot_0' in children.output(process)
                         or process.poll() is not None, timeout=60.0, what='the node built')
    else:
        planner = fed_planner(num_directions=4096)
        process = planner.process
        planner.send_step(1.0)
        planner.wait_answer(1.0)
        # Plans of 4096 headings keep it busy while the signal lands.
        for step in range(1, 6):
            planner.send_step(1.0 + 0.1 * step)
    process.send_signal(signal_number)
    assert process.wait(timeout=30.0) == 0, children.output(process)
    output = children.output(process)
    assert 'FATAL' not in output and 'Traceback' not in output, output

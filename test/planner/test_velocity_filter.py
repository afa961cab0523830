"""The velocity filter: upstream commands pass unchanged when free, timeouts as Nav2's monitor.

The agent-level tests feed measurements and commands with explicit times; the node-level ones
run a real PlannerNode in this process (its own ROS domain) and call its callbacks directly,
catching what it publishes, so that the bytes of every message can be compared.
"""

import dataclasses
import math

import numpy as np
import pytest

from prvo_planner.agent import AgentSettings, PlannerAgent
from prvo_planner.core import PlannerConfig
from prvo_planner.preferred import FilterGate, UpstreamCommand

COVARIANCE = 1e-4 * np.eye(4)


@dataclasses.dataclass(frozen=True)
class _Measurement:
    stamp: float
    position: np.ndarray
    velocity: np.ndarray
    covariance: np.ndarray
    yaw: float = 0.0


def _random_commands(rng, count):
    """Return COUNT upstream (linear (x, y), angular z): spins, back-ups, drives, stops."""
    commands = []
    for index in range(count):
        kind = index % 4
        linear = rng.uniform(-0.6, 0.6, 2)
        angular = float(rng.uniform(-1.5, 1.5))
        if kind == 0:
            linear = np.zeros(2)  # a spin in place
        elif kind == 1:
            linear = np.array([-abs(linear[0]), 0.0])  # backing up
        elif kind == 2:
            angular = 0.0
        commands.append(((float(linear[0]), float(linear[1])), angular))
    return commands


def _filter_agent(kinematics='holonomic', neighbours=None, **settings):
    settings = AgentSettings(preferred_source='velocity', kinematics=kinematics, **settings)
    return PlannerAgent('robot_0', PlannerConfig(max_speed=1.0), settings,
                        listed_neighbours=neighbours)


@pytest.mark.parametrize('kinematics', ['holonomic', 'unicycle'])
def test_free_commands_pass_unchanged(kinematics):
    rng = np.random.default_rng(7)
    agent = _filter_agent(kinematics)
    for step, (linear, angular) in enumerate(_random_commands(rng, 40)):
        yaw = float(rng.uniform(-math.pi, math.pi))
        agent.receive_own(_Measurement(0.1 * step, rng.uniform(-5, 5, 2), rng.uniform(-1, 1, 2),
                                       COVARIANCE, yaw), 0.1 * step)
        upstream = UpstreamCommand(linear, angular, message=object())
        agent.receive_upstream(upstream, 0.1 * step)
        assert agent.ready(0.1 * step)
        command = agent.plan()
        assert command.passed_through and command.upstream is upstream
        if kinematics == 'unicycle':
            assert command.drive == (linear[0], angular)


def test_a_constrained_command_becomes_the_nearest_safe_velocity():
    agent = _filter_agent(neighbours=['robot_1'])
    agent.receive_footprint('robot_1', 0.3, 0.0)
    agent.receive_share('robot_1', 0.0, 0.0)
    agent.receive_neighbour('robot_1', _Measurement(0.0, np.array([1.2, 0.0]), np.zeros(2),
                                                    COVARIANCE), 0.0)
    agent.receive_own(_Measurement(0.0, np.zeros(2), np.array([0.8, 0.0]), COVARIANCE), 0.0)
    agent.receive_upstream(UpstreamCommand((0.8, 0.0), 0.3), 0.0)
    command = agent.plan()
    assert not command.passed_through
    assert command.result is not None and command.result.feasible
    # Heading at a robot 1.2 m ahead at 0.8 m/s is not kept: the plan turns or slows.
    assert np.hypot(*(command.velocity - [0.8, 0.0])) > 0.1
    assert agent.own_announcement.avoidance_share == 0.5


def test_share_follows_the_input():
    agent = _filter_agent()
    assert agent.own_announcement.avoidance_share == 0.0
    for stamp, (linear, share) in enumerate((((0.5, 0.0), 0.5), ((0.0, 0.0), 0.0))):
        agent.receive_own(_Measurement(float(stamp), np.zeros(2), np.zeros(2), COVARIANCE),
                          float(stamp))
        agent.receive_upstream(UpstreamCommand(linear, 0.0), float(stamp))
        agent.plan()
        assert agent.own_announcement.avoidance_share == share


def test_model_none_passes_even_a_command_into_a_neighbour():
    agent = _filter_agent(neighbours=['robot_1'], model='none')
    agent.receive_footprint('robot_1', 0.3, 0.0)
    agent.receive_share('robot_1', 0.0, 0.0)
    agent.receive_neighbour('robot_1', _Measurement(0.0, np.array([0.7, 0.0]), np.zeros(2),
                                                    COVARIANCE), 0.0)
    agent.receive_own(_Measurement(0.0, np.zeros(2), np.zeros(2), COVARIANCE), 0.0)
    agent.receive_upstream(UpstreamCommand((0.8, 0.0), 0.0), 0.0)
    command = agent.plan()
    assert command.passed_through and command.result is None


def test_input_stopping_gives_zeros_for_stop_pub_timeout_then_silence():
    agent = _filter_agent(stop_pub_timeout=2.0)
    published = []
    # 20 Hz: moving for 1 s, then zeros (a smoother ramped down) for 4 s.
    for step in range(100):
        now = 0.05 * step
        agent.receive_own(_Measurement(now, np.zeros(2), np.zeros(2), COVARIANCE), now)
        agent.receive_upstream(UpstreamCommand((0.3 if now < 1.0 else 0.0, 0.0), 0.0), now)
        published.append((now, agent.plan().published))
    first_zero = 20
    assert all(flag for _, flag in published[:first_zero])
    # Zeros are sent from the first on for 2 s, none after.
    for now, flag in published[first_zero:]:
        assert flag == (now - published[first_zero][0] <= 2.0 + 1e-9), now


def test_resuming_publishes_again_and_restarts_the_stop_clock():
    gate = FilterGate(1.0)
    assert gate.publishes(True, 0.0) and gate.publishes(True, 1.0)
    assert not gate.publishes(True, 1.5)
    assert gate.publishes(False, 2.0)
    # A new stop: its zeros are sent again for the whole timeout.
    assert gate.publishes(True, 3.0) and gate.publishes(True, 3.9)
    assert not gate.publishes(True, 4.1)
    assert FilterGate(math.inf).publishes(True, 0.0) and FilterGate(math.inf).publishes(True, 1e9)


def test_stale_own_state_gives_zero_and_fresh_state_resumes():
    agent = _filter_agent(kinematics='unicycle', state_timeout=0.5)
    agent.receive_own(_Measurement(0.0, np.zeros(2), np.zeros(2), COVARIANCE), 0.0)
    agent.receive_upstream(UpstreamCommand((0.4, 0.0), 0.2), 0.0)
    assert not agent.own_state_stale(0.0)
    assert agent.plan().passed_through
    # No odometry for 0.6 s: the command is answered by zero.
    agent.receive_upstream(UpstreamCommand((0.4, 0.0), 0.2), 0.6)
    assert agent.own_state_stale(0.6)
    stopped = agent.stale_answer()
    assert stopped is not None and stopped.drive == (0.0, 0.0)
    assert not agent.upstream_waiting
    # Odometry again: commands pass again.
    agent.receive_own(_Measurement(0.7, np.zeros(2), np.zeros(2), COVARIANCE), 0.7)
    agent.receive_upstream(UpstreamCommand((0.4, 0.0), 0.2), 0.7)
    assert not agent.own_state_stale(0.7)
    assert agent.plan().passed_through


def test_no_state_at_all_is_stale_once_the_first_command_waited_state_timeout():
    agent = _filter_agent(state_timeout=0.5)
    assert agent.own_state_stale(0.0)
    agent.receive_upstream(UpstreamCommand((0.4, 0.0), 0.0), 1.0)
    # The robot's first state may come after its controller's first command: wait for it.
    assert not agent.own_state_stale(1.4) and agent.upstream_answer(1.4) == 'wait'
    assert not agent.ready(1.4)
    agent.receive_upstream(UpstreamCommand((0.4, 0.0), 0.0), 1.6)
    assert agent.own_state_stale(1.6) and agent.upstream_answer(1.6) == 'stale'
    assert agent.stale_answer() is not None


# A node in this process --------------------------------------------------------------------


@pytest.fixture(params=[False, True], ids=['Twist', 'TwistStamped'])
def filter_node(request, ros_domain):
    """Yield (PlannerNode in /robot_0 as a filter, published messages, stamped)."""
    import rclpy

    from prvo_planner.planner_node import PlannerNode

    stamped = request.param
    rclpy.init(domain_id=ros_domain, args=[
        '--ros-args', '-r', '__ns:=/robot_0', '-p', 'preferred_source:=velocity',
        '-p', f'enable_stamped_cmd_vel:={str(stamped).lower()}', '-p', 'neighbors:=[""]'])
    node = PlannerNode()
    published = []
    node._cmd_vel_publisher.publish = published.append
    yield node, published, stamped
    node.destroy_node()
    rclpy.try_shutdown()


def _fields(message):
    """Return a Twist(Stamped)'s values as bytes (bit for bit, -0.0 apart from 0.0) and header.

    Not its serialization: the bytes that pad a CDR message between fields are undefined.
    """
    twist = getattr(message, 'twist', message)
    values = [getattr(vector, axis) for vector in (twist.linear, twist.angular)
              for axis in 'xyz']
    header = getattr(message, 'header', None)
    return (np.array(values).tobytes(), None if header is None else (
        header.stamp.sec, header.stamp.nanosec, header.frame_id))


def test_node_passes_random_twists_bit_for_bit(filter_node):
    from geometry_msgs.msg import Twist, TwistStamped

    from prvo_msgs_util import seconds_to_stamp, serialize_odometry

    node, published, stamped = filter_node
    rng = np.random.default_rng(11)
    sent = []
    for step, (linear, angular) in enumerate(_random_commands(rng, 24)):
        node._on_own_odometry(serialize_odometry(
            0.05 * step, rng.uniform(-3, 3, 2), rng.uniform(-1, 1, 2), 1e-4 * np.eye(2),
            1e-4 * np.eye(2), yaw=float(rng.uniform(-3, 3))))
        twist = Twist()
        twist.linear.x, twist.linear.y = linear
        twist.angular.z = angular
        message = twist
        if stamped:
            message = TwistStamped(twist=twist)
            message.header.stamp = seconds_to_stamp(100.0 + step)
            message.header.frame_id = 'robot_0/base_link'
        sent.append(_fields(message))
        node._on_upstream(message)
    assert [_fields(message) for message in published] == sent
    assert all(isinstance(message, TwistStamped if stamped else Twist) for message in published)


def test_node_answers_every_input_arriving_faster_than_its_state(filter_node):
    """Inputs at 20 Hz, states at 10 Hz: each input has its own output, in order.

    A stamped input later than the newest state waits for the state of its stamp; when the next
    input comes first, the waiting one is answered from the state in hand, not dropped.
    """
    from geometry_msgs.msg import Twist, TwistStamped

    from prvo_msgs_util import seconds_to_stamp, serialize_odometry

    node, published, stamped = filter_node
    sent = []
    for period in range(20):
        node._on_own_odometry(serialize_odometry(
            0.1 * period, [0.04 * period, 0.0], [0.4, 0.0], 1e-4 * np.eye(2), 1e-4 * np.eye(2)))
        for offset in (0.02, 0.07):
            twist = Twist()
            twist.linear.x = 0.4 + 0.001 * len(sent)
            message = twist
            if stamped:
                message = TwistStamped(twist=twist)
                message.header.stamp = seconds_to_stamp(0.1 * period + offset)
            sent.append(_fields(message))
            node._on_upstream(message)
    # The last input is answered with the next state.
    node._on_own_odometry(serialize_odometry(2.0, [0.8, 0.0], [0.4, 0.0], 1e-4 * np.eye(2),
                                             1e-4 * np.eye(2)))
    assert [_fields(message) for message in published] == sent


def test_a_waiting_command_is_answered_before_another_step_replaces_it():
    agent = _filter_agent()
    agent.receive_upstream(UpstreamCommand((0.4, 0.0), 0.0, stamp=0.1), 0.0)
    # Before the first own state nothing can answer it.
    assert not agent.upstream_superseded(0.2, 0.0)
    agent.receive_own(_Measurement(0.0, np.zeros(2), np.zeros(2), COVARIANCE), 0.0)
    assert agent.upstream_answer(0.0) == 'plan'
    agent.plan()
    agent.receive_upstream(UpstreamCommand((0.4, 0.0), 0.0, stamp=0.12), 0.05)
    assert agent.upstream_answer(0.05) == 'wait'
    # The same step sent again replaces it; another step or an unstamped command does not.
    assert not agent.upstream_superseded(0.12, 0.06)
    assert agent.upstream_superseded(0.17, 0.06) and agent.upstream_superseded(None, 0.06)
    # Nor while the own state is stale (the new command is answered by zero instead).
    assert not agent.upstream_superseded(0.17, 0.06 + agent.settings.state_timeout)


def test_node_names_the_topic_of_a_type_mismatch(filter_node, probe):
    import time

    from geometry_msgs.msg import Twist, TwistStamped

    node, _, stamped = filter_node
    warnings = []
    node._warnings.warn = lambda key, text: warnings.append(text)
    node._check_topic_types()
    assert not warnings
    # An upstream of the other type on the input topic (another process): it never connects.
    probe.node.create_publisher(Twist if stamped else TwistStamped, '/robot_0/cmd_vel_smoothed',
                                1)
    deadline = time.monotonic() + 30.0
    while not warnings and time.monotonic() < deadline:
        time.sleep(0.1)
        node._check_topic_types()
    assert warnings and warnings[0].startswith('/robot_0/cmd_vel_smoothed carries')


def test_a_re_sent_step_is_answered_by_the_last_answer():
    agent = _filter_agent()
    agent.receive_own(_Measurement(0.0, np.zeros(2), np.zeros(2), COVARIANCE), 0.0)
    agent.receive_upstream(UpstreamCommand((0.4, 0.0), 0.0, stamp=0.0), 0.0)
    assert agent.upstream_answer(0.0) == 'plan'
    agent.plan()
    # The same step again (the odometry re-sent, its answer re-sent): no second plan.
    agent.receive_upstream(UpstreamCommand((0.4, 0.0), 0.0, stamp=0.0), 0.1)
    assert agent.upstream_answer(0.1) == 'repeat' and not agent.upstream_waiting
    # A later stamp waits for the own state of it; unstamped commands are planned at once.
    agent.receive_upstream(UpstreamCommand((0.4, 0.0), 0.0, stamp=0.1), 0.1)
    assert agent.upstream_answer(0.1) == 'wait'
    agent.receive_own(_Measurement(0.1, np.zeros(2), np.zeros(2), COVARIANCE), 0.1)
    assert agent.upstream_answer(0.1) == 'plan'
    agent.plan()
    agent.receive_upstream(UpstreamCommand((0.3, 0.0), 0.0), 0.12)
    assert agent.upstream_answer(0.12) == 'plan' and agent.pending_stamp == 0.1


def test_a_re_sent_step_that_comes_after_the_next_state_waits_for_the_next_command():
    # A lockstep simulator sent step 0 again and, once answered, step 0.1: the stand-in's
    # answer to the repeat comes after the state of 0.1. Step 0.1 is planned with the command
    # that answers it, as in the in-process loop, once.
    agent = _filter_agent()
    agent.receive_own(_Measurement(0.0, np.zeros(2), np.zeros(2), COVARIANCE), 0.0)
    agent.receive_upstream(UpstreamCommand((0.4, 0.0), 0.0, stamp=0.0), 0.0)
    assert agent.upstream_answer(0.0) == 'plan'
    agent.plan()
    agent.receive_own(_Measurement(0.1, np.zeros(2), np.zeros(2), COVARIANCE), 0.1)
    agent.receive_upstream(UpstreamCommand((0.4, 0.0), 0.0, stamp=0.0), 0.1)
    assert agent.upstream_answer(0.1) == 'repeat' and agent.pending_stamp == 0.1
    agent.receive_upstream(UpstreamCommand((0.0, 0.3), 0.0, stamp=0.1), 0.1)
    assert agent.upstream_answer(0.1) == 'plan'
    command = agent.plan()
    assert command.stamp == 0.1 and command.upstream.stamp == 0.1
    np.testing.assert_array_equal(command.velocity, [0.0, 0.3])

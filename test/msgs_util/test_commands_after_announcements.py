"""A command that follows a changed announcement waits until every subscriber holds it."""

import os
import signal
import sys
import time

import pytest

SUBSCRIBER = """
import rclpy
from geometry_msgs.msg import Vector3Stamped
from prvo_msgs_util import ANNOUNCEMENT_QOS
rclpy.init()
node = rclpy.create_node('share_listener')
node.create_subscription(Vector3Stamped, '/robot_x/avoidance_share',
                         lambda message: print(f'share {message.vector.x:.2f}', flush=True),
                         ANNOUNCEMENT_QOS)
rclpy.spin(node)
"""

# Subscribes, and takes nothing until the file argv[1] exists: a node too busy to take what its
# DDS reader has already received and acknowledged.
SLOW_SUBSCRIBER = """
import os, sys, time
import rclpy
from geometry_msgs.msg import Vector3Stamped
from prvo_msgs_util import ANNOUNCEMENT_READER_QOS
rclpy.init()
node = rclpy.create_node('slow_share_listener')
node.create_subscription(
    Vector3Stamped, '/robot_x/avoidance_share',
    lambda message: print(f'share {message.vector.x:.2f} stamped {message.header.stamp.nanosec}',
                          flush=True), ANNOUNCEMENT_READER_QOS)
print('subscribed', flush=True)
while not os.path.exists(sys.argv[1]):
    time.sleep(0.05)
rclpy.spin(node)
"""


@pytest.fixture
def announcing_robot(spinning_node):
    """Return a node in /robot_x with an Announcer and its commands, spinning in a thread."""
    from geometry_msgs.msg import Twist
    from rclpy.clock import Clock, ClockType

    from prvo_msgs_util import CMD_VEL, CMD_VEL_QOS, Announcer, CommandsAfterAnnouncements

    node = spinning_node('planner', 'robot_x')
    late = []
    robot = {'node': node, 'announcer': Announcer(node, 'robot_x'), 'late': late,
             'cmd_vel': node.create_publisher(Twist, CMD_VEL, CMD_VEL_QOS),
             'clock': Clock(clock_type=ClockType.STEADY_TIME)}
    robot['commands'] = lambda timeout: CommandsAfterAnnouncements(
        node, robot['cmd_vel'], robot['clock'], late.append, timeout=timeout)
    return robot


def started_listener(children, probe, announcing_robot):
    """Start the share listener in its own process; return it once it holds share 0.5."""
    listener = children.start('listener', [sys.executable, '-c', SUBSCRIBER])
    announcing_robot['announcer'].announce(0.3, 0.5, 0.0)
    probe.wait_until(lambda: 'share 0.50' in children.output(listener), 30.0,
                     'the listener to receive the first announcement')
    return listener


def test_a_command_waits_for_a_subscriber_to_hold_the_change(children, probe,
                                                             announcing_robot):
    from geometry_msgs.msg import Twist

    from prvo_msgs_util import CMD_VEL_QOS

    commands_received = probe.record(Twist, '/robot_x/cmd_vel', CMD_VEL_QOS)
    commands = announcing_robot['commands'](60.0)
    listener = started_listener(children, probe, announcing_robot)
    # Without a change the command goes at once.
    commands.publish(Twist(), announcing_robot['announcer'].announce(0.3, 0.5, 0.0))
    assert not commands.holding
    probe.wait_until(lambda: len(commands_received) == 1, 15.0, 'the first command')
    # A stopped process acknowledges nothing: the command after a change waits for it.
    children.stop(listener)
    try:
        changed = announcing_robot['announcer'].announce(0.3, 0.0, 0.1)
        assert changed == [announcing_robot['announcer'].share_publisher]
        commands.publish(Twist(), changed)
        time.sleep(1.0)
        assert commands.holding and len(commands_received) == 1
    finally:
        os.kill(listener.pid, signal.SIGCONT)
    probe.wait_until(lambda: len(commands_received) == 2, 15.0, 'the held command')
    assert 'share 0.00' in children.output(listener)
    assert announcing_robot['late'] == []


def test_an_unacknowledged_command_goes_after_the_timeout_with_a_warning(children, probe,
                                                                         announcing_robot):
    from geometry_msgs.msg import Twist

    from prvo_msgs_util import CMD_VEL_QOS

    commands_received = probe.record(Twist, '/robot_x/cmd_vel', CMD_VEL_QOS)
    commands = announcing_robot['commands'](0.5)
    listener = started_listener(children, probe, announcing_robot)
    children.stop(listener)
    try:
        commands.publish(Twist(), announcing_robot['announcer'].announce(0.3, 0.0, 0.1))
        probe.wait_until(lambda: len(commands_received) == 1, 15.0, 'the command')
    finally:
        os.kill(listener.pid, signal.SIGCONT)
    assert not commands.holding
    assert announcing_robot['late'] == [
        'announcement not acknowledged by every subscriber within 0.5 s: command sent anyway']


def test_changes_of_consecutive_steps_all_reach_a_slow_subscriber(children, probe,
                                                                  announcing_robot, tmp_path):
    # A robot at its goal changes its share at two consecutive steps; each command waits for
    # the change to be acknowledged. A neighbour that was slow to take the first change must
    # still get it: it holds for the step between the two.
    from geometry_msgs.msg import Twist

    from prvo_msgs_util import CMD_VEL_QOS

    commands_received = probe.record(Twist, '/robot_x/cmd_vel', CMD_VEL_QOS)
    commands = announcing_robot['commands'](60.0)
    announcer = announcing_robot['announcer']
    gate = tmp_path / 'take'
    listener = children.start('slow_listener', [sys.executable, '-c', SLOW_SUBSCRIBER,
                                                str(gate)])
    probe.wait_until(lambda: 'subscribed' in children.output(listener), 30.0,
                     'the slow listener to subscribe')
    probe.wait_until(lambda: announcer.share_publisher.get_subscription_count() == 1, 30.0,
                     'the slow listener to match')
    for count, (share, stamp) in enumerate(((0.5, 0.0), (0.0, 0.1), (0.5, 0.2)), start=1):
        commands.publish(Twist(), announcer.announce(0.3, share, stamp))
        probe.wait_until(lambda count=count: len(commands_received) == count, 15.0,
                         f'command {count}')
    gate.touch()
    probe.wait_until(lambda: 'stamped 200000000' in children.output(listener), 30.0,
                     'the last change')
    taken = [line for line in children.output(listener).splitlines()
             if line.startswith('share')]
    assert taken == ['share 0.50 stamped 0', 'share 0.00 stamped 100000000',
                     'share 0.50 stamped 200000000']

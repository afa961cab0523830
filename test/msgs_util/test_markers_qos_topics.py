"""Belief markers, diagnostics helpers, QoS profiles, topic helpers and the SIGINT recorder."""

import math
import re
import signal
import subprocess
import sys

from diagnostic_msgs.msg import DiagnosticStatus
import numpy as np
import pytest
from rclpy.qos import DurabilityPolicy, HistoryPolicy, ReliabilityPolicy
from scipy.stats import chi2
from visualization_msgs.msg import Marker

from prvo_msgs_util import (
    CLOCK_QOS,
    CMD_VEL_QOS,
    CONTACT_QOS,
    DIAGNOSTICS_QOS,
    GOAL_QOS,
    MARKER_QOS,
    ODOM_QOS,
    diagnostic_values,
    make_belief_markers,
    make_diagnostic_array,
    make_diagnostic_status,
    robot_from_topic,
    robot_topic,
    validate_robot_name,
)
from prvo_planner.core import k_from_eta
from prvo_planner.core.probability import confidence_ellipse_scale


def test_belief_markers_match_chi2_ellipse():
    rng = np.random.default_rng(4)
    positions = rng.normal(size=(3, 2))
    factors = rng.normal(size=(3, 2, 2))
    covariances = factors @ np.transpose(factors, (0, 2, 1))
    radii = np.array([0.3, 0.25, 0.4])
    shares = [0.5, 0.0, 0.5]
    markers = make_belief_markers(
        7.5, 'map', 'robot_0', [1.0, 2.0], [0.5, -0.2], positions, covariances, radii,
        confidence_ellipse_scale(k_from_eta(0.9)), shares).markers

    assert markers[0].action == Marker.DELETEALL
    arrow = markers[1]
    assert (arrow.type, arrow.action, arrow.ns) == (Marker.ARROW, Marker.ADD, 'robot_0')
    assert [(point.x, point.y) for point in arrow.points] == [(1.0, 2.0), (1.5, 1.8)]
    ellipses, labels = markers[2:5], markers[5:]
    assert len(labels) == 3
    assert len({marker.id for marker in markers[1:]}) == 7
    # Each neighbour's label states the size and share it is planned with, at its position.
    assert [label.text for label in labels] == [
        'r 0.30 m, share 0.50', 'r 0.25 m, share 0.00', 'r 0.40 m, share 0.50']
    for label, position in zip(labels, positions, strict=True):
        assert label.type == Marker.TEXT_VIEW_FACING
        assert (label.pose.position.x, label.pose.position.y) == tuple(position)
    quantile = chi2.ppf(0.9, df=2)
    for marker, position, covariance, radius in zip(
            ellipses, positions, covariances, radii, strict=True):
        assert marker.type == Marker.CYLINDER
        assert marker.header.frame_id == 'map'
        assert marker.header.stamp.sec == 7 and marker.header.stamp.nanosec == 500_000_000
        assert (marker.pose.position.x, marker.pose.position.y) == tuple(position)
        # Closed-form eigenvalues of a symmetric 2x2 matrix.
        a, b, d = covariance[0, 0], covariance[0, 1], covariance[1, 1]
        half_gap = math.hypot((a - d) / 2, b)
        major, minor = (a + d) / 2 + half_gap, (a + d) / 2 - half_gap
        assert marker.scale.x == pytest.approx(2 * (math.sqrt(quantile * major) + radius))
        assert marker.scale.y == pytest.approx(2 * (math.sqrt(quantile * minor) + radius))
        # The marker's x axis (its yaw) must be an eigenvector of the major eigenvalue.
        yaw = 2 * math.atan2(marker.pose.orientation.z, marker.pose.orientation.w)
        axis = np.array([math.cos(yaw), math.sin(yaw)])
        np.testing.assert_allclose(covariance @ axis, major * axis, atol=1e-9)


def test_belief_markers_reject_mismatched_neighbours():
    with pytest.raises(ValueError, match='2 neighbour positions, 1 covariances'):
        make_belief_markers(0.0, 'map', 'r', [0, 0], [0, 0], np.zeros((2, 2)),
                            [np.eye(2)], [0.3, 0.3], 1.0, [0.5, 0.5])
    with pytest.raises(ValueError, match='2 radii and 1 shares'):
        make_belief_markers(0.0, 'map', 'r', [0, 0], [0, 0], np.zeros((2, 2)),
                            [np.eye(2)] * 2, [0.3, 0.3], 1.0, [0.5])


def test_diagnostic_status_values_round_trip():
    status = make_diagnostic_status(
        'prvo_sim', 'running', {'sim_time': 0.1 + 0.2, 'step': 3, 'finished': True,
                                'mode': 'lockstep'},
        level=DiagnosticStatus.WARN, hardware_id='sim')
    assert (status.level, status.name, status.message, status.hardware_id) == (
        DiagnosticStatus.WARN, 'prvo_sim', 'running', 'sim')
    values = diagnostic_values(status)
    assert values == {'sim_time': '0.30000000000000004', 'step': '3', 'finished': 'true',
                      'mode': 'lockstep'}
    assert float(values['sim_time']) == 0.1 + 0.2
    array = make_diagnostic_array(2.25, [status])
    assert (array.header.stamp.sec, array.header.stamp.nanosec) == (2, 250_000_000)
    assert array.status == [status]
    assert make_diagnostic_status('x', '', {}).level == DiagnosticStatus.OK


@pytest.mark.parametrize(('profile', 'depth', 'durability'), [
    (ODOM_QOS, 10, DurabilityPolicy.VOLATILE),
    (CMD_VEL_QOS, 10, DurabilityPolicy.VOLATILE),
    (CLOCK_QOS, 10, DurabilityPolicy.VOLATILE),
    (DIAGNOSTICS_QOS, 50, DurabilityPolicy.VOLATILE),
    (MARKER_QOS, 1, DurabilityPolicy.VOLATILE),
    (CONTACT_QOS, 100, DurabilityPolicy.TRANSIENT_LOCAL),
    (GOAL_QOS, 1, DurabilityPolicy.VOLATILE),
])
def test_qos_profiles(profile, depth, durability):
    assert profile.reliability == ReliabilityPolicy.RELIABLE
    assert profile.history == HistoryPolicy.KEEP_LAST
    assert profile.depth == depth
    assert profile.durability == durability


def test_topic_helpers():
    assert robot_topic('robot_0', 'odom') == '/robot_0/odom'
    assert robot_from_topic('/robot_0/odom', 'odom') == 'robot_0'
    assert robot_from_topic('/_r2/cmd_vel', 'cmd_vel') == '_r2'
    for topic in ('/robot_0/ground_truth', 'robot_0/odom', '/a/b/odom', '//odom',
                  '/0robot/odom', '/robot-0/odom', '/robot_0/odom/'):
        assert robot_from_topic(topic, 'odom') is None, topic
    for good in ('robot_0', 'R', '_x9'):
        validate_robot_name(good)
    for bad in ('', '0robot', 'robot-0', 'a/b', 'robot 0', None, 'robot__0', '__robot'):
        with pytest.raises(ValueError, match=re.escape(repr(bad))):
            validate_robot_name(bad)
    with pytest.raises(ValueError, match='robot-0'):
        robot_topic('robot-0', 'odom')


def test_qos_watch_reports_each_incompatible_remote_endpoint_once(probe):
    from geometry_msgs.msg import TwistStamped
    from nav_msgs.msg import Odometry
    import rclpy
    from rclpy.qos import DurabilityPolicy, QoSProfile, qos_profile_sensor_data

    from prvo_msgs_util import (
        CMD_VEL_QOS,
        ODOM_LATEST_QOS,
        QosWatch,
        quiet_publisher_events,
        quiet_subscription_events,
    )

    watcher = rclpy.create_node('qos_watcher', namespace='/watched', context=probe.context)
    try:
        watch = QosWatch(watcher)
        watch.watch(watcher.create_subscription(
            Odometry, 'odom', lambda msg: None, ODOM_LATEST_QOS,
            event_callbacks=quiet_subscription_events()))
        watch.watch(watcher.create_publisher(
            TwistStamped, 'cmd_vel', CMD_VEL_QOS, event_callbacks=quiet_publisher_events()))
        # A best-effort odometry publisher cannot feed a reliable subscription, a reliable one
        # can; a transient-local subscription cannot be served by a volatile publisher, one
        # with the same profile can.
        probe.node.create_publisher(Odometry, '/watched/odom', qos_profile_sensor_data)
        probe.node.create_publisher(Odometry, '/watched/odom', ODOM_LATEST_QOS)
        probe.node.create_subscription(
            TwistStamped, '/watched/cmd_vel', lambda msg: None,
            QoSProfile(depth=1, durability=DurabilityPolicy.TRANSIENT_LOCAL))
        probe.node.create_subscription(TwistStamped, '/watched/cmd_vel', lambda msg: None,
                                       CMD_VEL_QOS)
        reported = []
        probe.wait_until(lambda: reported.extend(watch.check()) or len(reported) >= 2,
                         timeout=10.0, what='both incompatible endpoints reported')
        assert len(reported) == 2
        odometry, = [text for text in reported if '/watched/odom' in text]
        command, = [text for text in reported if '/watched/cmd_vel' in text]
        assert odometry.startswith('publisher of /prvo_test_probe') and 'effort' in odometry
        assert command.startswith('subscription of /prvo_test_probe')
        assert 'transient local' in command
        assert watch.check() == []
    finally:
        watcher.destroy_node()


# A process whose SIGINT handler was a Python function (as a node's is) and that gets SIGINT
# while Python finalizes it, after main() returned: here from an object cleared at exit.
_LATE_SIGINT = """
import os, signal, sys
from prvo_msgs_util import ignore_stop_signals
class Late:
    def __del__(self, kill=os.kill, pid=os.getpid()):
        kill(pid, signal.SIGINT)
late = Late()
signal.signal(signal.SIGINT, lambda signal_number, frame: None)
if sys.argv[1] == 'ignore':
    ignore_stop_signals()
sys.exit(0)
"""


@pytest.mark.parametrize('ending, returncode', [('handler', -signal.SIGINT), ('ignore', 0)])
def test_ignored_stop_signals_stay_ignored_while_python_finalizes(ending, returncode):
    finished = subprocess.run([sys.executable, '-c', _LATE_SIGINT, ending], timeout=60)
    assert finished.returncode == returncode

"""A live planner announces its size and share, and plans with its neighbours' announcements."""

import math
import threading

from diagnostic_msgs.msg import DiagnosticArray
from geometry_msgs.msg import Point32, PolygonStamped, Vector3Stamped
from nav_msgs.msg import Path
import numpy as np
import pytest
from rclpy.duration import Duration
from test_planner_robustness import FedPlanner

from prvo_msgs_util import (
    ANNOUNCEMENT_QOS,
    DIAGNOSTICS,
    DIAGNOSTICS_QOS,
    PLAN_QOS,
    diagnostic_values,
    footprint_message,
    make_path,
    robot_topic,
    share_message,
    stamp_to_seconds,
)

pytestmark = pytest.mark.integration


class Latest:
    """The last message of a topic a probe listens to."""

    def __init__(self):
        self._lock = threading.Lock()
        self.message = None

    def __call__(self, message):
        with self._lock:
            self.message = message

    def get(self):
        with self._lock:
            return self.message


def test_a_planner_announces_itself_and_plans_with_what_its_neighbours_announce(
        children, ros2_executable, probe):
    # Its listed neighbours do not announce in full: it waits for them neighbor_timeout long.
    planner = FedPlanner(children, ros2_executable, probe, announce=False, radius=0.3,
                         unknown_neighbor_radius=0.7, status_period=0.0, neighbor_timeout=1.0)
    # Latched: a probe subscribing after the planner published still receives both.
    footprint, share = Latest(), Latest()
    probe.node.create_subscription(PolygonStamped, robot_topic('robot_0', 'footprint'),
                                   footprint, ANNOUNCEMENT_QOS)
    probe.node.create_subscription(Vector3Stamped, robot_topic('robot_0', 'avoidance_share'),
                                   share, ANNOUNCEMENT_QOS)
    probe.wait_until(lambda: footprint.get() is not None and share.get() is not None,
                     timeout=30.0, what="the planner's announcements")
    assert footprint.get().header.frame_id == 'robot_0/base_link'
    assert len(footprint.get().polygon.points) == 16
    assert all(math.hypot(point.x, point.y) == pytest.approx(0.3, rel=1e-6)
               for point in footprint.get().polygon.points)
    assert share.get().header.frame_id == 'robot_0/base_link'
    assert (share.get().vector.x, share.get().vector.y, share.get().vector.z) == (0.5, 0.0, 0.0)
    # Before its first plan: from the start.
    for message in (footprint.get(), share.get()):
        assert (message.header.stamp.sec, message.header.stamp.nanosec) == (0, 0)

    # robot_1 announces a footprint of radius 0.6 and no share; robot_2 an impossible share.
    publishers = {(robot, kind): probe.node.create_publisher(
        message_type, robot_topic(robot, kind), ANNOUNCEMENT_QOS)
        for robot in ('robot_1', 'robot_2')
        for kind, message_type in (('footprint', PolygonStamped),
                                   ('avoidance_share', Vector3Stamped))}
    probe.wait_until(lambda: all(publisher.get_subscription_count() > 0
                                 for publisher in publishers.values()),
                     timeout=30.0, what='the planner subscribing to the announcements')
    publishers['robot_1', 'footprint'].publish(footprint_message(0.6, 'robot_1/base_link', 0.0))
    impossible_share = Vector3Stamped()
    impossible_share.vector.x = 1.5
    publishers['robot_2', 'avoidance_share'].publish(impossible_share)
    statuses = Latest()
    probe.node.create_subscription(
        DiagnosticArray, DIAGNOSTICS, lambda message: [
            statuses(diagnostic_values(status)) for status in message.status
            if status.name == 'prvo_planner/robot_0'], DIAGNOSTICS_QOS)
    expected = {'neighbour.robot_1.radius': '0.6000000238418579',
                'neighbour.robot_1.avoidance_share': '0.0',
                'neighbour.robot_2.radius': '0.7', 'neighbour.robot_2.avoidance_share': '0.0'}
    # Diagnostics on every plan: the first plan after the announcements arrived shows them.
    stamp = plan_until_reported(planner, statuses, expected, 9.9)
    probe.wait_until(lambda: 'ignoring announcement on /robot_2/avoidance_share: avoidance '
                     'share must be in [0, 1), got 1.5' in children.output(planner.process),
                     timeout=20.0, what='the warning about the bad share')

    # Without a map it publishes its straight way (latched), stamped with its first plan.
    own_route = Latest()
    probe.node.create_subscription(Path, robot_topic('robot_0', 'plan'), own_route, PLAN_QOS)
    probe.wait_until(own_route.get, timeout=20.0, what="the planner's route")
    assert own_route.get().header.frame_id == 'map'
    assert stamp_to_seconds(own_route.get().header.stamp) == pytest.approx(10.0)
    assert [(pose.pose.position.x, pose.pose.position.y) for pose in own_route.get().poses][
        1] == (5.0, 0.0)
    # robot_1 publishes a route from the start, robot_2 one with NaN: it claims nothing.
    routes = {robot: probe.node.create_publisher(Path, robot_topic(robot, 'plan'), PLAN_QOS)
              for robot in ('robot_1', 'robot_2')}
    probe.wait_until(lambda: all(publisher.get_subscription_count() > 0
                                 for publisher in routes.values()),
                     timeout=30.0, what='the planner subscribing to the routes')
    # Heard again first (neighbor_timeout is 1 s): a route goes with a neighbour dropped.
    stamp = plan_until_reported(planner, statuses, {}, stamp)
    routes['robot_1'].publish(make_path(0.0, [[0.0, 2.0], [3.0, 2.0], [3.0, 5.0]]))
    routes['robot_2'].publish(make_path(0.0, [[0.0, 4.0], [float('nan'), 4.0]]))
    expected = {'neighbour.robot_1.route_points': '3', 'neighbour.robot_1.route_stamp': '0.0',
                'neighbour.robot_2.route_points': '0', 'neighbour.robot_2.route_stamp': 'none'}
    plan_until_reported(planner, statuses, expected, stamp)
    probe.wait_until(lambda: 'ignoring route on /robot_2/plan (the robot claims nothing): '
                     'poses[1].pose.position contains NaN' in children.output(planner.process),
                     timeout=20.0, what='the warning about the bad route')
    assert planner.process.poll() is None


def plan_until_reported(planner, statuses, expected, stamp):
    """Plan the steps after STAMP until the planner's status (STATUSES) holds EXPECTED.

    Returns the last step's stamp; fails naming the status after 200 steps.
    """
    for _ in range(200):
        stamp = round(stamp + 0.1, 9)
        planner.send_step(stamp)
        planner.wait_answer(stamp)
        values = statuses.get() or {}
        if all(values.get(key) == value for key, value in expected.items()):
            return stamp
    raise AssertionError(f'the status never held {expected}: {values}')


def footprint_of_radius(radius, robot):
    """Return a footprint of one vertex at RADIUS [m], from the start."""
    message = PolygonStamped()
    message.header.frame_id = f'{robot}/base_link'
    message.polygon.points = [Point32(x=radius, y=0.0, z=0.0)]
    return message


def test_a_stamped_share_counts_from_the_plan_after_its_stamp_and_implausible_footprints_not(
        children, ros2_executable, probe):
    planner = FedPlanner(children, ros2_executable, probe, status_period=0.0)
    statuses = {}
    probe.node.create_subscription(
        DiagnosticArray, DIAGNOSTICS, lambda message: [
            statuses.__setitem__(stamp_to_seconds(message.header.stamp),
                                 diagnostic_values(status))
            for status in message.status if status.name == 'prvo_planner/robot_0'],
        DIAGNOSTICS_QOS)
    planner.send_step(10.0)
    planner.wait_answer(10.0)
    # robot_1 stops avoiding with its plan of 10.2 (it arrived); a foreign giant and a point
    # then claim the footprints of robot_1 and robot_2.
    publishers = {(robot, kind): probe.node.create_publisher(
        message_type, robot_topic(robot, kind), ANNOUNCEMENT_QOS)
        for robot in ('robot_1', 'robot_2')
        for kind, message_type in (('footprint', PolygonStamped),
                                   ('avoidance_share', Vector3Stamped))}
    probe.wait_until(lambda: all(publisher.get_subscription_count() > 0
                                 for publisher in publishers.values()),
                     timeout=30.0, what='the planner subscribing to the announcements')
    publishers['robot_1', 'avoidance_share'].publish(
        share_message(0.0, 'robot_1/base_link', 10.2))
    publishers['robot_1', 'footprint'].publish(footprint_of_radius(1.0e6, 'robot_1'))
    publishers['robot_2', 'footprint'].publish(footprint_of_radius(1.0e-12, 'robot_2'))
    # Point32 is single precision: 1e-12 arrives as the nearest float32.
    for topic, value in (('/robot_1/footprint', '1000000.0'),
                         ('/robot_2/footprint', repr(float(np.float32(1.0e-12))))):
        probe.wait_until(
            lambda topic=topic, value=value: f'ignoring announcement on {topic}: footprint '
            f'radius must be in [0.01, 100] m, got {value}' in children.output(planner.process),
            timeout=20.0, what=f'the warning about the footprint on {topic}')
    assert all(publisher.wait_for_all_acked(Duration(seconds=10.0))
               for publisher in publishers.values())
    stamps = [round(10.0 + 0.1 * step, 9) for step in range(1, 6)]
    for stamp in stamps:
        planner.send_step(stamp)
        planner.wait_answer(stamp)
    probe.wait_until(lambda: all(stamp in statuses for stamp in stamps), timeout=20.0,
                     what='the diagnostics of every plan')
    for stamp in stamps:
        values = statuses[stamp]
        assert values['neighbour.robot_1.avoidance_share'] == (
            '0.5' if stamp <= 10.2 else '0.0'), (stamp, values)
        # The last valid footprints (radius 0.3, single precision) stay; the plans stay
        # feasible.
        for robot in ('robot_1', 'robot_2'):
            assert values[f'neighbour.{robot}.radius'] == '0.30000001192092896', (stamp, values)
        assert values['neighbour.robot_2.avoidance_share'] == '0.5'
        assert values['feasible'] == 'true', (stamp, values)
    assert planner.process.poll() is None

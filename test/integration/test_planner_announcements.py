"""A live planner announces its size and share, and plans with its neighbours' announcements."""

import math
import threading

from diagnostic_msgs.msg import DiagnosticArray
from geometry_msgs.msg import PolygonStamped
import pytest
from std_msgs.msg import Float32
from test_planner_robustness import FedPlanner

from prvo_msgs_util import (
    ANNOUNCEMENT_QOS,
    DIAGNOSTICS,
    DIAGNOSTICS_QOS,
    diagnostic_values,
    footprint_message,
    robot_topic,
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
    probe.node.create_subscription(Float32, robot_topic('robot_0', 'avoidance_share'), share,
                                   ANNOUNCEMENT_QOS)
    probe.wait_until(lambda: footprint.get() is not None and share.get() is not None,
                     timeout=30.0, what="the planner's announcements")
    assert footprint.get().header.frame_id == 'robot_0/base_link'
    assert len(footprint.get().polygon.points) == 16
    assert all(math.hypot(point.x, point.y) == pytest.approx(0.3, rel=1e-6)
               for point in footprint.get().polygon.points)
    assert share.get().data == 0.5

    # robot_1 announces a footprint of radius 0.6 and no share; robot_2 an impossible share.
    publishers = {(robot, kind): probe.node.create_publisher(
        message_type, robot_topic(robot, kind), ANNOUNCEMENT_QOS)
        for robot in ('robot_1', 'robot_2')
        for kind, message_type in (('footprint', PolygonStamped),
                                   ('avoidance_share', Float32))}
    probe.wait_until(lambda: all(publisher.get_subscription_count() > 0
                                 for publisher in publishers.values()),
                     timeout=30.0, what='the planner subscribing to the announcements')
    publishers['robot_1', 'footprint'].publish(footprint_message(0.6, 'robot_1/base_link'))
    publishers['robot_2', 'avoidance_share'].publish(Float32(data=1.5))
    statuses = Latest()
    probe.node.create_subscription(
        DiagnosticArray, DIAGNOSTICS, lambda message: [
            statuses(diagnostic_values(status)) for status in message.status
            if status.name == 'prvo_planner/robot_0'], DIAGNOSTICS_QOS)
    expected = {'neighbour.robot_1.radius': '0.6000000238418579',
                'neighbour.robot_1.avoidance_share': '0.0',
                'neighbour.robot_2.radius': '0.7', 'neighbour.robot_2.avoidance_share': '0.0'}
    # Diagnostics on every plan: the first plan after the announcements arrived shows them.
    for step in range(200):
        stamp = 10.0 + 0.1 * step
        planner.send_step(stamp)
        planner.wait_answer(stamp)
        values = statuses.get() or {}
        if all(values.get(key) == value for key, value in expected.items()):
            break
    assert all(values.get(key) == value for key, value in expected.items()), values
    probe.wait_until(lambda: 'ignoring announcement on /robot_2/avoidance_share: avoidance '
                     'share must be in [0, 1), got 1.5' in children.output(planner.process),
                     timeout=20.0, what='the warning about the bad share')
    assert planner.process.poll() is None

"""What a robot announces about itself to its neighbours: its footprint and share of avoidance.

Every planner publishes, latched (ANNOUNCEMENT_QOS), on `/<robot>/footprint` a
`geometry_msgs/PolygonStamped` in `<robot>/base_link` (a regular polygon with its vertices on the
robot's radius, as Nav2 publishes a circular footprint) and on `/<robot>/avoidance_share` a
`std_msgs/Float32`: the share of a pair's avoidance the robot takes itself, in [0, 1) (0.5 for a
reciprocating planner, 0 for a robot that does not avoid). See docs/interfaces.md.
"""

import math
import time

from geometry_msgs.msg import Point32, PolygonStamped
from rclpy.duration import Duration
from std_msgs.msg import Float32

from prvo_msgs_util.qos import (
    ANNOUNCEMENT_QOS,
    quiet_publisher_events,
    quiet_subscription_events,
)
from prvo_msgs_util.topics import AVOIDANCE_SHARE, FOOTPRINT, robot_topic

# Vertices of a circular footprint, as Nav2's costmap publishes one.
FOOTPRINT_VERTICES = 16


def footprint_message(radius, frame_id):
    """Return the PolygonStamped footprint of a disk of RADIUS [m] in FRAME_ID.

    Raises ValueError unless RADIUS is finite and > 0.
    """
    radius = float(radius)
    if not (math.isfinite(radius) and radius > 0.0):
        raise ValueError(f'footprint radius must be finite and > 0, got {radius!r}')
    message = PolygonStamped()
    message.header.frame_id = frame_id
    message.polygon.points = [
        Point32(x=radius * math.cos(angle), y=radius * math.sin(angle), z=0.0)
        for angle in (2.0 * math.pi * index / FOOTPRINT_VERTICES
                      for index in range(FOOTPRINT_VERTICES))]
    return message


def radius_of_footprint(message):
    """Return the circumscribed radius [m] of a PolygonStamped footprint about its frame origin.

    Raises ValueError naming the problem for a footprint without vertices, with a non-finite
    coordinate, or whose radius is not > 0.
    """
    points = message.polygon.points
    if not points:
        raise ValueError('footprint has no vertices')
    coordinates = [(point.x, point.y) for point in points]
    if not all(math.isfinite(x) and math.isfinite(y) for x, y in coordinates):
        raise ValueError(f'footprint has a non-finite vertex: {coordinates!r}')
    radius = max(math.hypot(x, y) for x, y in coordinates)
    if not radius > 0.0:
        raise ValueError(f'footprint radius must be > 0, got {radius!r}')
    return radius


def share_message(avoidance_share):
    """Return the Float32 announcement of AVOIDANCE_SHARE; ValueError unless it is in [0, 1)."""
    return Float32(data=_checked_share(avoidance_share))


def share_of(message):
    """Return the share a Float32 announcement states; ValueError unless it is in [0, 1)."""
    return _checked_share(message.data)


def _checked_share(value):
    share = float(value)
    if not 0.0 <= share < 1.0:
        raise ValueError(f'avoidance share must be in [0, 1), got {share!r}')
    return share


class Announcer:
    """A robot's two latched announcement publishers; publishes only what changed.

    Parameters
    ----------
    node : rclpy.node.Node
        The robot's node, in the robot's namespace (the topics are relative).
    robot : str
        The robot's name (the footprint's frame is `<robot>/base_link`).
    in_robot_namespace : bool
        Whether the node runs in the robot's namespace; if not (the simulator announcing a
        scripted robot), the topics are the absolute /<robot>/footprint and so on.

    """

    def __init__(self, node, robot, in_robot_namespace=True):
        self._frame_id = f'{robot}/base_link'
        footprint, share = FOOTPRINT, AVOIDANCE_SHARE
        if not in_robot_namespace:
            footprint, share = robot_topic(robot, FOOTPRINT), robot_topic(robot, AVOIDANCE_SHARE)
        self.footprint_publisher = node.create_publisher(
            PolygonStamped, footprint, ANNOUNCEMENT_QOS, event_callbacks=quiet_publisher_events())
        self.share_publisher = node.create_publisher(
            Float32, share, ANNOUNCEMENT_QOS, event_callbacks=quiet_publisher_events())
        self._radius = self._share = None

    def announce(self, radius, avoidance_share):
        """Publish RADIUS [m] and AVOIDANCE_SHARE, each only if it differs from the last.

        Returns the publishers that published (empty if nothing changed), for a caller that
        waits until every subscriber has acknowledged the change (`all_acknowledged`).
        """
        published = []
        if radius != self._radius:
            self.footprint_publisher.publish(footprint_message(radius, self._frame_id))
            self._radius = radius
            published.append(self.footprint_publisher)
        if avoidance_share != self._share:
            self.share_publisher.publish(share_message(avoidance_share))
            self._share = avoidance_share
            published.append(self.share_publisher)
        return published


def all_acknowledged(publishers):
    """Whether every subscriber of each of PUBLISHERS has acknowledged all it was sent.

    Announcements are reliable: a subscriber acknowledges a message once it holds it, so
    whatever the robot publishes after that reaches the subscriber's node later. Does not wait.
    """
    return all(publisher.wait_for_all_acked(Duration()) for publisher in publishers)


class CommandsAfterAnnouncements:
    """Publishes a robot's commands only after its neighbours hold its announcements.

    Announcements travel apart from commands and odometry. A changed share published just
    before a command could, on a loaded machine, reach a neighbour after the odometry that the
    command leads to, and count a step late there: a lockstep run would then depend on timing.
    A command that follows a changed announcement is therefore held until every subscriber
    has acknowledged the announcement (a few ms between processes), then published; a later
    command replaces a held one. Nothing blocks: a steady-clock timer polls while a command is
    held, and after `timeout` [s] the command goes out anyway and `on_late(text)` is called.

    Parameters
    ----------
    node : rclpy.node.Node
        Owns the polling timer.
    publisher : rclpy.publisher.Publisher
        Where the commands go.
    clock : rclpy.clock.Clock
        A steady clock (under simulated time, sim time waits for the command).
    on_late : callable
        Told, with a one-line text, when a command went out unacknowledged after `timeout`.
    timeout : float
        Wall time [s] a command waits at most.

    """

    POLL_PERIOD = 1e-3

    def __init__(self, node, publisher, clock, on_late, timeout=1.0):
        self._publisher, self._on_late, self._timeout = publisher, on_late, timeout
        self._timer = node.create_timer(self.POLL_PERIOD, self._poll, clock=clock,
                                        autostart=False)
        self._held = None
        self._waiting_on = []
        self._deadline = None

    @property
    def holding(self):
        """Whether a command waits for acknowledgements."""
        return self._held is not None

    def publish(self, message, announced):
        """Publish MESSAGE now, or hold it until its announcements are acknowledged.

        ANNOUNCED: the publishers that published just before it (`Announcer.announce`); a held
        command also waits for those an earlier held command waited on.
        """
        if announced and self._held is None:
            self._deadline = time.monotonic() + self._timeout
        self._waiting_on = self._waiting_on + list(announced)
        if not self._waiting_on or all_acknowledged(self._waiting_on):
            self._send(message)
            return
        self._held = message
        self._timer.reset()

    def _poll(self):
        if self._held is None:
            # A timer event queued before the command went.
            return
        if all_acknowledged(self._waiting_on):
            self._send(self._held)
        elif time.monotonic() > self._deadline:
            self._on_late(f'announcement not acknowledged by every subscriber within '
                          f'{self._timeout:g} s: command sent anyway')
            self._send(self._held)

    def _send(self, message):
        self._timer.cancel()
        self._held, self._waiting_on = None, []
        self._publisher.publish(message)


def subscribe_announcements(node, robot, receive_radius, receive_share, on_fault):
    """Subscribe NODE to ROBOT's footprint and share; return the two subscriptions.

    `receive_radius(robot, radius)` and `receive_share(robot, share)` get the converted values.
    A message that cannot be converted, or that they refuse with ValueError, goes to
    `on_fault(topic, error)` instead.
    """
    def handler(topic, convert, receive):
        def on_message(message):
            try:
                receive(robot, convert(message))
            except ValueError as error:
                on_fault(topic, error)
        return on_message

    footprint, share = robot_topic(robot, FOOTPRINT), robot_topic(robot, AVOIDANCE_SHARE)
    return [node.create_subscription(kind, topic, handler(topic, convert, receive),
                                     ANNOUNCEMENT_QOS,
                                     event_callbacks=quiet_subscription_events())
            for kind, topic, convert, receive in (
                (PolygonStamped, footprint, radius_of_footprint, receive_radius),
                (Float32, share, share_of, receive_share))]

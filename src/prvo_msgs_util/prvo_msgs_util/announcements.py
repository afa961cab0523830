"""What a robot announces about itself to its neighbours: its footprint and share of avoidance.

Every planner publishes, latched (ANNOUNCEMENT_QOS; subscribers queue more:
ANNOUNCEMENT_READER_QOS), on `/<robot>/footprint` a `geometry_msgs/PolygonStamped` in
`<robot>/base_link` (a regular polygon with its vertices on the robot's radius, as Nav2
publishes a circular footprint) and on `/<robot>/avoidance_share` a `geometry_msgs/Vector3Stamped`
in `<robot>/base_link` whose `vector.x` is the share of a pair's avoidance the robot takes
itself, in [0, 1) (0.5 for a reciprocating planner, 0 for a robot that does not avoid; y and z
are 0). Each holds for the plans of odometry stamped after its `header.stamp`, the stamp of the
plan that changed it; a zero stamp, from the start. A planner reads its neighbours' routes on
`/<robot>/plan` the same way (`subscribe_route`). See docs/interfaces.md.
"""

import math
import time

from geometry_msgs.msg import Point32, PolygonStamped, Vector3Stamped
from nav_msgs.msg import Path
from rclpy.duration import Duration

from prvo_msgs_util.conversions import (
    MAX_FOOTPRINT_RADIUS,
    MIN_FOOTPRINT_RADIUS,
    checked_stamp_seconds,
    seconds_to_stamp,
    serialized_path_stamp,
    serialized_path_to_waypoints,
)
from prvo_msgs_util.qos import (
    ANNOUNCEMENT_QOS,
    ANNOUNCEMENT_READER_QOS,
    PLAN_READER_QOS,
    quiet_publisher_events,
    quiet_subscription_events,
)
from prvo_msgs_util.topics import AVOIDANCE_SHARE, FOOTPRINT, PLAN, WORLD_FRAME, robot_topic

# Vertices of a circular footprint, as Nav2's costmap publishes one.
FOOTPRINT_VERTICES = 16


def footprint_message(radius, frame_id, stamp):
    """Return the PolygonStamped footprint of a disk of RADIUS [m] in FRAME_ID, stamped STAMP [s].

    Raises ValueError unless RADIUS is finite and > 0 and STAMP is finite and >= 0.
    """
    radius = float(radius)
    if not (math.isfinite(radius) and radius > 0.0):
        raise ValueError(f'footprint radius must be finite and > 0, got {radius!r}')
    message = PolygonStamped()
    message.header.frame_id = frame_id
    message.header.stamp = seconds_to_stamp(stamp)
    message.polygon.points = [
        Point32(x=radius * math.cos(angle), y=radius * math.sin(angle), z=0.0)
        for angle in (2.0 * math.pi * index / FOOTPRINT_VERTICES
                      for index in range(FOOTPRINT_VERTICES))]
    return message


def radius_of_footprint(message):
    """Return the circumscribed radius [m] of a PolygonStamped footprint about its frame origin.

    Raises ValueError naming the problem for a footprint without vertices, with a non-finite
    coordinate, or whose radius is outside the plausible [MIN_FOOTPRINT_RADIUS,
    MAX_FOOTPRINT_RADIUS].
    """
    points = message.polygon.points
    if not points:
        raise ValueError('footprint has no vertices')
    coordinates = [(point.x, point.y) for point in points]
    if not all(math.isfinite(x) and math.isfinite(y) for x, y in coordinates):
        raise ValueError(f'footprint has a non-finite vertex: {coordinates!r}')
    radius = max(math.hypot(x, y) for x, y in coordinates)
    if not MIN_FOOTPRINT_RADIUS <= radius <= MAX_FOOTPRINT_RADIUS:
        raise ValueError(f'footprint radius must be in [{MIN_FOOTPRINT_RADIUS:g}, '
                         f'{MAX_FOOTPRINT_RADIUS:g}] m, got {radius!r}')
    return radius


def share_message(avoidance_share, frame_id, stamp):
    """Return the Vector3Stamped announcement of AVOIDANCE_SHARE in FRAME_ID, stamped STAMP [s].

    Raises ValueError unless the share is in [0, 1) and STAMP is finite and >= 0.
    """
    message = Vector3Stamped()
    message.header.frame_id = frame_id
    message.header.stamp = seconds_to_stamp(stamp)
    message.vector.x = _checked_share(avoidance_share)
    return message


def share_of(message):
    """Return the share a Vector3Stamped announcement states (its vector.x).

    Raises ValueError unless it is in [0, 1) and the vector's y and z are 0.
    """
    vector = message.vector
    if vector.y != 0.0 or vector.z != 0.0:
        raise ValueError(f'avoidance share must have vector.y = vector.z = 0, got '
                         f'{[vector.x, vector.y, vector.z]!r}')
    return _checked_share(vector.x)


def announcement_stamp(message):
    """Return the stamp [s] of an announcement (either kind): it holds for later plans.

    For the plans of odometry stamped after it; 0 means from the start. Raises ValueError
    (MessageFault) for a stamp that is no time (negative seconds, nanoseconds of a second or
    more).
    """
    return checked_stamp_seconds(message.header.stamp, 'announcement header.stamp')


def _checked_share(value):
    share = float(value)
    if not 0.0 <= share < 1.0:
        raise ValueError(f'avoidance share must be in [0, 1), got {share!r}')
    return share


class AnnouncementChanges:
    """The announcement messages of one robot that differ from those it announced before.

    The `Announcer` publishes them; the in-process engine delivers them to its agents.
    """

    def __init__(self, robot):
        self._frame_id = f'{robot}/base_link'
        self._radius = self._share = None

    def messages(self, radius, avoidance_share, stamp):
        """Return (footprint, share) of RADIUS [m] and AVOIDANCE_SHARE, stamped STAMP [s].

        Each message is None if its value is the one of the last call.
        """
        footprint = share = None
        if radius != self._radius:
            footprint = footprint_message(radius, self._frame_id, stamp)
            self._radius = radius
        if avoidance_share != self._share:
            share = share_message(avoidance_share, self._frame_id, stamp)
            self._share = avoidance_share
        return footprint, share


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
        self._changes = AnnouncementChanges(robot)
        footprint, share = FOOTPRINT, AVOIDANCE_SHARE
        if not in_robot_namespace:
            footprint, share = robot_topic(robot, FOOTPRINT), robot_topic(robot, AVOIDANCE_SHARE)
        self.footprint_publisher = node.create_publisher(
            PolygonStamped, footprint, ANNOUNCEMENT_QOS, event_callbacks=quiet_publisher_events())
        self.share_publisher = node.create_publisher(
            Vector3Stamped, share, ANNOUNCEMENT_QOS, event_callbacks=quiet_publisher_events())

    def announce(self, radius, avoidance_share, stamp):
        """Publish RADIUS [m] and AVOIDANCE_SHARE, each only if it differs from the last.

        STAMP [s]: the stamp of the plan that changed them (they hold for the plans of odometry
        stamped after it), 0 for what holds from the start. Returns the publishers that
        published (empty if nothing changed), for a caller that waits until every subscriber
        has acknowledged the change (`all_acknowledged`).
        """
        published = []
        for publisher, message in zip(
                (self.footprint_publisher, self.share_publisher),
                self._changes.messages(radius, avoidance_share, stamp), strict=True):
            if message is not None:
                publisher.publish(message)
                published.append(publisher)
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

    `receive_radius(robot, radius, stamp)` and `receive_share(robot, share, stamp)` get the
    converted values and the announcement's stamp [s] (`announcement_stamp`). A message that
    cannot be converted, or that they refuse with ValueError, goes to `on_fault(topic, error)`
    instead.
    """
    def handler(topic, convert, receive):
        def on_message(message):
            try:
                receive(robot, convert(message), announcement_stamp(message))
            except ValueError as error:
                on_fault(topic, error)
        return on_message

    footprint, share = robot_topic(robot, FOOTPRINT), robot_topic(robot, AVOIDANCE_SHARE)
    return [node.create_subscription(kind, topic, handler(topic, convert, receive),
                                     ANNOUNCEMENT_READER_QOS,
                                     event_callbacks=quiet_subscription_events())
            for kind, topic, convert, receive in (
                (PolygonStamped, footprint, radius_of_footprint, receive_radius),
                (Vector3Stamped, share, share_of, receive_share))]


def serialized_route(data, expected_frame=WORLD_FRAME):
    """Return (stamp [s], waypoints (K, 2)) of a route, a serialized nav_msgs/Path DATA.

    Raises MessageFault as `serialized_path_to_waypoints` does (another frame than
    EXPECTED_FRAME, a coordinate that is not finite, more than MAX_PATH_POSES poses) and for a
    stamp that is no time (`serialized_path_stamp`). An empty path reads as (0, 2) waypoints.
    """
    return serialized_path_stamp(data), serialized_path_to_waypoints(data, expected_frame)


def subscribe_route(node, robot, receive, on_fault, expected_frame=WORLD_FRAME):
    """Subscribe NODE to ROBOT's route on /<robot>/plan, serialized; return the subscription.

    `receive(robot, waypoints (K, 2), stamp)` gets each route (`serialized_route`); a message
    that cannot be read, or that it refuses with ValueError, goes to `on_fault(robot, topic,
    error)` instead.
    """
    topic = robot_topic(robot, PLAN)

    def on_message(data):
        try:
            stamp, waypoints = serialized_route(data, expected_frame)
            receive(robot, waypoints, stamp)
        except ValueError as error:
            on_fault(robot, topic, error)

    # Serialized: a long route's poses are read from the bytes, not made into Python objects.
    return node.create_subscription(Path, topic, on_message, PLAN_READER_QOS, raw=True,
                                    event_callbacks=quiet_subscription_events())

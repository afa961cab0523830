"""QoS profiles of every prvo topic (see docs/interfaces.md), and a graph check of QoS."""

from rclpy.duration import Infinite
from rclpy.event_handler import PublisherEventCallbacks, SubscriptionEventCallbacks
from rclpy.qos import (
    DurabilityPolicy,
    HistoryPolicy,
    LivelinessPolicy,
    QoSCompatibility,
    QoSProfile,
    ReliabilityPolicy,
    qos_check_compatible,
)
from rclpy.subscription import Subscription


def _reliable(depth, durability=DurabilityPolicy.VOLATILE):
    return QoSProfile(
        reliability=ReliabilityPolicy.RELIABLE, history=HistoryPolicy.KEEP_LAST, depth=depth,
        durability=durability)


ODOM_QOS = _reliable(10)
# A planner reads odometry with a queue of one: when it falls behind, it plans on the newest
# state instead of working through stale ones (compatible with ODOM_QOS publishers).
ODOM_LATEST_QOS = _reliable(1)
CMD_VEL_QOS = _reliable(10)
# A reliable publisher also serves rclpy's own best-effort /clock subscription (use_sim_time).
CLOCK_QOS = _reliable(10)
DIAGNOSTICS_QOS = _reliable(50)
MARKER_QOS = _reliable(1)
# Transient local so a runner that subscribes late still receives every contact event.
CONTACT_QOS = _reliable(100, DurabilityPolicy.TRANSIENT_LOCAL)
GOAL_QOS = _reliable(1)
# Latched: a planner that starts or discovers a robot later still receives its announcements.
# A publisher keeps one: Fast DDS asks for an acknowledgement with every sample only of a
# writer this shallow (a deeper one asks every few samples, and a command that waits for the
# acknowledgement waits for the periodic heartbeat, seconds).
ANNOUNCEMENT_QOS = _reliable(1, DurabilityPolicy.TRANSIENT_LOCAL)
# A subscriber queues more: each announcement is a change that holds from a step on, and a
# robot at its goal can change its share at two consecutive steps; a queue of one, whose node
# was slow to take the first change, would hold only the second (stamped a step later), and
# the plan of the step between would use the value from before both.
ANNOUNCEMENT_READER_QOS = _reliable(16, DurabilityPolicy.TRANSIENT_LOCAL)
# As map_server publishes the map: latched, so that a planner started later receives it.
MAP_QOS = _reliable(1, DurabilityPolicy.TRANSIENT_LOCAL)
# A route is published when it changes: latched, for an RViz or a neighbour started later (one
# sample per write: the command that waits for a neighbour's acknowledgement does not wait long).
PLAN_QOS = _reliable(1, DurabilityPolicy.TRANSIENT_LOCAL)
# A neighbour's routes are queued deeper, as announcements are: each holds from a step on.
PLAN_READER_QOS = _reliable(16, DurabilityPolicy.TRANSIENT_LOCAL)


def quiet_subscription_events():
    """Event callbacks for a control-loop subscription: no rclpy QoS event handlers.

    rclpy gives every endpoint two default event handlers (incompatible QoS, incompatible
    type). Each is a waitable: rclpy's default executor adds it to every wait set and polls it
    after every wake-up, about a millisecond per planner step, and every executor holds it.
    ``QosWatch`` reports incompatible QoS from the ROS graph instead.
    """
    return SubscriptionEventCallbacks(use_default_callbacks=False)


def quiet_publisher_events():
    """Event callbacks for a control-loop publisher (see ``quiet_subscription_events``)."""
    return PublisherEventCallbacks(use_default_callbacks=False)


def _as_in_graph(profile):
    """
    Return PROFILE with its defaults resolved as the middleware reports endpoints in the graph.

    The graph gives remote endpoints infinite durations and automatic liveliness where a profile
    says "default"; compared with the unresolved profile, they would look incompatible.
    """
    def resolved(duration):
        return duration if duration.nanoseconds else Infinite

    liveliness = profile.liveliness
    if liveliness == LivelinessPolicy.SYSTEM_DEFAULT:
        liveliness = LivelinessPolicy.AUTOMATIC
    return QoSProfile(
        history=profile.history, depth=profile.depth, reliability=profile.reliability,
        durability=profile.durability, deadline=resolved(profile.deadline),
        lifespan=resolved(profile.lifespan), liveliness=liveliness,
        liveliness_lease_duration=resolved(profile.liveliness_lease_duration))


class QosWatch:
    """
    Warn, once per remote endpoint, when its QoS cannot match one of a node's endpoints.

    What rclpy's default incompatible-QoS event handlers report, found in the ROS graph by a
    periodic ``check()`` instead of by an event handler per endpoint (see
    ``quiet_subscription_events``).
    """

    def __init__(self, node):
        self._node = node
        # Fully qualified topic -> (our QoS, whether we subscribe to it).
        self._watched = {}
        # Topic -> remote endpoint count at the last check: the graph's endpoint details cost
        # 10-30 times what a count does, so a topic is examined again only when its count moves.
        self._counts = {}
        self._reported = set()

    def watch(self, *endpoints):
        """Watch Subscriptions and Publishers of the node."""
        for endpoint in endpoints:
            self._watched[endpoint.topic_name] = (
                _as_in_graph(endpoint.qos_profile), isinstance(endpoint, Subscription))

    def forget(self, endpoint):
        """Stop watching an endpoint (before it is destroyed)."""
        self._watched.pop(endpoint.topic_name, None)
        self._counts.pop(endpoint.topic_name, None)

    def check(self):
        """
        Warn about every new remote endpoint whose QoS is incompatible with ours.

        A topic is examined when its number of remote endpoints changed since the last check (an
        endpoint replaced by another between two checks goes unexamined).

        Returns
        -------
        list of str
            The warnings logged by this call (each remote endpoint is reported once).

        """
        warnings = []
        for topic, (ours, subscribing) in self._watched.items():
            count = (self._node.count_publishers(topic) if subscribing
                     else self._node.count_subscribers(topic))
            if self._counts.get(topic) == count:
                continue
            self._counts[topic] = count
            if subscribing:
                remotes, role = self._node.get_publishers_info_by_topic(topic), 'publisher'
            else:
                remotes, role = self._node.get_subscriptions_info_by_topic(topic), 'subscription'
            for remote in remotes:
                offered, requested = (
                    (remote.qos_profile, ours) if subscribing else (ours, remote.qos_profile))
                compatibility, reason = qos_check_compatible(offered, requested)
                key = (topic, bytes(remote.endpoint_gid))
                if compatibility != QoSCompatibility.ERROR or key in self._reported:
                    continue
                self._reported.add(key)
                name = f'{remote.node_namespace.rstrip("/")}/{remote.node_name}'
                warnings.append(
                    f'{role} of {name} on {topic} has incompatible QoS, no messages will pass: '
                    f'{reason.strip()}')
                self._node.get_logger().warning(warnings[-1])
        return warnings

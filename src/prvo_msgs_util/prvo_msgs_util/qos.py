"""QoS profiles of every prvo topic (see docs/interfaces.md)."""

from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy


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

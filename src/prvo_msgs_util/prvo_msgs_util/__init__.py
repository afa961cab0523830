"""Conversions between ROS 2 messages and numpy arrays for the PRVO stack."""

from prvo_msgs_util.announcements import (
    Announcer,
    CommandsAfterAnnouncements,
    all_acknowledged,
    footprint_message,
    radius_of_footprint,
    share_message,
    share_of,
    subscribe_announcements,
)
from prvo_msgs_util.conversions import (
    MAX_SPEED_COMPONENT,
    MAX_VARIANCE,
    MAX_WORLD_COORDINATE,
    MessageFault,
    OdometryMeasurement,
    body_to_world,
    check_world_point,
    make_odometry,
    make_pose_stamped,
    make_twist,
    make_twist_stamped,
    odometry_to_measurement,
    pose_stamped_to_goal,
    seconds_to_stamp,
    serialize_odometry,
    serialized_odometry_to_measurement,
    stamp_to_seconds,
    twist_to_velocity,
    world_to_body,
)
from prvo_msgs_util.diagnostics import (
    diagnostic_values,
    make_diagnostic_array,
    make_diagnostic_status,
)
from prvo_msgs_util.interrupts import (
    STOP_SIGNALS,
    SigintRecorder,
    hold_stop_signals,
    ignore_stop_signals,
    release_stop_signals,
)
from prvo_msgs_util.markers import make_belief_markers
from prvo_msgs_util.parameters import (
    PARAMETER_TYPES,
    declare_parameters,
    parameter_descriptor,
)
from prvo_msgs_util.qos import (
    ANNOUNCEMENT_QOS,
    CLOCK_QOS,
    CMD_VEL_QOS,
    CONTACT_QOS,
    DIAGNOSTICS_QOS,
    GOAL_QOS,
    MARKER_QOS,
    ODOM_LATEST_QOS,
    ODOM_QOS,
    QosWatch,
    quiet_publisher_events,
    quiet_subscription_events,
)
from prvo_msgs_util.runtime import (
    ThrottledWarnings,
    freeze_startup_objects,
    quiet_after_shutdown,
    spin_events,
)
from prvo_msgs_util.topics import (
    AVOIDANCE_SHARE,
    CLOCK,
    CMD_VEL,
    CONTACTS,
    DIAGNOSTICS,
    FOOTPRINT,
    GOAL_POSE,
    GROUND_TRUTH,
    MARKERS,
    ODOM,
    WORLD_FRAME,
    robot_from_topic,
    robot_topic,
    robots_with_topic,
    validate_robot_name,
)

__all__ = [
    'ANNOUNCEMENT_QOS', 'AVOIDANCE_SHARE', 'FOOTPRINT', 'footprint_message',
    'radius_of_footprint', 'share_message', 'share_of', 'Announcer', 'subscribe_announcements',
    'all_acknowledged', 'CommandsAfterAnnouncements',
    'CLOCK', 'CLOCK_QOS', 'CMD_VEL', 'CMD_VEL_QOS', 'CONTACTS', 'CONTACT_QOS', 'DIAGNOSTICS',
    'DIAGNOSTICS_QOS', 'GOAL_POSE', 'GOAL_QOS', 'GROUND_TRUTH', 'MARKERS', 'MARKER_QOS',
    'MAX_SPEED_COMPONENT', 'MAX_VARIANCE', 'MAX_WORLD_COORDINATE',
    'MessageFault', 'ODOM', 'ODOM_LATEST_QOS', 'ODOM_QOS', 'OdometryMeasurement',
    'QosWatch', 'quiet_publisher_events', 'quiet_subscription_events',
    'SigintRecorder', 'STOP_SIGNALS', 'hold_stop_signals', 'ignore_stop_signals',
    'release_stop_signals', 'body_to_world', 'check_world_point', 'declare_parameters',
    'diagnostic_values', 'freeze_startup_objects', 'PARAMETER_TYPES', 'parameter_descriptor',
    'quiet_after_shutdown', 'spin_events', 'ThrottledWarnings',
    'make_belief_markers', 'make_diagnostic_array', 'make_diagnostic_status', 'make_odometry',
    'make_pose_stamped', 'make_twist', 'make_twist_stamped', 'odometry_to_measurement',
    'pose_stamped_to_goal', 'robot_from_topic', 'robot_topic', 'robots_with_topic',
    'seconds_to_stamp', 'serialize_odometry', 'serialized_odometry_to_measurement',
    'stamp_to_seconds',
    'twist_to_velocity', 'validate_robot_name', 'WORLD_FRAME', 'world_to_body',
]

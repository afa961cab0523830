"""Topic names of the prvo stack and helpers for per-robot namespaces."""

import re

ODOM = 'odom'
GROUND_TRUTH = 'ground_truth'
CMD_VEL = 'cmd_vel'
GOAL_POSE = 'goal_pose'
MARKERS = 'prvo_markers'
FOOTPRINT = 'footprint'
AVOIDANCE_SHARE = 'avoidance_share'
DIAGNOSTICS = '/diagnostics'
CONTACTS = '/prvo_sim/contacts'
CLOCK = '/clock'
# The static world as an occupancy grid (map_server's topic), and each robot's way to its goal.
MAP = '/map'
PLAN = 'plan'
# The simulator's walls and obstacles as RViz markers (latched, MAP_QOS).
WORLD_MARKERS = '/prvo_sim/world_markers'
# The world frame of odometry, ground truth, goals and world-frame commands.
WORLD_FRAME = 'map'

_NAME_SEGMENT = re.compile(r'[A-Za-z_][A-Za-z0-9_]*')


def validate_robot_name(name):
    """Raise ValueError naming NAME unless it is a single valid ROS name segment.

    Repeated underscores are refused too: a robot's nodes are started with the remap rule
    `__ns:=/NAME`, whose parser reads `__` as the start of one of its own tokens (`__ns`,
    `__node`), although rclpy's name validators take it.
    """
    if not isinstance(name, str) or _NAME_SEGMENT.fullmatch(name) is None:
        raise ValueError(
            f'robot name {name!r} is not a valid ROS name segment '
            '(letters, digits and underscores, not starting with a digit)')
    if '__' in name:
        raise ValueError(
            f"robot name {name!r} holds '__': ROS cannot parse the remap rule "
            f'__ns:=/{name} (no repeated underscores in a ROS name)')


def robot_topic(robot, leaf):
    """Return the absolute topic '/<robot>/<leaf>'."""
    validate_robot_name(robot)
    return f'/{robot}/{leaf}'


def robot_from_topic(topic, leaf):
    """Return the robot name if TOPIC is exactly '/<name>/<leaf>', else None."""
    prefix, separator, name_and_leaf = topic.partition('/')
    if prefix or not separator:
        return None
    name, separator, rest = name_and_leaf.partition('/')
    if not separator or rest != leaf or _NAME_SEGMENT.fullmatch(name) is None:
        return None
    return name


def robots_with_topic(node, leaf, message_type):
    """Return the robots whose topic '/<name>/<LEAF>' carries MESSAGE_TYPE in NODE's graph.

    MESSAGE_TYPE is a type name as the graph states it, such as 'nav_msgs/msg/Odometry'.
    """
    return {robot for topic, types in node.get_topic_names_and_types()
            if (robot := robot_from_topic(topic, leaf)) and message_type in types}

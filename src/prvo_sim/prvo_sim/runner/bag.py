"""A run's rosbag2 recording: `<out>/bag/`, metadata.yaml and one .mcap file (rosbag2's layout).

The bag holds /clock, every robot's odom, ground_truth, cmd_vel and prvo_markers,
/diagnostics, and in a world with walls, obstacles or a map, /map and every planner's route
`<robot>/plan`, each message serialized as it was published. Messages are logged at their
sim-time stamp, as `ros2 bag record --use-sim-time` logs them, so that both engines give the
same bag and `ros2 bag play --clock` replays a run at its own pace. The `rosbags` library
writes it.
"""

import math
import pathlib
import shutil
import struct
import tempfile

from prvo_msgs_util import (
    CLOCK,
    CLOCK_QOS,
    CMD_VEL,
    CMD_VEL_QOS,
    DIAGNOSTICS,
    DIAGNOSTICS_QOS,
    GROUND_TRUTH,
    MAP,
    MAP_QOS,
    MARKER_QOS,
    MARKERS,
    ODOM,
    ODOM_QOS,
    PLAN,
    PLAN_QOS,
    robot_topic,
)

BAG_FOLDER = 'bag'
ROSBAG2_VERSION = 9  # metadata.yaml's version: rosbag2 of Jazzy
CLOCK_TYPE = 'rosgraph_msgs/msg/Clock'
ODOMETRY_TYPE = 'nav_msgs/msg/Odometry'
TWIST_STAMPED_TYPE = 'geometry_msgs/msg/TwistStamped'
MARKER_ARRAY_TYPE = 'visualization_msgs/msg/MarkerArray'
DIAGNOSTIC_ARRAY_TYPE = 'diagnostic_msgs/msg/DiagnosticArray'
OCCUPANCY_GRID_TYPE = 'nav_msgs/msg/OccupancyGrid'
PATH_TYPE = 'nav_msgs/msg/Path'
# Where the stamp (builtin_interfaces/Time: int32 sec, uint32 nanosec) of a serialized message
# of each type starts: after the 4-byte CDR encapsulation header, the header's stamp (or the
# clock) comes first; a MarkerArray's first marker's header follows its uint32 length.
_STAMP_OFFSETS = {CLOCK_TYPE: 4, ODOMETRY_TYPE: 4, TWIST_STAMPED_TYPE: 4,
                  DIAGNOSTIC_ARRAY_TYPE: 4, MARKER_ARRAY_TYPE: 8, OCCUPANCY_GRID_TYPE: 4,
                  PATH_TYPE: 4}
_CDR_LITTLE_ENDIAN = 1  # the second byte of the encapsulation header: 0 big, 1 little endian


def bag_topics(robot_names, planned_names=None, with_map=False):
    """Return {topic: (message type, publisher QoS profile)} of a run of ROBOT_NAMES, in order.

    PLANNED_NAMES (default: all) are the robots with a planner: only they publish cmd_vel and
    markers (a scripted robot is moved by the simulator). WITH_MAP: the world has static
    shapes, which the simulator publishes on /map at start-up, and the planners their routes.
    """
    planned_names = robot_names if planned_names is None else planned_names
    # In the order a step publishes them: the bag keeps it among messages of one stamp.
    topics = {MAP: (OCCUPANCY_GRID_TYPE, MAP_QOS)} if with_map else {}
    topics[CLOCK] = (CLOCK_TYPE, CLOCK_QOS)
    for leaf, message_type, qos in ((ODOM, ODOMETRY_TYPE, ODOM_QOS),
                                    (GROUND_TRUTH, ODOMETRY_TYPE, ODOM_QOS)):
        topics.update({robot_topic(name, leaf): (message_type, qos) for name in robot_names})
    topics[DIAGNOSTICS] = (DIAGNOSTIC_ARRAY_TYPE, DIAGNOSTICS_QOS)
    for leaf, message_type, qos in ((CMD_VEL, TWIST_STAMPED_TYPE, CMD_VEL_QOS),
                                    (MARKERS, MARKER_ARRAY_TYPE, MARKER_QOS)):
        topics.update({robot_topic(name, leaf): (message_type, qos) for name in planned_names})
    if with_map:
        topics.update({robot_topic(name, PLAN): (PATH_TYPE, PLAN_QOS) for name in planned_names})
    return topics


def stamp_ns(data, message_type):
    """Return the stamp [ns] of serialized DATA of MESSAGE_TYPE, None if it has none.

    Only a MarkerArray can lack one (no marker at all).
    """
    offset = _STAMP_OFFSETS[message_type]
    if message_type == MARKER_ARRAY_TYPE and _unpack(data, 'I', 4)[0] == 0:
        return None
    sec, nanosec = _unpack(data, 'iI', offset)
    return sec * 1_000_000_000 + nanosec


def _unpack(data, layout, offset):
    byte_order = '<' if data[1] == _CDR_LITTLE_ENDIAN else '>'
    return struct.unpack_from(byte_order + layout, data, offset)


class BagMessages:
    """Every serialized message of a run's bag, by topic, each with its sim-time stamp [ns]."""

    def __init__(self, robot_names, planned_names=None, with_map=False):
        """Hold no message yet of any topic of a run of ROBOT_NAMES (see bag_topics)."""
        self.topics = bag_topics(robot_names, planned_names, with_map)
        self.messages = {topic: [] for topic in self.topics}

    def add(self, topic, data, stamp=None):
        """Add serialized DATA published on TOPIC, at STAMP [ns] (default: DATA's own stamp).

        A message without a stamp of its own is logged at the topic's previous one. A message
        equal to the topic's previous one (the simulator sends its first state again until the
        run starts) is kept once.
        """
        messages = self.messages[topic]
        data = bytes(data)
        if messages and messages[-1][1] == data:
            return
        if stamp is None:
            stamp = stamp_ns(data, self.topics[topic][0])
        if stamp is None:
            stamp = messages[-1][0] if messages else 0
        messages.append((stamp, data))

    def drop_after(self, stamp):
        """Leave out every message logged after STAMP [ns] (the end of the run)."""
        for topic, messages in self.messages.items():
            self.messages[topic] = [message for message in messages if message[0] <= stamp]

    def missing_odometry(self, robot_names, stamps):
        """Return (robot, missing count, first missing stamp [ns]) of each incomplete odometry.

        STAMPS [ns] are the run's recorded steps; every robot of ROBOT_NAMES publishes its
        odometry at each. Under heavy load the middleware can drop a sample a slow recorder had
        not yet taken (a publisher keeps only its last ODOM_QOS.depth).
        """
        missing = []
        for name in robot_names:
            held = {stamp for stamp, _ in self.messages[robot_topic(name, ODOM)]}
            lacking = sorted(set(stamps) - held)
            if lacking:
                missing.append((name, len(lacking), lacking[0]))
        return missing

    def counts(self):
        """Return {topic: number of messages}."""
        return {topic: len(messages) for topic, messages in self.messages.items()}


def _rosbags_qos(profile):
    """Return an rclpy QoSProfile as rosbags' Qos (the offered profile in metadata.yaml)."""
    from rosbags.interfaces import (
        Qos,
        QosDurability,
        QosHistory,
        QosLiveliness,
        QosReliability,
        QosTime,
    )

    def duration(value):
        sec, nanosec = divmod(value.nanoseconds, 1_000_000_000)
        return QosTime(sec, nanosec)

    return Qos(QosHistory(profile.history.value), profile.depth,
               QosReliability(profile.reliability.value),
               QosDurability(profile.durability.value), duration(profile.deadline),
               duration(profile.lifespan), QosLiveliness(profile.liveliness.value),
               duration(profile.liveliness_lease_duration),
               profile.avoid_ros_namespace_conventions)


def write_bag(out_dir, bag_messages, file_mode=0o644):
    """Write BAG_MESSAGES as OUT_DIR/bag/, replacing an earlier run's bag; return its path.

    The bag is written in full into a temporary folder beside it first, so that OUT_DIR never
    holds half a bag. Messages go in time order (a topic's order is kept among equal stamps).
    Its files get FILE_MODE, its folder the same with search permission where it reads.
    """
    from rosbags.rosbag2 import CompressionFormat, CompressionMode, StoragePlugin, Writer
    from rosbags.typesys import Stores, get_typestore

    out_dir = pathlib.Path(out_dir)
    typestore = get_typestore(Stores.ROS2_JAZZY)
    staging = pathlib.Path(tempfile.mkdtemp(dir=out_dir, prefix=f'.{BAG_FOLDER}-'))
    try:
        staged = staging / BAG_FOLDER
        writer = Writer(staged, version=ROSBAG2_VERSION, storage_plugin=StoragePlugin.MCAP)
        # zstd chunks inside the .mcap, which rosbag2's MCAP storage reads as it is.
        writer.set_compression(CompressionMode.STORAGE, CompressionFormat.ZSTD)
        with writer:
            connections = {
                topic: writer.add_connection(topic, message_type, typestore=typestore,
                                             offered_qos_profiles=[_rosbags_qos(qos)])
                for topic, (message_type, qos) in bag_messages.topics.items()}
            ordered = sorted(
                ((stamp, index, topic, data)
                 for index, topic in enumerate(bag_messages.topics)
                 for stamp, data in bag_messages.messages[topic]),
                key=lambda message: message[:2])
            for stamp, _, topic, data in ordered:
                writer.write(connections[topic], stamp, data)
        for path in staged.iterdir():
            path.chmod(file_mode)
        # Search permission wherever the mode gives read permission.
        staged.chmod(file_mode | (file_mode & 0o444) >> 2)
        bag_path = out_dir / BAG_FOLDER
        remove_bag(out_dir)
        staged.rename(bag_path)
        return bag_path
    finally:
        shutil.rmtree(staging, ignore_errors=True)


def remove_bag(out_dir):
    """Remove OUT_DIR/bag/ (an earlier run's), if there is one."""
    shutil.rmtree(pathlib.Path(out_dir) / BAG_FOLDER, ignore_errors=True)



class TeamMessages:
    """The messages a ROS lockstep run publishes, built from an in-process team's steps.

    Before each step, `add_state()` adds the simulator's /clock and /diagnostics of the state
    about to be planned on; after it, `add_step(step)` adds that state's odometry and ground
    truth (the engine's serialized messages) and each planner's cmd_vel, and every
    `status_period` of sim time (the node's period is wall time) its status and markers.
    """

    def __init__(self, names, planner_values, team):
        """Build the messages of robots NAMES with the PLANNER_VALUES of TEAM (InProcessTeam)."""
        from rclpy.serialization import serialize_message

        from prvo_sim.world_messages import map_message

        grid = map_message(team.world)
        self.bag_messages = BagMessages(names, [
            name for name, values in zip(names, planner_values, strict=True)
            if values is not None], with_map=grid is not None)
        if grid is not None:
            # The simulator's /map, published once at start-up.
            self.bag_messages.add(MAP, serialize_message(grid))
        self._names = list(names)
        self._planner_values = list(planner_values)
        self._team = team
        self._status_at = [-math.inf] * len(self._names)

    def add_state(self):
        """Add the simulator's /clock and /diagnostics of the team's current state."""
        from rclpy.serialization import serialize_message
        from rosgraph_msgs.msg import Clock

        from prvo_msgs_util import seconds_to_stamp
        from prvo_sim.world_messages import status_array

        world = self._team.world
        self.bag_messages.add(CLOCK, serialize_message(
            Clock(clock=seconds_to_stamp(world.time))))
        message = 'finished' if world.finished else 'running'
        self.bag_messages.add(DIAGNOSTICS, serialize_message(status_array(
            world, message, 'lockstep', [0] * len(self._names))))

    def add_step(self, step):
        """Add the odometry, ground truth and planners' messages of the team's last STEP."""
        from rclpy.serialization import serialize_message

        from prvo_msgs_util import make_diagnostic_array
        from prvo_planner.reports import command_message, plan_markers, plan_status

        add, team = self.bag_messages.add, self._team
        for name, (odometry, ground_truth) in zip(self._names, team.last_odometry, strict=True):
            add(robot_topic(name, ODOM), odometry)
            add(robot_topic(name, GROUND_TRUTH), ground_truth)
        # plan_ms has one entry per planned robot, in order; scripted robots publish no plans.
        plan_ms = iter(step.plan_ms)
        for index, (name, command) in enumerate(zip(self._names, team.last_commands,
                                                    strict=True)):
            if command is None:
                continue
            plan_time_ms = float(next(plan_ms))
            add(robot_topic(name, CMD_VEL),
                serialize_message(command_message(name, command, stamped=True)))
            agent = team.agents[index]
            values, config = self._planner_values[index], agent.config
            if step.time - self._status_at[index] < values['status_period']:
                continue
            self._status_at[index] = step.time
            status = plan_status(name, command, plan_time_ms, config.model,
                                 agent.settings.planning_radius)
            add(DIAGNOSTICS, serialize_message(make_diagnostic_array(command.stamp, [status])))
            add(robot_topic(name, MARKERS), serialize_message(plan_markers(
                name, command, values['frame_id'], config.effective_k)))

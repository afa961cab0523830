"""The recorder: an rclpy node in the runner that records a run and watches its domain.

Besides ground truth, commands and diagnostics it reads the ROS graph: before a run, a domain
with strangers on it (anything publishing beyond /rosout and /parameter_events, or touching the
run's topics) is refused; during a run, a publisher the runner did not start, or a second
publisher on a topic of the run, fails it. Pure observers (subscribers) are welcome then.
"""

import contextlib
import copy
import itertools
import math
import os
import threading
import time

import numpy as np

RECORDER_CLOSE_TIMEOUT = 5.0  # wall seconds the recorder's DDS teardown may take
# Topics every rclpy node publishes on; publishing there says nothing about a node.
ROS_DEFAULT_TOPICS = ('/rosout', '/parameter_events')
RECORDER_QUEUE_DEPTH = 2000  # messages per topic held until the recorder takes them
MAX_NAMED_INTRUDERS = 3  # in a one-line failure
_INSTANCES = itertools.count()
# What the graph says of an endpoint whose participant's node names have not arrived yet.
_UNKNOWN_NODE_NAME = '_NODE_NAME_UNKNOWN_'
UNNAMED_NODE = '(a node not named yet)'


def _stamp_ns(stamp):
    return stamp.sec * 1_000_000_000 + stamp.nanosec


def _seconds_ns(seconds):
    """Return a stamp in float seconds (sec + nanosec * 1e-9) as integer nanoseconds again."""
    return round(seconds * 1e9)


class Recorder:
    """An rclpy node in a context of its own that records what the run needs to be measured."""

    def __init__(self, domain_id, robot_names, role='recorder', planned_names=None,
                 record_bag=False):
        """Create the node on DOMAIN_ID, subscribed to what ROBOT_NAMES' run publishes.

        ROLE goes into the node's name, which is unique to the process and the instance.
        PLANNED_NAMES are the robots with a planner (default: all); the others are scripted,
        moved by the simulator, and publish no cmd_vel or planner diagnostics. With
        RECORD_BAG it also keeps, serialized, everything else of the run's bag (see
        `bag_messages`): /clock, odometry and markers; planners build markers only then.
        """
        from diagnostic_msgs.msg import DiagnosticArray
        from geometry_msgs.msg import TwistStamped
        from nav_msgs.msg import Odometry
        import rclpy
        from rclpy.context import Context
        from rclpy.experimental import EventsExecutor
        from rclpy.signals import SignalHandlerOptions
        from rclpy.task import Future

        from prvo_msgs_util import (
            CMD_VEL,
            CMD_VEL_QOS,
            DIAGNOSTICS,
            DIAGNOSTICS_QOS,
            GROUND_TRUTH,
            ODOM_QOS,
            quiet_subscription_events,
            robot_topic,
        )
        from prvo_sim.runner.session import run_topics

        self.robot_names = list(robot_names)
        self.planned_names = list(robot_names if planned_names is None else planned_names)
        # Ground truth and commands are kept serialized as they arrive and decoded when read:
        # decoding costs the recorder most of its CPU, which the team it measures needs.
        self._serialized = {kind: {name: [] for name in self.robot_names}
                            for kind in ('ground_truth', 'commands')}
        self._decoded = {kind: ({name: {} for name in self.robot_names},
                                dict.fromkeys(self.robot_names, 0))
                         for kind in ('ground_truth', 'commands')}
        self.plan_times_ms = []
        # The simulator's latest prvo_sim status (world_messages.SimStatus), None before.
        self.sim_status = None
        self.context = Context()
        # The runner handles SIGINT/SIGTERM itself, so that children are always stopped.
        rclpy.init(context=self.context, domain_id=domain_id,
                   signal_handler_options=SignalHandlerOptions.NO)
        self.domain_id = domain_id
        # Unique to the run: the simulator waits for this node by name (its `observers`).
        self.node = rclpy.create_node(
            f'prvo_run_{role}_d{domain_id}_p{os.getpid()}_{next(_INSTANCES)}',
            context=self.context)
        self.name = self.node.get_fully_qualified_name()
        self.run_topics = run_topics(self.robot_names)
        # The recorder shares the CPU with the team it measures: the events executor (see
        # prvo_msgs_util.spin_events) and bookkeeping a few times per second, not per message.
        self._executor = EventsExecutor(context=self.context)
        self._executor.add_node(self.node)
        self._never_done = Future()
        # No per-endpoint QoS event handlers (prvo_msgs_util.quiet_subscription_events): it
        # only listens to prvo nodes.
        self._command_subscriptions = {}
        for name in self.robot_names:
            for kind, topic, message_type, qos in (
                    ('ground_truth', GROUND_TRUTH, Odometry, ODOM_QOS),
                    ('commands', CMD_VEL, TwistStamped, CMD_VEL_QOS)):
                subscription = self.node.create_subscription(
                    message_type, robot_topic(name, topic), self._serialized[kind][name].append,
                    _deep(qos), event_callbacks=quiet_subscription_events(), raw=True)
                if kind == 'commands':
                    self._command_subscriptions[name] = subscription
        self._serialized_diagnostics = []
        self._diagnostics_subscription = self.node.create_subscription(
            DiagnosticArray, DIAGNOSTICS, self._on_diagnostics, _deep(DIAGNOSTICS_QOS),
            event_callbacks=quiet_subscription_events(), raw=True)
        self._bag_topics = None
        if record_bag:
            self._subscribe_bag_topics()

    def _subscribe_bag_topics(self):
        """Keep every message of the bag's topics that the recording does not keep already."""
        from nav_msgs.msg import Odometry
        from rosgraph_msgs.msg import Clock
        from visualization_msgs.msg import MarkerArray

        from prvo_msgs_util import (
            CLOCK,
            CLOCK_QOS,
            CMD_VEL,
            DIAGNOSTICS,
            GROUND_TRUTH,
            MARKER_QOS,
            MARKERS,
            ODOM,
            ODOM_QOS,
            quiet_subscription_events,
            robot_topic,
        )

        self._bag_topics = {CLOCK: [], DIAGNOSTICS: self._serialized_diagnostics}
        subscribed = [(CLOCK, Clock, CLOCK_QOS)]
        for name in self.robot_names:
            self._bag_topics[robot_topic(name, GROUND_TRUTH)] = (
                self._serialized['ground_truth'][name])
            self._bag_topics[robot_topic(name, CMD_VEL)] = self._serialized['commands'][name]
            for leaf, message_type, qos in ((ODOM, Odometry, ODOM_QOS),
                                            (MARKERS, MarkerArray, MARKER_QOS)):
                topic = robot_topic(name, leaf)
                self._bag_topics[topic] = []
                subscribed.append((topic, message_type, qos))
        for topic, message_type, qos in subscribed:
            self.node.create_subscription(
                message_type, topic, self._bag_topics[topic].append, _deep(qos),
                event_callbacks=quiet_subscription_events(), raw=True)

    def bag_messages(self):
        """Return the run's `runner.bag.BagMessages` of everything received, None if not kept."""
        from prvo_sim.runner.bag import BagMessages

        if self._bag_topics is None:
            return None
        messages = BagMessages(self.robot_names, self.planned_names)
        for topic in messages.topics:
            for data in self._bag_topics[topic]:
                messages.add(topic, data)
        return messages

    def unheard_planners(self):
        """Return the robots whose cmd_vel or diagnostics publisher this node has not matched.

        Every planner publishes both; diagnostics carry its plan times from the first plan on.
        """
        unheard = [name for name in self.planned_names
                   if self._command_subscriptions[name].get_publisher_count() == 0]
        if not unheard and (self._diagnostics_subscription.get_publisher_count()
                            < len(self.planned_names)):
            return ['diagnostics']
        return unheard

    def latest(self):
        """Return {robot: (stamp ns, position (2,))} of the newest ground truth of each robot."""
        from prvo_msgs_util import serialized_odometry_to_measurement

        latest = {}
        for name, received in self._serialized['ground_truth'].items():
            if received:
                measurement = serialized_odometry_to_measurement(received[-1])
                latest[name] = (_seconds_ns(measurement.stamp), measurement.position)
        return latest

    @property
    def ground_truth(self):
        """{robot: {stamp ns: (x, y, vx, vy, yaw)}} of every ground truth received."""
        from prvo_msgs_util import serialized_odometry_to_measurement

        def decode(data):
            measurement = serialized_odometry_to_measurement(data)
            return _seconds_ns(measurement.stamp), (
                *measurement.position, *measurement.velocity, measurement.yaw)

        return self._decode('ground_truth', decode)

    @property
    def commands(self):
        """{robot: {stamp ns: (x, y, frame_id)}} of every command received, in its frame."""
        from geometry_msgs.msg import TwistStamped
        from rclpy.serialization import deserialize_message

        def decode(data):
            msg = deserialize_message(data, TwistStamped)
            # Kept in the message's frame: a body-frame command is rotated once the ground
            # truth (and so the robot's heading) at its stamp is known.
            return _stamp_ns(msg.header.stamp), (
                msg.twist.linear.x, msg.twist.linear.y, msg.header.frame_id)

        return self._decode('commands', decode)

    def _decode(self, kind, decode):
        """Decode the KIND of messages received since the last call; return all decoded."""
        decoded, counts = self._decoded[kind]
        for name, received in self._serialized[kind].items():
            for data in received[counts[name]:]:
                stamp, value = decode(data)
                decoded[name][stamp] = value
            counts[name] = len(received)
        return decoded

    def _on_diagnostics(self, data):
        from diagnostic_msgs.msg import DiagnosticArray
        from rclpy.serialization import deserialize_message

        from prvo_msgs_util import diagnostic_values
        from prvo_sim.world_messages import sim_status_of

        self._serialized_diagnostics.append(data)
        for status in deserialize_message(data, DiagnosticArray).status:
            if status.name == 'prvo_sim':
                self.sim_status = sim_status_of(status)
            elif status.name.startswith('prvo_planner/'):
                value = diagnostic_values(status).get('plan_time_ms')
                if value is not None:
                    with contextlib.suppress(ValueError):
                        self.plan_times_ms.append(float(value))

    def _publishers(self):
        """Return {topic: [node, ...]} (one entry per publisher) of all but the default topics."""
        publishers = {}
        for topic, _ in self.node.get_topic_names_and_types():
            if topic in ROS_DEFAULT_TOPICS:
                continue
            for info in self.node.get_publishers_info_by_topic(topic):
                publishers.setdefault(topic, []).append(
                    _full_name(info.node_namespace, info.node_name))
        return publishers

    def _strangers(self):
        """Return {node: {what it does}} of every node here but this one (see strangers)."""
        found = {}
        for topic, nodes in self._publishers().items():
            for node in nodes:
                if node != self.name:
                    found.setdefault(node, set()).add(f'publishes {topic}')
        for topic in self.run_topics:
            for info in self.node.get_subscriptions_info_by_topic(topic):
                node = _full_name(info.node_namespace, info.node_name)
                if node != self.name:
                    found.setdefault(node, set()).add(f'subscribes {topic}')
        return found

    def strangers(self):
        """Describe in one line every node already here before the run starts, else None.

        A node is a stranger if it publishes anywhere but on the default topics, or subscribes
        to one of the run's topics: a simulator or planner left over from a killed run would
        feed this run its clock, odometry and 'finished' status.
        """
        found = self._strangers()
        return None if not found else self._refusal(found)

    def _refusal(self, found):
        return (f'ROS_DOMAIN_ID {self.domain_id} is in use by processes this runner did not '
                f'start: {_describe(found)}')

    def foreign_traffic(self, duration):
        """Watch the domain for up to DURATION s before anything starts; describe strangers.

        Returns None once DURATION s of discovery showed no stranger, else a one-line failure
        (see `strangers`) as soon as every stranger's node name is known, or at the end.
        """
        deadline = time.monotonic() + duration
        while True:
            self.spin_for(0.05)
            found = self._strangers()
            if found and UNNAMED_NODE not in found:
                return self._refusal(found)
            if time.monotonic() >= deadline:
                return self._refusal(found) if found else None

    def intruders(self, own_nodes):
        """Describe in one line publishers the run did not start, else None.

        OWN_NODES are the fully qualified names of the runner's children: any other node
        publishing beyond the default topics, or a second publisher of one node name on a
        topic (a stranger named like one of the children), is an intruder. An endpoint whose
        node the graph does not name yet is judged at a later call, once it is named.
        """
        found = {}
        own_nodes = {*own_nodes, self.name}
        for topic, nodes in self._publishers().items():
            for node in set(nodes) - {UNNAMED_NODE}:
                if node not in own_nodes:
                    found.setdefault(node, set()).add(f'publishes {topic}')
                elif nodes.count(node) > 1:
                    found.setdefault(node, set()).add(f'publishes {topic} twice')
        if not found:
            return None
        return (f'processes this runner did not start publish on ROS_DOMAIN_ID '
                f'{self.domain_id}: {_describe(found)}')

    def recording_gaps(self, dt, commands_expected, grace):
        """Return what the recording lacks (see recording_gaps), after up to GRACE s more.

        Messages still on their way when the run ended (the last steps' commands travel from
        other processes than the ground truth) get GRACE s of wall time to arrive.
        """
        deadline = time.monotonic() + grace
        while True:
            gaps = recording_gaps(self.ground_truth, self.commands, self.robot_names, dt,
                                  commands_expected, self.planned_names)
            if gaps is None or time.monotonic() >= deadline:
                return gaps
            self.spin_for(0.05)

    def spin_for(self, duration):
        """Handle every message that arrives in the next DURATION s."""
        self._executor.spin_until_future_complete(self._never_done, timeout_sec=duration)

    def close(self, timeout=RECORDER_CLOSE_TIMEOUT):
        """Destroy the node and shut its context down; return False if that hung.

        Fast DDS can deadlock while deleting a DataWriter (ResourceEvent::unregister_timer,
        eProsima/Fast-DDS#6193, #6502), seen here after a child stopped answering. The
        destruction runs on a daemon thread so that a hang costs TIMEOUT s, not the run.
        """
        self._executor.shutdown()

        def destroy():
            self.node.destroy_node()
            self.context.try_shutdown()

        closer = threading.Thread(target=destroy, name='recorder-close', daemon=True)
        closer.start()
        closer.join(timeout)
        return not closer.is_alive()

    def recording(self):
        """Return the `Recording` of the run: the steps every robot's ground truth has.

        Commands are world-frame (a body-frame command is turned by the robot's heading at its
        stamp, as the simulator does), NaN where missing.
        """
        from prvo_msgs_util import WORLD_FRAME, body_to_world
        from prvo_sim.runner.outputs import Recording

        ground_truth, received_commands = self.ground_truth, self.commands
        stamps = sorted(set.intersection(
            *(set(ground_truth[name]) for name in self.robot_names)))
        states = np.full((len(stamps), len(self.robot_names), 5), math.nan)
        commands = np.full((len(stamps), len(self.robot_names), 2), math.nan)
        for step, stamp in enumerate(stamps):
            for robot, name in enumerate(self.robot_names):
                states[step, robot] = ground_truth[name][stamp]
                if stamp in received_commands[name]:
                    command_x, command_y, frame_id = received_commands[name][stamp]
                    command = (command_x, command_y)
                    if frame_id not in ('', WORLD_FRAME):
                        command = body_to_world(command, states[step, robot, 4])
                    commands[step, robot] = command
        status = self.sim_status
        return Recording(np.asarray(stamps, dtype=float) * 1e-9, states[..., :4], commands,
                         tuple(self.plan_times_ms),
                         None if status is None else status.deadline_misses,
                         yaws=states[..., 4], bag_messages=self.bag_messages())


def _deep(qos):
    """Return QOS with a queue of RECORDER_QUEUE_DEPTH (compatible: depth is not matched).

    A lockstep team steps hundreds of times per second; between two spins of the recorder the
    messages wait in this queue, and a shorter one would drop the oldest.
    """
    deep = copy.copy(qos)
    deep.depth = RECORDER_QUEUE_DEPTH
    return deep


def _full_name(namespace, name):
    """Return the node's fully qualified name, or UNNAMED_NODE while discovery lacks it."""
    if name == _UNKNOWN_NODE_NAME:
        return UNNAMED_NODE
    return f"{namespace.rstrip('/')}/{name}"


def _shortened(items):
    """Return the first MAX_NAMED_INTRUDERS of ITEMS, sorted, and how many more there are."""
    items = sorted(items)
    if len(items) <= MAX_NAMED_INTRUDERS:
        return items
    return [*items[:MAX_NAMED_INTRUDERS], f'{len(items) - MAX_NAMED_INTRUDERS} more']


def _describe(found):
    """Return '<node> publishes /a, subscribes /b; ...' for the first few nodes of FOUND."""
    return '; '.join(node if node not in found else f'{node} ' + ', '.join(_shortened(found[node]))
                     for node in _shortened(found))


def recording_gaps(ground_truth, commands, robot_names, dt, commands_expected,
                   planned_names=None):
    """Describe in one line what a recording lacks, else None.

    GROUND_TRUTH and COMMANDS are {robot: {stamp ns: ...}} (Recorder.ground_truth, .commands).
    A complete recording has every robot's ground truth at every step t = k DT from t = 0 to
    its last, and, if COMMANDS_EXPECTED (lockstep: every step is answered), the command of
    each of PLANNED_NAMES (default: every robot; scripted robots have none) answering each of
    those steps but the last.
    """
    for name in robot_names:
        steps = sorted(round(stamp * 1e-9 / dt) for stamp in ground_truth[name])
        if not steps:
            return f'the recorder received no ground truth of {name}'
        missing = sorted(set(range(steps[-1] + 1)) - set(steps))
        if missing:
            return (f'the recorder missed {len(missing)} ground truth message(s) of {name}, '
                    f'the first at t = {missing[0] * dt:g} s')
        if commands_expected and (planned_names is None or name in planned_names):
            answered = {round(stamp * 1e-9 / dt) for stamp in commands[name]}
            unanswered = sorted(set(steps[:-1]) - answered)
            if unanswered:
                return (f'the recorder missed {len(unanswered)} command(s) of {name}, the first '
                        f'answering t = {unanswered[0] * dt:g} s')
    return None


def foreign_participants(domain_id, robot_names, duration=None):
    """Return why DOMAIN_ID is not fit for a run of ROBOT_NAMES (strangers on it), else None.

    Listens DURATION s (default DOMAIN_CHECK_TIME) for discovery to show what is there.
    """
    from prvo_sim.runner.session import DOMAIN_CHECK_TIME

    recorder = Recorder(domain_id, robot_names, role='domain_check')
    try:
        return recorder.foreign_traffic(DOMAIN_CHECK_TIME if duration is None else duration)
    finally:
        recorder.close()

"""The recorder: what a run heard, kept in the runner; its DDS side is a child process.

The runner holds no DDS participant (see prvo_sim.runner.listener, which says why): a listener
child subscribes to the run and streams every message it takes and snapshots of the ROS graph
to this class, which keeps the messages serialized, decodes them when read, and judges the
graph. Before a run, a domain with strangers on it (anything publishing beyond /rosout and
/parameter_events) is refused; nodes that only subscribe, such as `ros2 topic echo /clock`,
cannot change a run's numbers and are welcome. During a run, a publisher the runner did not
start, or a second publisher on a topic of the run, fails it.
"""

import contextlib
import itertools
import json
import math
import os
import signal
import socket
import subprocess
import sys
import tempfile
import time

import numpy as np

from prvo_sim.runner.listener import UNNAMED_NODE
from prvo_sim.runner.processes import (
    RunInterruptedError,
    child_environment,
    die_with,
    untranslated,
)

# Sim seconds within which two stamps count as equal (the runner's end is a float of a stamp).
TIME_EPSILON = 1e-6
LISTENER_START_LIMIT = 60.0  # wall seconds for the listener to start (rclpy, DDS discovery)
LISTENER_STOP_WAIT = 1.0  # wall seconds the listener gets to leave before SIGKILL
# Wall seconds of listening for strangers on the domain before a run. Longer than Fast DDS's
# periodic participant announcement (3 s): a stranger starved of CPU when the check's own
# announcements arrive is still heard once.
DOMAIN_CHECK_TIME = 3.5
NAMING_GRACE = 5.0  # wall seconds more for a stranger's node name to arrive
MAX_NAMED_INTRUDERS = 3  # in a one-line failure
_INSTANCES = itertools.count()


class RecorderError(Exception):
    """The recorder's listener process could not start or stopped answering."""


def _stamp_ns(stamp):
    return stamp.sec * 1_000_000_000 + stamp.nanosec


def _seconds_ns(seconds):
    """Return a stamp in float seconds (sec + nanosec * 1e-9) as integer nanoseconds again."""
    return round(seconds * 1e9)


class Recorder:
    """What a run heard, streamed from a listener child on the run's domain (see the module)."""

    def __init__(self, domain_id, robot_names, role='recorder', planned_names=None,
                 record_bag=False, with_map=False):
        """Start a listener on DOMAIN_ID subscribed to what ROBOT_NAMES' run publishes.

        ROLE goes into the listener's node name, which is unique to the runner and the
        instance. PLANNED_NAMES are the robots with a planner (default: all); the others are
        scripted, moved by the simulator, and publish no cmd_vel or planner diagnostics. With
        RECORD_BAG it also keeps, serialized, everything else of the run's bag (see
        `bag_messages`): /clock, odometry and markers; planners build markers only then.
        WITH_MAP (a world with static shapes) records the simulator's /map and each planner's
        route in the bag too.
        Raises RecorderError if the listener does not start.
        """
        from prvo_msgs_util import (
            CLOCK,
            CMD_VEL,
            DIAGNOSTICS,
            GROUND_TRUTH,
            MAP,
            MARKERS,
            ODOM,
            PLAN,
            robot_topic,
        )

        self.robot_names = list(robot_names)
        self.planned_names = list(robot_names if planned_names is None else planned_names)
        self._with_map = with_map
        self.domain_id = domain_id
        # Ground truth and commands are kept serialized as they arrive and decoded when read.
        self._serialized = {kind: {name: [] for name in self.robot_names}
                            for kind in ('ground_truth', 'commands')}
        self._decoded = {kind: ({name: {} for name in self.robot_names},
                                dict.fromkeys(self.robot_names, 0))
                         for kind in ('ground_truth', 'commands')}
        self.plan_times_ms = []
        # The planner nodes' (plan, node) CPU times [ms] (`reports.plan_status`).
        self.planner_cpu_ms = []
        # The simulator's latest prvo_sim status (world_messages.SimStatus), None before.
        self.sim_status = None
        # Called with every DiagnosticArray received (the team benchmark times steps so).
        self.diagnostics_listeners = []
        self._serialized_diagnostics = []
        # Per planned robot, the plan tallies of its statuses: (stamp s, plans, infeasible,
        # lowest achieved eta).
        self._tallies = {}
        self._publishers = {}
        self._matched = {}
        # Each subscribed topic, with its kind and where its messages go.
        routes = []
        for name in self.robot_names:
            routes.append((robot_topic(name, GROUND_TRUTH), 'odometry',
                           self._serialized['ground_truth'][name].append))
            routes.append((robot_topic(name, CMD_VEL), 'command',
                           self._serialized['commands'][name].append))
        routes.append((DIAGNOSTICS, 'diagnostics', self._on_diagnostics))
        # The simulator waits for /clock too (its observers), so that a bag starts at t_0.
        self._clock = []
        routes.append((CLOCK, 'clock', self._clock.append))
        self._bag_topics = None
        if record_bag:
            self._bag_topics = {CLOCK: self._clock, DIAGNOSTICS: self._serialized_diagnostics}
            for name in self.robot_names:
                self._bag_topics[robot_topic(name, GROUND_TRUTH)] = (
                    self._serialized['ground_truth'][name])
                self._bag_topics[robot_topic(name, CMD_VEL)] = self._serialized['commands'][name]
                for leaf, kind in ((ODOM, 'odometry'), (MARKERS, 'markers')):
                    topic = robot_topic(name, leaf)
                    self._bag_topics[topic] = []
                    routes.append((topic, kind, self._bag_topics[topic].append))
            if with_map:
                # Latched, as each planner's route: the listener receives them whenever it
                # subscribes.
                for topic, kind in [(MAP, 'map')] + [(robot_topic(name, PLAN), 'plan')
                                                     for name in self.planned_names]:
                    self._bag_topics[topic] = []
                    routes.append((topic, kind, self._bag_topics[topic].append))
        if role == 'domain_check':
            # It only reads the graph.
            routes = []
        self._routes = [route for _, _, route in routes]
        self._command_topics = {name: robot_topic(name, CMD_VEL) for name in self.planned_names}
        matched = [*self._command_topics.values(), DIAGNOSTICS] if routes else []
        self.name = f'/prvo_run_{role}_d{domain_id}_p{os.getpid()}_{next(_INSTANCES)}'
        self.lost = None
        self._stopping = False
        self._start_listener({'domain_id': domain_id, 'node_name': self.name[1:],
                              'topics': [[topic, kind] for topic, kind, _ in routes],
                              'matched': matched})

    def _start_listener(self, spec):
        """Start the listener child with SPEC and wait until it is subscribed."""
        runner_end, listener_end = socket.socketpair()
        self._log = tempfile.TemporaryFile()
        try:
            self._process = subprocess.Popen(
                [sys.executable, '-m', 'prvo_sim.runner.listener', json.dumps(spec),
                 str(listener_end.fileno())],
                env=child_environment(self.domain_id), stdin=subprocess.DEVNULL,
                stdout=self._log, stderr=subprocess.STDOUT, pass_fds=(listener_end.fileno(),),
                start_new_session=True, preexec_fn=die_with(os.getpid()))
        finally:
            listener_end.close()
        from multiprocessing.connection import Connection

        self._socket = runner_end
        self._connection = Connection(os.dup(runner_end.fileno()))
        deadline = time.monotonic() + LISTENER_START_LIMIT
        try:
            while self._connection is not None and not self._ready(deadline):
                pass
        except RunInterruptedError:
            # Not yet the caller's to close.
            self.close()
            raise

    def _ready(self, deadline):
        """Take one message of the listener's start-up; return whether it is subscribed."""
        remaining = deadline - time.monotonic()
        if remaining <= 0.0 or not self._connection.poll(remaining):
            self.close()
            raise RecorderError(f'the recorder did not start within {LISTENER_START_LIMIT:g} s'
                                f'{self._log_tail()}')
        try:
            kind, payload = self._connection.recv()
        except (EOFError, OSError):
            self._process.wait()
            code = self._process.returncode
            tail = self._log_tail()
            self.close()
            raise RecorderError(
                f'the recorder exited with code {code} at start-up{tail}') from None
        if kind == 'ready':
            return True
        self._handle(kind, payload)
        return False

    def _log_tail(self):
        """Return ': <the listener's last output line>', or '' if it printed nothing."""
        with contextlib.suppress(OSError, ValueError):
            self._log.seek(0)
            lines = self._log.read().decode(errors='replace').strip().splitlines()
            if lines:
                return f': {lines[-1]}'
        return ''

    # A Ctrl-C while rclpy deserializes must stay a Ctrl-C.
    @untranslated()
    def _handle(self, kind, payload):
        if kind == 'messages':
            for index, data in payload:
                self._routes[index](data)
        elif kind == 'graph':
            self._publishers, self._matched = payload['publishers'], payload['matched']

    def spin_for(self, duration):
        """Take everything the listener sends in the next DURATION s."""
        deadline = time.monotonic() + duration
        while self._connection is not None:
            remaining = deadline - time.monotonic()
            if remaining <= 0.0 or not self._connection.poll(remaining):
                return
            try:
                self._handle(*self._connection.recv())
            except (EOFError, OSError):
                if not self._stopping:
                    self._process.wait()
                    self.lost = (f'the recorder exited with code {self._process.returncode}'
                                 f'{self._log_tail()}')
                self._drop_connection()
                return

    def bag_messages(self):
        """Return the run's `runner.bag.BagMessages` of everything received, None if not kept."""
        from prvo_sim.runner.bag import BagMessages

        if self._bag_topics is None:
            return None
        messages = BagMessages(self.robot_names, self.planned_names, self._with_map)
        for topic in messages.topics:
            for data in self._bag_topics[topic]:
                messages.add(topic, data)
        return messages

    def unheard_planners(self):
        """Return the robots whose cmd_vel or diagnostics publisher the listener has not matched.

        Every planner publishes both; diagnostics carry its plan times from the first plan on.
        """
        from prvo_msgs_util import DIAGNOSTICS

        unheard = [name for name, topic in self._command_topics.items()
                   if self._matched.get(topic, 0) == 0]
        if not unheard and self._matched.get(DIAGNOSTICS, 0) < len(self.planned_names):
            return ['diagnostics']
        return unheard

    @untranslated()
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

    @untranslated()
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
        message = deserialize_message(data, DiagnosticArray)
        for status in message.status:
            if status.name == 'prvo_sim':
                self.sim_status = sim_status_of(status)
            elif status.name.startswith('prvo_planner/'):
                values = diagnostic_values(status)
                value = values.get('plan_time_ms')
                if value is not None:
                    with contextlib.suppress(ValueError):
                        self.plan_times_ms.append(float(value))
                with contextlib.suppress(KeyError, ValueError):
                    self.planner_cpu_ms.append((float(values['plan_cpu_ms']),
                                                float(values['node_cpu_ms'])))
                self._take_tally(status.name.removeprefix('prvo_planner/'), values)
        for listener in self.diagnostics_listeners:
            listener(message)

    def _take_tally(self, robot, values):
        """Keep ROBOT's plan tally of a planner status (see plan_tallies)."""
        try:
            tally = (float(values['tally_stamp']), int(values['plans']),
                     int(values['infeasible_plans']), float(values['min_achieved_eta']))
        except (KeyError, ValueError):
            # Before its first plan ('none'), or not a prvo planner's status.
            return
        self._tallies.setdefault(robot, []).append(tally)

    def plan_tallies(self, until=None):
        """Return {robot: (plans, infeasible plans, lowest achieved eta)} of the planners.

        Each planner's newest tally in its status, of the plans up to UNTIL [s] if given (the
        end of the run); statuses come a few times per second, so the plans of the last
        fraction of a second may be missing. Robots without a tally are left out.
        """
        tallies = {}
        for robot, received in self._tallies.items():
            counted = [tally for tally in received
                       if until is None or tally[0] <= until + TIME_EPSILON]
            if counted:
                tallies[robot] = max(counted)[1:]
        return tallies

    def _strangers(self):
        """Return {node: {what it publishes}} of every node here but this one's listener."""
        found = {}
        for topic, nodes in self._publishers.items():
            for node in nodes:
                if node != self.name:
                    found.setdefault(node, set()).add(f'publishes {topic}')
        return found

    def strangers(self):
        """Describe in one line every node publishing here before the run starts, else None.

        A node is a stranger if it publishes anywhere but on the default topics: a simulator
        or planner left over from a killed run would feed this run its clock, odometry and
        'finished' status. A node that only subscribes cannot change the run and is welcome.
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
            if self.lost is not None:
                return self.lost
            found = self._strangers()
            if found and UNNAMED_NODE not in found:
                return self._refusal(found)
            now = time.monotonic()
            if now >= deadline and not found:
                return None
            # A stranger whose name has not arrived yet is named once it has, if it does soon.
            if now >= deadline + NAMING_GRACE:
                return self._refusal(found)

    def intruders(self, own_nodes):
        """Describe in one line publishers the run did not start, else None.

        OWN_NODES are the fully qualified names of the runner's children: any other node
        publishing beyond the default topics, or a second publisher of one node name on a
        topic (a stranger named like one of the children), is an intruder. An endpoint whose
        node the graph does not name yet is judged at a later call, once it is named.
        """
        found = {}
        own_nodes = {*own_nodes, self.name}
        for topic, nodes in self._publishers.items():
            for node in set(nodes) - {UNNAMED_NODE}:
                if node not in own_nodes:
                    found.setdefault(node, set()).add(f'publishes {topic}')
                elif nodes.count(node) > 1:
                    found.setdefault(node, set()).add(f'publishes {topic} twice')
        if not found:
            return None
        return (f'processes this runner did not start publish on ROS_DOMAIN_ID '
                f'{self.domain_id}: {_describe(found)}')

    def recording_gaps(self, dt, commands_expected, grace, until=None):
        """Return what the recording lacks (see recording_gaps), after up to GRACE s more.

        Messages still on their way when the run ended (the last steps' commands travel from
        other processes than the ground truth) get GRACE s of wall time to arrive. UNTIL [s],
        if given, is the end of the run: later steps are not judged.

        A bag's odometry gets the same GRACE to reach the last step: it travels beside the
        ground truth, and a loaded listener may take it later. Odometry that does not come is
        left out of the bag; the run does not fail for it.
        """
        deadline = time.monotonic() + grace
        while True:
            gaps = recording_gaps(self.ground_truth, self.commands, self.robot_names, dt,
                                  commands_expected, self.planned_names, until)
            if (time.monotonic() >= deadline or self.lost is not None
                    or gaps is None and not self._odometry_behind(until)):
                return gaps
            self.spin_for(0.05)

    def _odometry_behind(self, until):
        """Return the robots whose odometry in the bag ends before the last recorded step."""
        from prvo_msgs_util import ODOM, robot_topic

        if self._bag_topics is None:
            return []
        ground_truth = self.ground_truth
        last = min((max((stamp for stamp in ground_truth[name]
                         if until is None or stamp <= _seconds_ns(until)), default=0)
                    for name in self.robot_names), default=0)
        return odometry_behind({name: self._bag_topics[robot_topic(name, ODOM)]
                                for name in self.robot_names}, last)

    def close(self):
        """Stop the listener: ask it to leave, SIGKILL it if it has not within a second.

        What it sent until it left is taken (also what it sent while the runner was not
        listening); bounded whatever DDS does in the listener.
        """
        if self._connection is not None:
            self._stopping = True
            with contextlib.suppress(OSError, ValueError):
                self._connection.send(('stop', None))
            # It sends what it holds, then leaves: the connection ends.
            self.spin_for(LISTENER_STOP_WAIT)
        with contextlib.suppress(subprocess.TimeoutExpired):
            self._process.wait(timeout=LISTENER_STOP_WAIT)
        if self._process.poll() is None:
            with contextlib.suppress(ProcessLookupError, PermissionError):
                os.killpg(self._process.pid, signal.SIGKILL)
            self._process.wait()
        self._drop_connection()
        self._log.close()

    def _drop_connection(self):
        if self._connection is not None:
            self._connection.close()
            self._socket.close()
            self._connection = None

    def recording(self, until=None):
        """Return the `Recording` of the run: the steps every robot's ground truth has.

        UNTIL [s], if given, ends it: later steps (the simulator goes on until it is stopped)
        and messages stamped later are left out. Commands are world-frame (a body-frame
        command is turned by the robot's heading at its stamp, as the simulator does), NaN
        where missing.
        """
        from prvo_msgs_util import WORLD_FRAME, body_to_world
        from prvo_sim.runner.outputs import Recording

        ground_truth, received_commands = self.ground_truth, self.commands
        stamps = sorted(set.intersection(
            *(set(ground_truth[name]) for name in self.robot_names)))
        if until is not None:
            stamps = [stamp for stamp in stamps if stamp <= _seconds_ns(until)]
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
        bag_messages = self.bag_messages()
        if bag_messages is not None and until is not None:
            bag_messages.drop_after(_seconds_ns(until))
        return Recording(np.asarray(stamps, dtype=float) * 1e-9, states[..., :4], commands,
                         tuple(self.plan_times_ms),
                         None if status is None else status.deadline_misses,
                         yaws=states[..., 4], bag_messages=bag_messages,
                         plan_tallies=self.plan_tallies(until),
                         planner_cpu_ms=tuple(self.planner_cpu_ms))


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


def odometry_behind(odometry, last_stamp):
    """Return the robots whose serialized odometry ends before LAST_STAMP [ns], in order.

    ODOMETRY: {robot: [serialized nav_msgs/Odometry, in the order received]}; a robot's
    messages arrive in order, so its last one is its newest.
    """
    from prvo_sim.runner.bag import ODOMETRY_TYPE, stamp_ns

    return [name for name, messages in odometry.items()
            if not messages or stamp_ns(messages[-1], ODOMETRY_TYPE) < last_stamp]


def recording_gaps(ground_truth, commands, robot_names, dt, commands_expected,
                   planned_names=None, until=None):
    """Describe in one line what a recording lacks, else None.

    GROUND_TRUTH and COMMANDS are {robot: {stamp ns: ...}} (Recorder.ground_truth, .commands).
    A complete recording has every robot's ground truth at every step t = k DT from t = 0 to
    its last (the last at or before UNTIL [s], if given), and, if COMMANDS_EXPECTED (lockstep:
    every step is answered), the command of each of PLANNED_NAMES (default: every robot;
    scripted robots have none) answering each of those steps but the last. With UNTIL the
    last is answered too: the run ended there while the team went on, and the in-process
    engine records that answer, so a recording never depends on when it arrived.
    """
    last_step = math.inf if until is None else round(until / dt)
    for name in robot_names:
        steps = sorted(step for step in (round(stamp * 1e-9 / dt) for stamp in ground_truth[name])
                       if step <= last_step)
        if not steps:
            return f'the recorder received no ground truth of {name}'
        missing = sorted(set(range(steps[-1] + 1)) - set(steps))
        if missing:
            return (f'the recorder missed {len(missing)} ground truth message(s) of {name}, '
                    f'the first at t = {missing[0] * dt:g} s')
        if commands_expected and (planned_names is None or name in planned_names):
            answered = {round(stamp * 1e-9 / dt) for stamp in commands[name]}
            unanswered = sorted(set(steps if until is not None else steps[:-1]) - answered)
            if unanswered:
                return (f'the recorder missed {len(unanswered)} command(s) of {name}, the first '
                        f'answering t = {unanswered[0] * dt:g} s')
    return None


def foreign_participants(domain_id, robot_names, duration=None):
    """Return why DOMAIN_ID is not fit for a run of ROBOT_NAMES (strangers on it), else None.

    Listens DURATION s (default DOMAIN_CHECK_TIME) for discovery to show what is there.
    """
    recorder = Recorder(domain_id, robot_names, role='domain_check')
    try:
        return recorder.foreign_traffic(DOMAIN_CHECK_TIME if duration is None else duration)
    finally:
        recorder.close()

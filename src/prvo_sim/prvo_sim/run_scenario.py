"""Run a scenario end to end: the simulator and one planner per robot, recorded and measured.

    run_scenario SCENARIO.yaml [--out DIR] [--method M] [--eta ETA] [--seed S] [--seeds N]

The children are launch-free subprocesses, each in a session of its own, on a private
ROS_DOMAIN_ID with localhost-only discovery. The runner records every robot's ground truth and
commands, ends the run when every robot has arrived (and stayed), when the simulator reports
`finished`, when a child dies or at a wall-clock limit, shuts every child down (SIGINT, then
SIGKILL) whatever happened, and writes metrics.json, trajectories.csv and trajectories.png.

Exit codes: 0 the run completed (collisions are a result, not an error), 1 a child failed or
the run timed out, 2 bad input (nothing was started), 128 + signal number when interrupted.
"""

import argparse
import contextlib
import csv
import fcntl
import json
import math
import os
import pathlib
import shlex
import signal
import subprocess
import sys
import tempfile
import threading
import time
import types

import numpy as np

from prvo_sim import metrics

METHODS = ('prvo', 'rvo', 'inflate', 'prvo-no-ego')
# The planner's `model` parameter for each method; prvo-no-ego is PRVO planned with S_a = 0.
MODEL_OF_METHOD = {'prvo': 'prvo', 'rvo': 'rvo', 'inflate': 'inflate', 'prvo-no-ego': 'prvo'}
MODES = ('lockstep', 'realtime')
WORLD_FRAME = 'map'
DEFAULT_ETA = 0.8
# Private domains, disjoint from the test fixtures' (30-99) and hand-run processes' (111-120).
# Ids above 101 put Fast DDS's ports into Linux's ephemeral range; 0 is everyone's default.
# Tests claim their domains here too, so runs and tests on one machine never share one.
DOMAIN_IDS = range(1, 102)
DOMAIN_LOCK_DIR = pathlib.Path(tempfile.gettempdir()) / 'prvo-ros-domains'
STEP_TIMEOUT = 2.0  # wall seconds the sim waits for a late planner before reusing its command
SHUTDOWN_GRACE = 10.0  # wall seconds children get to exit after SIGINT before SIGKILL
RECORDER_CLOSE_TIMEOUT = 5.0  # wall seconds the recorder's DDS teardown may take
STARTUP_LIMIT = 60.0  # wall seconds to the first ground truth before the run counts as failed
SETTLE_TIME = 1.0  # sim seconds every robot must stay at its goal before the run ends
PROGRESS_PERIOD = 0.5
# Planner waits in lockstep [s]: for same-stamp odometry (under the sim's step_timeout), and
# for every listed neighbour's first message.
LOCKSTEP_SYNC = {'sync_timeout': '1.0', 'neighbor_timeout': '5.0'}
DOMAIN_CHECK_TIME = 2.0  # wall seconds of listening for strangers on the domain before a run
# Parameters the runner sets itself; a scenario's planner block cannot override them.
RUNNER_PARAMETERS = ('use_sim_time', 'goal', 'radius', 'max_speed', 'actuation_std',
                     'goal_tolerance', 'model', 'eta')
AGGREGATED_KEYS = ('success_rate', 'collisions', 'min_separation', 'makespan',
                   'mean_time_to_goal', 'planner_ms.median', 'planner_ms.p95', 'planner_ms.max',
                   'deadline_misses', 'sim_time', 'wall_time')


class UsageError(Exception):
    """Bad input detected before anything started (exit code 2)."""


class RunInterruptedError(Exception):
    """The runner received SIGINT or SIGTERM."""

    def __init__(self, signum):
        super().__init__(signal.Signals(signum).name)
        self.signum = signum


class _ArgumentParser(argparse.ArgumentParser):
    """An argument parser that reports errors as UsageError instead of exiting."""

    def error(self, message):
        raise UsageError(message)


def build_parser():
    """Return the command-line parser of the runner."""
    parser = _ArgumentParser(
        prog='run_scenario',
        description='Run a PRVO scenario: simulator plus one planner per robot, recorded.')
    parser.add_argument('scenario', help='scenario YAML file (or the name of a shipped one)')
    parser.add_argument('--out', default=None,
                        help='output folder (default: results/<scenario name>)')
    parser.add_argument('--method', choices=METHODS, default='prvo',
                        help='planner variant (default: prvo)')
    parser.add_argument('--eta', type=float, default=None,
                        help="collision-avoidance probability in (0, 1) (default: the scenario's"
                        f' planner eta, else {DEFAULT_ETA})')
    parser.add_argument('--seed', type=int, default=None,
                        help="random seed (default: the scenario's)")
    parser.add_argument('--seeds', type=int, default=1,
                        help='repeat over N consecutive seeds from --seed and aggregate')
    parser.add_argument('--mode', choices=MODES, default='lockstep',
                        help='simulator stepping (default: lockstep)')
    parser.add_argument('--timeout', type=float, default=None,
                        help='wall-clock limit per run [s] (default: 10 x duration + 60)')
    parser.add_argument('--domain-id', type=int, default=None,
                        help=f'ROS_DOMAIN_ID (default: a free one in {DOMAIN_IDS.start}..'
                        f'{DOMAIN_IDS.stop - 1})')
    parser.add_argument('--sim-command', default=None,
                        help="command to start instead of prvo_sim's sim (ROS args appended)")
    parser.add_argument('--planner-command', default=None,
                        help="command to start instead of prvo_planner's planner")
    parser.add_argument('--quiet', action='store_true', help='no progress line')
    return parser


def parse_arguments(argv):
    """Parse and check ARGV; return (options, scenario). Raise UsageError on bad input."""
    from prvo_sim.scenario import (
        ScenarioError,
        check_team_memory,
        find_scenario,
        load_scenario,
    )

    options = build_parser().parse_args(argv)
    if options.eta is not None and not 0.0 < options.eta < 1.0:
        raise UsageError(f'--eta: {options.eta} is outside (0, 1)')
    if options.seeds < 1:
        raise UsageError(f'--seeds: {options.seeds} is not a positive count')
    if options.timeout is not None and not options.timeout > 0.0:
        raise UsageError(f'--timeout: {options.timeout} is not a positive time')
    if options.domain_id is not None and not 0 <= options.domain_id <= 232:
        raise UsageError(f'--domain-id: {options.domain_id} is outside 0..232')
    for name in ('sim_command', 'planner_command'):
        command = getattr(options, name)
        if command is not None and not shlex.split(command):
            raise UsageError(f"--{name.replace('_', '-')}: empty command")
    try:
        scenario = load_scenario(find_scenario(options.scenario), seed=options.seed)
        check_team_memory(scenario)
    except ScenarioError as error:
        raise UsageError(str(error)) from None
    except OSError as error:
        raise UsageError(f'{options.scenario}: {error.strerror or error}') from None
    options.out = pathlib.Path(options.out or pathlib.Path('results') / scenario.name)
    check_writable(options.out)
    return options, scenario


def check_writable(folder):
    """Create FOLDER if needed and prove a file can be written in it; raise UsageError if not."""
    try:
        folder.mkdir(parents=True, exist_ok=True)
        with tempfile.TemporaryFile(dir=folder):
            pass
    except OSError as error:
        raise UsageError(f'--out: cannot write to {folder}: {error.strerror or error}') from None


@contextlib.contextmanager
def claimed_domain(requested):
    """Yield a ROS_DOMAIN_ID: REQUESTED, or one no other runner holds (lock kept until exit)."""
    if requested is not None:
        yield requested
        return
    DOMAIN_LOCK_DIR.mkdir(exist_ok=True)
    for domain_id in DOMAIN_IDS:
        lock_file = open(DOMAIN_LOCK_DIR / f'{domain_id}.lock', 'w')
        try:
            fcntl.flock(lock_file, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError:
            lock_file.close()
            continue
        try:
            yield domain_id
        finally:
            fcntl.flock(lock_file, fcntl.LOCK_UN)
            lock_file.close()
        return
    raise RuntimeError(f'no free ROS_DOMAIN_ID in {DOMAIN_IDS.start}..{DOMAIN_IDS.stop - 1}')


class _InterruptGate:
    """Turns SIGINT/SIGTERM into RunInterruptedError, deferred out of critical sections.

    Blocking the signals instead (pthread_sigmask) would be inherited by the children, which
    then could not be stopped with SIGINT.
    """

    def __init__(self):
        self._deferring = False
        self._pending = None

    def handle(self, signum, _frame):
        """Signal handler: raise now, or once the current critical section ends."""
        if self._deferring:
            self._pending = signum
            return
        raise RunInterruptedError(signum)

    @contextlib.contextmanager
    def deferred(self):
        """Hold interrupts back while the block runs (e.g. starting a child and recording it)."""
        self._deferring = True
        try:
            yield
        finally:
            self._deferring = False
            pending, self._pending = self._pending, None
            if pending is not None:
                raise RunInterruptedError(pending)


INTERRUPTS = _InterruptGate()
# Set once a recorder's DDS teardown hung in this process (see Recorder.close).
DDS_HANG = types.SimpleNamespace(noticed=False)


def package_command(package, executable, module):
    """Return the argv prefix 'ros2 run PACKAGE EXECUTABLE' would run, else MODULE's main()."""
    try:
        from ament_index_python.packages import PackageNotFoundError, get_package_prefix

        path = pathlib.Path(get_package_prefix(package)) / 'lib' / package / executable
        if os.access(path, os.X_OK):
            return [str(path)]
    except (ImportError, PackageNotFoundError):
        pass
    return [sys.executable, '-c', f'import sys; from {module} import main; sys.exit(main())']


def ros_parameter(value):
    """Format VALUE for `-p name:=value` so that ROS parses it with the same type."""
    if isinstance(value, bool):
        return 'true' if value else 'false'
    if isinstance(value, (int, np.integer)):
        return str(int(value))
    if isinstance(value, (float, np.floating)):
        return repr(float(value))
    if isinstance(value, (list, tuple, np.ndarray)):
        return '[' + ', '.join(ros_parameter(item) for item in value) + ']'
    return str(value)


def planner_parameters(robot, scenario, method, eta, mode='lockstep'):
    """Return the planner parameters of ROBOT, in order, as a dict of ROS-formatted values."""
    parameters = {
        'use_sim_time': 'true',
        'goal': ros_parameter([float(value) for value in robot.goal]),
        'radius': ros_parameter(float(robot.radius)),
        'max_speed': ros_parameter(float(robot.max_speed)),
        # The robot's known execution error; the ablation plans as if there were none.
        'actuation_std': ros_parameter(
            0.0 if method == 'prvo-no-ego' else float(robot.noise.actuation_std)),
        # Half the scenario's: when the planner's estimate says it arrived, the ground truth is
        # inside the scenario's tolerance.
        'goal_tolerance': ros_parameter(scenario.goal_tolerance / 2.0),
        'model': MODEL_OF_METHOD[method],
        'eta': ros_parameter(float(eta)),
        # Named rather than discovered: each planner waits for all of them from t_0, so a seed
        # reproduces its run.
        'neighbors': ros_parameter(
            [other.name for other in scenario.robots if other.name != robot.name]),
    }
    if mode == 'lockstep':
        # The simulator waits for every answer, so a planner can wait for every neighbour's
        # odometry of the same stamp however loaded the machine: that makes runs reproducible.
        parameters.update(LOCKSTEP_SYNC)
    for key, value in robot.planner.items():
        if key not in RUNNER_PARAMETERS:
            parameters[key] = ros_parameter(value)
    return parameters


def run_eta(options, scenario):
    """Return the eta of the run: --eta, else the first robot's planner block, else 0.8."""
    if options.eta is not None:
        return options.eta
    return float(scenario.robots[0].planner.get('eta', DEFAULT_ETA))


def child_environment(domain_id):
    """Return the environment of every child: private domain, localhost discovery, unbuffered."""
    env = dict(os.environ)
    env.update({'ROS_DOMAIN_ID': str(domain_id), 'ROS_AUTOMATIC_DISCOVERY_RANGE': 'LOCALHOST',
                'PYTHONUNBUFFERED': '1', 'RCUTILS_LOGGING_BUFFERED_STREAM': '0'})
    # A process per robot: idle BLAS threads spinning on few cores would cost more than they give.
    env.setdefault('OPENBLAS_NUM_THREADS', '1')
    # Shared memory can keep a restarted process from hearing the ones that outlived the old.
    env.setdefault('FASTDDS_BUILTIN_TRANSPORTS', 'UDPv4')
    return env


class Children:
    """The run's child processes, each in its own session, output in LOG_DIR/<label>.log."""

    def __init__(self, env, log_dir):
        self._env = env
        self._log_dir = log_dir
        self.processes = []

    def start(self, label, argv):
        """Start ARGV as child LABEL."""
        log_path = self._log_dir / f'{label}.log'
        with open(log_path, 'ab') as log_file:
            log_file.write(f'$ {shlex.join(argv)}\n'.encode())
            log_file.flush()
            # A signal between Popen and the append would orphan the child: hold it back.
            with INTERRUPTS.deferred():
                process = subprocess.Popen(
                    argv, env=self._env, stdout=log_file, stderr=subprocess.STDOUT,
                    stdin=subprocess.DEVNULL, start_new_session=True)
                process.label = label
                process.log_path = log_path
                self.processes.append(process)
        return process

    def first_exited(self):
        """Return a child that has exited, or None while all run."""
        for process in self.processes:
            if process.poll() is not None:
                return process
        return None

    def stop(self, grace=SHUTDOWN_GRACE):
        """SIGINT every child's process group, wait up to GRACE s, then SIGKILL what is left."""
        for process in self.processes:
            if process.poll() is None:
                _signal_group(process.pid, signal.SIGINT)
        deadline = time.monotonic() + grace
        for process in self.processes:
            try:
                process.wait(timeout=max(0.0, deadline - time.monotonic()))
            except subprocess.TimeoutExpired:
                pass
        # Also catches grandchildren left in a group whose leader has exited.
        for process in self.processes:
            _signal_group(process.pid, signal.SIGKILL)
            process.wait()


def _signal_group(pgid, signum):
    try:
        os.killpg(pgid, signum)
    except (ProcessLookupError, PermissionError):
        pass


def _stamp_ns(stamp):
    return stamp.sec * 1_000_000_000 + stamp.nanosec


def _seconds_ns(seconds):
    """Return a stamp in float seconds (sec + nanosec * 1e-9) as integer nanoseconds again."""
    return round(seconds * 1e9)


class Recorder:
    """An rclpy node in a context of its own that records what the run needs to be measured."""

    def __init__(self, domain_id, robot_names):
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

        self.robot_names = list(robot_names)
        # Ground truth and commands are kept serialized as they arrive and decoded when read:
        # decoding costs the recorder most of its CPU, which the team it measures needs.
        self._serialized = {kind: {name: [] for name in self.robot_names}
                            for kind in ('ground_truth', 'commands')}
        self._decoded = {kind: ({name: {} for name in self.robot_names},
                                dict.fromkeys(self.robot_names, 0))
                         for kind in ('ground_truth', 'commands')}
        self.plan_times_ms = []
        self.sim_status = {}
        self.context = Context()
        # The runner handles SIGINT/SIGTERM itself, so that children are always stopped.
        rclpy.init(context=self.context, domain_id=domain_id,
                   signal_handler_options=SignalHandlerOptions.NO)
        self.domain_id = domain_id
        self.node = rclpy.create_node('prvo_run_recorder', context=self.context)
        # The recorder shares the CPU with the team it measures: the events executor (see
        # prvo_msgs_util.spin_events) and bookkeeping a few times per second, not per message.
        self._executor = EventsExecutor(context=self.context)
        self._executor.add_node(self.node)
        self._never_done = Future()
        # No per-endpoint QoS event handlers (prvo_msgs_util.quiet_subscription_events): it
        # only listens to prvo nodes.
        for name in self.robot_names:
            for kind, topic, message_type, qos in (
                    ('ground_truth', GROUND_TRUTH, Odometry, ODOM_QOS),
                    ('commands', CMD_VEL, TwistStamped, CMD_VEL_QOS)):
                self.node.create_subscription(
                    message_type, robot_topic(name, topic), self._serialized[kind][name].append,
                    qos, event_callbacks=quiet_subscription_events(), raw=True)
        self.node.create_subscription(DiagnosticArray, DIAGNOSTICS, self._on_diagnostics,
                                      DIAGNOSTICS_QOS, event_callbacks=quiet_subscription_events())

    def latest(self):
        """Return {robot: (stamp ns, position (2,))} of the newest ground truth of each robot."""
        from prvo_msgs_util import serialized_odometry_to_measurement

        latest = {}
        for name, received in self._serialized['ground_truth'].items():
            if received:
                measurement = serialized_odometry_to_measurement(
                    received[-1], expected_frame=WORLD_FRAME)
                latest[name] = (_seconds_ns(measurement.stamp), measurement.position)
        return latest

    @property
    def ground_truth(self):
        """{robot: {stamp ns: (x, y, vx, vy, yaw)}} of every ground truth received."""
        from prvo_msgs_util import serialized_odometry_to_measurement

        def decode(data):
            measurement = serialized_odometry_to_measurement(data, expected_frame=WORLD_FRAME)
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

    def _on_diagnostics(self, msg):
        from prvo_msgs_util import diagnostic_values

        for status in msg.status:
            if status.name == 'prvo_sim':
                self.sim_status = diagnostic_values(status)
            elif status.name.startswith('prvo_planner/'):
                value = diagnostic_values(status).get('plan_time_ms')
                if value is not None:
                    with contextlib.suppress(ValueError):
                        self.plan_times_ms.append(float(value))

    def foreign_traffic(self, duration):
        """Watch the domain for DURATION s before anything starts; describe what is there.

        Returns None for an empty domain, else a one-line failure: a simulator left over from
        a killed run would otherwise feed this run its clock and its 'finished' status.
        """
        from prvo_msgs_util import CLOCK, DIAGNOSTICS

        deadline = time.monotonic() + duration
        while time.monotonic() < deadline:
            self.spin_for(0.05)
            busy = [topic for topic in (CLOCK, DIAGNOSTICS) if self.node.count_publishers(topic)]
            if busy:
                return (f'ROS_DOMAIN_ID {self.domain_id} is in use by processes this runner did '
                        f'not start (publishers on {", ".join(busy)}): stop them or pass '
                        f'--domain-id')
        return None

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

    def arrays(self):
        """Return times [s], states (T, N, 4) and commands (T, N, 2) at the common stamps.

        States are ground truth x, y, vx, vy; commands are world-frame (a body-frame command is
        rotated by the robot's heading at its stamp), NaN where missing; only instants every
        robot has are kept.
        """
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
                    command = np.array([command_x, command_y])
                    if frame_id not in ('', WORLD_FRAME):
                        yaw = states[step, robot, 4]
                        command = np.array([[math.cos(yaw), -math.sin(yaw)],
                                            [math.sin(yaw), math.cos(yaw)]]) @ command
                    commands[step, robot] = command
        return np.asarray(stamps, dtype=float) * 1e-9, states[..., :4], commands


class RunSpec:
    """Everything one run needs: the scenario and the resolved options."""

    def __init__(self, options, scenario, eta, seed, out_dir):
        self.scenario = scenario
        self.method = options.method
        self.mode = options.mode
        self.eta = eta
        self.seed = seed
        self.out_dir = out_dir
        self.timeout = options.timeout or 10.0 * scenario.duration + 60.0
        self.quiet = options.quiet
        self.sim_command = (shlex.split(options.sim_command) if options.sim_command
                            else package_command('prvo_sim', 'sim', 'prvo_sim.sim_node'))
        self.planner_command = (
            shlex.split(options.planner_command) if options.planner_command
            else package_command('prvo_planner', 'planner', 'prvo_planner.planner_node'))


def start_children(children, spec):
    """Start one planner per robot, then the simulator."""
    scenario = spec.scenario
    for robot in scenario.robots:
        argv = [*spec.planner_command, '--ros-args', '-r', f'__ns:=/{robot.name}',
                '-r', '__node:=planner']
        parameters = planner_parameters(robot, scenario, spec.method, spec.eta, spec.mode)
        for key, value in parameters.items():
            argv += ['-p', f'{key}:={value}']
        children.start(f'planner_{robot.name}', argv)
    sim_parameters = {'scenario': str(pathlib.Path(scenario.path).resolve()), 'mode': spec.mode,
                      'seed': str(int(spec.seed)), 'step_timeout': repr(STEP_TIMEOUT)}
    argv = [*spec.sim_command, '--ros-args']
    for key, value in sim_parameters.items():
        argv += ['-p', f'{key}:={value}']
    children.start('sim', argv)


def wait_for_end(recorder, children, spec, progress):
    """Record until the run ends; return None if it completed, else a one-line failure."""
    scenario = spec.scenario
    goals = np.array([robot.goal for robot in scenario.robots], dtype=float)
    started = time.monotonic()
    settled_since = None
    next_progress = started
    while True:
        recorder.spin_for(0.05)
        now = time.monotonic()
        exited = children.first_exited()
        if exited is not None:
            return (f'{exited.label} exited with code {exited.returncode} '
                    f'(log: {exited.log_path})')
        if now - started > spec.timeout:
            return f'timed out after {spec.timeout:g} s of wall time'
        latest = recorder.latest()
        if len(latest) < len(scenario.robots):
            if now - started > STARTUP_LIMIT:
                return f'no ground truth from every robot within {STARTUP_LIMIT:g} s'
            continue
        sim_time = min(stamp for stamp, _ in latest.values()) * 1e-9
        positions = np.array([latest[robot.name][1] for robot in scenario.robots])
        arrived = np.linalg.norm(positions - goals, axis=1) <= scenario.goal_tolerance
        if now >= next_progress:
            progress(sim_time, int(arrived.sum()), now - started)
            next_progress = now + PROGRESS_PERIOD
        if arrived.all():
            settled_since = sim_time if settled_since is None else settled_since
            if sim_time - settled_since >= SETTLE_TIME:
                return None
        else:
            settled_since = None
        if recorder.sim_status.get('finished') == 'true':
            return None


def run_once(spec, domain_id, monitor=None):
    """Run SPEC once on DOMAIN_ID; write its outputs; return (metrics dict, interrupting signal).

    The metrics carry a 'failure' key when the run failed. The children are stopped whatever
    happens, including SIGINT/SIGTERM (returned as the interrupting signal, else None).
    MONITOR, if given, watches the run from inside (the team benchmark measures the children
    with it): monitor.started(children, recorder) is called once every child has been started,
    monitor.ending(children, recorder) once the run has ended, just before the children are
    stopped (not when the run was interrupted).
    """
    scenario = spec.scenario
    log_dir = spec.out_dir / 'logs'
    log_dir.mkdir(parents=True, exist_ok=True)
    os.environ['ROS_AUTOMATIC_DISCOVERY_RANGE'] = 'LOCALHOST'
    children = Children(child_environment(domain_id), log_dir)
    recorder = None
    failure = None
    interrupted = None
    progress = ProgressLine(spec, quiet=spec.quiet)
    started = time.monotonic()
    try:
        recorder = Recorder(domain_id, [robot.name for robot in scenario.robots])
        failure = recorder.foreign_traffic(DOMAIN_CHECK_TIME)
        if failure is None:
            start_children(children, spec)
            if monitor is not None:
                monitor.started(children, recorder)
            failure = wait_for_end(recorder, children, spec, progress)
        if monitor is not None:
            monitor.ending(children, recorder)
    except RunInterruptedError as interruption:
        interrupted = interruption.signum
        failure = f'interrupted by {interruption}'
    finally:
        previous_handlers = {signum: signal.signal(signum, signal.SIG_IGN)
                             for signum in (signal.SIGINT, signal.SIGTERM)}
        try:
            children.stop()
            if recorder is not None and not recorder.close():
                DDS_HANG.noticed = True
                print('run_scenario: warning: the DDS layer hung while closing the recorder '
                      '(a known Fast DDS deadlock); the results are still written, and the '
                      'runner exits without DDS cleanup', file=sys.stderr)
        finally:
            for signum, handler in previous_handlers.items():
                signal.signal(signum, handler)
            progress.finish()
    wall_time = time.monotonic() - started
    run_metrics = write_outputs(spec, recorder, failure, wall_time)
    return run_metrics, interrupted


class ProgressLine:
    """A one-line progress report on stderr, rewritten in place on a terminal."""

    def __init__(self, spec, quiet):
        self._spec = spec
        self._quiet = quiet
        self._tty = sys.stderr.isatty()
        self._last_printed = -math.inf
        self._written = False

    def __call__(self, sim_time, arrived, wall_time):
        """Report SIM_TIME, the number of ARRIVED robots and WALL_TIME."""
        if self._quiet:
            return
        scenario = self._spec.scenario
        line = (f'{scenario.name} seed {self._spec.seed}: sim {sim_time:5.1f}/'
                f'{scenario.duration:g} s, arrived {arrived}/{len(scenario.robots)}, '
                f'wall {wall_time:5.1f} s')
        if self._tty:
            sys.stderr.write('\r' + line + '   ')
            sys.stderr.flush()
            self._written = True
        elif wall_time - self._last_printed >= 5.0:
            print(line, file=sys.stderr, flush=True)
            self._last_printed = wall_time

    def finish(self):
        """End the rewritten line."""
        if self._written:
            sys.stderr.write('\n')
            sys.stderr.flush()


def write_outputs(spec, recorder, failure, wall_time):
    """Write metrics.json, trajectories.csv and trajectories.png; return the metrics."""
    scenario = spec.scenario
    names = [robot.name for robot in scenario.robots]
    if recorder is not None and all(recorder.ground_truth[name] for name in names):
        times, states, commands = recorder.arrays()
    else:
        times, states, commands = np.zeros(0), np.zeros((0, len(names), 4)), np.zeros(
            (0, len(names), 2))
    radii = np.array([robot.radius for robot in scenario.robots], dtype=float)
    goals = np.array([robot.goal for robot in scenario.robots], dtype=float)
    run_metrics = {'scenario': scenario.name, 'method': spec.method, 'eta': spec.eta,
                   'seed': spec.seed, 'mode': spec.mode}
    if times.size:
        measured = metrics.run_metrics(times, states[..., :2], radii, goals,
                                       scenario.goal_tolerance, names)
        contacts = metrics.contact_events(times, states[..., :2], radii)
    else:
        measured = {'robots': {name: {'arrived': False, 'time_to_goal': None,
                                      'path_length': None} for name in names},
                    'success_rate': 0.0, 'collisions': 0, 'min_separation': None,
                    'makespan': None, 'mean_time_to_goal': None, 'sim_time': 0.0}
        contacts = []
    sim_status = recorder.sim_status if recorder is not None else {}
    deadline_misses = sim_status.get('deadline_misses')
    run_metrics.update({
        'robots': measured['robots'],
        'success_rate': measured['success_rate'],
        'collisions': measured['collisions'],
        'min_separation': measured['min_separation'],
        'makespan': measured['makespan'],
        'mean_time_to_goal': measured['mean_time_to_goal'],
        'planner_ms': metrics.distribution_summary(
            recorder.plan_times_ms if recorder is not None else []),
        'deadline_misses': int(deadline_misses) if deadline_misses is not None else None,
        'sim_time': measured['sim_time'],
        'wall_time': round(wall_time, 3),
    })
    if failure is not None:
        run_metrics['failure'] = failure
    with open(spec.out_dir / 'metrics.json', 'w') as metrics_file:
        json.dump(run_metrics, metrics_file, indent=2)
        metrics_file.write('\n')
    write_trajectories_csv(spec.out_dir / 'trajectories.csv', times, names, states, commands)
    if times.size:
        from prvo_sim.plotting import plot_run

        plot_run(spec.out_dir / 'trajectories.png', times, states[..., :2],
                 np.array([robot.start for robot in scenario.robots], dtype=float), goals,
                 radii, names, contacts, plot_title(run_metrics))
    return run_metrics


def write_trajectories_csv(path, times, names, states, commands):
    """Write one row per time and robot: ground truth x, y, vx, vy and the command answering it."""
    with open(path, 'w', newline='') as csv_file:
        writer = csv.writer(csv_file)
        writer.writerow(['time', 'robot', 'x', 'y', 'vx', 'vy', 'cmd_vx', 'cmd_vy'])
        for step, time_s in enumerate(times):
            for robot, name in enumerate(names):
                command = ['' if math.isnan(value) else f'{value:.6g}'
                           for value in commands[step, robot]]
                writer.writerow([f'{time_s:.6g}', name,
                                 *(f'{value:.6g}' for value in states[step, robot]), *command])


def outcome(run_metrics):
    """Return a short description of how a run ended."""
    if 'failure' in run_metrics:
        return 'FAILED: ' + run_metrics['failure']
    robots = run_metrics['robots']
    arrived = sum(robot['arrived'] for robot in robots.values())
    collisions = run_metrics['collisions']
    contact_text = 'no contact' if collisions == 0 else f'{collisions} contact(s)'
    return f'{arrived}/{len(robots)} arrived, {contact_text}'


def plot_title(run_metrics):
    """Return the figure title: scenario, method, eta, seed and outcome."""
    return (f"{run_metrics['scenario']}: method {run_metrics['method']}, eta "
            f"{run_metrics['eta']:g}, seed {run_metrics['seed']}\n{outcome(run_metrics)}")


def _format(value, unit='', digits=2):
    return 'n/a' if value is None else f'{value:.{digits}f}{unit}'


def print_summary(run_metrics, out_dir):
    """Print one run's results on one screen."""
    print(f"{run_metrics['scenario']} | method {run_metrics['method']}, eta "
          f"{run_metrics['eta']:g} | seed {run_metrics['seed']} | {run_metrics['mode']}")
    print(f"  {'robot':<12} {'arrived':<8} {'time to goal':>12} {'path length':>12}")
    for name, robot in run_metrics['robots'].items():
        print(f"  {name:<12} {'yes' if robot['arrived'] else 'no':<8} "
              f"{_format(robot['time_to_goal'], ' s', 1):>12} "
              f"{_format(robot['path_length'], ' m'):>12}")
    planner_ms = run_metrics['planner_ms']
    print(f"  outcome: {outcome(run_metrics)}; success rate {run_metrics['success_rate']:.2f}, "
          f"min separation {_format(run_metrics['min_separation'], ' m')}, "
          f"makespan {_format(run_metrics['makespan'], ' s', 1)}")
    print(f"  planner ms median/p95/max {_format(planner_ms['median'])}/"
          f"{_format(planner_ms['p95'])}/{_format(planner_ms['max'])}; deadline misses "
          f"{run_metrics['deadline_misses']}; sim {run_metrics['sim_time']:.1f} s in "
          f"{run_metrics['wall_time']:.1f} s wall")
    print(f'  results: {out_dir}/metrics.json, trajectories.csv, trajectories.png '
          f'(child logs in {out_dir}/logs)')


def write_summary(out_dir, runs):
    """Write and print the aggregate summary.json of a multi-seed run; return its dict."""
    first = runs[0][0]
    summary = {
        'scenario': first['scenario'], 'method': first['method'], 'eta': first['eta'],
        'mode': first['mode'], 'seeds': [run_metrics['seed'] for run_metrics, _ in runs],
        'runs': [{'seed': run_metrics['seed'], 'dir': str(run_dir),
                  'outcome': outcome(run_metrics)} for run_metrics, run_dir in runs],
        'failed_runs': sum('failure' in run_metrics for run_metrics, _ in runs),
        'metrics': metrics.aggregate([run_metrics for run_metrics, _ in runs], AGGREGATED_KEYS),
    }
    with open(out_dir / 'summary.json', 'w') as summary_file:
        json.dump(summary, summary_file, indent=2)
        summary_file.write('\n')
    print(f"{summary['scenario']} | method {summary['method']}, eta {summary['eta']:g} | "
          f"{len(runs)} seeds, {summary['failed_runs']} failed")
    print(f"  {'metric':<20} {'mean':>9} {'std':>9} {'min':>9} {'max':>9} {'n':>4}")
    for key, stats in summary['metrics'].items():
        print(f"  {key:<20} {_format(stats['mean'], '', 3):>9} {_format(stats['std'], '', 3):>9}"
              f" {_format(stats['min'], '', 3):>9} {_format(stats['max'], '', 3):>9}"
              f" {stats['n']:>4}")
    print(f'  results: {out_dir}/summary.json and seed_<n>/ folders')
    return summary


def run(options, scenario):
    """Run every requested seed; return the exit code."""
    eta = run_eta(options, scenario)
    seeds = [scenario.seed + offset for offset in range(options.seeds)]
    runs = []
    with claimed_domain(options.domain_id) as domain_id:
        for seed in seeds:
            out_dir = options.out if options.seeds == 1 else options.out / f'seed_{seed}'
            spec = RunSpec(options, scenario, eta, seed, out_dir)
            run_metrics, interrupted = run_once(spec, domain_id)
            runs.append((run_metrics, out_dir))
            print_summary(run_metrics, out_dir)
            if interrupted is not None:
                return 128 + interrupted
    if options.seeds > 1:
        write_summary(options.out, runs)
    return 1 if any('failure' in run_metrics for run_metrics, _ in runs) else 0


def run_interruptibly(program, job):
    """Return JOB()'s exit code, with SIGINT/SIGTERM turned into RunInterruptedError meanwhile.

    A signal that arrives between runs, when no child is alive, ends PROGRAM with 128 + signal.
    """
    previous_handlers = {signum: signal.signal(signum, INTERRUPTS.handle)
                         for signum in (signal.SIGINT, signal.SIGTERM)}
    try:
        code = job()
    except RunInterruptedError as interruption:
        print(f'{program}: interrupted by {interruption}', file=sys.stderr)
        code = 128 + interruption.signum
    finally:
        for signum, handler in previous_handlers.items():
            signal.signal(signum, handler)
    if DDS_HANG.noticed:
        # A thread is stuck inside Fast DDS: interpreter shutdown would wait on it forever.
        sys.stdout.flush()
        sys.stderr.flush()
        os._exit(code)
    return code


def main(argv=None):
    """Run the scenario runner's command line; return the exit code."""
    argv = sys.argv[1:] if argv is None else argv
    try:
        options, scenario = parse_arguments(argv)
    except UsageError as error:
        print(f'run_scenario: error: {error}', file=sys.stderr)
        return 2
    return run_interruptibly('run_scenario', lambda: run(options, scenario))

if __name__ == '__main__':
    sys.exit(main())

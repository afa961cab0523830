"""Shared fixtures: private ROS domains, child processes and an rclpy probe node.

Integration tests start real processes on a ROS_DOMAIN_ID of their own (so tests and developers
on one machine never see each other's topics), observe them through a probe node spinning in a
background thread, and wait on events with timeouts, never on fixed sleeps.
"""

import contextlib
import os
import pathlib
import signal
import subprocess
import sys
import threading
import time

import pytest
from worker_domains import worker_domain_ids

os.environ['ROS_AUTOMATIC_DISCOVERY_RANGE'] = 'LOCALHOST'
# The probe talks to the children over the same transport they use (see env.sh).
os.environ.setdefault('FASTDDS_BUILTIN_TRANSPORTS', 'UDPv4')


# The order the tests are handed out in. ./run.sh test runs two workers (pytest-xdist,
# worksteal): each starts on its half of this order and takes tests off the end of the other's
# queue once its own runs out. The 24-robot run (both cores for about 100 s) goes first, so that
# the other worker's tests run beside it instead of it running alone at the end; then the
# directories whose tests start teams, the longest first; the many short tests last, where they
# even out the two workers' ends. Within a directory the order is the collection's (modules
# stay whole for their module-scoped fixtures).
FIRST_TESTS = (
    'test/runner/test_runner_teardown.py::test_a_24_robot_lockstep_ros_run_ends_with_its_results',
)
DIRECTORY_ORDER = ('runner', 'integration', 'sim', 'foundation', 'core', 'planner', 'msgs_util')


def pytest_collection_modifyitems(config, items):
    """Order ITEMS as FIRST_TESTS and DIRECTORY_ORDER say (a stable sort)."""
    root = pathlib.Path(__file__).resolve().parent

    def rank(item):
        if item.nodeid in FIRST_TESTS:
            return (0, FIRST_TESTS.index(item.nodeid))
        try:
            directory = item.path.resolve().relative_to(root).parts[0]
        except ValueError:
            return (2, 0)
        if directory in DIRECTORY_ORDER:
            return (1, DIRECTORY_ORDER.index(directory))
        return (2, 0)

    items.sort(key=rank)


@pytest.fixture
def ros_domain():
    """Claim a ROS_DOMAIN_ID no test or scenario run on this machine holds; release it after."""
    from prvo_sim.run_scenario import claimed_domain

    with claimed_domain(None, candidates=worker_domain_ids()) as domain_id:
        yield domain_id


def child_environment(domain_id):
    """Environment for child processes: DOMAIN_ID, localhost discovery, no buffering."""
    env = dict(os.environ)
    env['ROS_DOMAIN_ID'] = str(domain_id)
    env['ROS_AUTOMATIC_DISCOVERY_RANGE'] = 'LOCALHOST'
    env['PYTHONUNBUFFERED'] = '1'
    env['RCUTILS_LOGGING_BUFFERED_STREAM'] = '0'
    env.setdefault('OPENBLAS_NUM_THREADS', '1')
    env.setdefault('FASTDDS_BUILTIN_TRANSPORTS', 'UDPv4')
    return env


@pytest.fixture
def ros_env(ros_domain):
    """Environment for child processes: the private domain, localhost discovery, no buffering."""
    return child_environment(ros_domain)


def executable(package, name):
    """Return the path 'ros2 run PACKAGE NAME' would execute: <prefix>/lib/<package>/<name>."""
    from ament_index_python.packages import get_package_prefix

    path = pathlib.Path(get_package_prefix(package)) / 'lib' / package / name
    if not os.access(path, os.X_OK):
        raise FileNotFoundError(f'{path} is not an executable file')
    return str(path)


def session_processes(session_id):
    """Return the pids of every live process in session SESSION_ID (read from /proc)."""
    pids = []
    for entry in pathlib.Path('/proc').iterdir():
        if not entry.name.isdigit():
            continue
        try:
            stat = (entry / 'stat').read_text()
        except OSError:
            continue
        # Fields after the parenthesised command: state ppid pgrp session ...
        fields = stat[stat.rindex(')') + 2:].split()
        if fields[0] != 'Z' and int(fields[3]) == session_id:
            pids.append(int(entry.name))
    return pids


@pytest.fixture
def live_session_processes():
    """Return `session_processes`: the live pids of a session, to check for orphans."""
    return session_processes


class ChildProcesses:
    """Child processes of one test, each in its own session, output captured to files."""

    def __init__(self, env, log_dir):
        self._env = env
        self._log_dir = pathlib.Path(log_dir)
        self._children = []

    def start(self, label, argv, env=None):
        """Start ARGV in a new session; stdout and stderr go to LOG_DIR/LABEL.log."""
        log_path = self._log_dir / f'{label}.log'
        log_file = open(log_path, 'ab')
        process = subprocess.Popen(
            argv, env=env or self._env, stdout=log_file, stderr=subprocess.STDOUT,
            stdin=subprocess.DEVNULL, start_new_session=True)
        process.label = label
        process.log_path = log_path
        log_file.close()
        self._children.append(process)
        return process

    @staticmethod
    def stop(process, timeout=10.0):
        """Stop PROCESS (SIGSTOP) and return once every one of its threads has stopped.

        The kernel stops a process's threads one after the other: until the thread that takes
        the signal runs, the others (a DDS receive thread on the other core) still run, and may
        acknowledge a message sent after `kill` returned.
        """
        process.send_signal(signal.SIGSTOP)
        deadline = time.monotonic() + timeout

        def state(task):
            # "TID (COMM) STATE ...": COMM may hold spaces and parentheses.
            with contextlib.suppress(OSError):
                return (task / 'stat').read_text().rsplit(')', 1)[1].split()[0]
            return 'T'

        tasks = pathlib.Path(f'/proc/{process.pid}/task')
        while not all(state(task) in ('T', 't') for task in tasks.iterdir()):
            if time.monotonic() > deadline:
                raise TimeoutError(f'{process.label} did not stop within {timeout} s')
            threading.Event().wait(0.005)

    @staticmethod
    def output(process):
        """Return everything PROCESS printed so far."""
        return process.log_path.read_text(errors='replace')

    @staticmethod
    def interrupt(process, timeout=15.0):
        """Send SIGINT (Ctrl-C) to PROCESS and return its exit code once it has exited."""
        if process.poll() is None:
            process.send_signal(signal.SIGINT)
        return process.wait(timeout=timeout)

    def kill_all(self):
        """Kill every child's whole process group (teardown; a test never relies on it)."""
        for process in self._children:
            try:
                os.killpg(process.pid, signal.SIGKILL)
            except ProcessLookupError:
                pass
            process.wait()


@pytest.fixture
def children(ros_env, tmp_path):
    """Start child processes on the test's private domain; all are killed at teardown."""
    group = ChildProcesses(ros_env, tmp_path)
    yield group
    group.kill_all()


class Probe:
    """An rclpy node in its own context, spinning in a background thread.

    Tests subscribe through it and wait on `threading.Event`s or futures with timeouts.
    """

    # How long one spin waits for work: the longest `close` waits for the spin thread to see
    # that it should stop.
    SPIN_PERIOD = 0.05

    def __init__(self, domain_id, name='prvo_test_probe', namespace=None):
        import rclpy
        from rclpy.context import Context
        from rclpy.executors import SingleThreadedExecutor

        self.context = Context()
        rclpy.init(context=self.context, domain_id=domain_id)
        self.node = rclpy.create_node(name, namespace=namespace, context=self.context)
        self._executor = SingleThreadedExecutor(context=self.context)
        self._executor.add_node(self.node)
        self._lock = threading.Lock()
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._spin, daemon=True)
        self._thread.start()

    def _spin(self):
        from rclpy.executors import ExternalShutdownException

        try:
            while not self._stop.is_set() and self.context.ok():
                self._executor.spin_once(timeout_sec=self.SPIN_PERIOD)
        except ExternalShutdownException:
            pass

    def record(self, msg_type, topic, qos=10):
        """Subscribe to TOPIC and keep every message; return the list that fills up."""
        from prvo_msgs_util import quiet_subscription_events

        received = []

        def keep(msg):
            with self._lock:
                received.append(msg)

        self.node.create_subscription(msg_type, topic, keep, qos,
                                      event_callbacks=quiet_subscription_events())
        return received

    def wait_for_message(self, msg_type, topic, predicate=None, timeout=10.0, qos=10):
        """Return the first message on TOPIC that satisfies PREDICATE, or fail after TIMEOUT."""
        from prvo_msgs_util import quiet_subscription_events

        arrived = threading.Event()
        holder = []

        def check(msg):
            if not arrived.is_set() and (predicate is None or predicate(msg)):
                holder.append(msg)
                arrived.set()

        # Without QoS event handlers: destroying one while the spin thread waits on it kills
        # that thread (rclpy's InvalidHandle); a plain subscription is destroyed safely.
        subscription = self.node.create_subscription(
            msg_type, topic, check, qos, event_callbacks=quiet_subscription_events())
        try:
            if not arrived.wait(timeout):
                raise TimeoutError(f'no matching message on {topic} within {timeout} s')
            return holder[0]
        finally:
            self.node.destroy_subscription(subscription)

    def call(self, client, request, what, timeout=60.0, resend_after=10.0):
        """Return CLIENT's answer to REQUEST; raise TimeoutError naming WHAT after TIMEOUT.

        A request sent just after discovery can be lost (the server may not yet know the
        client's response reader), so one unanswered for RESEND_AFTER seconds is sent again:
        the parameter services these tests call give the same answer to a repeated request.
        """
        deadline = time.monotonic() + timeout
        while True:
            future = client.call_async(request)
            resend_at = min(time.monotonic() + resend_after, deadline)
            while not future.done() and time.monotonic() < resend_at:
                threading.Event().wait(0.05)
            if future.done():
                return future.result()
            client.remove_pending_request(future)
            if time.monotonic() >= deadline:
                raise TimeoutError(f'{what} did not happen within {timeout} s')

    def wait_until(self, condition, timeout, what, poll=0.05):
        """Return once CONDITION() is true; raise TimeoutError naming WHAT after TIMEOUT."""
        deadline = time.monotonic() + timeout
        while True:
            with self._lock:
                value = condition()
            if value:
                return value
            if time.monotonic() > deadline:
                raise TimeoutError(f'{what} did not happen within {timeout} s')
            # Graph and message state change in the spin thread; polling it is an event wait.
            threading.Event().wait(poll)

    def close(self):
        """Stop spinning, then destroy the node and shut the probe's context down.

        The spin thread is joined first: rclpy's `Executor.shutdown` returns without waiting
        for a spin in another thread, and a node or context destroyed while that thread still
        waits on or runs one of its entities can crash the process (a pytest worker, once in
        CI).
        """
        self._stop.set()
        self._thread.join(timeout=30.0)
        if self._thread.is_alive():
            raise RuntimeError(
                f'the spin thread of {self.node.get_name()} did not stop within 30 s')
        self._executor.shutdown()
        self.node.destroy_node()
        self.context.try_shutdown()


@pytest.fixture
def probe(ros_domain, children):
    """Probe node on the test's private ROS domain, closed before the test's children are killed.

    A peer killed mid-run leaves its last messages in flight; a pytest worker crashed in CI
    destroying the probe's node in that moment (twice, the same test). Closed first, the probe
    stops answering before its subscriptions go, and a lockstep simulator then waits.
    """
    ros_probe = Probe(ros_domain)
    yield ros_probe
    ros_probe.close()


@pytest.fixture
def spinning_node(ros_domain, children):
    """Return `make(name, namespace)`: a node spinning as the probe's does, closed after the test.

    On the test's private ROS domain, in a context of its own: a stand-in for a robot's node.
    Closed before the test's children are killed, as the probe is.
    """
    made = []

    def make(name, namespace=None):
        made.append(Probe(ros_domain, name, namespace))
        return made[-1].node

    yield make
    for spinning in made:
        spinning.close()


@pytest.fixture(scope='module')
def module_domains(tmp_path_factory):
    """Return a factory of (`ChildProcesses`, `Probe`) pairs, each on a ROS domain of its own.

    For a team started once and observed by several tests of a module, each asserting one
    property of it. Every pair lives until the module's last test: its children are killed,
    its probe closed and its domain released then.
    """
    from prvo_sim.run_scenario import claimed_domain

    with contextlib.ExitStack() as stack:
        def open_domain():
            domain_id = stack.enter_context(
                claimed_domain(None, candidates=worker_domain_ids()))
            group = ChildProcesses(child_environment(domain_id),
                                   tmp_path_factory.mktemp('module_children'))
            stack.callback(group.kill_all)
            ros_probe = Probe(domain_id)
            stack.callback(ros_probe.close)
            return group, ros_probe

        yield open_domain


@pytest.fixture
def python_executable():
    """Return the interpreter running the tests (the project's venv under ./run.sh test)."""
    return sys.executable


@pytest.fixture(scope='session')
def ros2_executable():
    """Return `executable`: the path of a package's executable as 'ros2 run' finds it."""
    return executable

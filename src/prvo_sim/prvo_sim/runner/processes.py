"""The run's child processes: started, watched, stopped, and never outliving the runner.

Each child runs in a session of its own (a Ctrl-C at the terminal reaches the runner only, which
stops the children in order). Two things end them should the runner die without cleaning up:
the Linux parent-death signal (SIGKILL to the child when the runner dies) and a watchdog
process that holds the read end of a pipe from the runner and, when the pipe closes, SIGKILLs
every process group the runner registered, grandchildren included.
"""

import contextlib
import ctypes
import os
import pathlib
import shlex
import signal
import subprocess
import sys
import time

SHUTDOWN_GRACE = 10.0  # wall seconds children get to exit after SIGINT before SIGKILL
# The signals that stop a run cleanly (SIGHUP: the runner's terminal was closed).
INTERRUPT_SIGNALS = (signal.SIGINT, signal.SIGTERM, signal.SIGHUP)
_PR_SET_PDEATHSIG = 1
# Resolved here, not in the forked child, where loading a library could deadlock.
_PRCTL = ctypes.CDLL(None, use_errno=True).prctl

# Reads '<pgid>' (register) and '-<pgid>' (stopped by the runner) lines until the runner's end
# of the pipe closes, however the runner ended, then SIGKILLs the groups still registered.
WATCHDOG_SOURCE = """
import os, signal, sys
for signum in (signal.SIGINT, signal.SIGTERM, signal.SIGHUP):
    signal.signal(signum, signal.SIG_IGN)
groups = set()
for line in sys.stdin:
    pgid = int(line)
    if pgid > 0:
        groups.add(pgid)
    else:
        groups.discard(-pgid)
for pgid in groups:
    try:
        os.killpg(pgid, signal.SIGKILL)
    except OSError:
        pass
"""


class RunInterruptedError(Exception):
    """The runner received SIGINT, SIGTERM or SIGHUP."""

    def __init__(self, signum):
        super().__init__(signal.Signals(signum).name)
        self.signum = signum


class _InterruptGate:
    """Turns the interrupt signals into RunInterruptedError, or notes them in a teardown.

    During a run a signal raises RunInterruptedError, deferred out of critical sections (a child
    started but not yet recorded). Once a run ends (`teardown`), nothing can stand between its
    end and its results: a signal is only noted (`last_signal`), which cuts waits short (the
    children's grace) and aborts what is optional (`abortable`: the animation).

    Blocking the signals instead (pthread_sigmask) would be inherited by the children, which
    then could not be stopped with SIGINT.
    """

    def __init__(self):
        self._deferring = False
        self._pending = None
        self._teardowns = 0
        self._abortable = False
        self.last_signal = None

    def handle(self, signum, _frame):
        """Signal handler: raise now, note it in a teardown, or raise once a section ends."""
        if self._teardowns:
            self.last_signal = signum
            if self._abortable:
                raise RunInterruptedError(signum)
            return
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

    @contextlib.contextmanager
    def teardown(self):
        """Note interrupts instead of raising them while the block runs (it may be nested)."""
        if not self._teardowns:
            self.last_signal = None
        self._teardowns += 1
        try:
            yield self
        finally:
            self._teardowns -= 1

    @contextlib.contextmanager
    def abortable(self):
        """Within a teardown, let an interrupt (also one noted before) cut the block short."""
        self._abortable = True
        try:
            if self.last_signal is not None:
                raise RunInterruptedError(self.last_signal)
            yield
        finally:
            self._abortable = False


INTERRUPTS = _InterruptGate()


@contextlib.contextmanager
def untranslated(*kinds):
    """Re-raise, as itself, a signal handler's exception that a C extension translated.

    A handler's exception raised while the interpreter runs Python code called from C (rclpy's
    deserialization calls each message class's constructor) can reach the caller as the
    extension's own error: pybind11 raises TypeError with the handler's exception as its cause.
    Within the block, such an error whose cause or context is one of KINDS (default:
    RunInterruptedError) is replaced by that exception.
    """
    kinds = kinds or (RunInterruptedError,)
    try:
        yield
    except kinds:
        raise
    except Exception as error:
        seen = set()
        origin = error
        while origin is not None and id(origin) not in seen and not isinstance(origin, kinds):
            seen.add(id(origin))
            origin = origin.__cause__ or origin.__context__
        if origin is None:
            raise
        raise origin from None


def package_command(package, executable, module):
    """Return the argv prefix 'ros2 run PACKAGE EXECUTABLE' would run, else MODULE's main().

    The executable is looked up in the ament index where AMENT_PREFIX_PATH is set, else in
    this Python's own prefix, where `./run.sh setup` installs it (no env.sh needed).
    """
    prefixes = [pathlib.Path(sys.prefix)]
    try:
        from ament_index_python.packages import PackageNotFoundError, get_package_prefix

        prefixes.insert(0, pathlib.Path(get_package_prefix(package)))
    except (ImportError, PackageNotFoundError, OSError):
        # OSError: AMENT_PREFIX_PATH is not set.
        pass
    for prefix in prefixes:
        path = prefix / 'lib' / package / executable
        if os.access(path, os.X_OK):
            return [str(path)]
    return [sys.executable, '-c', f'import sys; from {module} import main; sys.exit(main())']


def child_environment(domain_id):
    """Return the environment of every child: private domain, localhost discovery, unbuffered."""
    env = dict(os.environ)
    env.update({'ROS_DOMAIN_ID': str(domain_id), 'ROS_AUTOMATIC_DISCOVERY_RANGE': 'LOCALHOST',
                'PYTHONUNBUFFERED': '1', 'RCUTILS_LOGGING_BUFFERED_STREAM': '0'})
    # A process per robot: idle BLAS threads spinning on few cores would cost more than they give.
    env.setdefault('OPENBLAS_NUM_THREADS', '1')
    # Shared memory can keep a restarted process from hearing the ones that outlived the old.
    env.setdefault('FASTDDS_BUILTIN_TRANSPORTS', 'UDPv4')
    # The children find their packages (shipped scenarios, ament resources) without env.sh.
    if not env.get('AMENT_PREFIX_PATH'):
        env['AMENT_PREFIX_PATH'] = sys.prefix
    return env


def die_with(parent_pid):
    """Return a preexec function: SIGKILL the child when PARENT_PID (its forking thread) ends."""
    def set_parent_death_signal():
        _PRCTL(_PR_SET_PDEATHSIG, int(signal.SIGKILL), 0, 0, 0)
        if os.getppid() != parent_pid:
            # The runner died before the signal was armed.
            os._exit(1)
    return set_parent_death_signal


class Children:
    """The run's child processes, each in its own session, output in LOG_DIR/<label>.log."""

    def __init__(self, env, log_dir):
        self._env = env
        self._log_dir = log_dir
        self.processes = []
        self._watchdog = None
        self._stopped = False

    def _tell_watchdog(self, line):
        with contextlib.suppress(BrokenPipeError, ValueError):
            self._watchdog.stdin.write(f'{line}\n'.encode())
            self._watchdog.stdin.flush()

    def start(self, label, argv):
        """Start ARGV as child LABEL."""
        if self._watchdog is None:
            self._watchdog = subprocess.Popen(
                [sys.executable, '-I', '-c', WATCHDOG_SOURCE], stdin=subprocess.PIPE,
                stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, start_new_session=True)
        log_path = self._log_dir / f'{label}.log'
        with open(log_path, 'ab') as log_file:
            log_file.write(f'$ {shlex.join(argv)}\n'.encode())
            log_file.flush()
            # A signal between Popen and the bookkeeping would orphan the child: hold it back.
            with INTERRUPTS.deferred():
                process = subprocess.Popen(
                    argv, env=self._env, stdout=log_file, stderr=subprocess.STDOUT,
                    stdin=subprocess.DEVNULL, start_new_session=True,
                    preexec_fn=die_with(os.getpid()))
                self._tell_watchdog(process.pid)
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

    def interrupt(self):
        """SIGINT every running child's process group, once; do not wait."""
        for process in self.processes:
            if process.poll() is None and not getattr(process, 'interrupted', False):
                _signal_group(process.pid, signal.SIGINT)
                process.interrupted = True

    def stop(self, grace=SHUTDOWN_GRACE):
        """SIGINT every child's process group, wait up to GRACE s, then SIGKILL what is left.

        An interrupt signal noted meanwhile (INTERRUPTS.last_signal, in a teardown) ends the
        grace at once. Only the first call does anything: afterwards the groups' ids may
        belong to others.
        """
        if self._stopped:
            return
        self._stopped = True
        self.interrupt()
        deadline = time.monotonic() + grace
        while (any(process.poll() is None for process in self.processes)
               and time.monotonic() < deadline and INTERRUPTS.last_signal is None):
            time.sleep(0.02)
        # Also catches grandchildren left in a group whose leader has exited. The watchdog
        # forgets a group before its leader is reaped, after which the id may be reused.
        for process in self.processes:
            _signal_group(process.pid, signal.SIGKILL)
            if self._watchdog is not None:
                self._tell_watchdog(-process.pid)
            process.wait()
        if self._watchdog is not None:
            with contextlib.suppress(BrokenPipeError):
                self._watchdog.stdin.close()
            self._watchdog.wait()
            self._watchdog = None


def _signal_group(pgid, signum):
    with contextlib.suppress(ProcessLookupError, PermissionError):
        os.killpg(pgid, signum)

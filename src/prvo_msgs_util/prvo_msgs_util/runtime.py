"""Process settings, spinning and callback guards for long-running nodes with a control loop."""

import functools
import gc
import math
import time

import rclpy
from rclpy.executors import ExternalShutdownException
from rclpy.experimental import EventsExecutor

from prvo_msgs_util.interrupts import (
    hold_stop_signals,
    ignore_stop_signals,
    release_stop_signals,
)

EXIT_BAD_INPUT = 2  # a node's exit code when it cannot start on what it was given


def freeze_startup_objects():
    """
    Exempt every object alive now (imports, the node) from cyclic garbage collection.

    Call it once the node is built, just before spinning. Start-up objects live for the whole
    run, yet the collector rescans them: a planner's generation-1 collections took 8-11 ms and
    its full collections about 150 ms, pauses that land in the control loop and miss
    deadlines. Frozen, they are skipped; what the loop allocates is still collected.
    """
    gc.collect()
    gc.freeze()


# How long one spin_once may wait for an event: only how soon a shutdown from another thread
# is noticed when nothing else happens (SIGINT and rclpy's shutdown wake the executor at once).
_SPIN_WAIT = 0.5  # s


def spin_events(node):
    """
    Execute NODE's callbacks until rclpy shuts down, on rclpy's events executor.

    rclpy.spin()'s executor rebuilds and polls a wait set in Python on every wake-up, and a
    planner wakes once per odometry message, eight times per step in an 8-robot team. The events
    executor queues ready entities in C++ and runs their callbacks in arrival order.

    It spins by spin_once with a finite wait: in rclpy 7.1 (Jazzy) the events executor's
    spin(), and spin_once() without a timeout, return at once when idle, a busy loop that takes
    a whole core. Exceptions from callbacks, KeyboardInterrupt included, propagate as from
    rclpy.spin().
    """
    executor = EventsExecutor(context=node.context)
    executor.add_node(node)
    try:
        while node.context.ok():
            executor.spin_once(timeout_sec=_SPIN_WAIT)
    finally:
        executor.remove_node(node)
        executor.shutdown()


def run_node(make_node, logger_name, bad_input, args=None, bad_input_logged=False):
    """
    Build a node with MAKE_NODE() and spin it until SIGINT or SIGTERM; return the exit code.

    The body of a node's main(). BAD_INPUT: the exception classes that mean the node cannot
    start on what it was given (a scenario, a parameter); one is logged under LOGGER_NAME as
    'cannot start: ...', unless BAD_INPUT_LOGGED (the node logged it under its own name), and
    returns EXIT_BAD_INPUT. So does a malformed --ros-args value, which rcl rejects in
    rclpy.init before any node exists. ARGS: rclpy.init's.

    Stop signals are held while the node starts and then end spinning through rclpy's own
    handlers, which shut the context down (`hold_stop_signals`): no KeyboardInterrupt is raised
    inside a callback, where the events executor would log it as FATAL, or inside a message's
    constructor that rclpy's deserialization calls, which would turn it into a TypeError.
    """
    hold_stop_signals()
    node = None
    try:
        rclpy.init(args=args)
        node = make_node()
        freeze_startup_objects()
        if release_stop_signals():
            spin_events(node)
    except bad_input as error:
        if not bad_input_logged:
            rclpy.logging.get_logger(logger_name).error(f'cannot start: {error}')
        return EXIT_BAD_INPUT
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    except RuntimeError as error:
        if node is None and not rclpy.ok():
            # rcl parses --ros-args in init (rclpy's RCLError): a malformed -p value, such as
            # goal:="[nan, 0]" (a list of mixed types), fails before any parameter exists.
            rclpy.logging.get_logger(logger_name).fatal(
                f'invalid parameter: {str(error).split(", at ")[0]}')
            return EXIT_BAD_INPUT
        # A message take in flight when the context shuts down can fail with a RuntimeError.
        # That is the shutdown asked for; anything else is not.
        if rclpy.ok():
            raise
    finally:
        if node is not None:
            node.destroy_node()
        rclpy.try_shutdown()
        ignore_stop_signals()
    return 0


def quiet_after_shutdown(callback):
    """Wrap a node method CALLBACK so that a ROS error once the context is shut down ends it.

    A stop signal shuts the context down whenever it lands, also while a callback runs; the
    callback's next publish then fails, and the executor would report that as FATAL.
    """
    @functools.wraps(callback)
    def guarded(node, *args):
        try:
            return callback(node, *args)
        except RuntimeError:
            if node.context.ok():
                raise
            return None
    return guarded


class ThrottledWarnings:
    """Warnings to LOGGER, each kind at most once per PERIOD seconds, so one fault hides no other.

    rclpy's `throttle_duration_sec` throttles one call site; a kind here is any hashable key,
    such as (topic, fault).
    """

    def __init__(self, logger, period):
        self._logger = logger
        self._period = period
        self._warned_at = {}

    def warn(self, kind, message):
        """Log MESSAGE as a warning unless KIND was warned of within the period."""
        now = time.monotonic()
        if now - self._warned_at.get(kind, -math.inf) >= self._period:
            self._warned_at[kind] = now
            self._logger.warning(message)

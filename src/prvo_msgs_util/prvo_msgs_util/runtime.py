"""Process settings for long-running nodes with a control loop."""

import gc

from rclpy.experimental import EventsExecutor


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

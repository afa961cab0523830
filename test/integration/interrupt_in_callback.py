"""Run a node's main() with a SIGINT landing inside its first timer callback.

    python interrupt_in_callback.py MODULE [ROS arguments...]

A stop signal comes while the node is busy more often than not: a simulator steps, a planner
plans. Here it lands inside a timer callback every time.
"""

import importlib
import os
import signal
import sys

from rclpy.node import Node

_create_timer = Node.create_timer
_interrupted = []


def _create_timer_interrupting(node, period, callback, *args, **kwargs):
    def interrupting():
        if not _interrupted:
            _interrupted.append(None)
            os.kill(os.getpid(), signal.SIGINT)
        return callback()
    return _create_timer(node, period, interrupting, *args, **kwargs)


if __name__ == '__main__':
    Node.create_timer = _create_timer_interrupting
    module = importlib.import_module(sys.argv[1])
    sys.argv = [sys.argv[0], *sys.argv[2:]]
    sys.exit(module.main())

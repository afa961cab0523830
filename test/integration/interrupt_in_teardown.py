"""Run a node's main() with a second SIGINT landing inside its destroy_node().

    python interrupt_in_teardown.py MODULE [ROS arguments...]

Under `ros2 launch`, Ctrl-C reaches a node twice (from the terminal and from launch): the
second signal lands while the node is being torn down. Here it lands there every time.
"""

import importlib
import os
import signal
import sys

from rclpy.node import Node

_destroy_node = Node.destroy_node


def _destroy_node_interrupted(node):
    os.kill(os.getpid(), signal.SIGINT)
    return _destroy_node(node)


if __name__ == '__main__':
    Node.destroy_node = _destroy_node_interrupted
    module = importlib.import_module(sys.argv[1])
    sys.argv = [sys.argv[0], *sys.argv[2:]]
    sys.exit(module.main())

"""Stand-in for a sim or planner process in runner tests.

    fake_child.py run      start a grandchild that ignores SIGINT, then exit on SIGINT
    fake_child.py planner  as run, and publish the planner's endpoints (ROS arguments read)
    fake_child.py stubborn ignore SIGINT (only SIGKILL ends it)
    fake_child.py crash    exit at once with code 3
    fake_child.py watcher  subscribe to /clock (ROS arguments read), as `ros2 topic echo` does

'run', 'planner' and 'stubborn' print 'ready' once their signal handling is in place. A
'planner' creates its cmd_vel and /diagnostics publishers only once the file named by
PRVO_FAKE_PLANNER_GATE exists (at once without it), then prints 'publishing'.
"""

import signal
import sys

# First thing: a SIGINT during the imports below would otherwise be swallowed by importlib.
if sys.argv[1] in ('run', 'planner'):
    signal.signal(signal.SIGINT, lambda *_: sys.exit(0))

import os  # noqa: E402
import pathlib  # noqa: E402
import subprocess  # noqa: E402
import threading  # noqa: E402

IGNORING_SLEEPER = ('import signal, time; signal.signal(signal.SIGINT, signal.SIG_IGN); '
                    'time.sleep(600)')
GATE_VARIABLE = 'PRVO_FAKE_PLANNER_GATE'


def publish_planner_endpoints():
    """Create a node from the ROS arguments with the planner's publishers; return it."""
    from diagnostic_msgs.msg import DiagnosticArray
    from geometry_msgs.msg import TwistStamped
    import rclpy
    from rclpy.signals import SignalHandlerOptions

    from prvo_msgs_util import CMD_VEL_QOS, DIAGNOSTICS_QOS

    rclpy.init(args=sys.argv, signal_handler_options=SignalHandlerOptions.NO)
    node = rclpy.create_node('planner')
    gate = os.environ.get(GATE_VARIABLE)
    while gate is not None and not pathlib.Path(gate).exists():
        threading.Event().wait(0.05)
    node.create_publisher(TwistStamped, 'cmd_vel', CMD_VEL_QOS)
    node.create_publisher(DiagnosticArray, '/diagnostics', DIAGNOSTICS_QOS)
    print('publishing', flush=True)
    return node


def subscribe_to_clock():
    """Create a node from the ROS arguments that only subscribes to /clock; return it."""
    import rclpy
    from rclpy.qos import qos_profile_sensor_data
    from rosgraph_msgs.msg import Clock

    rclpy.init(args=sys.argv)
    node = rclpy.create_node('watcher')
    node.create_subscription(Clock, '/clock', lambda message: None, qos_profile_sensor_data)
    print('subscribed', flush=True)
    return node


def main():
    """Behave as the mode in argv[1] says."""
    mode = sys.argv[1]
    if mode == 'crash':
        return 3
    if mode == 'watcher':
        node = subscribe_to_clock()  # noqa: F841 (kept alive until the process ends)
        while True:
            signal.pause()
    if mode in ('run', 'planner'):
        # Same process group: only a group-wide SIGKILL can end it once its parent is gone.
        subprocess.Popen([sys.executable, '-c', IGNORING_SLEEPER])
    else:
        signal.signal(signal.SIGINT, signal.SIG_IGN)
    print('ready', flush=True)
    if mode == 'planner':
        node = publish_planner_endpoints()  # noqa: F841 (kept alive until the process ends)
    while True:
        signal.pause()


if __name__ == '__main__':
    sys.exit(main())

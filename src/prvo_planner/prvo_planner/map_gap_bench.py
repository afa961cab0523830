"""
Benchmark of a planner's control loop while a large map arrives: the gaps between its commands.

Usage: ``python -m prvo_planner.map_gap_bench [--size 4000] [--seconds 30]``. A planner process
(in /robot_0, heading for a far goal, no neighbours) is fed odometry at 10 Hz from this process,
which records when each of its `cmd_vel` messages arrives; after 6 s another process publishes
one SIZE x SIZE OccupancyGrid of 0.05 m cells on `/map` (a wall across it, so that the map
is built). Printed: the longest gap between commands within 1 s of the message and over the
whole run after it [s, wall]. Run it with ROS_DOMAIN_ID set to a domain of its own and
ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST.
"""

import argparse
import subprocess
import sys
import time

import numpy as np

PERIOD = 0.1
SEND_AFTER = 6.0


def send_map(size, delay):
    """Publish the SIZE x SIZE grid on /map after DELAY [s]; print when (monotonic); linger."""
    from nav_msgs.msg import OccupancyGrid
    import rclpy

    from prvo_msgs_util import MAP_QOS, make_occupancy_grid

    rclpy.init()
    node = rclpy.create_node('map_gap_sender')
    publisher = node.create_publisher(OccupancyGrid, '/map', MAP_QOS)
    cells = np.zeros((size, size), dtype=np.int8)
    cells[size // 2, :size - 100] = 100
    message = make_occupancy_grid(0.0, cells, 0.05, [0.0, 0.0])
    time.sleep(delay)
    print(f'sent {time.monotonic()}', flush=True)
    publisher.publish(message)
    # Latched (transient local) by this publisher: it stays until the run ends.
    time.sleep(3600.0)


def command_gaps(size, seconds):
    """Return (longest gap within 1 s of the map, longest after it) [s] of one run."""
    from geometry_msgs.msg import TwistStamped
    from nav_msgs.msg import Odometry
    import rclpy

    from prvo_msgs_util import make_odometry

    planner = subprocess.Popen([
        sys.executable, '-m', 'prvo_planner.planner_node', '--ros-args', '-r',
        '__ns:=/robot_0', '-p', 'goal:=[150.0, 150.0]', '-p', 'neighbors:=[""]'])
    sender = subprocess.Popen(
        [sys.executable, '-m', 'prvo_planner.map_gap_bench', '--send', str(SEND_AFTER),
         '--size', str(size)], stdout=subprocess.PIPE, text=True)
    rclpy.init()
    node = rclpy.create_node('map_gap_probe', namespace='/robot_0')
    odometry = node.create_publisher(Odometry, 'odom', 10)
    arrivals = []
    node.create_subscription(TwistStamped, 'cmd_vel',
                             lambda message: arrivals.append(time.monotonic()), 10)
    covariance = 1e-6 * np.eye(2)
    stamps = iter(range(1, 1 << 30))
    node.create_timer(PERIOD, lambda: odometry.publish(make_odometry(
        PERIOD * next(stamps), [1.0, 1.0], [0.0, 0.0], covariance, covariance,
        child_frame_id='robot_0/base_link')))
    try:
        ends = time.monotonic() + seconds
        while time.monotonic() < ends:
            rclpy.spin_once(node, timeout_sec=0.01)
    finally:
        planner.terminate()
        # rclpy takes SIGTERM for a shutdown request, and the sender only sleeps.
        sender.kill()
        sent = float(sender.communicate()[0].split()[1])
        planner.wait()
        node.destroy_node()
        rclpy.try_shutdown()
    after = np.array([arrival for arrival in arrivals if arrival >= sent])
    gaps = np.diff(np.concatenate([[max(a for a in arrivals if a < sent)], after]))
    near = gaps[np.concatenate([[sent], after[:-1]]) < sent + 1.0]
    return float(near.max()), float(gaps.max())


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.strip().splitlines()[0])
    parser.add_argument('--size', type=int, default=4000, help='cells along each side')
    parser.add_argument('--seconds', type=float, default=30.0, help='length of the run [s]')
    parser.add_argument('--send', type=float, help=argparse.SUPPRESS)
    arguments = parser.parse_args(argv)
    if arguments.send is not None:
        send_map(arguments.size, arguments.send)
        return 0
    near, longest = command_gaps(arguments.size, arguments.seconds)
    print(f'{arguments.size} x {arguments.size} map: longest gap between commands within 1 s '
          f'of the message {near:.3f} s, after it {longest:.3f} s')
    return 0


if __name__ == '__main__':
    sys.exit(main())

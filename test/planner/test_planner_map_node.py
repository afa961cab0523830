"""A running planner with a map: it takes a latched /map, publishes its route, names bad maps."""

import threading

from diagnostic_msgs.msg import DiagnosticArray
from geometry_msgs.msg import TwistStamped
from nav_msgs.msg import OccupancyGrid, Odometry, Path
import numpy as np
import pytest
from rcl_interfaces.msg import Log
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy

from prvo_msgs_util import (
    CMD_VEL_QOS,
    DIAGNOSTICS_QOS,
    GOAL_QOS,
    MAP_QOS,
    ODOM_QOS,
    PLAN_QOS,
    make_occupancy_grid,
    make_odometry,
    make_pose_stamped,
    robot_topic,
    stamp_to_seconds,
)

pytestmark = pytest.mark.integration

LOGGER = 'robot_0.planner'
ROSOUT_QOS = QoSProfile(depth=1000, reliability=ReliabilityPolicy.RELIABLE,
                        durability=DurabilityPolicy.TRANSIENT_LOCAL)
COVARIANCE = 1e-6 * np.eye(2)
START = (2.0, 1.5)
GOAL = (2.0, 4.5)


def walled_room():
    """Return an 8 m x 6 m room (0.1 m cells) split at y = 3 m, open only at x > 6 m.

    A closed box, walls 0.1 m thick, stands in the upper half from (6.4, 4.4) to (7.7, 5.7) m.
    """
    cells = np.zeros((60, 80), dtype=np.int8)
    cells[29:31, :60] = 100
    cells[[44, 56], 64:77] = 100
    cells[44:57, [64, 76]] = 100
    return cells


class Observer:
    """What the probe hears of robot_0's planner: commands, routes, logs, diagnostics."""

    def __init__(self, probe):
        self.lock = threading.Lock()
        self.commands, self.paths, self.logs, self.routes = {}, [], [], []
        node = probe.node
        node.create_subscription(TwistStamped, robot_topic('robot_0', 'cmd_vel'),
                                 self._on_command, CMD_VEL_QOS)
        node.create_subscription(Path, robot_topic('robot_0', 'plan'), self._keep(self.paths),
                                 PLAN_QOS)
        node.create_subscription(Log, '/rosout', self._on_log, ROSOUT_QOS)
        node.create_subscription(DiagnosticArray, '/diagnostics', self._on_diagnostics,
                                 DIAGNOSTICS_QOS)

    def _keep(self, into):
        def keep(msg):
            with self.lock:
                into.append(msg)
        return keep

    def _on_command(self, msg):
        with self.lock:
            self.commands[round(stamp_to_seconds(msg.header.stamp), 6)] = np.array(
                [msg.twist.linear.x, msg.twist.linear.y])

    def _on_log(self, msg):
        if msg.name == LOGGER:
            with self.lock:
                self.logs.append(msg.msg)

    def _on_diagnostics(self, msg):
        for status in msg.status:
            if status.name == 'prvo_planner/robot_0':
                with self.lock:
                    self.routes.append({item.key: item.value for item in status.values}['route'])

    def logged(self, text):
        with self.lock:
            return [line for line in self.logs if text in line]


class MappedPlanner:
    """robot_0's planner as a process, taking the map; the probe feeds it odometry at START."""

    def __init__(self, children, ros2_executable, probe, observer, *parameters):
        self.children, self.probe, self.observer = children, probe, observer
        self.odometry = probe.node.create_publisher(
            Odometry, robot_topic('robot_0', 'odom'), ODOM_QOS)
        self.process = children.start('planner', [
            ros2_executable('prvo_planner', 'planner'), '--ros-args', '-r', '__ns:=/robot_0',
            '-p', f'goal:=[{GOAL[0]}, {GOAL[1]}]', '-p', "neighbors:=['']", *parameters])
        self.stamp = 0.0
        probe.wait_until(lambda: self.alive(lambda: observer.logged('map 80 x 60 cells of 0.1 m')),
                         30.0, 'the planner taking the map')

    def alive(self, condition):
        """Return CONDITION(), failing at once with the planner's output if it has exited."""
        assert self.process.poll() is None, self.children.output(self.process)
        return condition()

    def command(self):
        """Send odometry 0.1 s after the last; return the command (2,) that answers it."""
        self.stamp = stamp = round(self.stamp + 0.1, 6)
        self.odometry.publish(make_odometry(stamp, START, [0.0, 0.0], COVARIANCE, COVARIANCE,
                                            child_frame_id='robot_0/base_link'))
        self.probe.wait_until(lambda: self.alive(lambda: stamp in self.observer.commands), 10.0,
                              f'the command for {stamp} s')
        return self.observer.commands[stamp]


def test_a_latched_map_before_the_planner_gives_a_route_and_bad_maps_are_named(
        children, ros2_executable, probe):
    node = probe.node
    map_publisher = node.create_publisher(OccupancyGrid, '/map', MAP_QOS)
    # Published once, before the planner exists: only a transient-local subscriber gets it.
    map_publisher.publish(make_occupancy_grid(0.0, walled_room(), 0.1, [0.0, 0.0]))
    observer = Observer(probe)
    goal_pose = node.create_publisher(
        type(make_pose_stamped(0.0, GOAL)), robot_topic('robot_0', 'goal_pose'), GOAL_QOS)
    planner = MappedPlanner(children, ros2_executable, probe, observer,
                            '-p', 'obstacle_distance:=0.5', '-p', 'status_period:=0.0')
    alive, command = planner.alive, planner.command

    velocity = command()
    probe.wait_until(lambda: alive(lambda: observer.paths), 10.0, 'a route on /robot_0/plan')
    path = observer.paths[-1]
    assert path.header.frame_id == 'map'
    waypoints = np.array([[pose.pose.position.x, pose.pose.position.y] for pose in path.poses])
    np.testing.assert_array_equal(waypoints[-1], GOAL)
    # Round the wall's end at x = 6 m, not straight through it.
    assert waypoints[:, 0].max() > 6.0
    heading = velocity / np.linalg.norm(velocity)
    assert heading @ (waypoints[1] - waypoints[0]) / np.linalg.norm(
        waypoints[1] - waypoints[0]) > 0.95
    probe.wait_until(lambda: observer.routes, 10.0, 'diagnostics')
    assert observer.routes[-1] == 'ok'

    # A map in another frame is refused, named; the planner keeps its map.
    bad = make_occupancy_grid(0.0, np.zeros((60, 80), dtype=np.int8), 0.1, [0.0, 0.0], 'odom')
    map_publisher.publish(bad)
    probe.wait_until(lambda: alive(lambda: observer.logged(
        "ignoring map on /map (keeping the map in force): header.frame_id is 'odom'")), 10.0,
        'the fault of a map in another frame')
    short = make_occupancy_grid(0.0, walled_room(), 0.1, [0.0, 0.0])
    short.data = short.data[:-1]
    map_publisher.publish(short)
    probe.wait_until(lambda: alive(lambda: observer.logged('data has 4799 cells')), 10.0,
                     'the fault of a map with too few cells')
    again = command()
    np.testing.assert_allclose(again / np.linalg.norm(again), heading, atol=0.05)

    # A goal in the wall is refused with a warning.
    goal_pose.publish(make_pose_stamped(0.0, (3.0, 3.0)))
    probe.wait_until(lambda: alive(lambda: observer.logged('lies in an obstacle of the map')),
                     10.0, 'the refusal of a goal in the wall')
    # A goal in the closed box is taken, but no way reaches it: named, the robot holds.
    goal_pose.publish(make_pose_stamped(0.0, (7.0, 5.0)))
    probe.wait_until(lambda: alive(lambda: observer.logged('new goal [7.0, 5.0]')), 10.0,
                     'the goal in the box taken')
    held = command()
    assert np.linalg.norm(held) < 1e-6
    probe.wait_until(lambda: alive(lambda: observer.logged(
        'no way on the map reaches the goal [7.0, 5.0]: holding the place')), 10.0,
        'the warning of an unreachable goal')
    probe.wait_until(lambda: observer.routes[-1] == 'unreachable', 10.0,
                     'diagnostics of an unreachable goal')
    # Its route says so: where it stands, alone.
    probe.wait_until(lambda: len(observer.paths[-1].poses) == 1, 10.0, 'a route of one pose')
    held_at = observer.paths[-1].poses[0].pose.position
    assert np.hypot(held_at.x - 7.0, held_at.y - 5.0) > 1.0
    assert children.interrupt(planner.process) == 0


@pytest.mark.parametrize('resolution', [1e-4, 1e-9])
def test_a_map_of_tiny_cells_is_refused_at_once_keeping_the_map_in_force(
        children, ros2_executable, probe, resolution):
    # 160 x 160 cells: the route's 0.6 m of clearance would be 6,000 cells of 1e-4 m (days of
    # work) or 6e8 of 1e-9 m (exabytes), on every side of the map.
    node = probe.node
    map_publisher = node.create_publisher(OccupancyGrid, '/map', MAP_QOS)
    map_publisher.publish(make_occupancy_grid(0.0, walled_room(), 0.1, [0.0, 0.0]))
    observer = Observer(probe)
    planner = MappedPlanner(children, ros2_executable, probe, observer)
    alive, command = planner.alive, planner.command

    heading = command()
    map_publisher.publish(make_occupancy_grid(0.0, np.zeros((160, 160), dtype=np.int8),
                                              resolution, [0.0, 0.0]))
    probe.wait_until(lambda: alive(lambda: observer.logged(
        f'cannot use the map on /map (keeping the map in force): 160 x 160 cells of '
        f'{resolution:g} m')), 10.0, 'the fault of a map of tiny cells')
    # Still round the wall by the map in force (a free map would head straight for the goal).
    again = command()
    np.testing.assert_allclose(again / np.linalg.norm(again),
                               heading / np.linalg.norm(heading), atol=0.05)
    assert children.interrupt(planner.process) == 0

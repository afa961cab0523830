"""A stand-in for Nav2's controller and velocity smoother of one robot, for tests and demos.

Run it in the robot's namespace; it reads the robot's odometry and publishes the pure-pursuit
command of `prvo_sim.upstream` on `cmd_vel_smoothed`, blind to other robots:

    ros2 run prvo_sim nav2_stand_in --ros-args -r __ns:=/robot_0 -p waypoints:="[0.0, 0.0, 4, 0]"

With `answer_odometry` (lockstep) it answers each odometry message, stamped with its stamp, so
that a lockstep run stays reproducible; otherwise it publishes at 20 Hz from the newest
odometry, as velocity_smoother does. The planner in `velocity` mode filters the command.
"""

import sys

from geometry_msgs.msg import Twist, TwistStamped
from nav_msgs.msg import Odometry
from rclpy.node import Node
from rclpy.parameter import Parameter

from prvo_msgs_util import (
    CMD_VEL_QOS,
    ODOM,
    ODOM_LATEST_QOS,
    MessageFault,
    declare_parameters,
    make_twist,
    parameter_descriptor,
    quiet_after_shutdown,
    quiet_publisher_events,
    quiet_subscription_events,
    run_node,
    seconds_to_stamp,
    serialized_odometry_to_measurement,
)
from prvo_planner.parameters import KINEMATICS
from prvo_sim.upstream import DECELERATION, LOOKAHEAD, RATE, PurePursuitUpstream

NODE = 'nav2_stand_in'
CMD_VEL_SMOOTHED = 'cmd_vel_smoothed'
_WARNING_THROTTLE = 2.0
PARAMETERS = {
    'waypoints': (Parameter.Type.DOUBLE_ARRAY, parameter_descriptor(
        'Waypoints [x0, y0, x1, y1, ...] in the map frame [m]', 'float[]')),
    'speed': (1.0, parameter_descriptor('Cruise speed [m/s]', 'float', (1e-3, 100.0))),
    'kinematics': ('holonomic', parameter_descriptor(
        'holonomic (linear x, y) or unicycle (linear.x and angular.z)', 'str')),
    'max_angular_speed': (2.0, parameter_descriptor('Unicycle turn limit [rad/s]', 'float',
                                                    (0.1, 1000.0))),
    'goal_tolerance': (0.1, parameter_descriptor(
        'Zero command within this distance of the last waypoint [m]', 'float', (1e-3, 100.0))),
    'lookahead': (LOOKAHEAD, parameter_descriptor('Pure-pursuit lookahead [m]', 'float',
                                                  (0.01, 100.0))),
    'deceleration': (DECELERATION, parameter_descriptor(
        'Braking to zero at the last waypoint [m/s^2]', 'float', (0.01, 100.0))),
    'answer_odometry': (False, parameter_descriptor(
        'Answer each odometry message (lockstep) instead of publishing at 20 Hz', 'bool')),
    'enable_stamped_cmd_vel': (False, parameter_descriptor(
        'Publish TwistStamped (true) or Twist (false)', 'bool')),
}


class StandInNode(Node):
    """Plays controller_server plus velocity_smoother for one robot: pure pursuit, blind."""

    def __init__(self):
        super().__init__(NODE)
        values = declare_parameters(self, PARAMETERS)
        waypoints = list(values['waypoints'] or [])
        if not waypoints or len(waypoints) % 2:
            raise ValueError(f'waypoints: expected [x0, y0, x1, y1, ...], got {waypoints}')
        if values['kinematics'] not in KINEMATICS:
            raise ValueError(f"kinematics: must be one of {', '.join(KINEMATICS)}, got "
                             f"{values['kinematics']!r}")
        self._upstream = PurePursuitUpstream(
            [waypoints[index:index + 2] for index in range(0, len(waypoints), 2)],
            values['speed'], values['kinematics'], values['goal_tolerance'],
            values['max_angular_speed'], values['lookahead'], values['deceleration'])
        self._stamped = values['enable_stamped_cmd_vel']
        self._frame = f"{self.get_namespace().strip('/')}/base_link"
        self._publisher = self.create_publisher(
            TwistStamped if self._stamped else Twist, CMD_VEL_SMOOTHED, CMD_VEL_QOS,
            event_callbacks=quiet_publisher_events())
        self._latest = None
        self._answer = values['answer_odometry']
        self.create_subscription(Odometry, ODOM, self._on_odometry, ODOM_LATEST_QOS,
                                 event_callbacks=quiet_subscription_events(), raw=True)
        if not self._answer:
            self.create_timer(1.0 / RATE, self._on_timer)

    @quiet_after_shutdown
    def _on_odometry(self, data):
        try:
            measurement = serialized_odometry_to_measurement(data)
        except MessageFault as fault:
            self.get_logger().warning(f'skipping odometry: {fault}',
                                      throttle_duration_sec=_WARNING_THROTTLE)
            return
        self._latest = measurement
        if self._answer:
            self._publish(measurement)

    @quiet_after_shutdown
    def _on_timer(self):
        if self._latest is not None:
            self._publish(self._latest)

    def _publish(self, measurement):
        linear, angular = self._upstream.command(measurement.position, measurement.yaw)
        twist = make_twist(linear, angular)
        if not self._stamped:
            self._publisher.publish(twist)
            return
        message = TwistStamped(twist=twist)
        # The odometry's stamp: in lockstep the simulator takes it as the answer to that step.
        message.header.stamp = seconds_to_stamp(measurement.stamp)
        message.header.frame_id = self._frame
        self._publisher.publish(message)


def main(args=None):
    """Run the stand-in until SIGINT or SIGTERM; exit 2 on a bad parameter."""
    return run_node(StandInNode, NODE, (ValueError,), args)


if __name__ == '__main__':
    sys.exit(main())

r"""A stand-in for Nav2's planner_server of one robot, for tests and demos: its route as a Path.

Run it in the robot's namespace; it publishes the route of its `waypoints` parameter as the
`nav_msgs/Path` of `prvo_sim.planned_path` (frame `map`) on `plan`, which a planner with
`preferred_source: path` follows:

    ros2 run prvo_sim planner_server_stand_in --ros-args -r __ns:=/robot_0 \
        -p waypoints:="[0.0, 0.0, 4.0, 0.0, 4.0, 3.0]"

The path is published reliable and transient local, at start-up and whenever `waypoints` is
set to another route; and once more to each subscriber that connects, since planner_server's
own `plan` is volatile and a follower subscribes it so (a late one would get nothing).
"""

import sys

from nav_msgs.msg import Path
from rcl_interfaces.msg import SetParametersResult
from rclpy.event_handler import PublisherEventCallbacks
from rclpy.node import Node
from rclpy.parameter import Parameter

from prvo_msgs_util import (
    PLAN,
    PLAN_QOS,
    WORLD_FRAME,
    declare_parameters,
    make_path,
    parameter_descriptor,
    quiet_after_shutdown,
    run_node,
)
from prvo_sim.planned_path import SPACING, PlannedPath

NODE = 'planner_server_stand_in'
PARAMETERS = {
    'waypoints': (Parameter.Type.DOUBLE_ARRAY, parameter_descriptor(
        'Route [x0, y0, x1, y1, ...] in the map frame [m]; set again to replan', 'float[]',
        read_only=False)),
    'spacing': (SPACING, parameter_descriptor('Largest distance between poses [m]', 'float',
                                              (1e-3, 100.0))),
}


def route_of(values):
    """Return the route (K, 2) of the flat list VALUES [x0, y0, ...]; ValueError if malformed."""
    values = list(values or [])
    if not values or len(values) % 2:
        raise ValueError(f'waypoints: expected [x0, y0, x1, y1, ...], got {values}')
    return [values[index:index + 2] for index in range(0, len(values), 2)]


class PlannedPathNode(Node):
    """Plays planner_server for one robot: publishes its route as a path, blind to others."""

    def __init__(self):
        super().__init__(NODE)
        values = declare_parameters(self, PARAMETERS)
        self._path = PlannedPath(values['spacing'])
        poses = self._path.replan(route_of(values['waypoints']))
        self._publisher = self.create_publisher(
            Path, PLAN, PLAN_QOS,
            event_callbacks=PublisherEventCallbacks(matched=self._on_matched,
                                                    use_default_callbacks=False))
        self.add_on_set_parameters_callback(self._on_set_parameters)
        self._publish(poses)

    def _on_set_parameters(self, parameters):
        for parameter in parameters:
            if parameter.name != 'waypoints':
                continue
            try:
                poses = self._path.replan(route_of(parameter.value))
            except ValueError as error:
                return SetParametersResult(successful=False, reason=str(error))
            if poses is not None:
                self._publish(poses)
        return SetParametersResult(successful=True)

    @quiet_after_shutdown
    def _on_matched(self, status):
        if status.current_count_change > 0:
            self._publish(self._path.poses)

    def _publish(self, poses):
        self._publisher.publish(make_path(
            self.get_clock().now().nanoseconds * 1e-9, poses, WORLD_FRAME))


def main(args=None):
    """Run the stand-in until SIGINT or SIGTERM; exit 2 on a bad parameter."""
    return run_node(PlannedPathNode, NODE, (ValueError,), args)


if __name__ == '__main__':
    sys.exit(main())

"""Republish a robot's odometry in the map frame, with covariance, for prvo (example only).

Nav2's loopback simulator publishes `odom` in the robot's own `odom` frame and the map -> odom
transform. prvo compares robots' states in one shared frame: this relay looks up map -> odom
in the robot's (namespaced) tf tree and publishes `odometry/global` in `map`, as
robot_localization with `world_frame: map` would, with a small covariance (the loopback
simulator's states are exact and carry none). On a real robot use robot_localization instead.
"""

import math
import sys

from nav_msgs.msg import Odometry
import rclpy
from rclpy.node import Node
from rclpy.time import Time
from tf2_ros import Buffer, TransformException, TransformListener

POSITION_VARIANCE = 0.02 ** 2  # m^2
VELOCITY_VARIANCE = 0.02 ** 2  # (m/s)^2


def _yaw(q):
    return math.atan2(2.0 * (q.w * q.z + q.x * q.y), 1.0 - 2.0 * (q.y * q.y + q.z * q.z))


class OdomInMap(Node):
    """odom (frame odom) in, odometry/global (frame map) out."""

    def __init__(self):
        super().__init__('odom_in_map')
        self._buffer = Buffer()
        self._listener = TransformListener(self._buffer, self)
        self._publisher = self.create_publisher(Odometry, 'odometry/global', 10)
        self.create_subscription(Odometry, 'odom', self._on_odom, 10)

    def _on_odom(self, msg):
        try:
            transform = self._buffer.lookup_transform('map', msg.header.frame_id, Time())
        except TransformException as error:
            self.get_logger().warning(f'no map -> {msg.header.frame_id}: {error}',
                                      throttle_duration_sec=2.0)
            return
        offset, rotation = transform.transform.translation, transform.transform.rotation
        turn = _yaw(rotation)
        cos, sin = math.cos(turn), math.sin(turn)
        pose = msg.pose.pose
        out = Odometry()
        out.header.stamp = msg.header.stamp
        out.header.frame_id = 'map'
        out.child_frame_id = msg.child_frame_id
        out.pose.pose.position.x = offset.x + cos * pose.position.x - sin * pose.position.y
        out.pose.pose.position.y = offset.y + sin * pose.position.x + cos * pose.position.y
        yaw = _yaw(pose.orientation) + turn
        out.pose.pose.orientation.z, out.pose.pose.orientation.w = (
            math.sin(0.5 * yaw), math.cos(0.5 * yaw))
        # The twist stays in the child (body) frame, as Odometry requires.
        out.twist.twist = msg.twist.twist
        covariance = [0.0] * 36
        covariance[0] = covariance[7] = POSITION_VARIANCE
        covariance[35] = 0.01
        out.pose.covariance = covariance
        covariance = [0.0] * 36
        covariance[0] = covariance[7] = VELOCITY_VARIANCE
        covariance[35] = 0.01
        out.twist.covariance = covariance
        self._publisher.publish(out)


def main():
    rclpy.init()
    node = OdomInMap()
    try:
        rclpy.spin(node)
    except KeyboardInterrupt:
        pass
    finally:
        node.destroy_node()
        rclpy.try_shutdown()
    return 0


if __name__ == '__main__':
    sys.exit(main())

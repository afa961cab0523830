"""Conversions between odometry, twist, pose and time messages and numpy arrays."""

from dataclasses import dataclass
import math
import struct

from builtin_interfaces.msg import Time
from geometry_msgs.msg import PointStamped, PoseStamped, Twist, TwistStamped
from nav_msgs.msg import Odometry, Path
import numpy as np

from prvo_msgs_util.topics import WORLD_FRAME

_NS_PER_S = 1_000_000_000
# Row-major indices of the x/y block inside a 6x6 ROS covariance.
_XY_FLAT_INDICES = (0, 1, 6, 7)
# Eigenvalues this far below zero, relative to the largest, are rounding, not a fault.
_PSD_RELATIVE_TOLERANCE = 1e-12
# A quaternion shorter than this has no direction to normalise to.
_MIN_QUATERNION_NORM = 1e-6
# Bounds of physical sense for a planar robot: beyond them a value is a fault, not a state.
# Finite but huge values would pass the NaN checks and then overflow or swamp the planner's
# arithmetic (squared distances, Kalman gains).
MAX_WORLD_COORDINATE = 1.0e6  # m
# The most poses a nav_msgs/Path may have: 500 m of a Nav2 plan at 5 cm a pose.
MAX_PATH_POSES = 10_000
MAX_SPEED_COMPONENT = 1.0e3  # m/s
MAX_VARIANCE = 1.0e6  # m^2 or (m/s)^2
# An announced footprint's radius: a huge one makes every plan near it infeasible, a tiny one
# makes a robot a point.
MIN_FOOTPRINT_RADIUS = 0.01  # m
MAX_FOOTPRINT_RADIUS = 100.0  # m
# Serialized (CDR) nav_msgs/Odometry: a 4-byte encapsulation header (0, 1: little-endian;
# 0, 0: big-endian), the header's stamp (int32 sec, uint32 nanosec) and frame_id, the
# child_frame_id, then 85 float64 aligned to 8 bytes from the end of the encapsulation header:
# pose (position 3, orientation 4), its covariance (36), twist (linear 3, angular 3) and its
# covariance (36).
_CDR_HEADER_BYTES = 4
_CDR_BYTE_ORDERS = {b'\x00\x00': '>', b'\x00\x01': '<'}
_CDR_LITTLE_ENDIAN = b'\x00\x01\x00\x00'
_ODOMETRY_FLOAT_COUNT = 85
_POSITION, _ORIENTATION = slice(0, 2), slice(3, 7)
_POSE_COVARIANCE, _LINEAR, _TWIST_COVARIANCE = slice(7, 43), slice(43, 45), slice(49, 85)
# twist.angular.z and its variance (the last entry of the row-major 6 x 6 twist covariance).
_ANGULAR_Z, _ANGULAR_Z_VARIANCE = 48, 84


class MessageFault(ValueError):  # noqa: N818 (the project's API name)
    """A message whose content cannot be used; the text names the field and the fault."""


def stamp_to_seconds(stamp):
    """Return a builtin_interfaces/Time as float seconds."""
    return stamp.sec + stamp.nanosec * 1e-9


def checked_stamp_seconds(stamp, field):
    """Return a builtin_interfaces/Time as float seconds; MessageFault unless it is a time >= 0.

    Time's fields are integers: a negative sec, or a nanosec of a second or more, is no time.
    """
    if stamp.sec < 0 or stamp.nanosec >= _NS_PER_S:
        raise MessageFault(
            f'{field} is no time >= 0 (sec {stamp.sec}, nanosec {stamp.nanosec})')
    return stamp_to_seconds(stamp)


def seconds_to_stamp(seconds):
    """Return float SECONDS (finite, >= 0) as a builtin_interfaces/Time, rounded to 1 ns."""
    sec, nanosec = _stamp_fields(seconds)
    return Time(sec=sec, nanosec=nanosec)


def _stamp_fields(seconds):
    """Return float SECONDS (finite, >= 0) as (sec, nanosec), rounded to 1 ns."""
    if not math.isfinite(seconds) or seconds < 0.0:
        raise ValueError(f'cannot make a stamp of {seconds} s')
    return divmod(round(seconds * _NS_PER_S), _NS_PER_S)


@dataclass(frozen=True)
class OdometryMeasurement:
    """Mean and covariance of one odometry message, over [x, y, vx, vy] in the world frame."""

    stamp: float
    frame_id: str
    child_frame_id: str
    position: np.ndarray
    velocity: np.ndarray
    covariance: np.ndarray
    yaw: float


def _require_finite(values, field):
    """Raise MessageFault unless every float of the sequence VALUES is finite."""
    if not all(math.isfinite(value) for value in values):
        raise MessageFault(f'{field} contains NaN or inf ({[float(value) for value in values]})')


def check_world_point(values, field):
    """Raise MessageFault unless VALUES (x, y) are finite and within MAX_WORLD_COORDINATE [m]."""
    _require_finite(values, field)
    _require_bounded(values, MAX_WORLD_COORDINATE, field)


def _require_bounded(values, bound, field):
    """Raise MessageFault unless every |value| of VALUES is at most BOUND."""
    if any(abs(value) > bound for value in values):
        raise MessageFault(
            f'{field} is beyond {bound:g} ({[float(value) for value in values]})')


def _check_frame(frame_id, expected_frame, field):
    if expected_frame is not None and frame_id != expected_frame:
        raise MessageFault(f'{field} is {frame_id!r}, expected {expected_frame!r}')


def _xy_covariance(covariance, field):
    """Return the checked x/y block (xx, xy, yy) of a 36-element row-major covariance."""
    # Plain floats: a 2x2 block is cheaper to check by hand than through numpy, and every
    # odometry message of every robot passes here.
    xx, xy, yx, yy = (float(covariance[index]) for index in _XY_FLAT_INDICES)
    _require_finite((xx, xy, yx, yy), field)
    tolerance = _PSD_RELATIVE_TOLERANCE * max(abs(xx), abs(xy), abs(yx), abs(yy))
    if abs(xy - yx) > tolerance:
        raise MessageFault(f'{field} xy block is not symmetric ({[[xx, xy], [yx, yy]]})')
    for axis, variance in (('x', xx), ('y', yy)):
        if variance < -tolerance:
            raise MessageFault(f'{field} has a negative {axis} variance ({variance})')
        if variance > MAX_VARIANCE:
            raise MessageFault(
                f'{field} has an {axis} variance beyond {MAX_VARIANCE:g} ({variance})')
    xy = 0.5 * (xy + yx)
    # The smaller eigenvalue of a symmetric 2x2 matrix, in closed form.
    smallest = 0.5 * (xx + yy) - math.hypot(0.5 * (xx - yy), xy)
    if smallest < -tolerance:
        raise MessageFault(
            f'{field} xy block is not positive semi-definite (eigenvalue {smallest:g})')
    if smallest < 0.0:
        eigenvalues, eigenvectors = np.linalg.eigh(np.array([[xx, xy], [xy, yy]]))
        block = eigenvectors @ np.diag(np.maximum(eigenvalues, 0.0)) @ eigenvectors.T
        xx, xy, yy = float(block[0, 0]), float(block[0, 1]), float(block[1, 1])
    return xx, xy, yy


def _yaw_from_quaternion(quaternion):
    """Return the yaw of QUATERNION (x, y, z, w)."""
    _require_finite(quaternion, 'pose.orientation')
    norm = math.hypot(*quaternion)
    if norm < _MIN_QUATERNION_NORM:
        raise MessageFault(f'pose.orientation has norm {norm:g}, cannot be normalised')
    x, y, z, w = (value / norm for value in quaternion)
    return math.atan2(2.0 * (w * z + x * y), 1.0 - 2.0 * (y * y + z * z))


def odometry_to_measurement(msg, expected_frame=WORLD_FRAME):
    """Return the world-frame OdometryMeasurement of a nav_msgs/Odometry.

    The twist is given in child_frame_id; it is rotated by the pose's yaw into the world frame,
    mean and covariance alike. Odometry carries no position-velocity cross terms, so they are 0.
    Raises MessageFault on NaN/inf, a bad covariance, a degenerate quaternion or a wrong frame.
    """
    pose, twist = msg.pose.pose, msg.twist.twist
    return _measurement(
        stamp_to_seconds(msg.header.stamp), msg.header.frame_id, msg.child_frame_id,
        (pose.position.x, pose.position.y),
        (pose.orientation.x, pose.orientation.y, pose.orientation.z, pose.orientation.w),
        msg.pose.covariance, (twist.linear.x, twist.linear.y), msg.twist.covariance,
        expected_frame)


def serialized_odometry_to_measurement(data, expected_frame=WORLD_FRAME):
    """Return the OdometryMeasurement of a serialized (CDR) nav_msgs/Odometry.

    DATA is what a raw subscription (``create_subscription(..., raw=True)``) delivers. The
    result and the faults are those of ``odometry_to_measurement`` on the deserialized message;
    reading the few fields needed straight from the bytes costs a small fraction of
    deserializing the whole message into Python objects. Raises MessageFault also when DATA is
    not a complete CDR-encoded Odometry.
    """
    data = bytes(data)
    byte_order = _CDR_BYTE_ORDERS.get(data[:2])
    if byte_order is None:
        raise MessageFault(
            f'serialized odometry has no CDR encapsulation header ({data[:4].hex()})')
    body = memoryview(data)[_CDR_HEADER_BYTES:]
    try:
        sec, nanosec = struct.unpack_from(byte_order + 'iI', body, 0)
        frame_id, offset = _cdr_string(body, 8, byte_order, 'header.frame_id')
        child_frame_id, offset = _cdr_string(body, offset, byte_order, 'child_frame_id')
        values = struct.unpack_from(f'{byte_order}{_ODOMETRY_FLOAT_COUNT}d', body,
                                    (offset + 7) & ~7)
    except struct.error:
        raise MessageFault(
            f'serialized odometry is truncated ({len(data)} bytes)') from None
    return _measurement(
        sec + nanosec * 1e-9, frame_id, child_frame_id, values[_POSITION],
        values[_ORIENTATION], values[_POSE_COVARIANCE], values[_LINEAR],
        values[_TWIST_COVARIANCE], expected_frame)


def _cdr_string(body, offset, byte_order, field, message='odometry'):
    """Return (the CDR string at OFFSET, aligned to 4, of BODY; the offset after it)."""
    offset = (offset + 3) & ~3
    (length,) = struct.unpack_from(byte_order + 'I', body, offset)
    start, end = offset + 4, offset + 4 + length
    # The length counts the terminating NUL.
    if length == 0 or end > len(body) or body[end - 1] != 0:
        raise MessageFault(f'serialized {message} has a malformed {field}')
    try:
        return bytes(body[start:end - 1]).decode(), end
    except UnicodeDecodeError:
        raise MessageFault(f'serialized {message} has a {field} that is not UTF-8') from None


def _measurement(stamp, frame_id, child_frame_id, position, orientation, pose_covariance,
                 body_velocity, twist_covariance, expected_frame):
    """Return the checked OdometryMeasurement of odometry fields (plain floats and sequences)."""
    _check_frame(frame_id, expected_frame, 'header.frame_id')
    check_world_point(position, 'pose.position')
    _require_finite(body_velocity, 'twist.linear')
    _require_bounded(body_velocity, MAX_SPEED_COMPONENT, 'twist.linear')
    yaw = _yaw_from_quaternion(orientation)
    pxx, pxy, pyy = _xy_covariance(pose_covariance, 'pose.covariance')
    # The twist into the world frame: rotated by yaw.
    cos_yaw, sin_yaw = math.cos(yaw), math.sin(yaw)
    vxx, vxy, vyy = _rotated_covariance(
        cos_yaw, sin_yaw, *_xy_covariance(twist_covariance, 'twist.covariance'))
    return OdometryMeasurement(
        stamp=stamp, frame_id=frame_id, child_frame_id=child_frame_id,
        position=np.array(position, dtype=float),
        velocity=np.array(_rotated_vector(cos_yaw, sin_yaw, *body_velocity)),
        covariance=np.array([[pxx, pxy, 0.0, 0.0], [pxy, pyy, 0.0, 0.0],
                             [0.0, 0.0, vxx, vxy], [0.0, 0.0, vxy, vyy]]),
        yaw=yaw)


# Rotations by the angle of (COS, SIN) in plain floats: every odometry message of every robot
# is built or read through them, and numpy's per-call cost exceeds the arithmetic of a 2x2.

def _rotated_vector(cos, sin, x, y):
    """Return R (x, y) as a tuple, R the rotation with cosine COS and sine SIN."""
    return cos * x - sin * y, sin * x + cos * y


def world_to_body(velocity, yaw):
    """Return the world-frame VELOCITY (2,) in the frame of a robot heading YAW [rad], (2,)."""
    return np.array(_rotated_vector(math.cos(yaw), -math.sin(yaw), velocity[0], velocity[1]))


def body_to_world(velocity, yaw):
    """Return VELOCITY (2,) in the frame of a robot heading YAW [rad] in the world frame (2,)."""
    return np.array(_rotated_vector(math.cos(yaw), math.sin(yaw), velocity[0], velocity[1]))


def _rotated_covariance(cos, sin, xx, xy, yy):
    """Return R C R^T as (xx, xy, yy), C = [[XX, XY], [XY, YY]], symmetric by construction."""
    cross = cos * sin
    return (cos * cos * xx - 2.0 * cross * xy + sin * sin * yy,
            cross * (xx - yy) + (cos * cos - sin * sin) * xy,
            sin * sin * xx + 2.0 * cross * xy + cos * cos * yy)


def make_odometry(stamp_seconds, position, velocity, position_cov, velocity_cov,
                  frame_id=WORLD_FRAME, child_frame_id='base_link', yaw=0.0, turn_rate=0.0,
                  turn_rate_variance=0.0):
    """Return a nav_msgs/Odometry of a planar robot.

    VELOCITY and both (2, 2) covariances are in the world frame; the twist is written in the
    child frame (rotated by -YAW), as Odometry requires. TURN_RATE [rad/s] is twist.angular.z,
    with TURN_RATE_VARIANCE its variance.
    """
    values = _odometry_values(position, velocity, position_cov, velocity_cov, yaw, turn_rate,
                              turn_rate_variance)
    msg = Odometry()
    msg.header.stamp = seconds_to_stamp(stamp_seconds)
    msg.header.frame_id = frame_id
    msg.child_frame_id = child_frame_id
    pose, twist = msg.pose.pose, msg.twist.twist
    pose.position.x, pose.position.y = values[_POSITION]
    pose.orientation.x, pose.orientation.y, pose.orientation.z, pose.orientation.w = (
        values[_ORIENTATION])
    msg.pose.covariance = values[_POSE_COVARIANCE]
    twist.linear.x, twist.linear.y = values[_LINEAR]
    twist.angular.z = values[_ANGULAR_Z]
    msg.twist.covariance = values[_TWIST_COVARIANCE]
    return msg


def serialize_odometry(stamp_seconds, position, velocity, position_cov, velocity_cov,
                       frame_id=WORLD_FRAME, child_frame_id='base_link', yaw=0.0, turn_rate=0.0,
                       turn_rate_variance=0.0):
    """Return make_odometry's message serialized (little-endian CDR), ready to publish.

    A publisher sends bytes as they are; packing the few fields a planar robot sets costs a
    small fraction of building the message in Python and having rclpy convert it.
    """
    values = _odometry_values(position, velocity, position_cov, velocity_cov, yaw, turn_rate,
                              turn_rate_variance)
    body = bytearray(struct.pack('<iI', *_stamp_fields(stamp_seconds)))
    for text in (frame_id, child_frame_id):
        body += bytes(-len(body) % 4)
        encoded = text.encode() + b'\x00'
        body += struct.pack('<I', len(encoded)) + encoded
    body += bytes(-len(body) % 8)
    body += struct.pack(f'<{_ODOMETRY_FLOAT_COUNT}d', *values)
    return _CDR_LITTLE_ENDIAN + bytes(body)


def _odometry_values(position, velocity, position_cov, velocity_cov, yaw, turn_rate=0.0,
                     turn_rate_variance=0.0):
    """Return the 85 floats of a planar robot's Odometry after its two frame names."""
    (axx, axy), (ayx, ayy) = np.asarray(velocity_cov, dtype=float).tolist()
    (pxx, pxy), (pyx, pyy) = np.asarray(position_cov, dtype=float).tolist()
    # The twist in the child frame: rotated by -yaw.
    cos_yaw, minus_sin_yaw = math.cos(yaw), -math.sin(yaw)
    bxx, bxy, byy = _rotated_covariance(cos_yaw, minus_sin_yaw, axx, 0.5 * (axy + ayx), ayy)
    values = [0.0] * _ODOMETRY_FLOAT_COUNT
    values[_POSITION] = (float(value) for value in position)
    values[_ORIENTATION] = (0.0, 0.0, math.sin(0.5 * yaw), math.cos(0.5 * yaw))
    values[_LINEAR] = _rotated_vector(cos_yaw, minus_sin_yaw,
                                      *(float(value) for value in velocity))
    for block, (xx, xy, yx, yy) in ((_POSE_COVARIANCE, (pxx, pxy, pyx, pyy)),
                                    (_TWIST_COVARIANCE, (bxx, bxy, bxy, byy))):
        for index, value in zip(_XY_FLAT_INDICES, (xx, xy, yx, yy), strict=True):
            values[block.start + index] = value
    values[_ANGULAR_Z] = float(turn_rate)
    values[_ANGULAR_Z_VARIANCE] = float(turn_rate_variance)
    return values


def make_twist(velocity, turn_rate=0.0):
    """Return a geometry_msgs/Twist with linear x, y = VELOCITY and angular z = TURN_RATE."""
    msg = Twist()
    msg.linear.x, msg.linear.y = (float(value) for value in velocity)
    msg.angular.z = float(turn_rate)
    return msg


def make_twist_stamped(stamp_seconds, velocity, frame_id, turn_rate=0.0):
    """Return a geometry_msgs/TwistStamped with linear x, y = VELOCITY in FRAME_ID.

    TURN_RATE is angular z.
    """
    msg = TwistStamped()
    msg.header.stamp = seconds_to_stamp(stamp_seconds)
    msg.header.frame_id = frame_id
    msg.twist = make_twist(velocity, turn_rate)
    return msg


def twist_to_velocity(msg):
    """Return linear x, y of a Twist or TwistStamped as an array (2,); MessageFault on NaN/inf."""
    twist = msg.twist if isinstance(msg, TwistStamped) else msg
    velocity = np.array([twist.linear.x, twist.linear.y])
    _require_finite(velocity, 'twist.linear')
    return velocity


def pose_stamped_to_goal(msg, expected_frame=WORLD_FRAME):
    """Return the x, y position of a PoseStamped goal.

    An empty frame_id (a message published without a header, as `ros2 topic pub` sends it) is
    EXPECTED_FRAME. Raises MessageFault on NaN/inf, a coordinate beyond MAX_WORLD_COORDINATE or
    another frame.
    """
    if msg.header.frame_id:
        _check_frame(msg.header.frame_id, expected_frame, 'header.frame_id')
    check_world_point((msg.pose.position.x, msg.pose.position.y), 'pose.position')
    return np.array([msg.pose.position.x, msg.pose.position.y])


def make_pose_stamped(stamp_seconds, position, frame_id=WORLD_FRAME):
    """Return a PoseStamped at POSITION (x, y) with identity orientation."""
    msg = PoseStamped()
    msg.header.stamp = seconds_to_stamp(stamp_seconds)
    msg.header.frame_id = frame_id
    msg.pose.position.x, msg.pose.position.y = (float(value) for value in position)
    msg.pose.orientation.w = 1.0
    return msg


def twist_components(msg):
    """Return ((linear x, y), angular z) of a Twist or TwistStamped; MessageFault on NaN/inf."""
    twist = msg.twist if isinstance(msg, TwistStamped) else msg
    values = (twist.linear.x, twist.linear.y, twist.angular.z)
    _require_finite(values, 'twist')
    return (values[0], values[1]), values[2]


def filtered_twist(upstream, velocity, turn_rate):
    """Return a message of UPSTREAM's type (Twist or TwistStamped) moving at VELOCITY (x, y).

    In the body frame, turning at TURN_RATE [rad/s]; a TwistStamped keeps UPSTREAM's header,
    as a filter between a controller and the base does.
    """
    twist = make_twist(velocity, turn_rate)
    if not isinstance(upstream, TwistStamped):
        return twist
    msg = TwistStamped()
    msg.header = upstream.header
    msg.twist = twist
    return msg


def path_to_waypoints(msg, expected_frame=WORLD_FRAME):
    """Return the positions (K, 2) of a nav_msgs/Path's poses (K may be 0: no path).

    The path's frame (an empty one is EXPECTED_FRAME) and every pose's non-empty frame must be
    EXPECTED_FRAME. Raises MessageFault on another frame, NaN/inf or a coordinate beyond
    MAX_WORLD_COORDINATE.
    """
    if msg.header.frame_id:
        _check_frame(msg.header.frame_id, expected_frame, 'header.frame_id')
    waypoints = np.empty((len(msg.poses), 2))
    for index, pose in enumerate(msg.poses):
        if pose.header.frame_id:
            _check_frame(pose.header.frame_id, expected_frame, f'poses[{index}].header.frame_id')
        point = (pose.pose.position.x, pose.pose.position.y)
        check_world_point(point, f'poses[{index}].pose.position')
        waypoints[index] = point
    return waypoints


def serialized_path_to_waypoints(data, expected_frame=WORLD_FRAME, max_poses=MAX_PATH_POSES):
    """Return the positions (K, 2) of a serialized (CDR) nav_msgs/Path's poses.

    DATA is what a raw subscription delivers. The result is that of `path_to_waypoints` on the
    deserialized message, and so are the faults (frames before positions). A path of more than
    MAX_POSES poses is refused (MessageFault) from its length alone, before any pose is read:
    deserializing a path into Python objects took about 50 us a pose (5 s for 100,000), reading
    the positions from the bytes a small fraction of that. Raises MessageFault also when DATA
    is not a complete CDR-encoded Path.
    """
    data = bytes(data)
    byte_order = _CDR_BYTE_ORDERS.get(data[:2])
    if byte_order is None:
        raise MessageFault(f'serialized path has no CDR encapsulation header ({data[:4].hex()})')
    body = memoryview(data)[_CDR_HEADER_BYTES:]
    try:
        frame_id, offset = _cdr_string(body, 8, byte_order, 'header.frame_id', 'path')
        offset = (offset + 3) & ~3
        (count,) = struct.unpack_from(byte_order + 'I', body, offset)
        if count > max_poses:
            raise MessageFault(f'the path has {count} poses, more than {max_poses}')
        if frame_id:
            _check_frame(frame_id, expected_frame, 'header.frame_id')
        waypoints = np.empty((count, 2))
        offset += 4
        for index in range(count):
            # A pose: its header's stamp (8 bytes) and frame_id, then 7 doubles from x, y.
            pose_frame, offset = _cdr_string(body, ((offset + 3) & ~3) + 8, byte_order,
                                             f'poses[{index}].header.frame_id', 'path')
            if pose_frame:
                _check_frame(pose_frame, expected_frame, f'poses[{index}].header.frame_id')
            offset = (offset + 7) & ~7
            waypoints[index] = struct.unpack_from(byte_order + 'dd', body, offset)
            offset += 56
        # The last pose's orientation, unread, must be there too.
        if offset > len(body):
            raise struct.error
    except struct.error:
        raise MessageFault(f'serialized path is truncated ({len(data)} bytes)') from None
    # NaN fails the comparison too.
    faulty = np.flatnonzero(~np.all(np.abs(waypoints) <= MAX_WORLD_COORDINATE, axis=1))
    if len(faulty):
        check_world_point(waypoints[faulty[0]], f'poses[{faulty[0]}].pose.position')
    return waypoints


def serialized_path_stamp(data):
    """Return the header stamp [s] of a serialized (CDR) nav_msgs/Path, DATA.

    Raises MessageFault for DATA without a CDR header or too short to hold a stamp, and for a
    stamp that is no time >= 0 (`checked_stamp_seconds`).
    """
    data = bytes(data)
    byte_order = _CDR_BYTE_ORDERS.get(data[:2])
    if byte_order is None:
        raise MessageFault(f'serialized path has no CDR encapsulation header ({data[:4].hex()})')
    try:
        sec, nanosec = struct.unpack_from(byte_order + 'iI', data, _CDR_HEADER_BYTES)
    except struct.error:
        raise MessageFault(f'serialized path is truncated ({len(data)} bytes)') from None
    return checked_stamp_seconds(Time(sec=sec, nanosec=nanosec), 'path header.stamp')


class SerializedPathReader:
    """Reads serialized nav_msgs/Path messages as they come, the same message again for nothing.

    Path senders re-publish the path they gave: the same bytes again are recognised by one
    comparison instead of being read again.
    """

    def __init__(self, expected_frame=WORLD_FRAME, max_poses=MAX_PATH_POSES):
        self._expected_frame = expected_frame
        self._max_poses = max_poses
        self._last = None

    def read(self, data):
        """Return the waypoints (K, 2) of DATA (`serialized_path_to_waypoints`), or None.

        None: DATA is the message read last, whose waypoints hold. Raises MessageFault as
        `serialized_path_to_waypoints` does; the message read last stays the last.
        """
        data = bytes(data)
        if data == self._last:
            return None
        waypoints = serialized_path_to_waypoints(data, self._expected_frame, self._max_poses)
        self._last = data
        return waypoints


def make_path(stamp_seconds, waypoints, frame_id=WORLD_FRAME):
    """Return a nav_msgs/Path through WAYPOINTS (K, 2) in FRAME_ID, every pose stamped alike."""
    msg = Path()
    msg.header.stamp = seconds_to_stamp(stamp_seconds)
    msg.header.frame_id = frame_id
    msg.poses = [make_pose_stamped(stamp_seconds, point, frame_id) for point in waypoints]
    return msg


def make_point_stamped(stamp_seconds, point, frame_id=WORLD_FRAME):
    """Return a geometry_msgs/PointStamped at POINT (x, y) in FRAME_ID."""
    msg = PointStamped()
    msg.header.stamp = seconds_to_stamp(stamp_seconds)
    msg.header.frame_id = frame_id
    msg.point.x, msg.point.y = (float(value) for value in point)
    return msg

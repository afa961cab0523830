"""Round trips and fault detection of the message <-> numpy conversions."""

import math
import struct

from geometry_msgs.msg import PoseStamped, Twist
from nav_msgs.msg import Odometry
import numpy as np
import pytest
from rclpy.serialization import deserialize_message, serialize_message

from prvo_msgs_util import (
    MAX_WORLD_COORDINATE,
    MessageFault,
    check_world_point,
    make_odometry,
    make_pose_stamped,
    make_twist,
    make_twist_stamped,
    odometry_to_measurement,
    pose_stamped_to_goal,
    seconds_to_stamp,
    serialize_odometry,
    serialized_odometry_to_measurement,
    stamp_to_seconds,
    twist_to_velocity,
)


def random_covariance(rng):
    """Return a random symmetric positive-definite 2x2 matrix."""
    factor = rng.normal(size=(2, 2))
    return factor @ factor.T + 0.01 * np.eye(2)


def rotation(angle):
    """Rotation matrix by ANGLE, written out independently of the code under test."""
    return np.array([[math.cos(angle), -math.sin(angle)], [math.sin(angle), math.cos(angle)]])


def test_stamp_round_trip_to_the_nanosecond():
    for seconds in (0.0, 0.1, 2.3, 17.000000001, 1e6 + 0.5):
        stamp = seconds_to_stamp(seconds)
        assert stamp.sec == math.floor(seconds)
        assert stamp.nanosec == round((seconds - math.floor(seconds)) * 1e9)
        assert stamp_to_seconds(stamp) == pytest.approx(seconds, abs=1e-9)
    # 0.9999999999 s rounds up to a whole second, not to nanosec == 1e9.
    stamp = seconds_to_stamp(0.9999999999)
    assert (stamp.sec, stamp.nanosec) == (1, 0)
    with pytest.raises(ValueError):
        seconds_to_stamp(float('nan'))


def test_odometry_round_trip_with_random_yaw():
    rng = np.random.default_rng(1)
    for _ in range(50):
        yaw = rng.uniform(-math.pi, math.pi)
        position, velocity = rng.normal(size=2), rng.normal(size=2)
        position_cov, velocity_cov = random_covariance(rng), random_covariance(rng)
        msg = make_odometry(12.5, position, velocity, position_cov, velocity_cov,
                            child_frame_id='robot_0/base_link', yaw=yaw)

        # The twist in the message is in the child frame: rotated by -yaw.
        body_velocity = rotation(yaw).T @ velocity
        assert msg.twist.twist.linear.x == pytest.approx(body_velocity[0])
        assert msg.twist.twist.linear.y == pytest.approx(body_velocity[1])
        body_cov = rotation(yaw).T @ velocity_cov @ rotation(yaw)
        twist_cov = np.array(msg.twist.covariance).reshape(6, 6)
        np.testing.assert_allclose(twist_cov[:2, :2], body_cov, atol=1e-12)
        np.testing.assert_allclose(
            np.array(msg.pose.covariance).reshape(6, 6)[:2, :2], position_cov, atol=1e-12)

        measurement = odometry_to_measurement(msg)
        assert measurement.stamp == pytest.approx(12.5)
        assert measurement.frame_id == 'map'
        assert measurement.child_frame_id == 'robot_0/base_link'
        assert math.remainder(measurement.yaw - yaw, 2 * math.pi) == pytest.approx(0, abs=1e-12)
        np.testing.assert_allclose(measurement.position, position, atol=1e-12)
        np.testing.assert_allclose(measurement.velocity, velocity, atol=1e-12)
        expected = np.zeros((4, 4))
        expected[:2, :2] = position_cov
        expected[2:, 2:] = velocity_cov
        np.testing.assert_allclose(measurement.covariance, expected, atol=1e-12)


def test_measurement_normalises_a_scaled_quaternion():
    msg = make_odometry(0.0, [0, 0], [0, 0], np.eye(2), np.eye(2), yaw=0.7)
    orientation = msg.pose.pose.orientation
    orientation.z, orientation.w = 3 * orientation.z, 3 * orientation.w
    assert odometry_to_measurement(msg).yaw == pytest.approx(0.7)


def test_rounding_level_negative_eigenvalue_is_clipped():
    msg = make_odometry(0.0, [0, 0], [0, 0], np.eye(2), np.eye(2))
    # [[1, 1], [1, 1 - 1e-15]] has eigenvalue about -5e-16: rounding, not a fault.
    msg.pose.covariance[1] = msg.pose.covariance[6] = 1.0
    msg.pose.covariance[7] = 1.0 - 1e-15
    position_cov = odometry_to_measurement(msg).covariance[:2, :2]
    assert np.linalg.eigvalsh(position_cov).min() >= 0.0
    np.testing.assert_allclose(position_cov, np.ones((2, 2)), atol=1e-12)


def odometry_with(change):
    """Return a valid Odometry after CHANGE(msg) has broken it."""
    msg = make_odometry(1.0, [1.0, 2.0], [0.5, 0.0], 0.01 * np.eye(2), 0.04 * np.eye(2))
    change(msg)
    return msg


def set_item(sequence, index, value):
    sequence[index] = value


@pytest.mark.parametrize(('change', 'fault'), [
    (lambda m: setattr(m.pose.pose.position, 'x', math.nan), 'pose.position'),
    (lambda m: setattr(m.twist.twist.linear, 'y', math.inf), 'twist.linear'),
    (lambda m: setattr(m.pose.pose.orientation, 'w', math.nan), 'pose.orientation'),
    (lambda m: set_item(m.pose.covariance, 7, math.nan), 'pose.covariance'),
    (lambda m: set_item(m.twist.covariance, 0, -0.5), 'twist.covariance has a negative x'),
    (lambda m: set_item(m.pose.covariance, 7, -0.01), 'pose.covariance has a negative y'),
    (lambda m: (set_item(m.pose.covariance, 1, 0.2), set_item(m.pose.covariance, 6, 0.2)),
     'pose.covariance xy block is not positive semi-definite'),
    (lambda m: set_item(m.pose.covariance, 1, 0.001), 'pose.covariance xy block is not symm'),
    (lambda m: setattr(m.pose.pose.orientation, 'w', 0.0), 'pose.orientation has norm 0'),
    (lambda m: setattr(m.header, 'frame_id', 'odom'), "header.frame_id is 'odom'"),
    # Finite but beyond physical sense: such values once reached the tracker and the planner.
    (lambda m: setattr(m.pose.pose.position, 'y', -1.0e308), 'pose.position is beyond 1e'),
    (lambda m: setattr(m.pose.pose.position, 'x', 1.5e6), 'pose.position is beyond 1e'),
    (lambda m: setattr(m.twist.twist.linear, 'x', 2.0e3), 'twist.linear is beyond 1000'),
    (lambda m: set_item(m.pose.covariance, 0, 1.0e7), 'pose.covariance has an x variance bey'),
    (lambda m: set_item(m.twist.covariance, 7, 1.0e300), 'twist.covariance has an y variance'),
])
@pytest.mark.parametrize('serialized', [False, True])
def test_odometry_faults_are_named(change, fault, serialized):
    msg = odometry_with(change)
    with pytest.raises(MessageFault, match=fault.replace('.', r'\.')):
        if serialized:
            serialized_odometry_to_measurement(serialize_message(msg))
        else:
            odometry_to_measurement(msg)


def test_non_psd_fault_reports_the_eigenvalue():
    msg = odometry_with(lambda m: (set_item(m.pose.covariance, 1, 0.2),
                                   set_item(m.pose.covariance, 6, 0.2)))
    # [[0.01, 0.2], [0.2, 0.01]] has eigenvalues 0.01 -+ 0.2.
    with pytest.raises(MessageFault, match=r'eigenvalue -0\.19'):
        odometry_to_measurement(msg)


def test_expected_frame_none_accepts_any_frame():
    msg = odometry_with(lambda m: setattr(m.header, 'frame_id', 'odom'))
    assert odometry_to_measurement(msg, expected_frame=None).frame_id == 'odom'


def cdr_odometry(msg, byte_order):
    """Encode MSG as CDR by hand, in BYTE_ORDER ('<' or '>'): a reference for the decoder."""
    def align(buffer, size):
        buffer += bytes(-len(buffer) % size)

    def string(buffer, text):
        align(buffer, 4)
        encoded = text.encode() + b'\x00'
        buffer += struct.pack(byte_order + 'I', len(encoded)) + encoded

    body = bytearray(struct.pack(byte_order + 'iI', msg.header.stamp.sec,
                                 msg.header.stamp.nanosec))
    string(body, msg.header.frame_id)
    string(body, msg.child_frame_id)
    align(body, 8)
    pose, twist = msg.pose.pose, msg.twist.twist
    values = [pose.position.x, pose.position.y, pose.position.z, pose.orientation.x,
              pose.orientation.y, pose.orientation.z, pose.orientation.w,
              *msg.pose.covariance, twist.linear.x, twist.linear.y, twist.linear.z,
              twist.angular.x, twist.angular.y, twist.angular.z, *msg.twist.covariance]
    body += struct.pack(f'{byte_order}{len(values)}d', *values)
    return (b'\x00\x01\x00\x00' if byte_order == '<' else b'\x00\x00\x00\x00') + bytes(body)


def random_odometry(rng, frame_id, child_frame_id):
    """Return an Odometry with random values in every field the decoder reads or skips."""
    msg = make_odometry(rng.uniform(0.0, 1e5), rng.normal(size=2), rng.normal(size=2),
                        random_covariance(rng), random_covariance(rng), frame_id=frame_id,
                        child_frame_id=child_frame_id, yaw=rng.uniform(-math.pi, math.pi))
    msg.pose.pose.position.z = rng.normal()
    msg.twist.twist.linear.z, msg.twist.twist.angular.z = rng.normal(size=2)
    return msg


def test_serialized_odometry_gives_the_measurement_of_the_message():
    rng = np.random.default_rng(3)
    # Frame names of every length modulo 8 move the floats across every alignment case.
    names = ['', 'm', 'map', 'odom', 'w\u00f6rld', 'robot_1/base_link', 'a' * 13, 'b' * 30]
    for index in range(64):
        frame_id, child_frame_id = names[index % 8], names[(index // 8) % 8]
        msg = random_odometry(rng, frame_id, child_frame_id)
        data = serialize_message(msg)
        # rclpy reads the hand encoding back as MSG, so it can stand in for big-endian.
        assert deserialize_message(cdr_odometry(msg, '<'), Odometry) == msg
        expected = odometry_to_measurement(msg, expected_frame=None)
        for encoded in (data, cdr_odometry(msg, '>')):
            measurement = serialized_odometry_to_measurement(encoded, expected_frame=None)
            assert measurement.stamp == expected.stamp
            assert (measurement.frame_id, measurement.child_frame_id) == (
                frame_id, child_frame_id)
            assert measurement.yaw == expected.yaw
            # And against the message's fields read by hand: the pose, the quaternion's yaw,
            # the body-frame twist turned into the world frame.
            pose, twist = msg.pose.pose, msg.twist.twist.linear
            q = pose.orientation
            yaw = math.atan2(2.0 * (q.w * q.z + q.x * q.y), 1.0 - 2.0 * (q.y ** 2 + q.z ** 2))
            assert measurement.yaw == pytest.approx(yaw, abs=1e-12)
            np.testing.assert_array_equal(measurement.position, [pose.position.x, pose.position.y])
            np.testing.assert_allclose(measurement.velocity, [
                math.cos(yaw) * twist.x - math.sin(yaw) * twist.y,
                math.sin(yaw) * twist.x + math.cos(yaw) * twist.y], rtol=1e-12, atol=1e-12)
            for field in ('position', 'velocity', 'covariance'):
                np.testing.assert_array_equal(
                    getattr(measurement, field), getattr(expected, field))


def test_serialize_odometry_gives_the_bytes_of_make_odometrys_message():
    rng = np.random.default_rng(4)
    names = ['', 'm', 'map', 'odom', 'w\u00f6rld', 'robot_1/base_link', 'a' * 13, 'b' * 30]
    for index in range(64):
        arguments = (rng.uniform(0.0, 1e5), rng.normal(size=2), rng.normal(size=2),
                     random_covariance(rng), random_covariance(rng))
        frames = {'frame_id': names[index % 8], 'child_frame_id': names[(index // 8) % 8],
                  'yaw': rng.uniform(-math.pi, math.pi)}
        # rclpy's deserializer reads the packed bytes back as the message make_odometry builds.
        assert deserialize_message(serialize_odometry(*arguments, **frames), Odometry) == (
            make_odometry(*arguments, **frames))


@pytest.mark.parametrize(('corrupt', 'fault'), [
    (lambda data: data[:40], 'truncated'),
    (lambda data: data[:-8], 'truncated'),
    (lambda data: b'\x00\x07' + data[2:], 'no CDR encapsulation header'),
    (lambda data: b'', 'no CDR encapsulation header'),
    # header.frame_id's length (after the stamp) claims more bytes than there are.
    (lambda data: data[:12] + struct.pack('<I', 10_000) + data[16:], 'malformed header'),
    # A zero length has no room for the terminating NUL.
    (lambda data: data[:12] + struct.pack('<I', 0) + data[16:], 'malformed header'),
])
def test_malformed_serialized_odometry_is_a_named_fault(corrupt, fault):
    data = serialize_message(odometry_with(lambda msg: None))
    with pytest.raises(MessageFault, match=fault):
        serialized_odometry_to_measurement(corrupt(data))


def test_twist_conversions():
    stamped = make_twist_stamped(3.2, [0.3, -0.4], 'map')
    assert stamped.header.frame_id == 'map'
    assert (stamped.header.stamp.sec, stamped.header.stamp.nanosec) == (3, 200_000_000)
    np.testing.assert_array_equal(twist_to_velocity(stamped), [0.3, -0.4])
    plain = make_twist([1.0, 2.0])
    assert isinstance(plain, Twist)
    np.testing.assert_array_equal(twist_to_velocity(plain), [1.0, 2.0])
    plain.linear.x = math.nan
    with pytest.raises(MessageFault, match='twist.linear contains NaN'):
        twist_to_velocity(plain)
    stamped.twist.linear.y = -math.inf
    with pytest.raises(MessageFault, match='twist.linear contains NaN or inf'):
        twist_to_velocity(stamped)


def test_goal_conversions():
    msg = make_pose_stamped(1.5, [2.0, -3.0])
    assert isinstance(msg, PoseStamped)
    assert msg.pose.orientation.w == 1.0
    np.testing.assert_array_equal(pose_stamped_to_goal(msg), [2.0, -3.0])
    with pytest.raises(MessageFault, match="header.frame_id is 'odom', expected 'map'"):
        pose_stamped_to_goal(make_pose_stamped(1.5, [2.0, -3.0], frame_id='odom'))
    msg.pose.position.y = math.nan
    with pytest.raises(MessageFault, match='pose.position contains NaN'):
        pose_stamped_to_goal(msg)
    msg.pose.position.y = 1.0e308
    with pytest.raises(MessageFault, match=r'pose\.position is beyond 1e\+06'):
        pose_stamped_to_goal(msg)


def test_world_point_check_accepts_the_bound_and_refuses_beyond_it():
    check_world_point((MAX_WORLD_COORDINATE, -MAX_WORLD_COORDINATE), 'goal')
    for point in ((0.0, MAX_WORLD_COORDINATE * (1.0 + 1e-9)), (-1.0e308, 0.0)):
        with pytest.raises(MessageFault, match='goal is beyond'):
            check_world_point(point, 'goal')
    with pytest.raises(MessageFault, match='goal contains NaN'):
        check_world_point((math.nan, 0.0), 'goal')


def test_odometry_is_a_nav_msgs_odometry_with_frames():
    msg = make_odometry(0.5, [0, 0], [0, 0], np.eye(2), np.eye(2), frame_id='world',
                        child_frame_id='r/base_link')
    assert isinstance(msg, Odometry)
    assert (msg.header.frame_id, msg.child_frame_id) == ('world', 'r/base_link')

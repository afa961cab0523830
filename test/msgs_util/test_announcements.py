"""Footprint and share announcements: the messages, their conversions and their QoS."""

import math

from builtin_interfaces.msg import Time
from geometry_msgs.msg import Point32, PolygonStamped, Vector3Stamped
import pytest
from rclpy.qos import DurabilityPolicy, HistoryPolicy, ReliabilityPolicy

from prvo_msgs_util import (
    ANNOUNCEMENT_QOS,
    ANNOUNCEMENT_READER_QOS,
    MAX_FOOTPRINT_RADIUS,
    MIN_FOOTPRINT_RADIUS,
    AnnouncementChanges,
    announcement_stamp,
    footprint_message,
    radius_of_footprint,
    seconds_to_stamp,
    share_message,
    share_of,
    stamp_to_seconds,
)


def polygon(points):
    message = PolygonStamped()
    message.polygon.points = [Point32(x=x, y=y, z=0.0) for x, y in points]
    return message


@pytest.mark.parametrize('radius', [0.2, 0.45, 0.8, 3.0])
def test_the_footprint_is_a_regular_16_gon_on_the_radius(radius):
    message = footprint_message(radius, 'robot_0/base_link', 12.5)
    assert message.header.frame_id == 'robot_0/base_link'
    assert (message.header.stamp.sec, message.header.stamp.nanosec) == (12, 500_000_000)
    assert announcement_stamp(message) == 12.5
    points = message.polygon.points
    assert len(points) == 16
    # Vertices on the circle (float32 coordinates), 22.5 degrees apart, counter-clockwise.
    for index, point in enumerate(points):
        assert math.hypot(point.x, point.y) == pytest.approx(radius, rel=1e-6)
        assert math.atan2(point.y, point.x) % (2 * math.pi) == pytest.approx(
            (2 * math.pi * index / 16) % (2 * math.pi), abs=1e-6)
    assert radius_of_footprint(message) == pytest.approx(radius, rel=1e-6)


def test_the_radius_of_any_footprint_is_the_circumscribed_one():
    # Nav2's rectangular footprint of a 0.6 x 0.4 robot: half-diagonal sqrt(0.3^2 + 0.2^2).
    rectangle = polygon([(0.3, 0.2), (0.3, -0.2), (-0.3, -0.2), (-0.3, 0.2)])
    assert radius_of_footprint(rectangle) == pytest.approx(math.hypot(0.3, 0.2), rel=1e-6)


IMPLAUSIBLE = r'footprint radius must be in \[0\.01, 100\] m, got '


@pytest.mark.parametrize('points, fault', [
    ([], 'footprint has no vertices'),
    ([(0.3, 0.0), (float('nan'), 0.1)], 'footprint has a non-finite vertex'),
    ([(float('inf'), 0.0)], 'footprint has a non-finite vertex'),
    ([(0.0, 0.0), (0.0, 0.0)], f'{IMPLAUSIBLE}0\\.0'),
    # A foreign giant, which would make every plan near it infeasible, and a point.
    ([(1.0e6, 0.0), (0.0, 0.3)], f'{IMPLAUSIBLE}1000000\\.0'),
    ([(1.0e-12, 0.0)], f'{IMPLAUSIBLE}1e-12'),
    ([(0.0, 0.0099)], f'{IMPLAUSIBLE}0\\.0099'),
    ([(100.1, 0.0)], f'{IMPLAUSIBLE}100\\.1')])
def test_an_unusable_footprint_is_named(points, fault):
    with pytest.raises(ValueError, match=f'^{fault}'):
        radius_of_footprint(polygon(points))


def test_the_plausible_footprint_radii_are_those_the_bounds_state():
    assert (MIN_FOOTPRINT_RADIUS, MAX_FOOTPRINT_RADIUS) == (0.01, 100.0)
    # Point32 holds float32: just inside each bound, as a float32 coordinate reads.
    for radius in (0.0101, 99.99):
        assert MIN_FOOTPRINT_RADIUS <= radius_of_footprint(polygon([(0.0, radius)])) <= (
            MAX_FOOTPRINT_RADIUS)


@pytest.mark.parametrize('radius', [0.0, -0.3, float('nan'), float('inf')])
def test_no_footprint_message_of_an_unusable_radius(radius):
    with pytest.raises(ValueError, match='^footprint radius must be finite and > 0'):
        footprint_message(radius, 'robot_0/base_link', 0.0)


@pytest.mark.parametrize('share', [0.0, 0.5, 0.25, 0.999])
@pytest.mark.parametrize('stamp', [0.0, 1e-9, 0.1, 12.3, 4000.7])
def test_shares_round_trip_with_their_stamps(share, stamp):
    message = share_message(share, 'robot_3/base_link', stamp)
    assert isinstance(message, Vector3Stamped)
    assert message.header.frame_id == 'robot_3/base_link'
    assert (message.vector.y, message.vector.z) == (0.0, 0.0)
    assert share_of(message) == message.vector.x == share
    assert announcement_stamp(message) == pytest.approx(stamp, abs=1e-9)


def test_the_stamp_of_an_odometry_message_comes_back_to_the_bit():
    # A planner stamps an announcement with the stamp of its odometry (seconds as
    # stamp_to_seconds reads them) and its neighbours compare it with theirs: it must come back
    # as the same float, as a command's stamp does.
    for step in range(0, 200_000, 997):
        odometry_stamp = stamp_to_seconds(seconds_to_stamp(step * 0.1))
        message = share_message(0.5, 'robot_0/base_link', odometry_stamp)
        assert announcement_stamp(message) == odometry_stamp
        assert announcement_stamp(footprint_message(0.3, 'robot_0/base_link',
                                                    odometry_stamp)) == odometry_stamp


def vector_share(x, y=0.0, z=0.0, sec=0, nanosec=0):
    message = Vector3Stamped()
    message.vector.x, message.vector.y, message.vector.z = x, y, z
    message.header.stamp = Time(sec=sec, nanosec=nanosec)
    return message


@pytest.mark.parametrize('share', [-0.1, 1.0, 2.0, float('nan'), float('inf'), -float('inf')])
def test_a_share_outside_zero_one_is_named(share):
    with pytest.raises(ValueError, match=r'^avoidance share must be in \[0, 1\), got '):
        share_of(vector_share(share))
    with pytest.raises(ValueError, match=r'^avoidance share must be in \[0, 1\), got '):
        share_message(share, 'robot_0/base_link', 0.0)


@pytest.mark.parametrize('y, z', [(0.5, 0.0), (0.0, -1.0), (float('nan'), 0.0)])
def test_a_share_vector_with_more_than_x_is_named(y, z):
    with pytest.raises(ValueError, match=r'^avoidance share must have vector\.y = vector\.z = 0, '
                       r'got \[0\.5, '):
        share_of(vector_share(0.5, y, z))


@pytest.mark.parametrize('sec, nanosec', [(-1, 0), (-2 ** 31, 0), (5, 1_000_000_000),
                                          (0, 2 ** 32 - 1)])
def test_an_announcement_stamp_that_is_no_time_is_named(sec, nanosec):
    for message in (vector_share(0.5, sec=sec, nanosec=nanosec), polygon([(0.3, 0.0)])):
        message.header.stamp = Time(sec=sec, nanosec=nanosec)
        with pytest.raises(ValueError, match=r'^announcement header\.stamp is no time >= 0 '
                           f'\\(sec {sec}, nanosec {nanosec}\\)'):
            announcement_stamp(message)


@pytest.mark.parametrize('stamp', [-0.1, float('nan'), float('inf')])
def test_no_announcement_of_a_stamp_that_is_no_time(stamp):
    with pytest.raises(ValueError, match='^cannot make a stamp of '):
        share_message(0.5, 'robot_0/base_link', stamp)
    with pytest.raises(ValueError, match='^cannot make a stamp of '):
        footprint_message(0.3, 'robot_0/base_link', stamp)


def test_only_what_changed_is_announced_again_with_the_new_stamp():
    changes = AnnouncementChanges('robot_2')
    footprint, share = changes.messages(0.3, 0.5, 0.0)
    assert footprint.header.frame_id == share.header.frame_id == 'robot_2/base_link'
    assert (announcement_stamp(footprint), announcement_stamp(share)) == (0.0, 0.0)
    assert changes.messages(0.3, 0.5, 0.25) == (None, None)
    footprint, share = changes.messages(0.3, 0.0, 0.5)
    assert footprint is None and (share_of(share), announcement_stamp(share)) == (0.0, 0.5)
    footprint, share = changes.messages(0.4, 0.0, 0.75)
    assert share is None and announcement_stamp(footprint) == 0.75
    assert radius_of_footprint(footprint) == pytest.approx(0.4, rel=1e-6)


def test_announcements_are_latched():
    assert ANNOUNCEMENT_QOS.reliability == ReliabilityPolicy.RELIABLE
    assert ANNOUNCEMENT_QOS.durability == DurabilityPolicy.TRANSIENT_LOCAL
    # A writer of one asks for an acknowledgement with every sample.
    assert (ANNOUNCEMENT_QOS.history, ANNOUNCEMENT_QOS.depth) == (HistoryPolicy.KEEP_LAST, 1)
    # A reader's queue is bounded, and deep enough that no change is replaced before a slow
    # node takes it.
    reader = ANNOUNCEMENT_READER_QOS
    assert (reader.reliability, reader.durability) == (ReliabilityPolicy.RELIABLE,
                                                       DurabilityPolicy.TRANSIENT_LOCAL)
    assert reader.history == HistoryPolicy.KEEP_LAST and reader.depth > 2

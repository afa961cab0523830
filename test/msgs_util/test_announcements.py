"""Footprint and share announcements: the messages, their conversions and their QoS."""

import math

from geometry_msgs.msg import Point32, PolygonStamped
import pytest
from rclpy.qos import DurabilityPolicy, HistoryPolicy, ReliabilityPolicy
from std_msgs.msg import Float32

from prvo_msgs_util import (
    ANNOUNCEMENT_QOS,
    footprint_message,
    radius_of_footprint,
    share_message,
    share_of,
)


def polygon(points):
    message = PolygonStamped()
    message.polygon.points = [Point32(x=x, y=y, z=0.0) for x, y in points]
    return message


@pytest.mark.parametrize('radius', [0.2, 0.45, 0.8, 3.0])
def test_the_footprint_is_a_regular_16_gon_on_the_radius(radius):
    message = footprint_message(radius, 'robot_0/base_link')
    assert message.header.frame_id == 'robot_0/base_link'
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


@pytest.mark.parametrize('points, fault', [
    ([], 'footprint has no vertices'),
    ([(0.3, 0.0), (float('nan'), 0.1)], 'footprint has a non-finite vertex'),
    ([(float('inf'), 0.0)], 'footprint has a non-finite vertex'),
    ([(0.0, 0.0), (0.0, 0.0)], r'footprint radius must be > 0, got 0\.0')])
def test_an_unusable_footprint_is_named(points, fault):
    with pytest.raises(ValueError, match=f'^{fault}'):
        radius_of_footprint(polygon(points))


@pytest.mark.parametrize('radius', [0.0, -0.3, float('nan'), float('inf')])
def test_no_footprint_message_of_an_unusable_radius(radius):
    with pytest.raises(ValueError, match='^footprint radius must be finite and > 0'):
        footprint_message(radius, 'robot_0/base_link')


@pytest.mark.parametrize('share', [0.0, 0.5, 0.25, 0.999])
def test_shares_round_trip(share):
    message = share_message(share)
    assert isinstance(message, Float32)
    assert share_of(message) == pytest.approx(share, rel=1e-7)


@pytest.mark.parametrize('share', [-0.1, 1.0, 2.0, float('nan'), float('inf')])
def test_a_share_outside_zero_one_is_named(share):
    with pytest.raises(ValueError, match=r'^avoidance share must be in \[0, 1\), got '):
        share_of(Float32(data=share))
    with pytest.raises(ValueError, match=r'^avoidance share must be in \[0, 1\), got '):
        share_message(share)


def test_announcements_are_latched():
    assert ANNOUNCEMENT_QOS.reliability == ReliabilityPolicy.RELIABLE
    assert ANNOUNCEMENT_QOS.durability == DurabilityPolicy.TRANSIENT_LOCAL
    assert (ANNOUNCEMENT_QOS.history, ANNOUNCEMENT_QOS.depth) == (HistoryPolicy.KEEP_LAST, 1)

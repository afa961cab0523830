"""Occupancy grids as messages, and the static world's markers."""

import math

import numpy as np
import pytest
from rclpy.serialization import deserialize_message, serialize_message
from visualization_msgs.msg import Marker

from prvo_msgs_util import (
    MessageFault,
    make_occupancy_grid,
    make_static_world_markers,
    occupancy_grid_arrays,
)


def received(message):
    return deserialize_message(serialize_message(message), type(message))


def test_a_grid_goes_through_a_message_unchanged():
    cells = np.array([[0, 100, -1], [50, 0, 100]], dtype=np.int8)
    message = received(make_occupancy_grid(cells, 0.05, (-1.5, 2.25), 3.0))
    assert message.header.frame_id == 'map'
    assert (message.info.width, message.info.height) == (3, 2)
    # Row-major from row 0 (the lowest y): as nav_msgs/OccupancyGrid states.
    assert list(message.data) == [0, 100, -1, 50, 0, 100]
    back, resolution, origin = occupancy_grid_arrays(message)
    assert np.array_equal(back, cells) and back.dtype == np.int8
    assert resolution == pytest.approx(0.05)
    assert origin.tolist() == [-1.5, 2.25]


def _grid(**changes):
    message = make_occupancy_grid(np.zeros((2, 3), dtype=np.int8), 0.1, (0.0, 0.0))
    for name, value in changes.items():
        target, _, field = name.rpartition('__')
        owner = message
        for part in target.split('__') if target else ():
            owner = getattr(owner, part)
        setattr(owner, field, value)
    return message


@pytest.mark.parametrize('message, named', [
    (_grid(data=[0] * 5), 'data holds 5 cells, info.width x info.height is 3 x 2 = 6'),
    (_grid(header__frame_id='odom'), "header.frame_id is 'odom', expected 'map'"),
    (_grid(info__resolution=0.0), 'info.resolution must be a positive'),
    (_grid(info__resolution=math.nan), 'info.resolution must be a positive'),
    (_grid(info__width=0, data=[]), 'an empty grid'),
    (_grid(data=[0, 0, 0, 0, 0, -5]), 'values from -5 to 0'),
    (_grid(info__origin__position__x=math.inf), 'info.origin.position'),
    (_grid(info__origin__orientation__z=0.5), 'info.origin.orientation must be the identity'),
])
def test_a_bad_grid_is_a_named_fault(message, named):
    with pytest.raises(MessageFault) as raised:
        occupancy_grid_arrays(received(message))
    assert named in str(raised.value)


def test_any_frame_when_none_is_expected():
    cells, _, _ = occupancy_grid_arrays(_grid(header__frame_id='odom'), expected_frame=None)
    assert cells.shape == (2, 3)


def test_static_world_markers():
    walls = [(np.array([[0.0, 0.0], [3.0, 4.0]]), 0.2), (np.array([[1.0, 1.0], [1.0, 2.0]]), 0.0)]
    discs = [(np.array([2.0, -1.0]), 0.5)]
    polygons = [np.array([[0.0, 0.0], [1.0, 0.0], [0.0, 1.0]])]
    markers = make_static_world_markers(0.0, 'map', walls, discs, polygons).markers
    assert markers[0].action == Marker.DELETEALL
    wall, thin, disc, polygon = markers[1:]
    assert [marker.id for marker in markers[1:]] == [0, 1, 2, 3]
    assert wall.type == Marker.CUBE
    assert (wall.pose.position.x, wall.pose.position.y) == pytest.approx((1.5, 2.0))
    # Along the segment (length 5) plus its thickness; turned by atan2(4, 3).
    assert (wall.scale.x, wall.scale.y) == pytest.approx((5.2, 0.2))
    assert 2.0 * math.atan2(wall.pose.orientation.z, wall.pose.orientation.w) == pytest.approx(
        math.atan2(4.0, 3.0))
    assert thin.scale.y > 0.0
    assert disc.type == Marker.CYLINDER and disc.scale.x == pytest.approx(1.0)
    assert polygon.type == Marker.LINE_STRIP
    assert [(point.x, point.y) for point in polygon.points] == [
        (0.0, 0.0), (1.0, 0.0), (0.0, 1.0), (0.0, 0.0)]

"""The static world's markers for RViz: walls, discs, polygons."""

import math

import numpy as np
import pytest
from visualization_msgs.msg import Marker

from prvo_msgs_util import make_static_world_markers


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

"""Occupancy grids and routes as messages: what a subscriber receives, and the faults named."""

import math

from nav_msgs.msg import Path
import numpy as np
import pytest
from rclpy.serialization import deserialize_message, serialize_message

from prvo_msgs_util import MessageFault, make_occupancy_grid, make_path, occupancy_grid_to_parts


def received(message):
    return deserialize_message(serialize_message(message), type(message))


def grid_message(seed=0, height=7, width=5):
    rng = np.random.default_rng(seed)
    cells = rng.choice(np.array([-1, 0, 12, 65, 100], dtype=np.int8), size=(height, width))
    return cells, make_occupancy_grid(3.25, cells, 0.05, [-1.5, 2.25])


def test_a_grid_arrives_as_it_was_sent_row_0_at_the_bottom():
    cells, message = grid_message()
    message = received(message)
    assert (message.info.width, message.info.height) == (5, 7)
    # Row-major, row 0 first: cell (row 1, column 0) is the sixth value.
    assert message.data[5] == cells[1, 0]
    got, resolution, origin = occupancy_grid_to_parts(message)
    np.testing.assert_array_equal(got, cells)
    assert got.dtype == np.int8
    # The message carries the resolution as float32.
    assert resolution == float(np.float32(0.05))
    np.testing.assert_array_equal(origin, [-1.5, 2.25])
    assert message.header.frame_id == 'map'
    assert message.header.stamp.sec == 3 and message.header.stamp.nanosec == 250_000_000


def faulty(change):
    _, message = grid_message()
    change(message)
    return message


def turned(message, yaw):
    message.info.origin.orientation.z = math.sin(yaw / 2.0)
    message.info.origin.orientation.w = math.cos(yaw / 2.0)


@pytest.mark.parametrize('change, named', [
    (lambda m: setattr(m.header, 'frame_id', 'odom'), "header.frame_id is 'odom'"),
    (lambda m: setattr(m.info, 'width', 6), 'data has 35 cells, expected'),
    (lambda m: setattr(m, 'data', m.data[:-1]), 'data has 34 cells'),
    (lambda m: (setattr(m.info, 'width', 0), setattr(m, 'data', [])), 'an empty grid'),
    (lambda m: setattr(m.info, 'resolution', 0.0), 'info.resolution'),
    (lambda m: setattr(m.info, 'resolution', math.nan), 'info.resolution'),
    (lambda m: turned(m, 0.1), 'info.origin.orientation must be the identity'),
    (lambda m: turned(m, math.pi), 'info.origin.orientation must be the identity'),
    (lambda m: setattr(m.info.origin.position, 'x', math.inf), 'info.origin.position'),
    (lambda m: m.data.__setitem__(3, -7), 'data must be -1 (unknown) or 0-100, got -7'),
    (lambda m: m.data.__setitem__(3, 101), 'got 101'),
])
def test_a_grid_the_planner_cannot_use_is_refused_naming_the_fault(change, named):
    with pytest.raises(MessageFault, match=named.replace('(', r'\(').replace(')', r'\)')):
        occupancy_grid_to_parts(faulty(change))


def test_an_origin_turned_by_a_float_round_off_is_not_turned():
    _, message = grid_message()
    turned(message, 1e-9)
    occupancy_grid_to_parts(message)
    message.info.origin.orientation.w = -1.0
    message.info.origin.orientation.z = 0.0
    occupancy_grid_to_parts(message)


def test_a_route_is_a_path_of_its_waypoints_in_map():
    waypoints = np.array([[0.0, 0.5], [1.25, -2.0], [3.0, 4.0]])
    message = received(make_path(7.5, waypoints))
    assert isinstance(message, Path) and message.header.frame_id == 'map'
    np.testing.assert_array_equal(
        [[pose.pose.position.x, pose.pose.position.y] for pose in message.poses], waypoints)
    assert all(pose.header.frame_id == 'map' and pose.pose.orientation.w == 1.0
               for pose in message.poses)
    assert len(received(make_path(0.0, ())).poses) == 0

"""Occupancy grids as messages: numpy cells to nav_msgs/OccupancyGrid and back."""

import math

from nav_msgs.msg import OccupancyGrid
import numpy as np

from prvo_msgs_util.conversions import (
    MAX_WORLD_COORDINATE,
    MessageFault,
    check_world_point,
    seconds_to_stamp,
)
from prvo_msgs_util.topics import WORLD_FRAME

# A map whose origin is turned by more than this [rad] is not axis-aligned: refused.
_MAX_ORIGIN_YAW = 1e-9


def make_occupancy_grid(cells, resolution, origin, stamp_seconds=0.0, frame_id=WORLD_FRAME):
    """Return the nav_msgs/OccupancyGrid of CELLS (H, W) int8, row 0 at the smallest y.

    RESOLUTION is a cell's edge [m], ORIGIN (2,) the world position of cell (0, 0)'s
    lower-left corner [m]; the grid is axis-aligned (identity orientation), its load time and
    header stamp STAMP_SECONDS.
    """
    cells = np.asarray(cells)
    message = OccupancyGrid()
    message.header.frame_id = frame_id
    message.header.stamp = seconds_to_stamp(stamp_seconds)
    info = message.info
    info.map_load_time = seconds_to_stamp(stamp_seconds)
    info.resolution = float(resolution)
    info.height, info.width = (int(size) for size in cells.shape)
    info.origin.position.x, info.origin.position.y = (float(value) for value in origin)
    info.origin.orientation.w = 1.0
    message.data = np.ascontiguousarray(cells, dtype=np.int8).ravel().tolist()
    return message


def occupancy_grid_arrays(message, expected_frame=WORLD_FRAME):
    """Return (cells (H, W) int8, resolution, origin (2,)) of a nav_msgs/OccupancyGrid.

    Raises MessageFault naming the field when the frame is not EXPECTED_FRAME (None: any),
    the data's length is not width x height, the grid is empty, a value is outside -1..100,
    the resolution is not a positive finite number, the origin is not finite or turned.
    Resolution and origin are as the message holds them (single-precision resolution).
    """
    frame = message.header.frame_id
    if expected_frame is not None and frame != expected_frame:
        raise MessageFault(f'header.frame_id is {frame!r}, expected {expected_frame!r}')
    info = message.info
    width, height = int(info.width), int(info.height)
    if width == 0 or height == 0:
        raise MessageFault(f'info.width x info.height is {width} x {height}: an empty grid')
    if len(message.data) != width * height:
        raise MessageFault(f'data holds {len(message.data)} cells, info.width x info.height '
                           f'is {width} x {height} = {width * height}')
    resolution = float(info.resolution)
    if not (math.isfinite(resolution) and resolution > 0.0):
        raise MessageFault(f'info.resolution must be a positive number of metres, got '
                           f'{resolution!r}')
    position = info.origin.position
    origin = np.array([position.x, position.y], dtype=float)
    check_world_point(origin, 'info.origin.position')
    if abs(position.z) > MAX_WORLD_COORDINATE or not math.isfinite(position.z):
        raise MessageFault(f'info.origin.position.z is {position.z!r}')
    orientation = info.origin.orientation
    yaw = 2.0 * math.atan2(orientation.z, orientation.w)
    if (not all(math.isfinite(value) for value in (orientation.x, orientation.y, orientation.z,
                                                  orientation.w))
            or abs(orientation.x) > 1e-9 or abs(orientation.y) > 1e-9
            or abs(math.remainder(yaw, 2.0 * math.pi)) > _MAX_ORIGIN_YAW):
        raise MessageFault('info.origin.orientation must be the identity (an axis-aligned '
                           f'grid), got ({orientation.x}, {orientation.y}, {orientation.z}, '
                           f'{orientation.w})')
    cells = np.asarray(message.data, dtype=np.int8).reshape(height, width)
    if ((cells < -1) | (cells > 100)).any():
        raise MessageFault(f'data holds values from {int(cells.min())} to {int(cells.max())}, '
                           'not only -1 (unknown) and 0-100')
    return cells, resolution, origin

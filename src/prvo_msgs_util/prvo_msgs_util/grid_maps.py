"""Occupancy grids and routes as messages: nav_msgs/OccupancyGrid and nav_msgs/Path.

A grid travels as its parts, (cells, resolution, origin) in the conventions of
``prvo_planner.maps.GridMap``: ``cells`` (height, width) int8, row 0 at the smallest y, values
-1 (unknown) or 0-100; ``origin`` the world position of cell (0, 0)'s lower-left corner.
"""

import array
import math

from geometry_msgs.msg import PoseStamped
from nav_msgs.msg import OccupancyGrid, Path
import numpy as np

from prvo_msgs_util.conversions import (
    MessageFault,
    _check_frame,
    check_world_point,
    seconds_to_stamp,
)
from prvo_msgs_util.topics import WORLD_FRAME

# An origin turned by less than this [rad] about z is axis-aligned (float32 round trips of a
# zero yaw stay far below it).
_ORIGIN_YAW_TOLERANCE = 1e-6


def occupancy_grid_to_parts(msg, expected_frame=WORLD_FRAME):
    """
    Return the (cells, resolution, origin) of a nav_msgs/OccupancyGrid.

    Parameters
    ----------
    msg : nav_msgs.msg.OccupancyGrid
        The grid: row-major data, ``info.origin`` the pose of cell (0, 0)'s corner.
    expected_frame : str
        The frame the grid must be in.

    Returns
    -------
    tuple
        ``cells`` (height, width) int8 (a copy), ``resolution`` [m] and ``origin`` (2,) [m].

    Raises
    ------
    MessageFault
        For another frame, an empty grid, data of another length than width * height, a
        resolution that is not a positive number, an origin turned about z (or tilted), a
        non-finite origin or a cell value other than -1 or 0-100.

    """
    _check_frame(msg.header.frame_id, expected_frame, 'header.frame_id')
    info = msg.info
    width, height = int(info.width), int(info.height)
    if width == 0 or height == 0:
        raise MessageFault(f'info.width x info.height is {width} x {height}: an empty grid')
    if len(msg.data) != width * height:
        raise MessageFault(f'data has {len(msg.data)} cells, expected info.width x info.height '
                           f'= {width * height} ({width} x {height})')
    resolution = float(info.resolution)
    if not (math.isfinite(resolution) and resolution > 0.0):
        raise MessageFault(f'info.resolution must be a positive number of metres ({resolution})')
    position, orientation = info.origin.position, info.origin.orientation
    check_world_point((position.x, position.y), 'info.origin.position')
    quaternion = (orientation.x, orientation.y, orientation.z, orientation.w)
    norm = math.hypot(*quaternion)
    if not (math.isfinite(norm) and norm > 0.0) or max(
            abs(value) for value in quaternion[:3]) > 0.5 * _ORIGIN_YAW_TOLERANCE * norm:
        raise MessageFault('info.origin.orientation must be the identity: a turned grid is not '
                           f'supported ({[float(value) for value in quaternion]})')
    cells = np.array(msg.data, dtype=np.int8).reshape(height, width)
    if ((cells < -1) | (cells > 100)).any():
        bad = cells[(cells < -1) | (cells > 100)]
        raise MessageFault(f'data must be -1 (unknown) or 0-100, got {int(bad[0])}')
    return cells, resolution, np.array([position.x, position.y])


def make_occupancy_grid(stamp_seconds, cells, resolution, origin, frame_id=WORLD_FRAME):
    """
    Return the nav_msgs/OccupancyGrid of a grid's parts.

    Parameters
    ----------
    stamp_seconds : float
        The header's stamp [s], also the map's load time.
    cells : numpy.ndarray
        Shape (height, width), values -1 or 0-100.
    resolution : float
        Cell edge [m].
    origin : array_like
        Shape (2,): world position of cell (0, 0)'s lower-left corner [m].
    frame_id : str
        The grid's frame.

    """
    cells = np.asarray(cells, dtype=np.int8)
    msg = OccupancyGrid()
    msg.header.stamp = seconds_to_stamp(stamp_seconds)
    msg.header.frame_id = frame_id
    msg.info.map_load_time = msg.header.stamp
    msg.info.resolution = float(resolution)
    msg.info.height, msg.info.width = (int(size) for size in cells.shape)
    msg.info.origin.position.x, msg.info.origin.position.y = (float(value) for value in origin)
    msg.info.origin.orientation.w = 1.0
    msg.data = array.array('b', cells.ravel().tobytes())
    return msg


def make_path(stamp_seconds, waypoints, frame_id=WORLD_FRAME):
    """Return the nav_msgs/Path through WAYPOINTS (K, 2) [m], poses of identity orientation."""
    msg = Path()
    msg.header.stamp = seconds_to_stamp(stamp_seconds)
    msg.header.frame_id = frame_id
    for x, y in np.asarray(waypoints, dtype=float).reshape(-1, 2):
        pose = PoseStamped()
        pose.header = msg.header
        pose.pose.position.x, pose.pose.position.y = float(x), float(y)
        pose.pose.orientation.w = 1.0
        msg.poses.append(pose)
    return msg

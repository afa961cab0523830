"""
Following a path with a carrot: the lookahead point of pure pursuit, ROS-free.

A path is a polyline of waypoints (K, 2) in the world frame. The carrot is where the path leaves
the circle of radius ``lookahead`` around the robot, searched from the robot's progress along the
path onward, so a path that loops back near the robot never pulls it backward.
"""

import numpy as np


def closest_on_path(path, position, start_segment=0):
    """
    Return the segment index and point of the path closest to ``position``.

    Parameters
    ----------
    path : numpy.ndarray
        Waypoints, shape (K, 2), K >= 1.
    position : array_like
        Robot position, shape (2,).
    start_segment : int
        First segment searched (the progress so far); segment ``i`` joins waypoints ``i`` and
        ``i + 1``.

    Returns
    -------
    tuple of (int, numpy.ndarray)
        The segment index (0 for a single waypoint) and the closest point, shape (2,).

    """
    path = np.asarray(path, dtype=float)
    position = np.asarray(position, dtype=float)
    if len(path) == 1:
        return 0, path[0].copy()
    starts = path[start_segment:-1]
    steps = path[start_segment + 1:] - starts
    lengths_squared = np.einsum('ij,ij->i', steps, steps)
    along = np.einsum('ij,ij->i', position - starts, steps)
    fractions = np.clip(np.divide(along, lengths_squared, out=np.zeros_like(along),
                                  where=lengths_squared > 0.0), 0.0, 1.0)
    points = starts + fractions[:, None] * steps
    distances = np.linalg.norm(points - position, axis=1)
    best = int(np.argmin(distances))
    return start_segment + best, points[best]


def carrot(path, position, lookahead, start_segment=0):
    """
    Return the lookahead point on a path and the segment the robot has reached.

    The carrot is the first point beyond the robot's closest point at which the path crosses
    the circle of radius ``lookahead`` around the robot (the path-circle intersection of pure
    pursuit); the path's last waypoint when the rest of the path lies inside the circle; the
    closest point itself when the robot is farther than ``lookahead`` from the path, so that it
    heads back to the path first.

    Parameters
    ----------
    path : numpy.ndarray
        Waypoints, shape (K, 2), K >= 1.
    position : array_like
        Robot position, shape (2,).
    lookahead : float
        Lookahead distance [m], positive.
    start_segment : int
        The segment reached so far (progress never goes backward).

    Returns
    -------
    tuple of (numpy.ndarray, int)
        The carrot, shape (2,), and the segment index of the robot's closest point.

    """
    path = np.asarray(path, dtype=float)
    position = np.asarray(position, dtype=float)
    segment, closest = closest_on_path(path, position, start_segment)
    if np.linalg.norm(closest - position) >= lookahead:
        return closest, segment
    start = closest
    for index in range(segment, len(path) - 1):
        end = path[index + 1]
        if np.linalg.norm(end - position) >= lookahead:
            step = end - start
            offset = start - position
            a = step @ step
            b = offset @ step
            c = offset @ offset - lookahead * lookahead
            # start is inside the circle and end is not, so the larger root lies in [0, 1].
            fraction = (-b + np.sqrt(max(b * b - a * c, 0.0))) / a
            return start + min(max(fraction, 0.0), 1.0) * step, segment
        start = end
    return path[-1].copy(), segment

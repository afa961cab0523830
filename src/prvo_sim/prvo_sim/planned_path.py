"""A stand-in for Nav2's planner_server, without ROS: a robot's route as the poses of a path.

planner_server publishes its global planner's plan as a `nav_msgs/Path` in the map frame, a
pose every costmap cell along the way. The stand-in publishes a given route that way: its
waypoints joined by straight segments, each segment sampled every `spacing` [m] or closer
(evenly, its ends included), so that a planner following it sees a path as dense as Nav2's.
It knows nothing of other robots: keeping them apart is the planner's work, in `path` mode.
A route that changes is published again; an unchanged one is not.
"""

import math

import numpy as np

# planner_server's poses lie a costmap cell apart: Nav2's default resolution [m].
SPACING = 0.05


def path_poses(waypoints, spacing=SPACING):
    """Return the positions (P, 2) of the poses of the path through WAYPOINTS (K, 2).

    Each segment of length L becomes ceil(L / SPACING) equal steps, ending at its waypoint
    exactly; a segment of length 0 adds no pose, so the poses never repeat a position in a row.
    Raises ValueError naming what is wrong with WAYPOINTS (not (K, 2) with K >= 1, not finite)
    or SPACING (not finite and > 0).
    """
    waypoints = np.asarray(waypoints, dtype=float)
    if waypoints.ndim != 2 or waypoints.shape[1] != 2 or len(waypoints) == 0:
        raise ValueError(f'route must be waypoints of shape (K, 2), K >= 1, got shape '
                         f'{waypoints.shape}')
    if not np.all(np.isfinite(waypoints)):
        raise ValueError('route waypoints must be finite')
    if not (math.isfinite(spacing) and spacing > 0.0):
        raise ValueError(f'spacing must be finite and > 0, got {spacing!r}')
    poses = [waypoints[:1]]
    for start, end in zip(waypoints[:-1], waypoints[1:], strict=True):
        length = float(np.hypot(*(end - start)))
        if length == 0.0:
            continue
        steps = math.ceil(length / spacing)
        fractions = np.arange(1, steps)[:, None] / steps
        # The waypoint itself ends the segment: the path passes through it exactly.
        poses += [start + fractions * (end - start), end[None]]
    return np.concatenate(poses)


def pose_count(waypoints, spacing=SPACING):
    """Return how many poses `path_poses(WAYPOINTS, SPACING)` has, without making them."""
    lengths = np.hypot(*np.diff(np.asarray(waypoints, dtype=float), axis=0).T)
    return 1 + int(np.ceil(lengths[lengths > 0.0] / spacing).sum())


class PlannedPath:
    """The path one robot is given: the poses of its route, published when they change."""

    def __init__(self, spacing=SPACING):
        self.spacing = float(spacing)
        self.poses = None

    def replan(self, waypoints):
        """Take the route WAYPOINTS (K, 2); return its poses (P, 2) if they changed, else None.

        Raises ValueError as `path_poses` does; the path in force then stays.
        """
        poses = path_poses(waypoints, self.spacing)
        if self.poses is not None and np.array_equal(poses, self.poses):
            return None
        self.poses = poses
        return poses

"""
Narrow passages: how wide the way ahead of a stalled robot is, and whether it can be certified.

A robot that holds in front of a door narrower than its walls' conditions can certify
(`core.walls.certifiable_width`) would otherwise stand there without saying why. When the stall
monitor finds the robot stalled, the agent measures the clear width across its preferred
direction at points up to LOOKAHEAD ahead (the free distance to the left plus to the right,
each found by stepping STEP out to at most REACH); where the narrowest is below the width the
planner needs, the stall is reported with both. ROS-free: the planner node and the in-process
engine report the same.
"""

from dataclasses import dataclass

import numpy as np

from prvo_planner.core.walls import certifiable_width, segment_distances

# How far ahead along the preferred direction the narrowest point is searched for [m].
LOOKAHEAD = 1.0
# How far to each side an obstacle bounds a passage [m]: farther, the way is open.
REACH = 2.0
# Spacing of the points sampled along the way and across it [m]: the widths' resolution.
STEP = 0.02


@dataclass(frozen=True)
class NarrowPassage:
    """
    A passage too narrow to certify.

    `point` (2,) [m] is where it is narrowest ahead of the robot, `width` its clear width there
    [m] and `needed` the width the planner needs (`certifiable_width`) [m].
    """

    point: np.ndarray
    width: float
    needed: float


def _clearances(obstacles, points):
    """Return the distance of POINTS (P, 2) from the surface of the nearest obstacle, (P,)."""
    distances = [np.full(len(points), np.inf)]
    if len(obstacles.segments):
        distances.append(np.min(segment_distances(
            points[:, None], obstacles.segments[None, :, 0], obstacles.segments[None, :, 1])
            - obstacles.half_widths[None], axis=1))
    if len(obstacles.disc_centres):
        distances.append(np.min(np.linalg.norm(
            points[:, None] - obstacles.disc_centres[None], axis=-1)
            - obstacles.disc_radii[None], axis=1))
    return np.min(distances, axis=0)


def clear_width(obstacles, point, direction):
    """
    Return the clear width across DIRECTION at POINT [m]: inf where a side is open.

    The free distance to the left plus the free distance to the right, each to the first of
    the points spaced STEP apart (at most REACH out) within half a step of an obstacle's
    surface (the width to within a step); 0 for a point inside an obstacle.
    """
    point = np.asarray(point, dtype=float)
    if _clearances(obstacles, point[None])[0] <= 0.0:
        return 0.0
    across = np.array([-direction[1], direction[0]]) / np.hypot(*direction)
    steps = np.arange(1, int(round(REACH / STEP)) + 1) * STEP
    width = 0.0
    for side in (across, -across):
        # Within half a step of a surface: a map's walls are boundaries without thickness,
        # which a step could jump over.
        blocked = np.flatnonzero(
            _clearances(obstacles, point + steps[:, None] * side) <= 0.5 * STEP)
        if blocked.size == 0:
            return np.inf
        width += steps[blocked[0]]
    return float(width)


def narrow_passage(obstacles, ego, config, direction):
    """
    Return the `NarrowPassage` ahead of EGO along DIRECTION, or None where it can be certified.

    OBSTACLES are the `StaticObstacles` near the robot, EGO its `AgentBelief` (mean position,
    covariance, planning radius) and CONFIG the `PlannerConfig` it plans with. The narrowest
    finite clear width over the points up to LOOKAHEAD ahead is compared with
    `certifiable_width`: a narrower passage is returned, with both widths.
    """
    if not np.any(direction):
        return None
    unit = np.asarray(direction, dtype=float) / np.hypot(*direction)
    ahead = ego.position + np.arange(0.0, LOOKAHEAD + 0.5 * STEP, STEP)[:, None] * unit
    widths = np.array([clear_width(obstacles, point, unit) for point in ahead])
    # A point inside an obstacle (past the end of the way) bounds no passage.
    widths[widths <= 0.0] = np.inf
    narrowest = int(np.argmin(widths))
    needed = certifiable_width(ego, config)
    if not np.isfinite(widths[narrowest]) or widths[narrowest] >= needed:
        return None
    return NarrowPassage(point=ahead[narrowest], width=float(widths[narrowest]), needed=needed)

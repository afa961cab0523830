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


def way_width(obstacles, point, direction, length):
    """
    Return the clear width of the way from POINT, LENGTH [m] along DIRECTION: a straight strip.

    The sum of `way_sides`.
    """
    left, right = way_sides(obstacles, point, direction, length)
    return left + right


def way_sides(obstacles, point, direction, length):
    """
    Return (left, right) [m]: the clear way from POINT, LENGTH [m] along DIRECTION, each side.

    The free distance to the left of the line from POINT (2,) along DIRECTION (2,) nonzero,
    the least over the way, and the same to the right, over the obstacles of OBSTACLES
    (`StaticObstacles`) beside the way (those whose extent along it overlaps [0, LENGTH]): inf
    where a side is open all along, both 0 where an obstacle reaches the line. Together the
    widest strip along the way that no obstacle enters; unlike `clear_width` at a few points,
    it does not step over a wall thinner than their spacing (a door's jambs). A wall's ends
    are counted a half-width early (a conservative width, by at most the half-width).
    """
    unit = np.asarray(direction, dtype=float) / np.hypot(*direction)
    left = np.array([-unit[1], unit[0]])
    point = np.asarray(point, dtype=float)
    sides = [np.inf, np.inf]
    if len(obstacles.segments):
        relative = obstacles.segments - point
        along, across = relative @ unit, relative @ left
        grown = obstacles.half_widths
        # The part of each segment whose position along the way is within the way, widened
        # by the segment's half-width at either end.
        start, end = along[:, 0], along[:, 1]
        span = end - start
        low, high = -grown, length + grown
        with np.errstate(divide='ignore', invalid='ignore'):
            first = np.where(span != 0.0, (low - start) / span, -np.inf)
            second = np.where(span != 0.0, (high - start) / span, np.inf)
        enter = np.clip(np.minimum(first, second), 0.0, 1.0)
        leave = np.clip(np.maximum(first, second), 0.0, 1.0)
        level = span == 0.0
        overlaps = np.where(level, (start >= low) & (start <= high), enter < leave)
        # (A segment across the way, level, is taken whole: enter 0, leave 1.)
        across_enter = across[:, 0] + enter * (across[:, 1] - across[:, 0])
        across_leave = across[:, 0] + leave * (across[:, 1] - across[:, 0])
        nearest = np.minimum(np.abs(across_enter), np.abs(across_leave)) - grown
        if np.any(overlaps & ((across_enter * across_leave <= 0.0) | (nearest <= 0.0))):
            return 0.0, 0.0
        _narrow_sides(sides, overlaps, across_enter, nearest)
    if len(obstacles.disc_centres):
        relative = obstacles.disc_centres - point
        along, across = relative @ unit, relative @ left
        radii = obstacles.disc_radii
        # A disc's nearest point within the way: its chord at the way's end beyond its centre.
        beyond = np.maximum(np.maximum(-along, along - length), 0.0)
        overlaps = beyond < radii
        nearest = np.abs(across) - np.sqrt(np.maximum(radii ** 2 - beyond ** 2, 0.0))
        if np.any(overlaps & (nearest <= 0.0)):
            return 0.0, 0.0
        _narrow_sides(sides, overlaps, across, nearest)
    return float(sides[0]), float(sides[1])


def _narrow_sides(sides, overlaps, across, nearest):
    """Lower SIDES [left, right] [m] to the NEAREST (K,) of the OVERLAPS (K,) on each side.

    ACROSS (K,) [m]: each obstacle's offset to the left of the way (negative: to the right).
    """
    for index, sign in enumerate((1.0, -1.0)):
        on_side = overlaps & (sign * across > 0.0)
        if np.any(on_side):
            sides[index] = min(sides[index], float(np.min(nearest[on_side])))


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

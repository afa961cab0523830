"""
The side on which two robots pass each other, decided once per encounter.

With ``r`` the neighbour's position relative to the robot and ``u`` the robot's velocity
relative to the neighbour's, the pair passes with the neighbour on the robot's left when
``r x u < 0`` (the relative motion goes to the right of the line between them) and on its right
when ``r x u > 0``. The neighbour sees ``-r`` and ``-u``: the same sign, so both robots of a pair
read the same side from the same states. An encounter begins when the pair, moving on as it
does, would come within a few combined radii of each other within the time horizon; its side is
the one the relative motion already takes, or, when that is too close to call, the common rule:
pass on the right (each keeps the other on its left). It is held until the pair moves apart.
"""

import math

import numpy as np

# Sides, as the sign of r x u.
KEEP_LEFT = -1
KEEP_RIGHT = 1
# An encounter begins when the closest approach comes within this many combined radii.
ENGAGE_RADII = 2.0
# A miss distance below this fraction of the combined radius is too close to call: the common
# rule decides.
TIE_FRACTION = 0.25


def closest_approach(position, velocity):
    """
    Return (time [s], signed miss distance [m]) of the closest approach of a pair.

    POSITION ``r`` (2,) is the neighbour's relative to the robot, VELOCITY ``u`` (2,) the
    robot's relative to the neighbour's. The miss distance is ``(r x u) / |u|``: negative when
    the neighbour passes on the robot's left. The time is ``inf`` when the pair does not move
    relative to each other.
    """
    speed_sq = velocity[0] * velocity[0] + velocity[1] * velocity[1]
    if speed_sq <= 1e-18:
        return math.inf, math.hypot(position[0], position[1])
    cross = position[0] * velocity[1] - position[1] * velocity[0]
    return ((position[0] * velocity[0] + position[1] * velocity[1]) / speed_sq,
            cross / math.sqrt(speed_sq))


def encounter_side(position, velocity, radius, horizon):
    """
    Return the side a pair takes if its encounter begins now, None if no encounter begins.

    POSITION and VELOCITY as in :func:`closest_approach`; RADIUS the combined radius [m],
    HORIZON [s] the time within which an approach counts. The side is ``KEEP_LEFT`` (the
    neighbour passes on the robot's left) or ``KEEP_RIGHT``.
    """
    time, miss = closest_approach(position, velocity)
    if not 0.0 < time <= horizon or abs(miss) >= ENGAGE_RADII * radius:
        return None
    if abs(miss) < TIE_FRACTION * radius:
        return KEEP_LEFT
    return KEEP_LEFT if miss < 0.0 else KEEP_RIGHT


def separating(position, velocity):
    """Whether the pair moves apart (``r . u <= 0``): its encounter is over."""
    return position[0] * velocity[0] + position[1] * velocity[1] <= 0.0


def passing_direction(position, side):
    """
    Return the unit direction whose left the passing bias charges, to hold SIDE, shape (2,).

    Keeping the neighbour on the left means not moving to the left of the line towards it:
    the direction is ``r``'s; keeping it on the right, the opposite.
    """
    direction = np.asarray(position, dtype=float) / math.hypot(position[0], position[1])
    return direction if side == KEEP_LEFT else -direction

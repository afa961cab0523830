"""
Pass beside: a robot on its way aims beside a neighbour that stands on it, no ROS.

A robot at its goal, or aside for another, announces no share of the avoidance
(`agent.PlannerAgent.own_announcement`) and steps off a passing neighbour's route only as far as
its room allows (`give_way`): against a wall where one side of the route has one, leaving the
passer the other side. The passer, following its route straight at the standing robot, counted
on it to back away; in a pocket at a corridor's end the standing one backed along the wall, away
from its goal and onto the passer's, and both turned round to face each other (`corridor8` as
shipped, seed 8: a stall of 13.7 s; docs/results.md, 3.19 and 3.20). A person walks round
someone who stands in the way; so does a robot here.

Where a neighbour that stands (it announces no share, or is within `AT_GOAL` of the end of the
route it publishes, `at_goal`) is ahead on the robot's way, within `RANGE` of it and nearer the
way than the two radii and `give_way.GAP`, the robot heads for the point beside
that neighbour at that distance, on the side away from it (to the way's right where it stands on
the way), or on the other side where the map leaves no room on that one: the side the neighbour,
stepping toward its wall, leaves open. The nearest such neighbour along the way decides; once it
is abreast, the route leads again. A neighbour that stands where the way ends (beside the
robot's goal) is not gone round: the robot cannot arrive without it making room.

Only the preferred velocity changes: the chance constraints against robots and walls, and so the
guarantee, are those of every plan.
"""

import math

import numpy as np

from prvo_planner.give_way import GAP, closest_on_route

# Neighbours farther ahead than this [m, straight] are not gone round yet: the route leads until
# a robot comes near one that stands on it.
RANGE = 3.0
# A neighbour this near the end of the route it publishes [m] (its goal) stands, whatever share
# it announces: at its goal, arriving, or stepping aside from it (`give_way`), it goes nowhere.
AT_GOAL = 0.5


def at_goal(position, route):
    """Whether a neighbour at POSITION (2,) [m] is within AT_GOAL of its ROUTE's end.

    ROUTE is the `routes.NeighbourRoute` it publishes, None: none.
    """
    return route is not None and math.hypot(route.end[0] - position[0],
                                            route.end[1] - position[1]) < AT_GOAL


def pass_beside(position, v_pref, way, radius, standing, room):
    """
    Return V_PREF (2,) [m/s] itself, or the same speed toward the point beside a standing one.

    POSITION (2,) [m] is the robot's, of RADIUS [m]; WAY (K, 2) [m], K >= 2, the part of its
    route ahead of it (`give_way.way_ahead`); STANDING a sequence of (position (2,), radius) of
    the neighbours that announce no share; ROOM(start (2,), end (2,)) -> bool whether the robot
    fits along the straight way between the two points (the map's cells that keep its
    clearance), None: open space.
    """
    speed = math.hypot(*v_pref)
    if speed <= 0.0 or len(way) < 2:
        return v_pref
    ahead = []
    for other, other_radius in standing:
        offset = other - position
        if math.hypot(*offset) > RANGE:
            continue
        nearest, direction, index = closest_on_route(way, other)
        if not direction.any() or np.array_equal(nearest, way[-1]):
            continue
        lateral = direction[0] * (other - nearest)[1] - direction[1] * (other - nearest)[0]
        needed = radius + other_radius + GAP
        if abs(lateral) >= needed or offset @ direction <= 0.0:
            continue
        travelled = (sum(math.hypot(*(way[k + 1] - way[k])) for k in range(index))
                     + math.hypot(*(nearest - way[index])))
        ahead.append((travelled, other, direction, lateral, needed))
    if not ahead:
        return v_pref
    _, other, direction, lateral, needed = min(ahead, key=lambda item: item[0])
    left = np.array([-direction[1], direction[0]])
    # Away from the neighbour; to the way's right where it stands on the way (within GAP).
    first = -1.0 if lateral > -GAP else 1.0
    for side in (first, -first):
        aim = other + (side * needed) * left
        if room is None or (room(other, aim) and room(position, aim)):
            heading = aim - position
            distance = math.hypot(*heading)
            return v_pref if distance <= 1e-9 else heading * (speed / distance)
    return v_pref

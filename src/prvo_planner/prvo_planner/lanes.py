"""
Keep right: a robot meeting others head-on leans its preferred velocity to its right, no ROS.

Robots meeting head-on in a corridor each choose the certified velocity nearest their
preference, which is to hold still or to sidestep the same way as the other: a symmetry a local,
reciprocal planner does not break on its own (issue 38). Traffic breaks it by convention: each
keeps to its right, and opposite flows form two lanes that pass each other. Here a robot with a
neighbour coming toward it (ahead, within `RANGE` and a cone of `CONE` either side of its way,
moving against it at more than `ONCOMING_SPEED`) turns its preferred velocity to the right by
the angle `keep_right`. Every robot turns the same way in its own frame, so two robots facing
each other turn apart in the world; following a route, the lean settles the robot beside its
route (the carrot ahead pulls it back as far as the lean pushes it off), in a corridor against
the wall on its right, where the walls' conditions hold it.

The lean is taken only where the free space is wide enough for two robots to pass: in open space
always, among walls where the narrowest clear width across the robot's way, from its position
to `AHEAD` in front, is at least two of the widths one robot needs to be certified through
(`core.walls.certifiable_width`, with the robot's own noise): through a door one robot wide,
leaning would only press the robot against a jamb. (Nor does the agent lean a robot at a
passage whose right of way is in force, `prvo_planner.right_of_way`: the passage's order leads
there.) It fades out over the last `FADE` metres to the goal, so that a robot arrives as it
would without it. Among walls (a static obstacle within the planner's `obstacle_distance`) the
lean is at most `WALL_LEAN`: the walls already hold the two lanes apart, and a wider lean only
pushes robots at a corridor's end past their goals (see `WALL_LEAN`).

**In a corridor of two lanes** (walls on both sides over `LANE_LENGTH` of the way, from two to
`LANES` widths apart) a lean of a fixed angle is not enough: robots that set out two abreast, as
`corridor8`'s groups do, keep their rows, and two such groups meet head-on across the whole
corridor and push one back to its end (issue 38). There a robot keeps to its lane
(`corridor_lane`): the middle of the right half of where its centre can be, across the way.
Meeting a neighbour coming toward it, it leans toward that lane, by the angle that would bring
it there `AHEAD` on (at most `keep_right`, and none once it is there or right of it); and while
it is more than `LANE_SLACK` out of its lane with a neighbour going its way abreast of it on
its right, in or toward that lane, it slows to `FALL_BACK` of its preferred speed: it falls in
behind, as a driver merging does, and the two rows become one file.

The trade-off of the angle: path length against flow. Held for a whole way in open space, a lean
of angle a lengthens it by a factor 1 / cos(a) (a logarithmic spiral into the goal: 1.5 % at
0.17 rad, 4.7 % at 0.3 rad, 14 % at 0.5 rad); a larger angle forms the lanes sooner and wider
apart, and a crowd swapping places turns into one roundabout sooner.

Only the preferred velocity changes: the chance constraints against robots and walls, and so the
guarantee, are those of every plan.
"""

import math

import numpy as np

from prvo_planner.core.walls import certifiable_width
from prvo_planner.escalation import turned_right
from prvo_planner.passages import way_sides, way_width

# Default of the planner parameter `keep_right` [rad] (`prvo_planner.parameters`): about 29
# degrees, at most 14 % longer ways in open space. 24 robots swapping places on a 6 m circle
# (noise 0.05, certified 0.95) took 1.55-1.70 times the straight-line time at 0.5, 1.58-1.88 at
# 0.3 (docs/results.md 3.13).
KEEP_RIGHT = 0.5
# Among walls the lean is at most this [rad], about 17 degrees. Following a route, the lean
# settles a robot about lookahead tan(lean) beside it; in a 2.4 m corridor at 0.3 rad robots in
# single file were a robot's width apart sideways when they met (at 0.17 rad not yet), and at
# 0.5 rad robots at the corridor's end were pushed past their goals and had to swap places
# diagonally between others standing at theirs, for 40-70 s (results.md 3.10).
WALL_LEAN = 0.3
# A neighbour is met when it is ahead, nearer than this [m]: two robots at full speed (1 m/s)
# meet 3 s later, time for each to move aside by about 0.9 m at the default lean.
RANGE = 6.0
# ... within this angle of the robot's way either side [rad] ...
CONE = math.pi / 4.0
# ... and moves toward it faster than this [m/s] along its way: one standing still is avoided
# as before, and a velocity estimate's noise does not count.
ONCOMING_SPEED = 0.1
# The clear width is also measured this far ahead [m]: a robot entering a narrow way straightens
# up before it.
AHEAD = 1.0
# The lean fades out over this way to the goal [m].
FADE = 1.0
# A way between walls is a corridor of two lanes up to this many widths one robot needs to be
# certified through (from two): wider, a room, where the lean of open space does.
LANES = 4.0
# ... walled on both sides this far along the way [m]: a robot turning across a corridor to a
# door, or near a corridor's end, keeps the lean of open space. (Judged over AHEAD, robots in
# `office` turning left into their doors were held in their lanes and pushed back along the
# corridor, for 25 s.)
LANE_LENGTH = 3.0
# Out of its lane by more than this [m], a robot with a neighbour going its way abreast on its
# right slows to this share of its preferred speed, to fall in behind it.
LANE_SLACK = 0.2
FALL_BACK = 0.5
# A neighbour is abreast up to this far ahead beyond the two radii [m] (behind, the two radii).
ABREAST_AHEAD = 0.2


def meets_oncoming(position, direction, neighbours):
    """
    Return whether a neighbour comes toward a robot at POSITION heading along DIRECTION.

    POSITION (2,) [m]; DIRECTION (2,) nonzero, the robot's way; NEIGHBOURS a sequence of
    `core.AgentBelief` (mean position and velocity used).
    """
    if not neighbours:
        return False
    unit = np.asarray(direction, dtype=float) / math.hypot(*direction)
    offset = np.array([neighbour.position for neighbour in neighbours]) - position
    velocity = np.array([neighbour.velocity for neighbour in neighbours])
    # Component by component, as a dot product of two 2-vectors rounds (a matrix product may
    # fuse its multiplications and additions): a neighbour on an edge is judged as alone.
    ahead = offset[:, 0] * unit[0] + offset[:, 1] * unit[1]
    across = np.abs(offset[:, 0] * unit[1] - offset[:, 1] * unit[0])
    coming = ((0.0 < ahead) & (ahead <= RANGE) & (across <= ahead * math.tan(CONE))
              & (velocity[:, 0] * unit[0] + velocity[:, 1] * unit[1] < -ONCOMING_SPEED))
    # math.hypot rounds otherwise than numpy's, and few neighbours are left to measure.
    return any(math.hypot(along, side) <= RANGE for along, side in zip(
        ahead[coming].tolist(), across[coming].tolist(), strict=True))


def wide_enough(obstacles, ego, config, direction):
    """
    Return whether the way along DIRECTION is wide enough for two robots to pass.

    OBSTACLES are the `StaticObstacles` near the robot (None: open space, always wide enough),
    EGO its `AgentBelief`, CONFIG its `PlannerConfig`. The narrowest clear width across the way
    from the robot to AHEAD in front (`passages.way_width`) must be at least twice the width
    the robot needs to be certified through.
    """
    if obstacles is None:
        return True
    needed = 2.0 * certifiable_width(ego, config)
    return way_width(obstacles, ego.position, direction, AHEAD) >= needed


def corridor_lane(v_pref, angle, ego, neighbours, distance_to_goal, obstacles, config):
    """
    Return (v_pref (2,), lean [rad]) in a corridor of two lanes; None elsewhere.

    The arguments as `keep_right`'s, OBSTACLES not None. A corridor: the clear way across
    V_PREF (`passages.way_sides`, from the robot to LANE_LENGTH) is walled on both sides, and
    from two to LANES times the width the robot needs to be certified through. Meeting a neighbour
    coming toward it, the robot leans right toward the middle of its lane (the right half of
    where its centre can be), by the angle that reaches it AHEAD on, at most ANGLE, faded near
    the goal; and while it is more than LANE_SLACK out of it with a neighbour going its way
    abreast on its right (`abreast_on_right`), at FALL_BACK of the speed.
    """
    left, right = way_sides(obstacles, ego.position, v_pref, LANE_LENGTH)
    width = left + right
    needed = certifiable_width(ego, config)
    if not (math.isfinite(width) and 2.0 * needed <= width < LANES * needed):
        return None
    if not meets_oncoming(ego.position, v_pref, neighbours):
        return v_pref, 0.0
    # The lane's middle, to the robot's right [m]: halfway between the middle of the way and
    # the farthest its centre can go right (its radius off the wall).
    offset = 0.75 * right - 0.25 * left - 0.5 * ego.radius
    lean = lean_angle(min(angle, math.atan2(max(offset, 0.0), AHEAD)), distance_to_goal)
    velocity = turned_right(v_pref, lean)
    unit = np.asarray(v_pref, dtype=float) / math.hypot(*v_pref)
    if offset > LANE_SLACK and abreast_on_right(ego, neighbours, unit, offset):
        velocity = velocity * FALL_BACK
    return velocity, lean


def abreast_on_right(ego, neighbours, unit, offset):
    """
    Return whether a neighbour going the robot's way is abreast of it, between it and its lane.

    EGO the robot's `AgentBelief`, NEIGHBOURS theirs; UNIT (2,) the robot's way; OFFSET [m] how
    far to its right its lane's middle is. Abreast: from the two radii behind to the two radii
    and ABREAST_AHEAD ahead along the way; to its right, up to OFFSET and the two radii; going
    the same way faster than ONCOMING_SPEED.
    """
    for neighbour in neighbours:
        relative = np.asarray(neighbour.position) - ego.position
        along = relative[0] * unit[0] + relative[1] * unit[1]
        right = relative[0] * unit[1] - relative[1] * unit[0]
        reach = ego.radius + neighbour.radius
        if (-reach <= along <= reach + ABREAST_AHEAD and 0.0 < right <= offset + reach
                and neighbour.velocity[0] * unit[0] + neighbour.velocity[1] * unit[1]
                > ONCOMING_SPEED):
            return True
    return False


def lean_angle(angle, distance_to_goal):
    """Return the lean [rad] of a robot DISTANCE_TO_GOAL [m] from its goal: ANGLE, faded."""
    return angle * min(1.0, max(0.0, distance_to_goal) / FADE)


def keep_right(v_pref, angle, ego, neighbours, distance_to_goal, obstacles, config):
    """
    Return the preferred velocity (2,) of a robot that keeps right, and the lean [rad].

    V_PREF (2,) [m/s] is the velocity toward the goal or along the route; ANGLE [rad] the lean
    (`keep_right`, 0: off; among OBSTACLES at most WALL_LEAN); EGO the robot's `AgentBelief`;
    NEIGHBOURS the neighbours' `AgentBelief`s; DISTANCE_TO_GOAL [m] the way left; OBSTACLES the
    `StaticObstacles` near (None: none); CONFIG the `PlannerConfig`. V_PREF comes back
    unchanged (lean 0) when the robot stands, meets nobody, or where the way is too narrow for
    two. In a corridor of two lanes, `corridor_lane`'s.
    """
    if angle <= 0.0 or not (v_pref[0] or v_pref[1]):
        return v_pref, 0.0
    if obstacles is not None:
        lane = corridor_lane(v_pref, angle, ego, neighbours, distance_to_goal, obstacles, config)
        if lane is not None:
            return lane
        angle = min(angle, WALL_LEAN)
    lean = lean_angle(angle, distance_to_goal)
    if (lean <= 0.0 or not meets_oncoming(ego.position, v_pref, neighbours)
            or not wide_enough(obstacles, ego, config, v_pref)):
        return v_pref, 0.0
    return turned_right(v_pref, lean), lean

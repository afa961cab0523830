"""
Give way: a robot standing at its goal steps off the route of a neighbour that has to pass, no ROS.

A robot at its goal announces no share of the avoidance (`agent.PlannerAgent.own_announcement`):
its neighbours plan around it as around a post, and it moves only when one comes at it. Where
goals lie in a passage, robots that arrived first stand across the way of those still coming
and of those still leaving, which stand in front of them for good: in `corridor8` two robots at
their goals 1.1 m apart across a 2.4 m corridor leave 0.6 m between them, and a robot of 0.5 m
behind them cannot certify that gap (issue 38). A person at their destination steps aside for
someone who has to pass; so does a robot here, from what its neighbours publish: the route each
follows to its goal (`<robot>/plan`).

A robot at its goal, or giving way, looks at the way ahead of every neighbour within `RANGE` of
its goal: its route from the point nearest the neighbour on. Where a route passes nearer its
goal than the two radii and `GAP`, the robot goes to the point beside the route at that
distance, on the side its goal lies (across the route where the goal is on it, to the route's
right), as far as its room allows (`room`: the map's cells that keep its clearance; without a
map, always), down to the two radii; with no room on that side, on the other. The nearest such
neighbour decides. Once no route passes by its goal (the neighbour went by, arrived, or went
silent) it returns to its goal.

With a map it stands against a wall rather than in the open (`_against_wall`): where its room
toward one side of the route ends within the two radii and `GAP` of it (a wall) and the other
side is open, it steps toward the wall, as far as its room allows, and leaves the passer the
open side whole; it crosses the route for that only from a goal on it (within `GAP`), where the
side was chance. Stepping into a corridor's middle, a robot at a goal near the corridor's end
stood in the way of those going to the goals behind it (`corridor8`). And a robot whose goal is
farther from the route, but within twice that distance and `GAP`, steps away from it to that
distance, as far as its room and the other neighbours allow: the passer, going round a robot
on its route, passes between the two.

A robot held short of its goal (`held_short`: stalled, or near its goal and hardly gaining on it)
gives way likewise to a neighbour whose way passes by where it stands, ahead of the neighbour,
and that has farther to go than it has (`yields_to`; within `TIE` the names decide). Two robots
that hold each other up near the end of a corridor otherwise wait for each other: the one with
less to go makes room, the other goes by, and the first goes on once no such way passes by the
place it stepped off (issue 38). A held robot is near the neighbour, in its way now: the way
counts from where the neighbour is, straight to its route's next point, then along the route (a
robot in a lane, or pushed aside, is off its route, and goes back to it), and not abreast of the
neighbour or behind it, where it goes away. Its spot beside that way is clear of every other
neighbour (`held_spot`, `clear_spot_beside`): where robots stand at their goals on both sides of
the way (a pocket at a corridor's end), the spot slides along the way to where none stands. It
goes on yielding to the one it yielded to though that one, gaining on its way, comes to have
less to go, while it moves (`PASSING_SPEED`): it would turn back into the way of one passing it;
one that stands passes nobody, and may be yielding to it. It does not yield to a neighbour
that stands, announcing no share (at its goal, or aside for another, maybe for it: both would
stand aside), nor to one that waits its turn at its passage (`right_of_way.waiting_at`); those
only take up room. Standing aside for one that holds its place behind it, both would wait for
good (`pillars12`, seed 9), and for one that waits behind others, all of them (a door with five
robots each way).

Only the preferred velocity changes: the chance constraints against robots and walls, and so the
guarantee, are those of every plan.
"""

import math

import numpy as np

# Room made beyond the two radii [m]: a neighbour passes at its certified clearance with some
# to spare (about two position stds of the shipped noise).
GAP = 0.1
# Routes of neighbours farther than this from the robot's goal are not looked at [m]: a robot
# steps aside for one about to pass, not for one across the room.
RANGE = 3.0
# The offsets tried, from the full one down to the two radii, this far apart [m].
STEP = 0.05
# A robot this near its goal [m, the way left] is held when it came less than HELD_PROGRESS [m]
# closer to it over the last HELD_WINDOW [s] (0.1 m/s): sooner than a stall (`stalls`, 10 s),
# since two robots that wait for each other at a corridor's end wait for good.
NEAR_GOAL = 2.5
HELD_WINDOW = 3.0
HELD_PROGRESS = 0.3
# A held robot goes on yielding to a neighbour only while it moves faster than this [m/s]: one
# that stands no longer passes, and may be yielding to it (above the velocity estimate's noise).
PASSING_SPEED = 0.15
# Ways left within this of each other [m] are a tie, which the names decide: two robots estimate
# each other's positions to within centimetres, and must agree on who yields.
TIE = 0.3


def closest_on_route(route, point):
    """
    Return (point (2,), direction (2,), index): the nearest point of ROUTE to POINT.

    `direction` is the unit direction of the segment it lies on (zero for a segment of no
    length), `index` that segment's. ROUTE (K, 2) [m], K >= 2; POINT (2,) [m].
    """
    nearest = _nearest_on_segments(route, point)
    index = int(np.argmin(np.sum((nearest - point) ** 2, axis=1)))
    edge = route[index + 1] - route[index]
    length = math.sqrt(np.sum(edge * edge))
    direction = edge / length if length > 0.0 else np.zeros(2)
    return nearest[index], direction, index


def _nearest_on_segments(route, points):
    """Return the point (..., K - 1, 2) of each segment of ROUTE (K, 2) nearest POINTS (..., 2)."""
    starts, edges = route[:-1], route[1:] - route[:-1]
    lengths_sq = np.sum(edges * edges, axis=1)
    along = np.clip(np.sum((points[..., np.newaxis, :] - starts) * edges, axis=-1)
                    / np.maximum(lengths_sq, 1e-300), 0.0, 1.0)
    return starts + along[..., np.newaxis] * edges


def way_ahead(route, position):
    """Return the part (K', 2) of ROUTE (K, 2) ahead of a robot at POSITION (2,).

    A route is published when it changes, not at every plan: the way behind the robot is cut
    off at the point nearest it.
    """
    nearest, _, index = closest_on_route(route, position)
    return np.vstack([nearest, route[index + 1:]])


def spot_beside(route, goal, radius, other_radius, room, others=()):
    """
    Return where a robot of RADIUS standing at GOAL lets a neighbour of OTHER_RADIUS pass.

    None when ROUTE (K, 2) passes GOAL at least the two radii and GAP away and no wall is near
    (nothing to do), or when no point beside it is within reach (ROOM(start (2,), end (2,)) ->
    bool; None: open space). Otherwise, with a map, against the wall (`_against_wall`) where
    one side of the route has a wall within reach and the other is open; else the point at the
    largest offset from the route, from the two radii and GAP down to the two radii, on the side
    of the goal, else on the other. OTHERS (a sequence of (position (2,), radius) of the other
    neighbours) bound how far it steps where the route passes beyond NEEDED (`_against_wall`).
    """
    nearest, direction, _ = closest_on_route(route, goal)
    offset = goal - nearest
    distance = math.hypot(*offset)
    needed = radius + other_radius + GAP
    if distance >= 2 * needed + GAP:
        return None
    if distance > 1e-9:
        side = offset / distance
    elif direction.any():
        side = np.array([direction[1], -direction[0]])
    else:
        return None
    if room is not None and (distance < needed or not np.array_equal(nearest, route[-1])):
        # Beyond NEEDED only for a way that goes on past the goal: one that ends beside it (a
        # neighbour's way back to its own goal) has nobody to pass.
        spot = _against_wall(nearest, goal, side, distance, needed, other_radius, room, others)
        if spot is not None:
            return None if math.hypot(*(spot - goal)) < STEP / 2 else spot
    if distance >= needed:
        return None
    least = radius + other_radius
    offsets = needed - STEP * np.arange(int(math.floor((needed - least) / STEP + 1e-9)) + 1)
    for way in (side, -side):
        for amount in offsets:
            spot = nearest + amount * way
            if room is None or room(goal, spot):
                return spot
    return None


def _against_wall(nearest, goal, side, distance, needed, other_radius, room, others):
    """
    Return the spot against the wall on one side of a passing route, None for none.

    A robot at GOAL, DISTANCE [m] from the route's NEAREST point (2,) on the unit SIDE (2,) of
    it, steps toward a wall rather than into the open: out of the way, it leaves the passer the
    free space on the other side whole. In `corridor8` the robots at the goals nearer the end
    stand 1.1 m apart across the corridor, on the way of those going to the goals behind them;
    stepping to the side its goal lay from a route through it, decided by centimetres, one
    stepped into the middle as often as not and stood in the way (docs/results.md, 3.18 and
    3.19). Where the route passes within NEEDED [m] (the two radii and GAP): toward the side on
    which ROOM ends within NEEDED of the route (a wall) while the other has NEEDED, the goal's
    side, or either where the goal is within GAP of the route (on it, give or take); where it
    passes farther, but within 2 NEEDED and GAP (the passer may go round a robot standing on its
    route, up to NEEDED off it, between that one and this, and then needs NEEDED and GAP from
    this one), away from the route on the goal's side to that distance, keeping the two radii
    and GAP from OTHERS (a sequence of (position (2,), radius)). As far as the room allows, and
    never back toward the route.
    """
    if distance < needed:
        reaches = [_reach(nearest, goal, way, needed, room) for way in (side, -side)]
        # Across the route only from a goal on it (within GAP), where its side is chance.
        sides = ((side, *reaches), (-side, *reaches[::-1]))[:2 if distance < GAP else 1]
        for way, reach, other in sides:
            if (reach is not None and reach < needed - 1e-9
                    and other is not None and other >= needed - 1e-9):
                return nearest + max(reach, float((goal - nearest) @ way)) * way
        return None
    radius = needed - other_radius - GAP
    beyond = 2 * needed + GAP - distance
    for amount in beyond - STEP * np.arange(int(math.floor(beyond / STEP + 1e-9)) + 1):
        spot = goal + amount * side
        if room(goal, spot) and all(math.hypot(*(spot - position)) >= radius + size + GAP
                                    for position, size in others):
            return spot
    return None


def _reach(start, goal, way, top, room):
    """
    Return the largest offset [m] along a line that a robot at GOAL (2,) can reach.

    The points tried are START (2,) plus TOP down to 0 by STEP times the unit WAY (2,); ROOM as
    in `spot_beside`. None when it reaches none of them.
    """
    for amount in top - STEP * np.arange(int(math.floor(top / STEP + 1e-9)) + 1):
        if room(goal, start + amount * way):
            return float(amount)
    return None


def clear_spot_beside(route, point, radius, other_radius, room, others):
    """
    Return where a robot held at POINT lets a neighbour following ROUTE pass, clear of OTHERS.

    As `spot_beside`, but a spot within the two radii and GAP of another neighbour (OTHERS: a
    sequence of (position (2,), radius)) is passed over, and the spot may slide along ROUTE
    (K, 2), by STEP, to where one is clear: the largest offset first, on the robot's own side
    first, the spot nearest POINT (2,) at each. Beside the point of the route nearest the robot
    is often where a robot standing at its goal is (a pocket at a corridor's end: robots at
    their goals on both sides of the way), and a spot on it would hold both up. A spot is also
    at least the two radii from every part of the route. With no clear spot within RANGE of
    POINT: `spot_beside`'s.
    """
    nearest, direction, _ = closest_on_route(route, point)
    offset = point - nearest
    distance = math.hypot(*offset)
    needed = radius + other_radius + GAP
    if distance >= needed or _behind(route, nearest):
        return None
    if distance <= 1e-9 and not direction.any():
        return None
    # +1: the robot is on the route's left; the route's right where it is on it.
    side = 1.0 if direction[0] * offset[1] - direction[1] * offset[0] > 1e-9 else -1.0
    samples, normals = _along(route)
    near = np.hypot(*(samples - point).T) <= RANGE
    samples, normals = samples[near], normals[near]
    least = radius + other_radius
    offsets = needed - STEP * np.arange(int(math.floor((needed - least) / STEP + 1e-9)) + 1)
    for way in (side, -side):
        for amount in offsets:
            spots = samples + (way * amount) * normals
            clear = _route_distance(route, spots) >= least - 1e-9
            for position, other in others:
                clear &= np.hypot(*(spots - position).T) >= radius + other + GAP
            spots = spots[clear]
            for index in np.argsort(np.hypot(*(spots - point).T), kind='stable'):
                if room is None or room(point, spots[index]):
                    return spots[index]
    return spot_beside(route, point, radius, other_radius, room)


def _behind(route, nearest):
    """Whether the point of ROUTE (K, 2) NEAREST (2,) a robot is where the route begins.

    The robot is abreast of or behind the neighbour that follows the route from there: it goes
    away from the robot, which need not make room for it.
    """
    return bool(np.all(nearest == route[0]))


def _along(route):
    """Return (points (P, 2), left unit normals (P, 2)) along ROUTE (K, 2), STEP apart.

    Each segment of nonzero length from its start, and the route's end.
    """
    points, normals = [], []
    for start, end in zip(route[:-1], route[1:], strict=True):
        edge = end - start
        length = math.hypot(*edge)
        if length <= 0.0:
            continue
        along = np.arange(0.0, length, STEP)
        points.append(start + along[:, None] * (edge / length))
        normals.append(np.tile([-edge[1] / length, edge[0] / length], (len(along), 1)))
    if not points:
        return np.zeros((0, 2)), np.zeros((0, 2))
    points.append(route[-1:])
    normals.append(normals[-1][-1:])
    return np.vstack(points), np.vstack(normals)


def _route_distance(route, points):
    """Return the distance (P,) [m] of each of POINTS (P, 2) to ROUTE (K, 2), K >= 2."""
    gaps = _nearest_on_segments(route, points) - points[:, np.newaxis, :]
    return np.min(np.hypot(gaps[..., 0], gaps[..., 1]), axis=1)


def give_way_spot(goal, radius, neighbours, room):
    """
    Return the spot (2,) a robot at its GOAL (2,) of RADIUS goes to, None to stay at its goal.

    NEIGHBOURS is a sequence of (position (2,), radius, route (K, 2) or None): their estimated
    positions, their radii and the routes they follow (None or fewer than two points: none).
    ROOM as in `spot_beside`. The neighbour nearest the goal among those within RANGE whose
    way ahead (`way_ahead`) passes by the goal decides; the others bound how far the robot steps
    away from a way that passes farther off (`_against_wall`).
    """
    spots = []
    neighbours = [(np.asarray(position, dtype=float), other_radius, route)
                  for position, other_radius, route in neighbours]
    for index, (position, other_radius, route) in enumerate(neighbours):
        distance = math.hypot(*(position - goal))
        ahead = _claimed_way(route, position, distance)
        if ahead is None:
            continue
        others = [(where, size) for where, size, _ in neighbours[:index] + neighbours[index + 1:]]
        spot = spot_beside(ahead, goal, radius, other_radius, room, others)
        if spot is not None:
            spots.append((distance, spot))
    return min(spots, key=lambda item: item[0])[1] if spots else None


def _claimed_way(route, position, distance, from_position=False):
    """Return the way ahead (K', 2) a neighbour at POSITION (2,) claims, None for none.

    From the route's point nearest POSITION on (`way_ahead`); FROM_POSITION: from POSITION, off
    its route or not, straight to the route's next point, then along the route. None beyond
    RANGE (DISTANCE [m] away), without a route (ROUTE None or fewer than two points), or at the
    end of its route: it arrived, and claims no way.
    """
    if route is None or len(route) < 2 or distance > RANGE:
        return None
    ahead = way_ahead(np.asarray(route, dtype=float), position)
    if not np.any(ahead[1:] != ahead[:-1]):
        return None
    return np.vstack([position, ahead[1:]]) if from_position else ahead


def way_left(route, position):
    """Return the length [m] of ROUTE (K, 2) ahead of a robot at POSITION (2,), to its end.

    Along the route from its point nearest the robot (`way_ahead`); a route of one point: the
    straight line. Not the way from the robot to the route: a robot stepping aside to give way
    (less than the lookahead off its route, which it keeps) has as far to go as before, to its
    neighbours as to itself, so who yields does not turn as it steps.
    """
    route = np.asarray(route, dtype=float)
    position = np.asarray(position, dtype=float)
    if len(route) < 2:
        return math.hypot(*(route[-1] - position))
    ahead = way_ahead(route, position)
    return float(np.sum(np.hypot(*np.diff(ahead, axis=0).T)))


def held_short(stalled, distance_to_goal, gained):
    """Whether a robot is held short of its goal: it yields (`held_spot`) to whoever has farther.

    STALLED: its stall monitor's status; DISTANCE_TO_GOAL [m] the way left; GAINED [m] how much
    closer it came over the last HELD_WINDOW (nan: less history, or at its goal within it).
    """
    return bool(stalled) or (distance_to_goal <= NEAR_GOAL and gained < HELD_PROGRESS)


def yields_to(own_left, own_name, other_left, other_name):
    """Whether a robot with OWN_LEFT [m] to go yields to a neighbour with OTHER_LEFT [m].

    It does to one with farther to go; within TIE the one whose name sorts later yields, so that
    of two that judge alike exactly one does.
    """
    if abs(other_left - own_left) > TIE:
        return other_left > own_left
    return other_name < own_name


def held_spot(position, left, name, radius, neighbours, room, waiting=(), yielding=None):
    """
    Return where a held robot steps to (`held_short`), and for whom.

    The robot, NAME, of RADIUS, was held at POSITION (2,) and has LEFT [m] to go (`way_left`
    along its own route). NEIGHBOURS is a
    sequence of (name, position (2,), radius, route (K, 2) or None); ROOM as in `spot_beside`.
    Of the neighbours within RANGE whose way ahead passes by POSITION and that it yields to
    (`yields_to`, their way left along their route), the nearest decides, as in
    `give_way_spot`; the spot is clear of the others (`clear_spot_beside`). It yields to none
    named in WAITING (those that wait their turn at its passage, or stand), which only take up
    room. It goes on yielding to the one named YIELDING (the one it yielded to at its last plan
    and that moves; None: none) though it no longer has farther to go: the one going by gains
    on its way while the other stepped off its own, and would otherwise turn back into its way
    as it passes.

    Return (spot (2,), the deciding neighbour's name), (None, None) when it need not step.
    """
    position = np.asarray(position, dtype=float)
    neighbours = list(neighbours)
    spots = []
    for index, (other_name, other_position, other_radius, route) in enumerate(neighbours):
        other_position = np.asarray(other_position, dtype=float)
        distance = math.hypot(*(other_position - position))
        if other_name in waiting:
            continue
        ahead = _claimed_way(route, other_position, distance, from_position=True)
        if ahead is None:
            continue
        other_left = way_left(route, other_position)
        if other_name != yielding and not yields_to(left, name, other_left, other_name):
            continue
        others = [(np.asarray(where, dtype=float), size) for _, where, size, _
                  in neighbours[:index] + neighbours[index + 1:]]
        spot = clear_spot_beside(ahead, position, radius, other_radius, room, others)
        if spot is not None:
            spots.append((distance, spot, other_name))
    return min(spots, key=lambda item: item[0])[1:] if spots else (None, None)

"""
Right of way at one-way passages: who goes through a door first, decided alike by all, no ROS.

Issue 39: robots that meet in a door too narrow for two (`prvo_planner.narrows`) freeze unless
someone goes first, and everyone has to agree who. Every robot decides from what every robot
publishes, its odometry and its route on ``<robot>/plan``, by the same rule, so that the robots
of one team reach the same order without talking (in the manner of navground's
``navground_narrow``; Open-RMF grants a door by a claim instead, which needs a server).

**Uses.** A robot uses a passage when its route (the way ahead of it, `give_way.way_ahead`)
enters the passage's cells within `LOOK_AHEAD` of it, or when it is inside them: it comes in by
the end nearest the route where it enters (none, for a robot inside) and leaves by the end
nearest where the route leaves (none where the route ends inside). Its *distance* is the length
of route to the passage, zero inside; inside, the length of route left to its way out. Two uses
*conflict* when they go out by different ends, inside or not (at a passage of two ends: one
comes in where the other goes out, or both are inside going opposite ways): they would meet
head-on, and where more ends meet, their ways cross once both are in. (Where a route ends
inside, one coming in conflicts with one going out by the end it comes in by, or, both inside,
with one going out.) Robots going the same way never conflict, so a robot follows another in.
At a passage of more than two ends, two judged apart by the ends they meet at alone were let in
together, then sent one back out by the rule inside: in a field of pillars a robot stood at a
mouth stepping in and out for 13 s. A neighbour that publishes no route (a walker, a robot of
another stack, a robot at its goal) uses nothing, claims nothing, and is avoided as every
neighbour is; so is, after `IDLE_INSIDE`, one standing in a passage (`IdleWatch`: a robot
broken down in a door).

**The order.** A robot inside keeps the passage: one coming in where it goes out waits. Of two
inside that conflict, the one with less of the passage left goes on and the other backs out.
Between two outside that conflict, the one with the shorter way to the passage goes first; ways
within `TIE` of each other are a tie, which the robots' names decide (the smaller first): noise
on the distances, a few centimetres, flips a decision only near the edge of the tie, where the
robot that decides wrongly waits a step or, both going, the rule inside sorts them out. Before
the ways, first come, first served: of two outside, the one that came to the passage (its route
entered it within `LOOK_AHEAD`, or it was inside, ever since) more than `QUEUE_TIE` earlier goes
first (`QueueWatch`). By the ways alone a robot at a waiting spot, a metre or more of route from
its entrance, lost every turn to any robot that came nearer the other end before the passage
emptied: while robots came one after another from one side, those on the other waited
(`pillars12`, whose three gaps between pillars are one passage with three ends: robots waited
their turn 17-27 s there). Robots that come together are ordered by their ways as before: a
crowd at a door goes through one side after the other.

**Waiting.** A robot without the right of way heads for the waiting spot of the end it comes in
by (`narrows.PassageEnd.waiting_spot`, beside the entrance, off the way out), or holds its
place where that end has none, and sees a *virtual wall* across its entrance: a static
obstacle, certified as every wall is, so that it cannot be pushed into the door by whoever
comes out. (Backing out of a passage, it sees none: it is on the wall's other side.)

Only the preferred velocity and the static obstacles change: the chance constraints, and so the
guarantee, are those of every plan.
"""

from dataclasses import dataclass, replace
import math

import numpy as np

from prvo_planner.core.obstacles import StaticObstacles
from prvo_planner.give_way import way_ahead

# A passage is looked at when a route enters it within this length of route [m]: about the
# distance a robot needs to slow down and turn to its waiting spot.
LOOK_AHEAD = 4.0
# Ways to a passage that differ by less than this [m] are a tie (the names decide): several
# position stds of the shipped noise, less than a robot's diameter.
TIE = 0.3
# Robots that came to a passage within this of each other [s] came together (`QueueWatch`):
# their ways decide. Beyond it the one that came first goes first.
QUEUE_TIE = 2.0
# A route is followed through a passage this far at most [m] to find where it leaves.
MAX_THROUGH = 50.0
# A route that leaves a passage's cells for less than this [m] has not left it.
REENTRY = 1.0
# Inside, a robot heads for the point of the passage's centre line AIM_ALONG [m] ahead of its
# own nearest point, the line running on straight out of the middle of its way out: one that
# came in off-centre comes back to the middle before the jambs, where its walls'
# conditions leave it the most room, instead of cutting the corner (at a door 0.35 m wider than
# a robot on either side, cutting it held a robot to a quarter of its speed).
AIM_ALONG = 0.6
# Outside, for the line out of its entrance's middle this much [m] nearer the entrance.
AIM_AHEAD = 0.5
# A robot following another in keeps this far [m] behind it: two abreast at a mouth one robot
# wide jam it.
FOLLOW_GAP = 1.2
# A neighbour inside a passage that moves less than IDLE_MOVE [m] in IDLE_INSIDE [s] claims
# nothing (`IdleWatch`): the stall monitor's 10 s without 0.5 m.
IDLE_INSIDE = 10.0
IDLE_MOVE = 0.5


@dataclass(frozen=True)
class PassageUse:
    """
    One robot's use of one passage.

    Attributes
    ----------
    name : str
        The robot.
    passage : int
        The passage's index in `PassageMap.passages`.
    entry : int or None
        The end it comes in by; None for a robot inside.
    exit : int or None
        The end it leaves by; None where its route ends inside.
    distance : float
        Outside: the length of route to the passage [m]. Inside: the length of route left to
        its way out (to its route's end inside), [m].
    position : numpy.ndarray or None
        Shape (2,): where the robot is [m]; None: unknown (it follows no one and no one keeps
        behind it).
    came : float or None
        Outside: when it came to the passage [s], kept while it uses it (`QueueWatch`); None:
        unknown (its way alone orders it).

    """

    name: str
    passage: int
    entry: int | None
    exit: int | None
    distance: float
    position: np.ndarray | None = None
    came: float | None = None

    @property
    def inside(self):
        """Whether the robot is inside the passage."""
        return self.entry is None


@dataclass(frozen=True)
class Decision:
    """
    A robot's right of way at the passage on its route.

    Attributes
    ----------
    use : PassageUse
        The robot's use of the passage.
    goes : bool
        Whether it may go on through; else it waits.
    waiting_spot : numpy.ndarray or None
        Shape (2,): where it waits [m] (it goes on: None; it waits with no spot: None).
    wall : numpy.ndarray or None
        Shape (2, 2): the virtual wall across its entrance [m], None when it goes or is inside.
    entrance : numpy.ndarray or None
        Shape (2,): the entrance of the end it waits at [m] (coming in, or backing out by);
        None when it goes, or holds its place behind one going its way.

    """

    use: PassageUse
    goes: bool
    waiting_spot: np.ndarray | None = None
    wall: np.ndarray | None = None
    entrance: np.ndarray | None = None

    @property
    def without_spot(self):
        """Whether the robot waits at an end where no waiting spot fits (it holds its place)."""
        return self.entrance is not None and self.waiting_spot is None


def conflict(first, second):
    """Whether the `PassageUse`s FIRST and SECOND of one passage would meet head-on.

    Two that leave by different ends, inside or not: once both are in, their ways cross (at a
    passage of two ends, one comes in by the end the other leaves by). Where a route ends
    inside, and one of the two is outside, head-on at an end: one comes in where the other
    leaves.
    """
    if (first.inside and second.inside) or (first.exit is not None and second.exit is not None):
        return first.exit != second.exit
    return ((first.entry is not None and first.entry == second.exit)
            or (second.entry is not None and second.entry == first.exit))


def ahead(first, second):
    """Whether the outside `PassageUse` FIRST comes before SECOND.

    The one that came more than QUEUE_TIE earlier; else the shorter way (ways within TIE: the
    names).
    """
    if (first.came is not None and second.came is not None
            and abs(first.came - second.came) > QUEUE_TIE):
        return first.came < second.came
    return (first.distance < second.distance - TIE
            or (abs(first.distance - second.distance) <= TIE and first.name < second.name))


def goes_first(me, others):
    """
    Whether the robot of the `PassageUse` ME may go on, given the uses OTHERS of the passage.

    The order of the module's docstring; every robot that computes it from the same uses gets
    the same answer.
    """
    return _unopposed(me, others) and not _too_close_behind(me, others)


def waiting_at(me, others):
    """Return the names of the robots of OTHERS that wait at ME's passage, ME among them.

    ME and OTHERS are `PassageUse`s; a robot waits when, by the order, it does not go
    (`goes_first`): before it is one coming the other way, or one going its way too close
    ahead (ME, or another).
    """
    same = [other for other in others if other.passage == me.passage]
    return tuple(other.name for other in same
                 if not goes_first(other, [use for use in same if use is not other] + [me]))


def _too_close_behind(me, others):
    """Whether ME, outside, is within FOLLOW_GAP of one going the same way before it."""
    if me.inside or me.position is None:
        return False
    for other in others:
        same_way = (other.exit == me.exit if other.inside
                    else other.entry == me.entry and ahead(other, me))
        if (same_way and other.position is not None
                and math.hypot(*(other.position - me.position)) < FOLLOW_GAP
                and _unopposed(other, [use for use in others if use is not other] + [me])):
            return True
    return False


def _unopposed(me, others):
    """Whether no use of OTHERS that would meet ME head-on comes before it."""
    for other in others:
        if not conflict(me, other):
            continue
        if other.inside and not me.inside:
            return False
        if other.inside and me.inside:
            if (other.distance, other.name) < (me.distance, me.name):
                return False
            continue
        if me.inside:
            continue
        if ahead(other, me):
            return False
    return True


class PassageMap:
    """
    The passages of a map, and which of them a route uses.

    Parameters
    ----------
    grid : maps.GridMap
        The map the passages were found on.
    passages : tuple of narrows.Passage
        `narrows.find_passages` of GRID.
    radius : float
        The radius [m] they were found for (the virtual wall keeps a robot's body out).

    """

    def __init__(self, grid, passages, radius):
        self.passages = tuple(passages)
        self.radius = float(radius)
        self._origin, self._resolution = np.asarray(grid.origin, dtype=float), grid.resolution
        # Each passage's cells as a mask over their bounding box: a point is looked up in the
        # few boxes it may lie in.
        self._boxes = []
        for passage in self.passages:
            low, high = passage.cells.min(axis=0), passage.cells.max(axis=0)
            mask = np.zeros(tuple(high - low + 1), dtype=bool)
            mask[tuple((passage.cells - low).T)] = True
            self._boxes.append((low, high, mask))

    def passage_at(self, points):
        """Return the index (K,) int of the passage each of POINTS (K, 2) [m] is in, -1: none."""
        points = np.asarray(points, dtype=float).reshape(-1, 2)
        cells = np.floor((points - self._origin) / self._resolution).astype(np.int64)[:, ::-1]
        found = np.full(len(points), -1)
        for index, (low, high, mask) in enumerate(self._boxes):
            within = np.all((cells >= low) & (cells <= high), axis=1) & (found < 0)
            rows, columns = (cells[within] - low).T
            hit = np.flatnonzero(within)[mask[rows, columns]]
            found[hit] = index
        return found

    def use_of(self, name, position, route):
        """
        Return the `PassageUse` of the first passage on a robot's way, None: none ahead.

        NAME: the robot; POSITION (2,) [m]: where it is; ROUTE (K, 2) [m], K >= 1: its route
        (from wherever it was published; the way behind the robot is cut off).
        """
        if not self.passages:
            return None
        route, position = np.asarray(route, dtype=float), np.asarray(position, dtype=float)
        ahead = way_ahead(route, position) if len(route) >= 2 else route
        points, along = _sampled(np.vstack([position, ahead]), 0.5 * self._resolution,
                                 LOOK_AHEAD + MAX_THROUGH)
        inside = self.passage_at(points)
        entered = np.flatnonzero((inside >= 0) & (along <= LOOK_AHEAD))
        if len(entered) == 0:
            return None
        first = int(entered[0])
        passage = int(inside[first])
        # The way out: where the route leaves the passage's cells for longer than REENTRY (a
        # route along the passage's rim may step out and back in).
        within = np.flatnonzero(inside[first:] == passage) + first
        gaps = np.flatnonzero(np.diff(along[within]) > REENTRY)
        last = int(within[gaps[0]] if len(gaps) else within[-1])
        if last == len(points) - 1:
            last = None
        ends = self.passages[passage].ends
        exit_end = None if last is None else _nearest_end(ends, points[last])
        if first == 0:
            distance = float(along[last] if last is not None else along[-1])
            return PassageUse(name, passage, None, exit_end, distance, position)
        entry = _nearest_end(ends, points[first])
        if entry == exit_end:
            # In and out by one end: the route only grazes the passage's cells at its mouth.
            return None
        return PassageUse(name, passage, entry, exit_end, float(along[first]), position)

    def aim(self, use, position):
        """Return the point (2,) [m] the robot of USE at POSITION (2,) heads for, None: none.

        Outside: the line out of its entrance's middle, `AIM_AHEAD` nearer the entrance than
        the robot (the entrance itself once nearer than that), so that it comes in centred;
        inside: the passage's centre line to its way out and on straight out of it, `AIM_ALONG`
        ahead of the robot's nearest point on it, until the robot is out past that entrance (a
        passage's cells reach past its mouths): then its route leads it on, which may turn at
        once (a door onto a corridor). Through the middle the jambs are farthest, and the
        walls' conditions leave the most room.
        """
        passage = self.passages[use.passage]
        ends = passage.ends
        if not use.inside:
            end = ends[use.entry]
            out = float(np.dot(position - end.entrance, end.outward))
            return end.entrance + end.outward * max(0.0, out - AIM_AHEAD)
        if use.exit is None:
            return None
        end = ends[use.exit]
        if np.dot(position - end.entrance, end.outward) > 0.0:
            return None
        line = np.vstack([_centre_line_to(passage, use.exit, position),
                          end.entrance + end.outward * AIM_ALONG])
        return _ahead_on(line, position, AIM_ALONG)

    def decision(self, me, others, position):
        """
        Return the `Decision` of the robot at POSITION (2,) [m] whose use is ME.

        OTHERS: the `PassageUse`s of the robot's neighbours (of any passage; those of ME's
        count).
        """
        others = [other for other in others if other.passage == me.passage]
        if _unopposed(me, others):
            # Behind one going the same way, it holds its place until the gap opens.
            return Decision(me, not _too_close_behind(me, others))
        ends = self.passages[me.passage].ends
        if me.inside:
            # Backing out: by the nearest end it does not leave by.
            back = [index for index in range(len(ends)) if index != me.exit] or [0]
            end = ends[min(back, key=lambda index: np.hypot(*(ends[index].entrance
                                                               - position)))]
            return Decision(me, False, end.waiting_spot, entrance=end.entrance)
        end = ends[me.entry]
        return Decision(me, False, end.waiting_spot,
                        self._wall(self.passages[me.passage], end, position), end.entrance)

    def _wall(self, passage, end, position):
        """Return the virtual wall (2, 2) across PASSAGE's END, None if the robot is at it.

        The wall lies a radius outside the entrance, across the whole passage and a radius
        beyond on either side, so that a robot it holds has its centre out of the passage; a
        robot nearer than a radius and a cell to it is let be (it would start inside the wall).
        """
        line = end.entrance + end.outward * self.radius
        offset = float(np.dot(position - line, end.outward))
        if offset < self.radius + self._resolution:
            return None
        across = np.array([-end.outward[1], end.outward[0]])
        half = 0.5 * passage.width + self.radius
        return np.array([line - half * across, line + half * across])


class IdleWatch:
    """Neighbours that stay in a passage without moving: after `IDLE_INSIDE` they claim nothing.

    A robot broken down in a door, or one of another stack parked there, would otherwise keep
    the door from every robot coming the other way for good; after the timeout they are
    avoided as every neighbour is, and the others go by the order without them.
    """

    def __init__(self):
        # robot -> (passage, where its stay began (2,), when [s]).
        self._stays = {}

    def claiming(self, uses, stamp):
        """Return the `PassageUse`s of USES that still claim their passage at STAMP [s]."""
        kept, stays = [], {}
        for use in uses:
            if not use.inside or use.position is None:
                kept.append(use)
                continue
            stay = self._stays.get(use.name)
            if (stay is None or stay[0] != use.passage
                    or math.hypot(*(use.position - stay[1])) > IDLE_MOVE):
                stay = (use.passage, use.position, stamp)
            stays[use.name] = stay
            if stamp - stay[2] <= IDLE_INSIDE:
                kept.append(use)
        self._stays = stays
        return kept


class QueueWatch:
    """When each robot came to the passage it uses, for first come, first served (`ahead`).

    Each robot watches its neighbours and itself alike, from the positions and routes all
    publish: a robot comes to a passage when its use of it begins, and stays come while it uses
    that passage, by any end or inside (backing out, or flickering in and out at a mouth, it
    keeps its place in the line). One that came into sight while a neighbour waited counts that
    neighbour from then, and for a while the two may judge apart, which the rule inside sorts
    out (the module's docstring).
    """

    def __init__(self):
        # robot -> (passage, when it came [s]).
        self._came = {}

    def ordered(self, uses, stamp):
        """Return USES (`PassageUse`s) at STAMP [s], each outside with when it came."""
        kept, came = [], {}
        for use in uses:
            seen = self._came.get(use.name)
            if seen is None or seen[0] != use.passage:
                seen = (use.passage, stamp)
            came[use.name] = seen
            kept.append(use if use.inside else replace(use, came=seen[1]))
        self._came = came
        return kept


def with_wall(obstacles, wall):
    """Return OBSTACLES (StaticObstacles or None) with the segment WALL (2, 2) [m] added."""
    if obstacles is None:
        obstacles = StaticObstacles.empty()
    return StaticObstacles(np.concatenate([obstacles.segments, wall[None]]),
                           np.append(obstacles.half_widths, 0.0), obstacles.disc_centres,
                           obstacles.disc_radii)


def _centre_line_to(passage, exit_end, point):
    """Return a centre line (K, 2) [m] of PASSAGE that ends at end EXIT_END's entrance.

    Centre lines run from the first end to each other; to the first end, the one nearest POINT
    (2,) [m], reversed.
    """
    if exit_end > 0:
        return passage.centre_lines[exit_end - 1]
    return min(passage.centre_lines, key=lambda line: _nearest_on(line, point)[1])[::-1]


def _nearest_on(line, point):
    """Return (the length [m] along LINE (K, 2) of its point nearest POINT (2,), the distance)."""
    if len(line) == 1:
        return 0.0, math.hypot(*(line[0] - point))
    edges = np.diff(line, axis=0)
    lengths = np.linalg.norm(edges, axis=1)
    fraction = np.clip(np.einsum('ij,ij->i', point - line[:-1], edges)
                       / np.maximum(lengths ** 2, 1e-300), 0.0, 1.0)
    distances = np.linalg.norm(line[:-1] + fraction[:, None] * edges - point, axis=1)
    index = int(np.argmin(distances))
    return float(np.sum(lengths[:index]) + fraction[index] * lengths[index]), distances[index]


def _ahead_on(line, point, distance):
    """Return the point (2,) of LINE (K, 2) DISTANCE [m] along it past its nearest to POINT."""
    return _at_lengths(line, np.array([_nearest_on(line, point)[0] + distance]))[0]


def _nearest_end(ends, point):
    """Return the index of the end of ENDS whose entrance is nearest POINT (2,)."""
    return int(np.argmin([math.hypot(*(end.entrance - point)) for end in ends]))


def _sampled(line, step, reach):
    """Return (points (K, 2), lengths (K,)): LINE (N, 2) sampled every STEP [m] up to REACH."""
    total = float(np.sum(np.linalg.norm(np.diff(line, axis=0), axis=1)))
    along = np.arange(0.0, min(total, reach) + step, step)
    along[-1] = min(along[-1], total)
    return _at_lengths(line, along), along


def _at_lengths(line, along):
    """Return the points (K, 2) of LINE (N, 2), N >= 2, at the lengths ALONG (K,) [m] on it."""
    edges = np.diff(line, axis=0)
    lengths = np.linalg.norm(edges, axis=1)
    starts = np.concatenate([[0.0], np.cumsum(lengths)])
    index = np.clip(np.searchsorted(starts, along, side='right') - 1, 0, len(edges) - 1)
    fraction = (along - starts[index]) / np.maximum(lengths[index], 1e-300)
    return line[index] + np.clip(fraction, 0.0, 1.0)[:, None] * edges[index]

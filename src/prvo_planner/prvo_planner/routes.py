"""Routes: the way a robot says it will take, and the checks a neighbour's route must pass.

ROS-free. A planner heading for a goal publishes its intent on `<robot>/plan` (a
`nav_msgs/Path`) whenever it changes (`RouteIntent`): the route on its map, or without a map
(or before the map's route is searched) the straight way from where it stands to its goal; at
its goal its goal alone, and while no way on its map reaches the goal its own position alone
(it holds its place). A route is stamped like an announcement (`route_stamp`): it holds for
the neighbours' plans of odometry stamped strictly later, so that in lockstep a route made by
the plan of step `t_k` is seen by every neighbour from its plan of `t_(k+1)` on, on both
engines. A neighbour's route that cannot be used (`checked_route`), or that changes too often
to be a claim (`RouteFlips`), claims nothing: its neighbours treat the robot as one without a
route.
"""

import dataclasses
import math

import numpy as np

# Command.route_status: no map (or no goal), a way to the goal found, no way reaches the goal.
ROUTE_NONE = 'none'
ROUTE_FOUND = 'ok'
ROUTE_UNREACHABLE = 'unreachable'
# Points kept of one neighbour's route at most: the poses a planner reads of any path message
# (prvo_msgs_util.MAX_PATH_POSES); longer routes are refused whole.
MAX_ROUTE_POINTS = 10_000
# The stamp of a route made by the plan of stamp 0 (the simulator's clock starts at 0): 1 ns,
# so that it counts from the next plan on, not from the start.
_AFTER_STAMP_ZERO = 1e-9
# A neighbour's route that changes more than FLIP_CHANGES times within FLIP_WINDOW [s] of its
# stamps flips (`RouteFlips`). A planner's route changes with a new goal, a new way on its map,
# an arrival: a few times a minute; Nav2's planner_server replans at 1 Hz by default. A route
# that changes every step of a 10 Hz loop is no claim another robot can keep its turn by.
FLIP_WINDOW = 5.0
FLIP_CHANGES = 10


@dataclasses.dataclass(frozen=True)
class NeighbourRoute:
    """A neighbour's route: `points` (K, 2) [m, the map frame; read-only] and its `stamp` [s].

    It holds for the plans of odometry stamped after `stamp` (0: for every plan). `end` is its
    last point as two floats: every plan of every robot asks how near each neighbour is to it.
    """

    points: np.ndarray
    stamp: float
    end: tuple = dataclasses.field(init=False, repr=False, compare=False)

    def __post_init__(self):
        object.__setattr__(self, 'end', tuple(self.points[-1].tolist()))


def route_stamp(plan_stamp):
    """Return the stamp [s] to publish the route made by the plan of PLAN_STAMP [s] with."""
    return max(float(plan_stamp), _AFTER_STAMP_ZERO)


def checked_route(points):
    """Return POINTS as a read-only float array (K, 2) of a route, 1 <= K <= MAX_ROUTE_POINTS.

    Raises ValueError naming the fault: an empty route, one of another shape, too many
    points, a coordinate that is not finite.
    """
    route = np.array(points, dtype=float)
    if route.ndim != 2 or route.shape[1:] != (2,):
        raise ValueError(f'a route is (K, 2) points, got shape {route.shape}')
    if len(route) == 0:
        raise ValueError('the route is empty')
    if len(route) > MAX_ROUTE_POINTS:
        raise ValueError(f'the route has {len(route)} points, more than {MAX_ROUTE_POINTS}')
    if not np.all(np.isfinite(route)):
        index = int(np.flatnonzero(~np.all(np.isfinite(route), axis=1))[0])
        raise ValueError(f'the route has a point that is not finite: points[{index}] = '
                         f'{route[index].tolist()}')
    # Every plan until the next route shares it.
    route.flags.writeable = False
    return route


class RouteFlips:
    """Neighbours whose routes change too often to be claims: they claim nothing while they do.

    A route the same as the one before (a publisher that sends it again) is no change. A
    neighbour flips while more than FLIP_CHANGES of its changes fall within FLIP_WINDOW before
    the stamp of its newest route: each route it sends then is refused, until its changes slow.
    """

    def __init__(self):
        # robot -> (its last route (K, 2), the stamps [s] of its changes within the window).
        self._seen = {}

    def check(self, robot, route, stamp):
        """Count ROBOT's ROUTE (K, 2) stamped STAMP [s]; raise ValueError while ROBOT flips."""
        last, changes = self._seen.get(robot, (None, ()))
        changes = [changed for changed in changes if changed > stamp - FLIP_WINDOW]
        if last is None or not np.array_equal(last, route):
            changes.append(stamp)
        self._seen[robot] = (route, changes[-(FLIP_CHANGES + 1):])
        if len(changes) > FLIP_CHANGES:
            raise ValueError(f'the route changed {len(changes)} times within {FLIP_WINDOW:g} s, '
                             f'more than {FLIP_CHANGES}: it flips, and claims nothing until it '
                             'changes less often')

    def forget(self, robot):
        """Forget ROBOT (it left): a robot heard anew starts with no changes counted."""
        self._seen.pop(robot, None)


class RouteIntent:
    """What a robot heading for a goal publishes of its way, once per change.

    The way changes with the goal, with the route on the map (a new one is taken when the
    robot strays from it), when the robot arrives (it then states its goal alone) and when it
    departs again: farther than DEPARTURES tolerances from its goal, as the agent counts a new
    arrival, so that noise that carries a robot standing at its goal in and out of the
    tolerance does not make its route flip.
    """

    def __init__(self, departures):
        self._departures = departures
        # What the route published last was made of (`_key`), None before the first, and the
        # map's route it was (None: another kind), compared by identity.
        self._published = None
        self._published_route = None
        self._at_goal = False

    def update(self, command, goal, goal_tolerance):
        """Return the route (K, 2) to publish after COMMAND (an agent `Command`), or None.

        GOAL (2,) is the goal in force (None: none), GOAL_TOLERANCE [m] the agent's. None: the
        route published last holds. An empty route (0, 2) withdraws it: the robot's goal was
        taken away.
        """
        position = command.own.mean[:2]
        if goal is None:
            self._at_goal = False
            key, route = ('none',), np.empty((0, 2))
        else:
            # At a new goal only once the agent finds it there.
            kept = self._published is not None and self._published[1:] == (tuple(goal.tolist()),)
            distance = math.hypot(*(goal - position))
            self._at_goal = command.arrived or (
                kept and self._at_goal and distance <= self._departures * goal_tolerance)
            key, route = self._key(command, goal, position)
        if self._published is None and goal is None:
            # Nothing was published: there is nothing to withdraw.
            return None
        map_route = command.route if key[0] == 'map' else None
        if key == self._published and map_route is self._published_route:
            return None
        self._published, self._published_route = key, map_route
        return route

    def _key(self, command, goal, position):
        """Return (what the route is made of, the route (K, 2)) heading for GOAL."""
        target = tuple(goal.tolist())
        if self._at_goal:
            return ('goal', target), goal[np.newaxis].copy()
        if command.route is not None:
            # A route on the map is taken anew only when the robot strays from it.
            return ('map', target), command.route
        if command.route_status == ROUTE_UNREACHABLE:
            return ('hold', target), position[np.newaxis].copy()
        return ('straight', target), np.array([position, goal])

"""The PRVO robot without ROS: measurements in, a world-frame velocity command out.

A `PlannerAgent` tracks its own robot and its neighbours from odometry measurements
(`prvo_msgs_util.OdometryMeasurement` or anything with the same fields), waits for the
neighbours' measurements of the stamp it plans for, applies the goal logic and plans with
`prvo_planner.core.plan_velocity`, taking each neighbour's size and share of the avoidance from
its stamped announcements (`AnnouncedValues`, `NeighbourAnnouncement`). It never reads a clock:
every call that needs the time of day takes `now`, monotonic seconds of the caller's choosing.
The planner node wraps it in ROS endpoints; an in-process engine can feed it step by step.

Given an occupancy grid (`set_map`), the agent plans against the obstacles of the grid near it
and, heading for its goal, follows a carrot on the shortest route there instead of the straight
line.
"""

import dataclasses
import functools
import math

import numpy as np

from prvo_planner.announced import (  # noqa: F401 (MAX_KEPT_ANNOUNCEMENTS: the agent's bound)
    ANNOUNCED_FROM_THE_START,
    MAX_KEPT_ANNOUNCEMENTS,
    AnnouncedValues,
    HeldValues,
    held,
)
from prvo_planner.core import AgentBelief, VelocityLimits, plan_velocity
from prvo_planner.core.beliefs import validated_share
from prvo_planner.core.standing import standing_decided
from prvo_planner.detours import DetourWatch
from prvo_planner.escalation import (
    ROOM_RADII,
    TURN_MAX,
    TURN_RATE,
    Escalation,
    EscalationSettings,
)
from prvo_planner.give_way import (
    HELD_WINDOW,
    PASSING_SPEED,
    give_way_spot,
    held_short,
    held_spot,
    way_ahead,
    way_left,
)
from prvo_planner.lanes import KEEP_RIGHT, keep_right
from prvo_planner.maps import (
    GridMap,
    MapTooLargeError,
    ObstacleIndex,
    check_route_work,
    grid_obstacles,
    occupied_at,
    occupied_cells,
    way_out,
)
from prvo_planner.narrows import find_passages
from prvo_planner.passages import narrow_passage
from prvo_planner.passing import at_goal, pass_beside
from prvo_planner.path_following import carrot, closest_on_path
from prvo_planner.preferred import (
    GOAL,
    PATH,
    VELOCITY,
    FilterGate,
    LookaheadSettings,
    PathFollower,
    path_preferred_velocity,
)
from prvo_planner.right_of_way import (
    IdleWatch,
    PassageMap,
    QueueWatch,
    waiting_at,
    with_wall,
)
from prvo_planner.route import RouteMap, path_length
from prvo_planner.routes import (
    ROUTE_FOUND,
    ROUTE_NONE,
    ROUTE_UNREACHABLE,
    NeighbourRoute,
    RouteFlips,
    checked_route,
)
from prvo_planner.stalls import StallMonitor, binding_conditions
from prvo_planner.tracking import TrackingModel, tracking_command
from prvo_planner.tracks import TrackTable, fuse

# Plans for a made-up encounter in warm_up().
_WARM_UP_PLANS = 3
# An arrival counts again only after the robot was this many goal tolerances from the goal:
# odometry noise carries a robot standing at its goal in and out of the tolerance.
DEPARTURE_TOLERANCES = 2.0

# A command below this [m/s] is standing still.
_STANDING_SPEED = 1e-6
# An upstream command goes on unchanged when the plan nearest to it is within this [m/s].
_PASSING_SLACK = 1e-6
# Every model of the core (prvo and its baselines rvo, inflate, mc) is reciprocal: it takes half
# of a pair's avoidance against a neighbour that takes the other half.
RECIPROCAL_SHARE = 0.5
# A neighbour that has not announced its share is assumed not to avoid.
UNANNOUNCED_SHARE = 0.0
# The stamp of a change made by the plan of stamp 0 (the simulator's clock starts at 0): 1 ns,
# the first stamp after 0 a message can carry, so that it does not hold from the start.
_AFTER_STAMP_ZERO = 1e-9
# Configs kept per plan horizon and control period: the horizon shrinks near the goal, so the
# pairs are few but not bounded.
MAX_PLANNING_CONFIGS = 32


@dataclasses.dataclass(frozen=True)
class NeighbourAnnouncement:
    """What a robot states about itself: its disk radius [m] and its share of the avoidance.

    `avoidance_share` is in [0, 1): 0.5 for a reciprocating planner, 0 for a robot that does
    not avoid. Raises ValueError naming the field for a value the planner cannot use.
    """

    radius: float
    avoidance_share: float

    def __post_init__(self):
        radius = float(self.radius)
        if not (np.isfinite(radius) and radius > 0.0):
            raise ValueError(f'radius must be finite and > 0, got {self.radius!r}')
        object.__setattr__(self, 'radius', radius)
        object.__setattr__(self, 'avoidance_share',
                           validated_share(self.avoidance_share, 'avoidance_share'))


@functools.lru_cache(maxsize=256)
def _announcement(radius, avoidance_share):
    """Return the `NeighbourAnnouncement` of the pair: a team announces few, every plan each."""
    return NeighbourAnnouncement(radius, avoidance_share)


def preferred_velocity(position, goal, max_speed, approach_time, goal_tolerance,
                       max_acceleration=math.inf):
    """Return (v_pref (2,), arrived): straight to the goal, slowing over the last stretch.

    With a finite MAX_ACCELERATION the speed is also at most the one that can still brake to a
    stop at the goal, sqrt(2 a d).
    """
    if goal is None:
        return np.zeros(2), False
    offset = goal - position
    distance = float(np.hypot(*offset))
    if distance <= goal_tolerance:
        return np.zeros(2), True
    speed = min(max_speed, distance / approach_time, math.sqrt(2.0 * max_acceleration * distance))
    return offset * (speed / distance), False


def route_preferred_velocity(position, goal, route, segment, lookahead, max_speed,
                             approach_time, goal_tolerance, max_acceleration=math.inf,
                             in_sight=None, shortest_lookahead=0.0):
    """Return (v_pref (2,), arrived, segment, remaining): toward the carrot on a route.

    ROUTE (K, 2) ends at GOAL; SEGMENT is the robot's progress along it (see
    `path_following.carrot`). The direction is the carrot's, LOOKAHEAD [m] ahead on the route,
    or half as far, and so on, until IN_SIGHT(position, carrot) (if given) holds or the
    lookahead is SHORTEST_LOOKAHEAD: a carrot beyond a corner would pull the robot into the
    corner. A carrot in sight moves on to the farthest waypoint beyond it still in sight: a
    carrot close ahead turns the robot back to its route at every push aside, and in a crowd
    that fights the sidesteps of the avoidance (with the goal in sight the robot heads for it,
    as without a map). The speed slows over the last stretch as `preferred_velocity` does, by the
    REMAINING length [m] of the way: from the robot to its closest point on the route, then
    along the route.
    """
    if float(np.hypot(*(goal - position))) <= goal_tolerance:
        return np.zeros(2), True, segment, 0.0
    target, reached = carrot(route, position, lookahead, segment)
    if in_sight is not None:
        if in_sight(position, target):
            target = _farthest_in_sight(route, position, target, reached, lookahead, in_sight)
        while lookahead > shortest_lookahead and not in_sight(position, target):
            lookahead *= 0.5
            target, reached = carrot(route, position, lookahead, segment)
    segment = reached
    segment, closest = closest_on_path(route, position, segment)
    remaining = float(np.hypot(*(closest - position)))
    if segment + 1 < len(route):
        remaining += float(np.hypot(*(route[segment + 1] - closest))) + path_length(
            route[segment + 1:])
    offset = target - position
    distance = float(np.hypot(*offset))
    if distance == 0.0:
        return np.zeros(2), False, segment, remaining
    speed = min(max_speed, remaining / approach_time,
                math.sqrt(2.0 * max_acceleration * remaining))
    return offset * (speed / distance), False, segment, remaining


def _farthest_in_sight(route, position, target, segment, lookahead, in_sight):
    """Return the last waypoint of ROUTE beyond TARGET, in order, still IN_SIGHT; else TARGET.

    The waypoints after SEGMENT at least LOOKAHEAD from POSITION are those beyond the carrot.
    """
    for waypoint in route[segment + 1:]:
        if float(np.hypot(*(waypoint - position))) < lookahead:
            continue
        if not in_sight(position, waypoint):
            break
        target = waypoint
    return target


def goal_horizon(distance_to_goal, max_speed, approach_time, time_horizon):
    """Return the time horizon of one plan [s]: no longer than the way to the goal takes.

    A robot that stops at its goal in about distance / max_speed, plus approach_time of slowing
    down, cannot collide later on the straight line it is planned on; without this cap, robots
    standing beyond a goal would forbid approaching it.
    """
    return min(time_horizon, distance_to_goal / max_speed + approach_time)


def nobody_comes(problem):
    """Whether standing still meets every neighbour's condition on the mean states.

    PROBLEM is the argument tuple of `plan_velocity`. Standing still is judged as the
    deterministic RVO baseline judges it (means only, the neighbours' shares and sizes): under
    noise the relative velocity of two robots that both stand has no mean direction, and no
    chance constraint can certify it, although nobody comes. That is whether the baseline's plan
    (inertia 0) stands; its conditions at zero tell, without the plan
    (`core.standing.standing_decided`), unless the robot prefers to move or stands on an edge.
    """
    ego, neighbours, v_pref, config = problem[:4]
    if not (v_pref[0] or v_pref[1]):
        decided = standing_decided(ego, neighbours, config, _STANDING_SPEED)
        if decided is not None:
            return decided
    result = plan_velocity(ego, neighbours, v_pref,
                           dataclasses.replace(config, model='rvo', inertia=0.0))
    # The core keeps its choice a hair inside a feasible interval: zero comes out as ~1e-9 m/s.
    return result.feasible and float(np.hypot(*result.velocity)) <= _STANDING_SPEED


@dataclasses.dataclass(frozen=True)
class AgentSettings:
    """The agent's settings besides the core's PlannerConfig; names as the node's parameters.

    `unknown_neighbor_radius` is assumed for a neighbour that announced no footprint;
    `neighbor_timeout` is in the seconds of the `now` arguments. `kinematics` is 'holonomic' or
    'unicycle' (which tracks its plans within `tracking_error` and plans, and announces itself,
    with its radius grown by it); the acceleration limits are inf when unlimited.
    """

    radius: float = 0.3
    unknown_neighbor_radius: float = 0.5
    approach_time: float = 0.5
    goal_tolerance: float = 0.2
    acceleration_std: float = 2.0
    neighbor_timeout: float = 2.0
    kinematics: str = 'holonomic'
    max_angular_speed: float = 2.0
    max_acceleration: float = math.inf
    max_angular_acceleration: float = math.inf
    tracking_error: float = 0.1
    tracking_horizon: float = 0.5
    # Where the preferred velocity comes from (`prvo_planner.preferred`); model 'none': the
    # command is the preferred velocity, unplanned.
    preferred_source: str = GOAL
    model: str = 'prvo'
    wait_for_path: bool = False
    lookahead_dist: float = 1.0
    use_velocity_scaled_lookahead_dist: bool = False
    min_lookahead_dist: float = 0.3
    max_lookahead_dist: float = 0.9
    lookahead_time: float = 1.5
    stop_pub_timeout: float = 2.0
    state_timeout: float = 1.0
    obstacle_distance: float = 3.0
    unknown_is_occupied: bool = True
    route_margin: float = 0.3
    wait_for_map: bool = False
    stall_escalation: bool = False
    stall_turn_rate: float = TURN_RATE
    stall_turn_max: float = TURN_MAX
    keep_right: float = KEEP_RIGHT
    give_way: bool = True
    right_of_way: bool = True

    @classmethod
    def from_parameters(cls, values):
        """Return the settings named in the mapping VALUES (extra names are ignored)."""
        return cls(**{field.name: values[field.name] for field in dataclasses.fields(cls)})

    @property
    def unicycle(self):
        """Whether the robot is differential drive."""
        return self.kinematics == 'unicycle'

    @property
    def planning_radius(self):
        """Return the radius the robot plans with [m]: grown by the tracking error if any."""
        return self.radius + self.tracking_error if self.unicycle else self.radius

    @property
    def avoids(self):
        """Whether the robot avoids its neighbours (model other than 'none')."""
        return self.model != 'none'

    @property
    def lookahead(self):
        """Return the `LookaheadSettings` of following a path, or a goal's route on a map."""
        return LookaheadSettings(self.lookahead_dist, self.use_velocity_scaled_lookahead_dist,
                                 self.min_lookahead_dist, self.max_lookahead_dist,
                                 self.lookahead_time)

    @property
    def escalation(self):
        """Return the `EscalationSettings` of a stalled robot's turn."""
        return EscalationSettings(self.stall_escalation, self.stall_turn_rate,
                                  self.stall_turn_max)

    def tracking_model(self, max_speed):
        """Return the `TrackingModel` of a unicycle with these settings and MAX_SPEED."""
        return TrackingModel(max_speed, self.max_angular_speed, self.max_acceleration,
                             self.max_angular_acceleration, self.tracking_horizon,
                             self.tracking_error)


@dataclasses.dataclass(frozen=True, eq=False)
class BuiltMap:
    """What an agent plans with of a map: made once per map and settings, never changed after.

    `built_for` is the `PlannerAgent.map_key` it was made for; `obstacle_index` holds the grid's
    obstacles (`maps.ObstacleIndex`), `route_map` its route graph (`route.RouteMap`),
    `passage_map` its passages (`right_of_way.PassageMap`, None without `right_of_way`, or
    where finding them would take more than `narrows.find_passages` allows: `passages_refused`
    says why) and `route_tree` the shortest paths on it to `goal` (None without a goal).
    `build_map` makes it from the grid and the key alone, in any thread: a node builds a large
    map beside its planning and swaps the result in whole (`PlannerAgent.install_map`), so that
    no plan ever sees a map half made.
    """

    grid: GridMap
    built_for: tuple
    obstacle_index: ObstacleIndex
    route_map: RouteMap
    passage_map: PassageMap
    goal: np.ndarray = None
    route_tree: object = None
    passages_refused: str = None


def same_grid(grid, other):
    """Whether the `maps.GridMap`s GRID and OTHER are the same map, cell for cell."""
    return (grid.resolution == other.resolution and np.array_equal(grid.origin, other.origin)
            and np.array_equal(grid.cells, other.cells))


def map_key_of(settings, safety_margin):
    """Return what a `BuiltMap` depends on besides the grid: the map key of these settings."""
    # The route's cells keep the clearance the planner keeps from a wall of no thickness.
    return (settings.unknown_is_occupied, settings.obstacle_distance,
            settings.planning_radius + safety_margin, settings.route_margin,
            settings.right_of_way)


def check_map_work(shape, resolution, built_for):
    """Raise `maps.MapTooLargeError` if a grid of SHAPE, RESOLUTION is beyond the bounds.

    BUILT_FOR is the map key the grid would be built for (its route's clearance and margin).
    """
    _, _, clearance, route_margin, _ = built_for
    check_route_work(shape, resolution, clearance + route_margin)


def build_map(grid, built_for, goal=None):
    """Return the `BuiltMap` of GRID for the map key BUILT_FOR, with the paths to GOAL (2,).

    Raises `maps.MapTooLargeError` at once for a map whose route is beyond the bounds.
    """
    check_map_work(grid.shape, grid.resolution, built_for)
    unknown_is_occupied, obstacle_distance, clearance, route_margin, passages = built_for
    route_map = RouteMap(occupied_cells(grid, unknown_is_occupied), grid.resolution,
                         grid.origin, clearance, route_margin)
    # With the right of way, the passages for robots of the route's clearance, each keeping the
    # route's margin beside its lane: the same for a team built alike (`prvo_planner.narrows`).
    # A map whose passages are beyond their bounds is still planned on, without turns.
    passage_map, refused = None, None
    if passages:
        try:
            passage_map = PassageMap(grid, find_passages(grid, clearance, route_margin,
                                                         unknown_is_occupied), clearance)
        except MapTooLargeError as error:
            refused = str(error)
    return BuiltMap(grid, built_for, ObstacleIndex(grid_obstacles(grid, unknown_is_occupied),
                                                   obstacle_distance),
                    route_map, passage_map,
                    None if goal is None else np.array(goal, dtype=float),
                    None if goal is None else route_map.tree_to(goal), refused)


@dataclasses.dataclass(frozen=True)
class PlanTally:
    """What the robot's plans achieved since its agent started (a new goal keeps counting).

    A plan is one the core made (`PlanResult`); standing still without one is none. `plans`
    counts them, `infeasible` those without a velocity that meets every constraint;
    `min_achieved_eta` is the lowest eta bound a plan achieved and `last_stamp` the stamp of
    the last plan counted, both None before the first.
    """

    plans: int = 0
    infeasible: int = 0
    min_achieved_eta: float | None = None
    last_stamp: float | None = None

    def counted(self, result, stamp):
        """Return this tally with RESULT, the core's plan for STAMP, counted."""
        eta = float(result.eta_bound)
        return PlanTally(
            self.plans + 1, self.infeasible + (not result.feasible),
            eta if self.min_achieved_eta is None else min(self.min_achieved_eta, eta), stamp)


@dataclasses.dataclass(frozen=True)
class Command:
    """One plan: the command for `stamp` and what it was planned from.

    `velocity` (2,) is in the world frame; `yaw` is the robot's yaw measured at `stamp`, to turn
    it into the body frame. `result` is the core's PlanResult, None when the robot stands still
    (no goal, or at its goal while nobody comes). `own` and `neighbours` are the `StateBelief`s
    at `stamp`; `neighbour_names` and `announcements` (`NeighbourAnnouncement`s, defaults for
    what was not announced) are in the same order. `drive` is a unicycle's (forward speed, turn
    rate) that tracks `velocity`, None for a holonomic robot. `arrival` marks the first plan at
    the goal since the robot set off for it. `tally` is the agent's `PlanTally` with this plan.
    In the velocity mode `upstream` is the `UpstreamCommand` answered, `passed_through` whether
    it goes on unchanged (nothing constrained it) and `published` whether the answer is sent
    (`FilterGate`). `route` (K, 2) is the way to the goal the plan followed (None without a map
    or a way) and `route_status` ROUTE_NONE (no map, no goal or another preferred source),
    ROUTE_FOUND or ROUTE_UNREACHABLE (the robot holds its place). `stall` is the robot's
    `stalls.StallStatus` at `stamp` and `binding` the plan's `stalls.binding_conditions` while
    it is stalled (empty otherwise); `narrow_passage` the `passages.NarrowPassage` ahead that
    it is stalled in front of, found when the stall began (None otherwise). `inside_obstacle`
    is (position (2,), way out (2,) or None) while the robot's centre is in an occupied cell of
    its map: it heads for the nearest free cell, the way out, and the map's obstacles do not
    constrain it until it is there (None otherwise). `neighbour_routes`, in the order of
    `neighbour_names`, is each neighbour's `routes.NeighbourRoute` for `stamp`
    (`PlannerAgent.route_of`: the newest it published with a stamp before `stamp`), None where
    it has none. `right_of_way` is the robot's `right_of_way.Decision` at the passage on its
    route (None: none, or `right_of_way` off), `idle_in_passage` the sorted names of the
    neighbours in that passage that stood in it too long and claim nothing
    (`right_of_way.IdleWatch`). `awaiting_map` marks a zero command held for a map still being
    built (`PlannerAgent.awaiting_map`).
    """

    stamp: float
    velocity: np.ndarray
    yaw: float
    result: object
    arrived: bool
    own: object
    neighbours: tuple
    neighbour_names: tuple
    announcements: tuple
    drive: tuple = None
    arrival: bool = False
    tally: PlanTally = PlanTally()
    upstream: object = None
    passed_through: bool = False
    published: bool = True
    route: np.ndarray = None
    route_status: str = ROUTE_NONE
    stall: object = None
    binding: tuple = ()
    narrow_passage: object = None
    inside_obstacle: tuple = None
    neighbour_routes: tuple = ()
    awaiting_map: bool = False
    right_of_way: object = None
    idle_in_passage: tuple = ()

    def announcement_values(self):
        """Return {'neighbour.<robot>.radius': m, 'neighbour.<robot>.avoidance_share': a}."""
        values = {}
        for robot, announcement in zip(self.neighbour_names, self.announcements, strict=True):
            values[f'neighbour.{robot}.radius'] = announcement.radius
            values[f'neighbour.{robot}.avoidance_share'] = announcement.avoidance_share
        return values

    def route_values(self):
        """Return {'neighbour.<robot>.route_points': K, 'neighbour.<robot>.route_stamp': s}.

        Of each neighbour's route the plan held: its point count and stamp; 0 and 'none' for a
        neighbour without one.
        """
        values = {}
        for robot, route in zip(self.neighbour_names, self.neighbour_routes, strict=True):
            values[f'neighbour.{robot}.route_points'] = 0 if route is None else len(route.points)
            values[f'neighbour.{robot}.route_stamp'] = 'none' if route is None else route.stamp
        return values


@dataclasses.dataclass(frozen=True)
class PlanRequest:
    """One plan about to be made: the beliefs at `stamp` and the core's problem.

    `problem` is the argument tuple of `prvo_planner.core.plan_velocity` (ego, neighbours,
    v_pref, config, previous, limits), or None when the robot stands still (no goal, or at its
    goal while nobody comes). `arrival` as in `Command`. `unplanned` is the velocity (2,)
    commanded without a plan (model 'none', or an upstream command passed through), None when
    there is none; `upstream` the `UpstreamCommand` answered (velocity mode) and `passed_through`
    whether it goes on unchanged. `obstacles` are the `StaticObstacles` of its map near it,
    passed as `plan_velocity(*problem, obstacles=obstacles)`, None without a map or with
    nothing near; `route`, `route_status`, `stall`, `inside_obstacle`, `neighbour_routes` and
    `awaiting_map` as in `Command`.
    """

    stamp: float
    own: object
    neighbours: tuple
    neighbour_names: tuple
    announcements: tuple
    problem: tuple
    arrival: bool = False
    unplanned: np.ndarray = None
    upstream: object = None
    passed_through: bool = False
    obstacles: object = None
    route: np.ndarray = None
    route_status: str = ROUTE_NONE
    stall: object = None
    inside_obstacle: tuple = None
    neighbour_routes: tuple = ()
    awaiting_map: bool = False


class PlannerAgent:
    """PRVO planner of one robot, without ROS.

    Parameters
    ----------
    name : str
        The robot's name (it is never its own neighbour).
    config : prvo_planner.core.PlannerConfig
        The core's configuration; `max_speed` also caps the preferred velocity.
    settings : AgentSettings
        Radii, goal approach, tracker noise and neighbour timeout.
    goal : array_like (2,) or None
        Goal in the world frame; None: stand still until `set_goal`.
    listed_neighbours : iterable of str or None
        Robots to wait for from the first own measurement on (for up to `neighbor_timeout`)
        before the first plan; None: plan with whoever has been heard.
    neighbour_tracks : prvo_planner.tracks.TrackTable or None
        Where the neighbours' measurements go. None: the agent's own table, fed by
        `receive_neighbour` and retuned by `reconfigure`. Agents fed the same measurements at
        the same `now` may share one table fed once per measurement by their caller (it may
        hold the agent's own robot too: the agent never plans against itself); the caller
        then keeps its settings.

    Use: `receive_own` and `receive_neighbour` for every measurement, `receive_footprint` and
    `receive_share` for every announcement (announce `own_announcement` with
    `own_announcement_stamp` after each plan and each `reconfigure`); when `ready(now)`, or when
    the caller's wait for neighbours (`sync_timeout`) ran out and `awaiting_listed(now)` is
    false, `plan()` returns the `Command` for the pending own stamp.

    """

    def __init__(self, name, config, settings=AgentSettings(), goal=None,
                 listed_neighbours=None, neighbour_tracks=None):
        self.name = name
        self.config = config
        self.settings = settings
        self.goal = None if goal is None else np.asarray(goal, dtype=float)
        self.listed_neighbours = (
            None if listed_neighbours is None else set(listed_neighbours) - {name})
        self.arrived = False
        # Whether this goal's arrival was reported, until the robot leaves the goal's vicinity.
        self._arrival_reported = False
        self._own_track = None
        self._owns_tracks = neighbour_tracks is None
        self._neighbour_tracks = (
            TrackTable(settings.acceleration_std, settings.neighbor_timeout)
            if neighbour_tracks is None else neighbour_tracks)
        # Announced by each neighbour, with the stamps they hold after: robot -> AnnouncedValues.
        self._announced_radius = {}
        self._announced_share = {}
        # The routes each neighbour published on <robot>/plan, likewise (`receive_route`).
        self._announced_route = {}
        # How often each neighbour's route changes (`routes.RouteFlips`).
        self._route_flips = RouteFlips()
        # Each neighbour's announcement and route that held for the last plan (`_held_of`).
        self._held = HeldValues(2)
        self._pending_stamp = None
        self._own_yaw = 0.0
        # The last planned velocity in the world frame, for the inertia term; None after a stop.
        self._previous_velocity = None
        # The command in force (world frame, zero at the start) and the stamp it answered: the
        # acceleration limits act on its change. A unicycle's (forward, turn) likewise.
        self._command_in_force = np.zeros(2)
        self._command_stamp = None
        self._drive = (0.0, 0.0)
        self._control_period = None
        # (the config they were made of, {(horizon, control period): config}): `_problem`'s.
        self._planning_configs = (None, {})
        # Listed neighbours are waited for from the first own measurement on, not from start-up:
        # a team's processes start at different speeds, and a run begins with all of them.
        self._first_own_at = None
        self.tally = PlanTally()
        self.stall_monitor = StallMonitor()
        # The passage too narrow to certify that the stall in progress is in front of.
        self._narrow_passage = None
        self.escalation = Escalation()
        # The spot beside a neighbour's route the robot gives way at (`give_way`), None: none;
        # held short of its goal, where it stood then, while it gives way.
        self._give_way = None
        self._held_at = None
        # The neighbour a held robot gives way to: it goes on yielding to it until it went by.
        self._yielding_to = None
        # Whether it stands at that spot (within the goal tolerance): it announces no share then.
        self._aside = False
        # The right of way at the passage on its route (`right_of_way.Decision`), None: none;
        # the neighbours standing in a passage (`right_of_way.IdleWatch`), and those of them
        # that stood too long and claim nothing (sorted names); when each came to the passage
        # it uses (`right_of_way.QueueWatch`).
        self.passage_decision = None
        self.idle_in_passage = ()
        self._idle_watch = IdleWatch()
        self._queue_watch = QueueWatch()
        # How long it waited at a passage, and the ways round those it avoids (`detours`).
        self._detours = DetourWatch()
        # Search a way round in the plan that needs it; False: elsewhere (`way_round_wanted`).
        self.search_ways_round = True
        # The path followed (path mode); the upstream command waiting for its answer, when it
        # came and the last one answered (velocity mode); when the own state was last received.
        self._path = None
        self._upstream = None
        self._upstream_received_at = None
        self._upstream_answered = None
        self._own_received_at = None
        # When the first upstream command came: before the first own state, staleness counts
        # from it.
        self._first_upstream_at = None
        self._gate = FilterGate(settings.stop_pub_timeout)
        # The map (set_map) and what the agent made of it; the route to the goal in force.
        self._grid = None
        self._map_built_for = None
        # Whether a map that arrived is being built by the caller (`install_map` ends it).
        self.map_pending = False
        self._obstacle_index = None
        self._route_map = None
        self._passage_map = None
        self._route_tree = None
        self._route = None
        self._route_segment = 0
        self._route_status = ROUTE_NONE

    @property
    def pending_stamp(self):
        """The own stamp waiting for a plan, or None."""
        return self._pending_stamp

    @property
    def neighbours(self):
        """Names of the neighbours tracked now."""
        return set(self._neighbour_names())

    def _neighbour_names(self):
        """Return the names of the neighbours tracked now, in the table's order."""
        return [robot for robot in self._neighbour_tracks.names() if robot != self.name]

    def reconfigure(self, config, settings, goal, rebuild_map=True):
        """Take new parameters; the plan in progress and the tracks go on.

        A GOAL other than the current one is taken as by `set_goal`; None keeps no goal. The map
        in force is made anew for settings it was not made for (`map_outdated`), unless
        REBUILD_MAP is false: the caller then builds it (`build_map`) and installs it, and
        meanwhile the agent plans with the map made for the settings before.
        """
        self.config, self.settings = config, settings
        # A neighbour that announced no size has the size of the settings in force.
        self._held.clear()
        if rebuild_map and self.map_outdated:
            self.install_map(build_map(self._grid, self.map_key, self.route_goal()))
        if goal is None:
            self.goal = None
        elif self.goal is None or not np.array_equal(self.goal, goal):
            self.set_goal(goal)
        self._gate.stop_pub_timeout = settings.stop_pub_timeout
        if self._owns_tracks:
            self._neighbour_tracks.acceleration_std = settings.acceleration_std
            self._neighbour_tracks.neighbor_timeout = settings.neighbor_timeout

    def set_goal(self, goal):
        """Head for a new GOAL (2,): not arrived, no previous command to stay close to."""
        self.goal = np.asarray(goal, dtype=float)
        self.arrived = False
        self._arrival_reported = False
        self._previous_velocity = None
        self._give_way = self._held_at = self._yielding_to = None
        self._aside = False
        self._detours.reset()

    # Measurements -----------------------------------------------------------------------------

    def receive_own(self, measurement, now):
        """Fuse the robot's own MEASUREMENT; return its `Fusion`.

        An accepted one becomes the pending stamp (replacing one not planned yet: a newer
        stamp is what a command should answer).
        """
        self._own_track, fusion = fuse(self._own_track, measurement, now,
                                       self.settings.acceleration_std,
                                       self.settings.neighbor_timeout)
        if fusion.accepted:
            self._own_received_at = now
            if self._first_own_at is None:
                self._first_own_at = now
            self._pending_stamp = measurement.stamp
            self._own_yaw = measurement.yaw
        return fusion

    def receive_neighbour(self, robot, measurement, now):
        """Fuse neighbour ROBOT's MEASUREMENT; return its `Fusion`."""
        return self._neighbour_tracks.receive(robot, measurement, now)

    @property
    def own_announcement(self):
        """What this robot announces: its radius, and its share of the avoidance.

        On its way, the reciprocal share. Without a goal it does not plan, and at its goal (or
        at the spot it gives way at, `_given_way`) it stands until someone comes: its
        neighbours must not count on it mirroring their moves, as a reciprocal planner does (a
        robot heading away from a standing one would otherwise see the standing one's half
        coming after it), so it announces none. A robot that waits
        for its path before its first plan (`wait_for_path`) plans its first step on it: it
        announces the share it will take from the start, so that what its neighbours' first
        plans count on does not depend on whether its path or their plans came first.
        """
        moving = self._moving()
        # A unicycle's path strays up to its tracking error from its plan: its neighbours must
        # keep clear of the grown disc it plans with.
        return NeighbourAnnouncement(
            self.settings.planning_radius, RECIPROCAL_SHARE if moving else UNANNOUNCED_SHARE)

    @property
    def own_announcement_stamp(self):
        """The stamp [s] to announce `own_announcement` with: it holds for plans after it.

        It changes with a plan (the robot arrived) or with new parameters, and the robot's next
        plan is of a later stamp than its last: the last plan's stamp, ANNOUNCED_FROM_THE_START
        before any. A change by the plan of stamp 0 is stamped 1 ns (0 means from the start).
        """
        if self._command_stamp is None:
            return ANNOUNCED_FROM_THE_START
        return max(self._command_stamp, _AFTER_STAMP_ZERO)

    def receive_footprint(self, robot, radius, stamp):
        """Take neighbour ROBOT's RADIUS [m], announced with STAMP [s] (see `receive_share`).

        Raises ValueError naming the value if RADIUS is not finite and > 0 or STAMP not finite
        and >= 0; the neighbour then keeps what it had (its valid announcements, else
        `unknown_neighbor_radius`).
        """
        self._take(self._announced_radius, robot,
                   NeighbourAnnouncement(radius, UNANNOUNCED_SHARE).radius, stamp)

    def receive_share(self, robot, avoidance_share, stamp):
        """Take neighbour ROBOT's share of the avoidance, announced with STAMP [s].

        It holds for the plans of own stamps after STAMP (0: for every plan), whether it
        arrives before or after the own odometry of those stamps: in lockstep a robot stamps a
        change with the step whose plan made it, and the change counts from the next step for
        every robot. Raises ValueError naming the value if the share is not in [0, 1) or STAMP
        not finite and >= 0; the neighbour then keeps what it had (its valid announcements,
        else not avoiding).
        """
        self._take(self._announced_share, robot,
                   validated_share(avoidance_share, 'avoidance_share'), stamp)

    def _take(self, announced, robot, value, stamp):
        stamp = float(stamp)
        if not (math.isfinite(stamp) and stamp >= 0.0):
            raise ValueError(f'announcement stamp must be finite and >= 0, got {stamp!r}')
        announced.setdefault(robot, AnnouncedValues()).add(stamp, value)
        self._held.changed(robot)

    def forget_announcements(self, robot):
        """Drop what ROBOT announced, its route too (it left: one of that name may come back)."""
        for announced in (self._announced_radius, self._announced_share, self._announced_route):
            announced.pop(robot, None)
        self._held.changed(robot)

    def announcement_of(self, robot, stamp):
        """Return the `NeighbourAnnouncement` of ROBOT for the plan of STAMP, defaults filled in.

        For a STAMP no earlier than the last plan's (what no later plan can use is dropped).
        """
        radius, share = (None if robot not in announced else announced[robot].take(stamp)
                         for announced in (self._announced_radius, self._announced_share))
        # What was dropped may still hold for the plans `_held_of` kept.
        self._held.changed(robot)
        return self._filled(radius, share)

    def _filled(self, radius, share):
        """Return the `NeighbourAnnouncement` of RADIUS and SHARE, None: not announced."""
        return _announcement(self.settings.unknown_neighbor_radius if radius is None else radius,
                             UNANNOUNCED_SHARE if share is None else share)

    def _held_of(self, robot, stamp):
        """Return ((`announcement_of`, `route_of`) of ROBOT, after, until) (`HeldValues`).

        Both hold for the plans of the stamps in (after, until].
        """
        (radius, *for_radius), (share, *for_share), (route, *for_route) = (
            held(announced.get(robot), stamp) for announced in (
                self._announced_radius, self._announced_share, self._announced_route))
        return ((self._filled(radius, share), route),
                max(for_radius[0], for_share[0], for_route[0]),
                min(for_radius[1], for_share[1], for_route[1]))

    def forget_neighbours(self, now, wanted=None):
        """Drop neighbours silent longer than neighbor_timeout, or not in WANTED (if given).

        Returns [(robot, seconds silent)] of those dropped. A dropped neighbour's route goes
        with it (it releases what it claimed); its announcements stay until it leaves.
        """
        dropped = self._neighbour_tracks.forget(now, wanted)
        for robot, _ in dropped:
            self.forget_route(robot)
            self._route_flips.forget(robot)
        return dropped

    def receive_route(self, robot, points, stamp):
        """Take neighbour ROBOT's route POINTS (K, 2) [m, the map frame], stamped STAMP [s].

        It holds for the plans of own stamps after STAMP (0: for every plan), as an
        announcement does (`receive_share`); a robot publishes the route its plan of a step made
        stamped with that step (`routes.route_stamp`). Raises ValueError naming the fault for
        a route `routes.checked_route` refuses (empty, not finite, more than MAX_ROUTE_POINTS
        points), a STAMP not finite and >= 0, or a route of a neighbour that flips
        (`routes.RouteFlips`): the neighbour then has no route (`forget_route`), it claims
        nothing.
        """
        try:
            route = checked_route(points)
            self._take(self._announced_route, robot, NeighbourRoute(route, float(stamp)), stamp)
            self._route_flips.check(robot, route, float(stamp))
        except ValueError:
            self.forget_route(robot)
            raise

    def forget_route(self, robot):
        """Drop ROBOT's routes: from now on it has none (it claims nothing) until it sends one."""
        self._announced_route.pop(robot, None)
        self._held.changed(robot)

    def route_of(self, robot, stamp):
        """Return ROBOT's `routes.NeighbourRoute` for the plan of STAMP, None if it has none.

        For a STAMP no earlier than the last plan's (what no later plan can use is dropped).
        """
        self._held.changed(robot)
        return held(self._announced_route.get(robot), stamp)[0]

    # Preferred velocity: goal, path or upstream command --------------------------------------

    def set_path(self, waypoints):
        """Follow the path WAYPOINTS (K, 2) instead of any before; None or K = 0: stop following.

        The goal becomes the path's last waypoint (none without a path). The path followed
        again (its sender re-publishes it) keeps the progress along it. Raises ValueError
        naming what is wrong with WAYPOINTS; the path followed then stays.
        """
        if waypoints is None or len(waypoints) == 0:
            self._path, self.goal, self.arrived = None, None, False
            self._previous_velocity = None
            return
        if self._path is not None and np.array_equal(self._path.waypoints, waypoints):
            return
        self._path = PathFollower(waypoints)
        self.set_goal(self._path.goal)

    @property
    def path(self):
        """The `PathFollower` of the path followed, None without one."""
        return self._path

    def receive_upstream(self, command, now):
        """Take the upstream COMMAND (`UpstreamCommand`) received at NOW, to be answered.

        The next plan answers it (a newer command replaces one not answered yet). Its stamp is
        the next own measurement's, or the last one's when the caller's wait for a newer one
        ran out (`repeat_last_stamp`).
        """
        self._upstream, self._upstream_received_at = command, now
        if self._first_upstream_at is None:
            self._first_upstream_at = now

    def upstream_answer(self, now):
        """Return how the waiting upstream command is to be answered at NOW.

        'stale': by zero (`stale_answer`), the own state is stale; 'repeat': by the last answer
        again (a stamped command no later than the last one answered, for that own state or
        with a newer one pending: its sender re-sent a step, as a lockstep simulator re-sends a
        step not answered and a stand-in answers each state sent, and one step has one answer);
        'plan': by `plan()`, the robot is ready; 'wait': for the first own state, for the own
        state the command's stamp is later than, or for the neighbours (the caller plans at the
        latest when its wait runs out: `repeat_last_stamp`). A command that finds no newer own
        state is answered from the last one.
        """
        upstream = self._upstream
        if self.own_state_stale(now):
            return 'stale'
        if self._own_track is None:
            return 'wait'
        answered = self._upstream_answered
        if (upstream.stamp is not None and answered is not None
                and answered.stamp is not None and upstream.stamp <= answered.stamp
                and (self._pending_stamp is not None
                     or self._command_stamp == self._own_track.stamp)):
            self._upstream = None
            return 'repeat'
        if self._pending_stamp is None:
            if upstream.stamp is not None and upstream.stamp > self._own_track.stamp:
                return 'wait'
            self.repeat_last_stamp()
        return 'plan' if self.ready(now) else 'wait'

    def upstream_superseded(self, stamp, now):
        """Whether the command waiting for its answer is to be answered before a newer one.

        STAMP is the newer command's (None: unstamped), NOW its arrival. A stamped command waits
        for the own state of its stamp (or for the neighbours); when a command of another step
        comes first, the waiting one is answered from the states in hand (`repeat_last_stamp`,
        then `plan`), so that every command gets its own answer. The same step sent again
        replaces it (one step, one answer). Not before the first own state nor while it is stale.
        """
        waiting = self._upstream
        return (waiting is not None and self._own_track is not None
                and not self.own_state_stale(now)
                and (stamp is None or waiting.stamp is None or stamp != waiting.stamp))

    @property
    def upstream_waiting(self):
        """Whether an upstream command waits for its answer."""
        return self._upstream is not None

    def own_state_stale(self, now):
        """Whether no own measurement came within `state_timeout` before NOW.

        Before the first one, the wait counts from the first upstream command: a controller
        started with the robot can send its first command before the robot's first state
        reaches the filter, which waits for it (answering nothing) up to `state_timeout`.
        """
        since = (self._first_upstream_at if self._own_received_at is None
                 else self._own_received_at)
        return since is None or now - since > self.settings.state_timeout

    def repeat_last_stamp(self):
        """Plan the next time for the last own stamp again (no newer measurement came)."""
        if self._pending_stamp is None and self._own_track is not None:
            self._pending_stamp = self._own_track.stamp

    def stale_answer(self):
        """Return the zero `Command` answering the waiting upstream command: no own state.

        The robot's own state is stale (`own_state_stale`): a filter that cannot tell where the
        robot is stops it. None if no command waits or the answer is not to be published.
        """
        upstream, self._upstream = self._upstream, None
        if upstream is None or not self._gate.publishes(True, self._upstream_received_at):
            return None
        self._upstream_answered = upstream
        self._command_in_force, self._drive = np.zeros(2), (0.0, 0.0)
        self._previous_velocity = None
        return Command(stamp=self._command_stamp or 0.0, velocity=np.zeros(2), yaw=self._own_yaw,
                       result=None, arrived=False, own=None, neighbours=(), neighbour_names=(),
                       announcements=(), drive=(0.0, 0.0) if self.settings.unicycle else None,
                       tally=self.tally, upstream=upstream)

    def _has_preference(self):
        """Whether the robot has what it needs to plan: in the velocity mode, a command."""
        return self.settings.preferred_source != VELOCITY or self._upstream is not None

    def _moving(self):
        """Whether the robot is on its way (it then takes its share of the avoidance)."""
        source = self.settings.preferred_source
        if source == VELOCITY:
            return self._upstream_answered is not None and not self._upstream_answered.is_zero
        if (source == PATH and self.settings.wait_for_path and self._path is None
                and self._command_stamp is None):
            return True
        # Standing aside for a passing neighbour the robot is where it should be, as at its goal.
        return self.goal is not None and not self.arrived and not self._aside

    def _preference(self, own):
        """Return (v_pref (2,), arrived, distance to the goal [m]) from the robot's OWN belief.

        The distance is along the path in the path mode and inf without a goal ahead.
        """
        settings = self.settings
        position = own.mean[:2]
        max_speed = self.config.max_speed
        source = settings.preferred_source
        if source == VELOCITY:
            upstream = self._upstream
            velocity = np.zeros(2) if upstream is None else upstream.world_velocity(
                self._own_yaw, settings.unicycle)
            return velocity, False, math.inf
        lookahead = settings.lookahead.distance(float(np.hypot(*own.mean[2:])))
        if source == PATH and self._path is not None:
            return path_preferred_velocity(
                position, self._path, lookahead, max_speed, settings.approach_time,
                settings.goal_tolerance, settings.max_acceleration)
        self._route_status = ROUTE_NONE
        if self._route_map is not None and self.goal is not None:
            return self._route_preference(position, lookahead)
        v_pref, arrived = preferred_velocity(
            position, self.goal, max_speed, settings.approach_time, settings.goal_tolerance,
            settings.max_acceleration)
        return v_pref, arrived, (
            math.inf if self.goal is None else float(np.hypot(*(self.goal - position))))

    def _route_preference(self, position, lookahead):
        """Return (v_pref, arrived, the way left [m]) along the route to the goal on the map.

        The carrot is LOOKAHEAD [m] ahead. No way reaching the goal: the robot holds its place
        (and keeps avoiding whoever comes).
        """
        settings = self.settings
        route = self._route_at(position, lookahead)
        if route is None:
            self._route_status = ROUTE_UNREACHABLE
            return np.zeros(2), False, math.inf
        self._route_status = ROUTE_FOUND
        v_pref, arrived, self._route_segment, remaining = route_preferred_velocity(
            position, self.goal, route, self._route_segment, lookahead,
            self.config.max_speed, settings.approach_time, settings.goal_tolerance,
            settings.max_acceleration, self._route_tree.route_map.in_sight,
            self._route_map.resolution)
        return v_pref, arrived, remaining

    def _problem(self, own, stamp, tracks, announcements, v_pref, horizon):
        """Return the argument tuple of `plan_velocity` for the plan of STAMP."""
        return (
            AgentBelief(own.mean[:2], own.mean[2:], own.covariance,
                        self.settings.planning_radius),
            [track.agent_belief(stamp, announcement.radius, announcement.avoidance_share)
             for track, announcement in zip(tracks, announcements, strict=True)],
            v_pref, self._planning_config(
                horizon, self._control_period or self.config.control_period),
            self._previous_velocity, self._limits(stamp))

    def _planning_config(self, horizon, control_period):
        """Return the config with this plan's HORIZON [s] and CONTROL_PERIOD [s].

        Kept per pair for the config in force: a plan's pair repeats from step to step, and
        making a `PlannerConfig` validates every field again.
        """
        if self._planning_configs[0] is not self.config:
            self._planning_configs = (self.config, {})
        made = self._planning_configs[1]
        key = (horizon, control_period)
        config = made.get(key)
        if config is None:
            if len(made) >= MAX_PLANNING_CONFIGS:
                made.clear()
            config = made[key] = dataclasses.replace(
                self.config, time_horizon=horizon, control_period=control_period)
        return config

    def _given_way(self, position, v_pref, stall, distance_to_goal, names, beliefs,
                   announcements, routes, uses):
        """Return V_PREF, or toward the spot beside a passing neighbour's route (`give_way`).

        Only a robot heading for a goal steps aside: at it or giving way from it already, or
        held short of it (`give_way.held_short`, from STALL and DISTANCE_TO_GOAL [m]) or giving
        way from where it was held. ROUTES are the neighbours' `routes.NeighbourRoute`s (None:
        none), in the order of NAMES and BELIEFS. A held robot does not step aside for one that
        waits at its passage (`right_of_way.waiting_at`, from USES, `_passage_uses`) or that
        announces no share (in ANNOUNCEMENTS): it would stand aside for one that stands, maybe
        behind it or aside for it.
        """
        settings = self.settings
        self._aside = False
        if not settings.give_way or self.goal is None or settings.preferred_source != GOAL:
            self._give_way = self._held_at = self._yielding_to = None
            return v_pref
        radius = settings.planning_radius
        room = None if self._route_map is None else self._route_map.in_sight
        points = [None if route is None else route.points for route in routes]
        if self.arrived or (self._give_way is not None and self._held_at is None):
            self._held_at = self._yielding_to = None
            neighbours = [(belief.mean[:2], announcement.radius, route) for belief, announcement,
                          route in zip(beliefs, announcements, points, strict=True)]
            self._give_way = give_way_spot(self.goal, radius, neighbours, room)
        else:
            held_at = self._held_at
            gained = self.stall_monitor.gained_over(HELD_WINDOW)
            if held_at is None and held_short(stall.stalled, distance_to_goal, gained):
                held_at = position.copy()
            yielding = self._yielding_to
            self._give_way = self._yielding_to = None
            if yielding is not None and yielding in names:
                velocity = beliefs[names.index(yielding)].mean[2:]
                if math.hypot(*velocity) < PASSING_SPEED:
                    yielding = None
            if held_at is not None:
                # The way left as the neighbours see it: along the route it publishes.
                own_route = (self._route if self._route_status == ROUTE_FOUND
                             and self._route is not None else self.goal[np.newaxis])
                # Those waiting their turn at its passage, and those that announce no share
                # (standing at their goal, or aside for another, maybe for it): both would wait.
                waiting = {name for name, announcement in zip(names, announcements, strict=True)
                           if announcement.avoidance_share == 0.0}
                waiting.update(() if uses is None else waiting_at(*uses))
                neighbours = [(name, belief.mean[:2], announcement.radius, route)
                              for name, belief, announcement, route
                              in zip(names, beliefs, announcements, points, strict=True)]
                self._give_way, self._yielding_to = held_spot(
                    held_at, way_left(own_route, position), self.name, radius, neighbours, room,
                    waiting, yielding)
            self._held_at = None if self._give_way is None else held_at
        if self._give_way is None:
            return v_pref
        self._aside = bool(np.hypot(*(self._give_way - position)) <= settings.goal_tolerance)
        return preferred_velocity(position, self._give_way, self.config.max_speed,
                                  settings.approach_time, 0.0, settings.max_acceleration)[0]

    def _passed_beside(self, position, v_pref, beliefs, announcements, standing):
        """Return V_PREF, or beside a neighbour standing on the robot's way (`passing`).

        For a robot on its way along a route to its goal, not giving way itself. STANDING: per
        neighbour (in the order of BELIEFS and ANNOUNCEMENTS) whether it stands (`plan_request`).
        """
        settings = self.settings
        if (not settings.give_way or self.arrived or self._give_way is not None
                or settings.preferred_source != GOAL or self._route_status != ROUTE_FOUND
                or self._route is None or len(self._route) < 2 or not any(standing)):
            return v_pref
        room = None if self._route_map is None else self._route_map.in_sight
        return pass_beside(position, v_pref, way_ahead(self._route, position),
                           settings.planning_radius,
                           [(belief.mean[:2], announcement.radius) for belief, announcement, still
                            in zip(beliefs, announcements, standing, strict=True) if still],
                           room)

    def _passage_uses(self, stamp, position, names, beliefs, routes):
        """Return (the robot's `PassageUse`, its neighbours' that claim), None: no passage ahead.

        Of the passage on the robot's route at POSITION (2,) [m], from the neighbours' beliefs
        and ROUTES (`routes.NeighbourRoute` or None, in the order of NAMES) at STAMP [s],
        without those standing in a passage for longer than `right_of_way.IDLE_INSIDE` (kept,
        sorted, in `idle_in_passage`).
        """
        settings = self.settings
        self.idle_in_passage = ()
        if (not settings.right_of_way or self._passage_map is None or self.arrived
                or settings.preferred_source != GOAL or self._route_status != ROUTE_FOUND):
            return None
        passages = self._passage_map
        me = passages.use_of(self.name, position, self._route)
        others = [passages.use_of(name, belief.mean[:2], route.points)
                  for name, belief, route in zip(names, beliefs, routes, strict=True)
                  if route is not None]
        # When each came is watched whether or not the robot has a passage ahead: one waiting
        # at a passage has waited since it came, not since the robot came near.
        uses = self._queue_watch.ordered([use for use in [me, *others] if use is not None],
                                         stamp)
        if me is None:
            return None
        me, *uses = uses
        claiming = self._idle_watch.claiming(uses, stamp)
        self.idle_in_passage = tuple(sorted({use.name for use in uses}
                                            - {use.name for use in claiming}))
        return me, claiming

    def _passage_turn(self, position, v_pref, uses):
        """Return (V_PREF or toward a waiting spot, the virtual wall (2, 2) or None).

        The right of way (`prvo_planner.right_of_way`) of the robot at POSITION (2,) [m] at the
        passage on its route, from USES (`_passage_uses`); kept in `passage_decision`.
        """
        settings = self.settings
        self.passage_decision = None
        if uses is None or self._give_way is not None:
            return v_pref, None
        passages = self._passage_map
        me, claiming = uses
        decision = passages.decision(me, claiming, position)
        self.passage_decision = decision
        if decision.goes:
            # Through the middle of the passage's mouths, where the route's way is in sight.
            aim = passages.aim(me, position)
            if (aim is None or np.hypot(*(aim - position)) < settings.goal_tolerance
                    or not self._route_map.in_sight(position, aim)):
                return v_pref, None
            way = aim - position
            return way * (math.hypot(*v_pref) / math.hypot(*way)), None
        if decision.waiting_spot is None:
            return np.zeros(2), decision.wall
        # Within the goal's tolerance of the spot the robot stands still: hunting about it
        # would make it, to those passing, a neighbour that may move anywhere.
        return preferred_velocity(position, decision.waiting_spot, self.config.max_speed,
                                  settings.approach_time, settings.goal_tolerance,
                                  settings.max_acceleration)[0], decision.wall

    def _take_way_round(self, stamp, position, remaining):
        """Follow the way round the passage the robot waits at once waiting cost as much.

        From the next plan on (`prvo_planner.detours`); REMAINING [m] is the route's length to
        the goal from POSITION (2,) [m] at STAMP [s].
        """
        tree = self._detours.update(stamp, self.passage_decision, position, remaining,
                                    self.config.max_speed, self._route_map, self._passage_map,
                                    self.goal, search=self.search_ways_round)
        if tree is not None:
            self._route_tree, self._route = tree, None

    @property
    def way_round_wanted(self):
        """The way round a plan lacked (`search_ways_round` False), None: none.

        The arguments of `detours.way_round` for the map and goal in force: (avoided passages,
        route map, passage map, goal); search it, then hand it to `install_way_round`.
        """
        wanted = self._detours.wanted
        if wanted is None or self._route_map is None or self.goal is None:
            return None
        return wanted, self._route_map, self._passage_map, self.goal

    def install_way_round(self, wanted, tree):
        """Take TREE, `detours.way_round` of WANTED (`way_round_wanted`), if it still fits.

        It fits if searched on the map in force, for the goal in force; returns whether.
        """
        avoided, route_map, passage_map, goal = wanted
        if (route_map is not self._route_map or passage_map is not self._passage_map
                or self.goal is None or not np.array_equal(goal, self.goal)):
            return False
        self._detours.install(avoided, tree)
        return True

    def _kept_right(self, problem, distance_to_goal, obstacles, standing):
        """Return PROBLEM with its preferred velocity leaning right (`prvo_planner.lanes`).

        The neighbours that stand (STANDING, per neighbour of PROBLEM) are not traffic to meet:
        one stepping aside toward the robot would lean it into that one as it goes round.
        """
        ego, neighbours, v_pref, config = problem[:4]
        moving = [neighbour for neighbour, still in zip(neighbours, standing, strict=True)
                  if not still]
        v_pref, _ = keep_right(v_pref, self.settings.keep_right, ego, moving,
                               distance_to_goal, obstacles, config)
        return (ego, neighbours, v_pref, *problem[3:])

    def _unplanned_request(self, request, v_pref, tracks):
        """Return REQUEST completed for a robot that does not avoid, or filters a command.

        Without avoidance the preferred velocity is the command. An upstream command goes on
        unchanged when it stands still, or when nothing constrains it: it is within max_speed
        and the plan nearest to it (choosing by distance alone, without the robot's limits) is
        the command itself. Otherwise the request is planned as a goal's is, with the command
        as the preferred velocity over the whole horizon.
        """
        upstream = request.upstream
        if not self.settings.avoids or upstream is None:
            return dataclasses.replace(request, unplanned=v_pref, obstacles=None,
                                       passed_through=upstream is not None)
        problem = self._problem(request.own, request.stamp, tracks, request.announcements,
                                v_pref, self.config.time_horizon)
        if upstream.is_zero or _unconstrained(problem, request.obstacles):
            return dataclasses.replace(request, unplanned=v_pref, obstacles=None,
                                       passed_through=True)
        return dataclasses.replace(request, problem=problem)

    # Planning ---------------------------------------------------------------------------------

    def awaiting_listed(self, now):
        """Whether a listed neighbour has not been heard in full yet and may still turn up.

        In full: its odometry, its footprint and its share. Announcements travel apart from
        odometry; without this, a team's first plans would depend on which came first. With
        `wait_for_map` the map is waited for likewise (one still being built after that is
        held for: `awaiting_map`), with `wait_for_path` (path mode) a path.
        """
        if self._first_own_at is None:
            return False
        if now - self._first_own_at > self.settings.neighbor_timeout:
            return False
        if self.settings.wait_for_map and self._grid is None:
            return True
        if (self.settings.wait_for_path and self.settings.preferred_source == PATH
                and self._path is None):
            return True
        return bool(self.unheard_listed())

    @property
    def awaiting_map(self):
        """Whether the robot holds for its map: `wait_for_map`, none in force, one on its way.

        Its plans are zero commands (`Command.awaiting_map`) until the map is in force: planning
        as if there were no map would ignore the one coming, and publishing nothing would stop
        the control loop for as long as the map takes to build.
        """
        return self.settings.wait_for_map and self._grid is None and self.map_pending

    def unheard_listed(self):
        """Return the listed neighbours not heard in full yet (odometry, footprint, share), sorted.

        A plan made while this is not empty (their wait, `neighbor_timeout`, ran out) is made
        without them: worth a word to whoever runs the team.
        """
        if self.listed_neighbours is None:
            return []
        return sorted(robot for robot in self.listed_neighbours
                      if robot not in self._neighbour_tracks
                      or robot not in self._announced_radius
                      or robot not in self._announced_share)

    def ready(self, now):
        """Whether a stamp is pending and every neighbour has been measured at or after it."""
        return (self._pending_stamp is not None and not self.awaiting_listed(now)
                and self._has_preference() and all(
            self._neighbour_tracks.track(robot).stamp >= self._pending_stamp
            for robot in self._neighbour_names()))

    def plan(self):
        """Plan for the pending stamp (neighbours predicted to it); return the `Command`.

        Raises RuntimeError when no own measurement is pending.
        """
        request = self.plan_request()
        result = None
        if request.problem is not None:
            result = (plan_velocity(*request.problem) if request.obstacles is None
                      else plan_velocity(*request.problem, obstacles=request.obstacles))
        return self.complete(request, result)

    def plan_request(self):
        """Take the pending stamp; return the `PlanRequest` of its plan.

        `plan()` is `complete(request, plan_velocity(*request.problem))`; a caller that plans
        a whole team at once (`prvo_planner.core.plan_velocities`) solves the problems of many
        requests together and completes each. Raises RuntimeError when no own measurement is
        pending.
        """
        if self._pending_stamp is None:
            raise RuntimeError('plan() without a pending own measurement')
        stamp, self._pending_stamp = self._pending_stamp, None
        own = self._own_track.belief_at(stamp)
        if self.awaiting_map:
            # A filter's command is answered too, by zero.
            upstream, self._upstream = self._upstream, None
            return PlanRequest(stamp=stamp, own=own, neighbours=(), neighbour_names=(),
                               announcements=(), problem=None, unplanned=np.zeros(2),
                               upstream=upstream, awaiting_map=True)
        max_speed = self.config.max_speed
        v_pref, self.arrived, distance_to_goal = self._preference(own)
        # A robot giving way, or waiting at a passage, is where it should be: its monitor
        # watches the spot, not the goal.
        spot = self._give_way
        if spot is None and self.passage_decision is not None and not self.passage_decision.goes:
            spot = self.passage_decision.waiting_spot
        stall = self.stall_monitor.update(
            stamp, own.mean[:2], self.goal if spot is None else spot,
            self.settings.goal_tolerance, distance_to_goal if spot is None else None)
        v_pref = self.escalation.preferred(v_pref, stall, self.settings.escalation,
                                           self._room_on_right(own.mean[:2]))
        route_status = self._route_status
        route = self._route if route_status == ROUTE_FOUND else None
        upstream, self._upstream = self._upstream, None
        arrival = self._arrival(own.mean[:2])
        names, tracks, neighbour_beliefs = self._neighbour_tracks.beliefs_at(stamp, self.name)
        announcements, routes = self._held.values(names, stamp, self._held_of)
        uses = self._passage_uses(stamp, own.mean[:2], names, neighbour_beliefs, routes)
        v_pref = self._given_way(own.mean[:2], v_pref, stall, distance_to_goal, names,
                                 neighbour_beliefs, announcements, routes, uses)
        # Those that stand (at their goals, arriving, or aside): gone round, not met as traffic.
        standing = [announcement.avoidance_share == 0.0 or at_goal(belief.mean[:2], route)
                    for belief, announcement, route
                    in zip(neighbour_beliefs, announcements, routes, strict=True)]
        v_pref = self._passed_beside(own.mean[:2], v_pref, neighbour_beliefs, announcements,
                                     standing)
        v_pref, passage_wall = self._passage_turn(own.mean[:2], v_pref, uses)
        self._take_way_round(stamp, own.mean[:2], distance_to_goal)
        if self._command_stamp is not None and 0.0 < stamp - self._command_stamp:
            self._control_period = stamp - self._command_stamp
        obstacles = None if self._obstacle_index is None else self._obstacle_index.near(
            own.mean[:2], self.settings.obstacle_distance)
        if obstacles is not None and len(obstacles) == 0:
            # Nothing near: the plan of an empty plane.
            obstacles = None
        if passage_wall is not None:
            obstacles = with_wall(obstacles, passage_wall)
        inside = self._inside_obstacle(own.mean[:2])
        if inside is not None:
            # Every way out of an obstacle crosses its edges, which the walls' conditions
            # forbid: the robot heads for the nearest free cell with only neighbours to avoid
            # (a filter's command, its controller's way out, goes on as it came).
            obstacles, exit_point = None, inside[1]
        if inside is not None and self.settings.preferred_source != VELOCITY:
            v_pref = np.zeros(2) if exit_point is None else preferred_velocity(
                own.mean[:2], exit_point, max_speed, self.settings.approach_time, 0.0,
                self.settings.max_acceleration)[0]
        problem = None
        if upstream is not None or not self.settings.avoids:
            return self._unplanned_request(PlanRequest(
                stamp=stamp, own=own, neighbours=neighbour_beliefs, neighbour_names=names,
                announcements=announcements, problem=None, arrival=arrival, upstream=upstream,
                obstacles=obstacles, stall=stall, inside_obstacle=inside,
                neighbour_routes=routes), v_pref, tracks)
        if self.goal is not None:
            # At its goal the robot keeps planning, with v_pref = 0: it stands while nobody
            # comes and takes its share of the avoidance when someone does, over the whole
            # horizon (its neighbours count on that share).
            horizon = self.config.time_horizon if self.arrived else goal_horizon(
                distance_to_goal, max_speed, self.settings.approach_time,
                self.config.time_horizon)
            problem = self._problem(own, stamp, tracks, announcements, v_pref, horizon)
            if inside is None and self.passage_decision is None:
                # At a passage its order leads: a lean would turn a robot off the passage's
                # middle, or off its waiting spot.
                problem = self._kept_right(problem, distance_to_goal, obstacles, standing)
            if ((self.arrived and self._give_way is None or route_status == ROUTE_UNREACHABLE)
                    and nobody_comes(problem)):
                problem = None
        return PlanRequest(stamp=stamp, own=own, neighbours=neighbour_beliefs,
                           neighbour_names=names, announcements=announcements,
                           problem=problem, arrival=arrival, obstacles=obstacles, route=route,
                           route_status=route_status, stall=stall, inside_obstacle=inside,
                           neighbour_routes=routes)

    # Map and route -----------------------------------------------------------------------------

    @property
    def grid_map(self):
        """The `GridMap` the agent plans with, None without one."""
        return self._grid

    def set_map(self, grid):
        """Plan with the occupancy grid GRID (a `maps.GridMap`) from now on; None: no map.

        The map is built here (`build_map`, with the paths to the goal), unless it is the one in
        force. The way to the goal is searched again on a map that differs from it.
        """
        if grid is not None and self.has_map(grid):
            return
        self.install_map(None if grid is None else build_map(grid, self.map_key,
                                                             self.route_goal()))

    def has_map(self, grid):
        """Whether GRID (a `maps.GridMap`) is the map in force, cell for cell."""
        return self._grid is not None and same_grid(grid, self._grid)

    @property
    def map_key(self):
        """What a `BuiltMap` depends on besides the grid, for the settings in force."""
        return map_key_of(self.settings, self.config.safety_margin)

    @property
    def map_outdated(self):
        """Whether the map in force was made for other settings than those in force."""
        return self._grid is not None and self._map_built_for != self.map_key

    def route_goal(self):
        """Return the goal a map's route is searched to (heading for a goal), else None."""
        return self.goal if self.settings.preferred_source == GOAL else None

    def install_map(self, built):
        """Plan with BUILT (a `BuiltMap`) from now on; None: no map.

        Its route tree counts if made for the goal in force; otherwise the next plan searches.
        A map pending (`map_pending`) is no more.
        """
        self.map_pending = False
        if built is None:
            self._grid = self._map_built_for = self._obstacle_index = self._route_map = None
            self._route_tree = self._passage_map = None
        else:
            self._grid, self._map_built_for = built.grid, built.built_for
            self._obstacle_index, self._route_map = built.obstacle_index, built.route_map
            self._route_tree, self._passage_map = built.route_tree, built.passage_map
        self._route = None
        self._detours.reset()

    @property
    def route_map(self):
        """The `route.RouteMap` of the map in force, None without a map."""
        return self._route_map

    @property
    def passage_map(self):
        """The `right_of_way.PassageMap` of the map in force, None: none (see `BuiltMap`).

        The passages that `passage_decision`'s `use.passage` indexes.
        """
        return self._passage_map

    def install_route_tree(self, tree):
        """Take TREE, the shortest paths to the goal in force searched elsewhere, if it fits.

        It fits if searched on the map in force (`route_map`), to that goal; returns whether.
        """
        if (self._route_map is None or tree.route_map is not self._route_map
                or self.goal is None or not np.array_equal(tree.goal, self.goal)):
            return False
        self._route_tree, self._route = tree, None
        self._detours.reset()
        return True

    def goal_blocked(self, goal):
        """Whether GOAL (2,) lies in an obstacle of the map, or off it (False without a map)."""
        return self._route_map is not None and self._route_map.blocked(goal)

    def _room_on_right(self, position):
        """Return the test of room toward a unit direction from POSITION (None: no map).

        Room for the escalation's sidestep (`prvo_planner.escalation`): ROOM_RADII of the
        planning radius through the route's admissible cells.
        """
        if self._route_map is None:
            return None
        room = ROOM_RADII * self.settings.planning_radius
        return lambda right: self._route_map.in_sight(position, position + room * right)

    def _route_at(self, position, lookahead):
        """Return the route in force from POSITION to the goal, None if no way reaches it.

        The shortest paths to a goal are searched once per goal and map; the route is taken
        anew from them when the robot strayed farther than LOOKAHEAD [m] from it.
        """
        if self._route_tree is None or not np.array_equal(self._route_tree.goal, self.goal):
            self._route_tree = self._route_map.tree_to(self.goal)
            self._route = None
        if self._route is not None:
            _, closest = closest_on_path(self._route, position, self._route_segment)
            if float(np.hypot(*(closest - position))) > lookahead:
                self._route = None
        if self._route is None:
            self._route = self._route_tree.route_from(position)
            self._route_segment = 0
        return self._route

    def _arrival(self, position):
        """Return whether arriving now is this goal's first arrival; track the departures."""
        if self.arrived:
            first, self._arrival_reported = not self._arrival_reported, True
            return first
        if self.goal is not None and np.hypot(*(self.goal - position)) > (
                DEPARTURE_TOLERANCES * self.settings.goal_tolerance):
            self._arrival_reported = False
        return False

    def complete(self, request, result):
        """Return the `Command` of REQUEST given the core's RESULT (None: stand still).

        Standing still under an acceleration limit is braking toward zero at that limit.
        """
        if request.unplanned is not None:
            velocity = request.unplanned
        elif result is None:
            velocity = np.zeros(2) if not math.isfinite(self.settings.max_acceleration) else (
                self._command_in_force - _clipped_norm(
                    self._command_in_force,
                    self.settings.max_acceleration * self._period(request)))
        else:
            velocity = result.velocity
        self._previous_velocity = None if result is None else velocity
        drive = None
        if request.passed_through and self.settings.unicycle:
            drive = (request.upstream.linear[0], request.upstream.angular)
            self._drive = drive
        elif self.settings.unicycle:
            drive = tracking_command(velocity, self._own_yaw, *self._drive,
                                     self.settings.tracking_model(self.config.max_speed),
                                     self._period(request))
            self._drive = drive
        self._command_in_force, self._command_stamp = velocity, request.stamp
        if result is not None:
            self.tally = self.tally.counted(result, request.stamp)
        published = True
        if request.upstream is not None:
            self._upstream_answered = request.upstream
            published = self._gate.publishes(
                _is_zero(request, velocity, drive), self._upstream_received_at)
        return Command(stamp=request.stamp, velocity=velocity, yaw=self._own_yaw, result=result,
                       arrived=self.arrived, own=request.own, neighbours=request.neighbours,
                       neighbour_names=request.neighbour_names,
                       announcements=request.announcements, drive=drive,
                       arrival=request.arrival, tally=self.tally, upstream=request.upstream,
                       passed_through=request.passed_through, published=published,
                       route=request.route, route_status=request.route_status,
                       stall=request.stall, binding=_binding(request, result),
                       narrow_passage=self._passage_ahead(request),
                       inside_obstacle=request.inside_obstacle,
                       neighbour_routes=request.neighbour_routes,
                       awaiting_map=request.awaiting_map, right_of_way=self.passage_decision,
                       idle_in_passage=self.idle_in_passage)

    def _inside_obstacle(self, position):
        """Return (POSITION, the way out or None) if POSITION is in an occupied cell, else None.

        The way out is the nearest free cell's centre within `obstacle_distance` (`maps.way_out`).
        """
        if self._route_map is None:
            return None
        route_map = self._route_map
        if not occupied_at(route_map.occupied, route_map.resolution, route_map.origin, position):
            return None
        return position, way_out(route_map.occupied, route_map.resolution, route_map.origin,
                                 position, self.settings.obstacle_distance)

    def _passage_ahead(self, request):
        """Return the `NarrowPassage` REQUEST's stall is in front of (None: none, not stalled).

        Looked for once, when the stall begins, along the preferred velocity.
        """
        stall = request.stall
        if stall is None or not stall.stalled:
            self._narrow_passage = None
        elif stall.began and request.obstacles is not None and request.problem is not None:
            ego, _, v_pref, config = request.problem[:4]
            self._narrow_passage = narrow_passage(request.obstacles, ego, config, v_pref)
        return self._narrow_passage

    def _period(self, request):
        """Return the time [s] the command for REQUEST will be in force (0 before any)."""
        if self._command_stamp is None or request.stamp <= self._command_stamp:
            return 0.0 if self._control_period is None else self._control_period
        return request.stamp - self._command_stamp

    def _limits(self, stamp):
        """Return the core's VelocityLimits for the plan of STAMP, None without limits."""
        settings = self.settings
        accelerating = math.isfinite(settings.max_acceleration)
        if not (accelerating or settings.unicycle):
            return None
        period = (stamp - self._command_stamp
                  if self._command_stamp is not None and stamp > self._command_stamp
                  else 0.0)
        limits = {}
        if accelerating:
            limits.update(current=self._command_in_force,
                          max_change=settings.max_acceleration * period)
        if settings.unicycle:
            # Before the first period is known, the tracking horizon stands in for it.
            model = settings.tracking_model(self.config.max_speed)
            limits.update(heading=self._own_yaw, trackable_speed=model.speed_function(
                self._control_period or settings.tracking_horizon))
        return VelocityLimits(**limits)

    def warm_up(self):
        """Plan for a made-up encounter a few times; no state of the agent changes.

        A process's first plans pay one-off costs (numpy's first calls into its linear algebra,
        the planner's caches). When a team starts together on few cores, that is enough to
        miss the first realtime deadlines.
        """
        radius = self.settings.radius
        own = AgentBelief([0.0, 0.0], [0.5, 0.0], 0.01 * np.eye(4), radius)
        neighbours = [AgentBelief([2.0, 0.2], [-0.5, 0.0], 0.01 * np.eye(4), radius),
                      AgentBelief([1.0, -1.5], [0.0, 0.5], 0.01 * np.eye(4), radius)]
        previous = None
        for _ in range(_WARM_UP_PLANS):
            previous = plan_velocity(own, neighbours, np.array([1.0, 0.0]), self.config,
                                     previous=previous).velocity



def _unconstrained(problem, obstacles=None):
    """Whether PROBLEM's v_pref meets every constraint: the robot may keep it unchanged.

    PROBLEM is the argument tuple of `plan_velocity`, OBSTACLES the map's obstacles near the
    robot (None: none). The plan is made choosing by the distance to v_pref alone and without
    the robot's limits (the command was made for them upstream); the core keeps a choice a hair
    inside its feasible interval.
    """
    ego, neighbours, v_pref, config = problem[:4]
    if float(np.hypot(*v_pref)) > config.max_speed:
        return False
    if not neighbours and obstacles is None:
        return True
    result = plan_velocity(ego, neighbours, v_pref, dataclasses.replace(
        config, inertia=0.0, passing_bias=0.0, progress_weight=0.0), obstacles=obstacles)
    return result.feasible and float(np.hypot(*(result.velocity - v_pref))) <= _PASSING_SLACK


def _binding(request, result):
    """Return the `stalls.binding_conditions` of REQUEST's plan RESULT while stalled, else ()."""
    if request.stall is None or not request.stall.stalled or result is None:
        return ()
    return tuple(binding_conditions(request.problem, request.neighbour_names, result))


def _is_zero(request, velocity, drive):
    """Whether the command of REQUEST (VELOCITY (2,), a unicycle's DRIVE) stands still."""
    if request.passed_through:
        return request.upstream.is_zero
    return not np.any(velocity) and (drive is None or not any(drive))


def _clipped_norm(vector, limit):
    """Return VECTOR (2,) scaled down to length LIMIT if longer."""
    norm = math.hypot(vector[0], vector[1])
    return vector * (limit / norm) if norm > limit else vector

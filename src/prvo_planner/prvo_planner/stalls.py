"""Stalls: a robot away from its goal that gains too little toward it, without ROS.

One rule, used by the planner's agent (its diagnostics) and by the benchmarks (their stall
columns): a robot that stayed farther than the goal tolerance from its goal over the last
STALL_WINDOW seconds (sim time) and whose distance to the goal fell by less than
STALL_PROGRESS over them is stalled. From closer than STALL_PROGRESS plus the tolerance, it
must instead have reached the tolerance. The stall begins when first seen (so a robot that
stands still is stalled from STALL_WINDOW s after it stopped) and ends when the robot is
STALL_PROGRESS closer to its goal than it was then, or within the tolerance, or given another
goal. A robot at its goal that steps aside for a passing neighbour and comes back does not
stall: it was within the tolerance during the window.

Beside the stalls, the monitor measures how long the robot stayed near one spot away from its
goal: a *dwell* begins at a position (the spot) and lasts while every later position is within
SPOT_RADIUS of it; the first position outside begins the next dwell there. Reaching the goal
tolerance, or another goal, ends the dwell (a robot waiting at its goal does not count). The
dwell time is the time from the spot's position to the last position within SPOT_RADIUS of it.

The distance to the goal is the straight line unless the caller gives another: the way left
along a route or a path.
"""

import collections
import dataclasses
import math

import numpy as np

from prvo_planner.core.encounter import build_encounter

STALL_WINDOW = 10.0  # s of sim time
STALL_PROGRESS = 0.5  # m toward the goal a robot gains within STALL_WINDOW, or it stalls
SPOT_RADIUS = 0.5  # m: a dwell lasts while the robot stays this close to where it began
BINDING_COUNT = 3  # neighbours reported per stall: those whose conditions are nearest failing
# Times within this [s] are the same: plans come at steps of a float dt.
_TIME_SLACK = 1e-9


@dataclasses.dataclass(frozen=True)
class StallStatus:
    """What a `StallMonitor` knows after an update at `time` [s].

    `stalled` whether the robot is stalled now, `began` whether this update found the stall,
    `since` [s] when it was first seen (None when not stalled); `position` (2,) [m] and
    `distance_to_goal` [m] (inf without a goal) are this update's; `gained` [m] is how much
    closer to the goal the robot came over the last window (nan before a full window). The
    rest count since the monitor started, over every goal: `stalls` the stalls seen,
    `longest_stall` [s] the longest (to the update that ended it; the one in progress to
    `time`; one ended by another goal to the last update before it) and `longest_dwell` [s]
    the longest time the robot stayed within SPOT_RADIUS of one spot away from its goal.
    """

    time: float
    stalled: bool
    began: bool
    since: float | None
    position: np.ndarray
    distance_to_goal: float
    gained: float
    stalls: int
    longest_stall: float
    longest_dwell: float

    @property
    def duration(self):
        """Return how long [s] the stall in progress has lasted (0 when not stalled)."""
        return 0.0 if self.since is None else self.time - self.since


class StallMonitor:
    """Watches one robot for stalls (see the module); fed every plan or step by `update`.

    Memory is bounded: the distances of the last STALL_WINDOW seconds, one entry per update.
    """

    def __init__(self):
        self._history = collections.deque()  # (time [s], distance to the goal [m])
        self._goal = None
        self._last_at_goal = -math.inf  # s: the last update within the tolerance
        self._stall_since = None
        self._stall_distance = None  # m: the distance to the goal when the stall began
        self._spot = None  # (time [s], position (2,)) where the current dwell began
        self.stalls = 0
        self.longest_stall = 0.0
        self.longest_dwell = 0.0

    def reset(self):
        """Forget the window, the stall and the dwell in progress (a new goal); keep the counts."""
        self._history.clear()
        self._last_at_goal = -math.inf
        self._stall_since = self._stall_distance = self._spot = None

    def update(self, time, position, goal, tolerance, distance=None):
        """Take the robot at POSITION (2,) [m] at TIME [s]; return its `StallStatus`.

        GOAL (2,) [m] is the goal it heads for (None: none, which resets the monitor) and
        TOLERANCE [m] the goal tolerance; DISTANCE [m] the way left to the goal when it is not
        the straight line (along a route or path; None or not finite: the straight line).
        """
        position = np.array(position, dtype=float)
        if goal is None:
            self.reset()
            self._goal = None
            return self._status(time, position, math.inf, math.nan, began=False)
        goal = np.asarray(goal, dtype=float)
        if self._goal is None or not np.array_equal(goal, self._goal):
            self.reset()
            self._goal = goal.copy()
        if distance is None or not math.isfinite(distance):
            distance = float(np.hypot(*(goal - position)))
        at_goal = distance <= tolerance
        if at_goal:
            self._last_at_goal = time
        self._history.append((time, distance))
        # Keep the latest entry at least a window old as the window's start.
        while (len(self._history) > 1
               and self._history[1][0] <= time - STALL_WINDOW + _TIME_SLACK):
            self._history.popleft()
        then, before = self._history[0]
        full = time - then >= STALL_WINDOW - _TIME_SLACK
        gained = before - distance if full else math.nan
        began = False
        if self._stall_since is not None:
            # The stall lasts up to the update that ends it.
            self.longest_stall = max(self.longest_stall, time - self._stall_since)
            if at_goal or distance <= self._stall_distance - STALL_PROGRESS:
                self._stall_since = self._stall_distance = None
        elif (full and self._last_at_goal < then
              and gained < min(STALL_PROGRESS, before - tolerance)):
            self._stall_since, self._stall_distance, began = time, distance, True
            self.stalls += 1
        self._dwell(time, position, at_goal)
        return self._status(time, position, distance, gained, began)

    def gained_over(self, seconds):
        """Return how much closer [m] to its goal the robot came over the last SECONDS.

        Up to the latest update, from the latest one at least SECONDS before it (SECONDS at most
        STALL_WINDOW); nan with less history than that, or when the robot was within the
        tolerance since.
        """
        if not self._history:
            return math.nan
        time, distance = self._history[-1]
        if self._last_at_goal > time - seconds - _TIME_SLACK:
            return math.nan
        for then, before in reversed(self._history):
            if then <= time - seconds + _TIME_SLACK:
                return before - distance
        return math.nan

    def _dwell(self, time, position, at_goal):
        """Carry the dwell on to POSITION at TIME, or begin the next (see the module)."""
        if at_goal:
            self._spot = None
        elif self._spot is None or np.hypot(*(position - self._spot[1])) > SPOT_RADIUS:
            self._spot = (time, position)
        else:
            self.longest_dwell = max(self.longest_dwell, time - self._spot[0])

    def _status(self, time, position, distance, gained, began):
        return StallStatus(time=time, stalled=self._stall_since is not None, began=began,
                           since=self._stall_since, position=position,
                           distance_to_goal=distance, gained=gained, stalls=self.stalls,
                           longest_stall=self.longest_stall, longest_dwell=self.longest_dwell)


# The benchmarks' table columns of a `stall_summary`: (key, heading).
SUMMARY_COLUMNS = (('stalls', 'stalls'), ('longest_stall_s', 'longest stall s'),
                   ('longest_dwell_s', 'longest near one spot s'))


def stall_summary(monitors):
    """Return what MONITORS (`StallMonitor`s) saw: {stalls, longest_stall_s, longest_dwell_s}.

    The stalls summed, the longest stall and dwell over the monitors [s, to 0.1 s], 0 without.
    """
    return {'stalls': sum(monitor.stalls for monitor in monitors),
            'longest_stall_s': round(max((monitor.longest_stall for monitor in monitors),
                                         default=0.0), 1),
            'longest_dwell_s': round(max((monitor.longest_dwell for monitor in monitors),
                                         default=0.0), 1)}


def trajectory_stalls(times, positions, goals, tolerance):
    """Return the `stall_summary` of a trajectory, every robot watched by its own monitor.

    TIMES (T,) [s], POSITIONS (T, N, 2) [m], GOALS (N, 2) [m], TOLERANCE [m].
    """
    monitors = [StallMonitor() for _ in range(len(goals))]
    for time, step in zip(times, positions, strict=True):
        for monitor, position, goal in zip(monitors, step, goals, strict=True):
            monitor.update(float(time), position, goal, tolerance)
    return stall_summary(monitors)


def binding_conditions(problem, names, result, count=BINDING_COUNT):
    """Return the COUNT neighbours of a plan whose conditions bind most, lowest bound first.

    PROBLEM is the plan's argument tuple of `plan_velocity` (ego, neighbours, v_pref, config,
    ...), NAMES the neighbours' names in its order and RESULT the core's `PlanResult`. Each as
    {neighbour, gap_m (the means' surface-to-surface gap [m]), bound (the probability bound at
    the chosen velocity), kind ('certified' or 'cantelli'), feasible}; [] when nobody was within
    reach.
    """
    ego, neighbours, _, config = problem[:4]
    encounter = build_encounter(ego, neighbours, config)
    # The encounter keeps the neighbours within reach, in order: match them by position.
    offsets = np.array([ego.position - neighbour.position for neighbour in neighbours])
    rows = [int(np.argmin(np.linalg.norm(offsets - origin[:2], axis=1)))
            for origin in encounter.origin]
    order = np.argsort(result.neighbour_bounds, kind='stable')[:count]
    return [{'neighbour': names[rows[row]],
             'gap_m': round(float(np.hypot(*encounter.origin[row, :2])
                                  - encounter.combined_radius[row]), 3),
             'bound': round(float(result.neighbour_bounds[row]), 4),
             'kind': result.bound_kinds[row], 'feasible': bool(result.feasible)}
            for row in order]

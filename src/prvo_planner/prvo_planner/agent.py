"""The PRVO robot without ROS: measurements in, a world-frame velocity command out.

A `PlannerAgent` tracks its own robot and its neighbours from odometry measurements
(`prvo_msgs_util.OdometryMeasurement` or anything with the same fields), waits for the
neighbours' measurements of the stamp it plans for, applies the goal logic and plans with
`prvo_planner.core.plan_velocity`, taking each neighbour's size and share of the avoidance from
its announcements (`NeighbourAnnouncement`). It never reads a clock: every call that needs the
time of day takes `now`, monotonic seconds of the caller's choosing. The planner node wraps it
in ROS endpoints; an in-process engine can feed it step by step.
"""

import dataclasses

import numpy as np

from prvo_planner.core import AgentBelief, plan_velocity
from prvo_planner.core.beliefs import validated_share
from prvo_planner.estimation import ConstantVelocityTracker, TrackFault

# A stamp this far behind a track's last one means its source restarted (e.g. the simulator):
# the track starts over instead of rejecting every message from then on.
_TIME_RESET_SECONDS = 1.0
# A stamp this far ahead of a track's last one is a fault (a wall-clock stamp among sim-time
# ones, a garbage sec field), not motion: odometry comes at several Hz, over 10 s the prediction
# of 1 m/s^2 noise is already some 18 m wide, and over years its rounding breaks the filter.
MAX_STAMP_JUMP_SECONDS = 10.0
# Plans for a made-up encounter in warm_up().
_WARM_UP_PLANS = 3
# A command below this [m/s] is standing still.
_STANDING_SPEED = 1e-6
# Every model of the core (prvo and its baselines rvo, inflate, mc) is reciprocal: it takes half
# of a pair's avoidance against a neighbour that takes the other half.
RECIPROCAL_SHARE = 0.5
# A neighbour that has not announced its share is assumed not to avoid.
UNANNOUNCED_SHARE = 0.0


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


def preferred_velocity(position, goal, max_speed, approach_time, goal_tolerance):
    """Return (v_pref (2,), arrived): straight to the goal, slowing over the last stretch."""
    if goal is None:
        return np.zeros(2), False
    offset = goal - position
    distance = float(np.hypot(*offset))
    if distance <= goal_tolerance:
        return np.zeros(2), True
    speed = min(max_speed, distance / approach_time)
    return offset * (speed / distance), False


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
    chance constraint can certify it, although nobody comes.
    """
    ego, neighbours, v_pref, config, _ = problem
    result = plan_velocity(ego, neighbours, v_pref,
                           dataclasses.replace(config, model='rvo', inertia=0.0))
    # The core keeps its choice a hair inside a feasible interval: zero comes out as ~1e-9 m/s.
    return result.feasible and float(np.hypot(*result.velocity)) <= _STANDING_SPEED


@dataclasses.dataclass(frozen=True)
class AgentSettings:
    """The agent's settings besides the core's PlannerConfig; names as the node's parameters.

    `unknown_neighbor_radius` is assumed for a neighbour that announced no footprint;
    `neighbor_timeout` is in the seconds of the `now` arguments.
    """

    radius: float = 0.3
    unknown_neighbor_radius: float = 0.5
    approach_time: float = 0.5
    goal_tolerance: float = 0.2
    acceleration_std: float = 1.0
    neighbor_timeout: float = 2.0

    @classmethod
    def from_parameters(cls, values):
        """Return the settings named in the mapping VALUES (extra names are ignored)."""
        return cls(**{field.name: values[field.name] for field in dataclasses.fields(cls)})


@dataclasses.dataclass(frozen=True)
class Fusion:
    """What became of one measurement.

    `status` is 'fused' or 'restarted' (accepted; 'restarted': its time went back, so the track
    started over), 'duplicate' (the stamp of the last accepted one), or a fault that left the
    track as it was: 'stale' (a little behind the last stamp), 'refused' (far ahead of it, or
    numerically unusable). `detail` says why, with the values.
    """

    status: str
    detail: str = ''

    @property
    def accepted(self):
        """Whether the measurement reached the track."""
        return self.status in ('fused', 'restarted')


@dataclasses.dataclass(frozen=True)
class Command:
    """One plan: the command for `stamp` and what it was planned from.

    `velocity` (2,) is in the world frame; `yaw` is the robot's yaw measured at `stamp`, to turn
    it into the body frame. `result` is the core's PlanResult, None when the robot stands still
    (no goal, or at its goal while nobody comes). `own` and `neighbours` are the `StateBelief`s
    at `stamp`; `neighbour_names` and `announcements` (`NeighbourAnnouncement`s, defaults for
    what was not announced) are in the same order.
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

    def announcement_values(self):
        """Return {'neighbour.<robot>.radius': m, 'neighbour.<robot>.avoidance_share': a}."""
        values = {}
        for robot, announcement in zip(self.neighbour_names, self.announcements, strict=True):
            values[f'neighbour.{robot}.radius'] = announcement.radius
            values[f'neighbour.{robot}.avoidance_share'] = announcement.avoidance_share
        return values


@dataclasses.dataclass(frozen=True)
class PlanRequest:
    """One plan about to be made: the beliefs at `stamp` and the core's problem.

    `problem` is the argument tuple of `prvo_planner.core.plan_velocity` (ego, neighbours,
    v_pref, config, previous), or None when the robot stands still (no goal, or at its goal
    while nobody comes).
    """

    stamp: float
    own: object
    neighbours: tuple
    neighbour_names: tuple
    announcements: tuple
    problem: tuple


class _Track:
    """One tracked robot: its filter and when (caller's `now`) it last accepted a measurement.

    `superseded` is the track a backward time jump replaced, kept until the new time goes on.
    """

    def __init__(self, acceleration_std, now, superseded=None):
        self.tracker = ConstantVelocityTracker(acceleration_std)
        self.last_heard = now
        self.superseded = superseded

    def fits(self, stamp):
        """Whether STAMP continues this track: later than its last, by a plausible step."""
        return 0.0 < stamp - self.tracker.stamp <= MAX_STAMP_JUMP_SECONDS


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

    Use: `receive_own` and `receive_neighbour` for every measurement, `receive_footprint` and
    `receive_share` for every announcement; when `ready(now)`, or when
    the caller's wait for neighbours (`sync_timeout`) ran out and `awaiting_listed(now)` is
    false, `plan()` returns the `Command` for the pending own stamp.

    """

    def __init__(self, name, config, settings=AgentSettings(), goal=None,
                 listed_neighbours=None):
        self.name = name
        self.config = config
        self.settings = settings
        self.goal = None if goal is None else np.asarray(goal, dtype=float)
        self.listed_neighbours = (
            None if listed_neighbours is None else set(listed_neighbours) - {name})
        self.arrived = False
        self._own_track = None
        self._neighbour_tracks = {}
        # Announced by each neighbour: robot -> radius, robot -> share; and changes received
        # since the last own measurement, which take effect with the next one.
        self._announced_radius = {}
        self._announced_share = {}
        self._changed_radius = {}
        self._changed_share = {}
        self._pending_stamp = None
        self._own_yaw = 0.0
        # The last planned velocity in the world frame, for the inertia term; None after a stop.
        self._previous_velocity = None
        # Listed neighbours are waited for from the first own measurement on, not from start-up:
        # a team's processes start at different speeds, and a run begins with all of them.
        self._first_own_at = None

    @property
    def pending_stamp(self):
        """The own stamp waiting for a plan, or None."""
        return self._pending_stamp

    @property
    def neighbours(self):
        """Names of the neighbours tracked now."""
        return set(self._neighbour_tracks)

    def reconfigure(self, config, settings, goal):
        """Take new parameters; the plan in progress and the tracks go on."""
        self.config, self.settings = config, settings
        self.goal = None if goal is None else np.asarray(goal, dtype=float)

    def set_goal(self, goal):
        """Head for a new GOAL (2,): not arrived, no previous command to stay close to."""
        self.goal = np.asarray(goal, dtype=float)
        self.arrived = False
        self._previous_velocity = None

    # Measurements -----------------------------------------------------------------------------

    def receive_own(self, measurement, now):
        """Fuse the robot's own MEASUREMENT; return its `Fusion`.

        An accepted one becomes the pending stamp (replacing one not planned yet: a newer
        stamp is what a command should answer).
        """
        self._own_track, fusion = self._fuse(self._own_track, measurement, now)
        if fusion.accepted:
            self._announced_radius.update(self._changed_radius)
            self._announced_share.update(self._changed_share)
            self._changed_radius.clear()
            self._changed_share.clear()
            if self._first_own_at is None:
                self._first_own_at = now
            self._pending_stamp = measurement.stamp
            self._own_yaw = measurement.yaw
        return fusion

    def receive_neighbour(self, robot, measurement, now):
        """Fuse neighbour ROBOT's MEASUREMENT; return its `Fusion`."""
        track, fusion = self._fuse(self._neighbour_tracks.get(robot), measurement, now)
        self._neighbour_tracks[robot] = track
        return fusion

    @property
    def own_announcement(self):
        """What this robot announces: its radius, and its share of the avoidance.

        On its way, the reciprocal share. Without a goal it does not plan, and at its goal it
        stands until someone comes: its neighbours must not count on it mirroring their moves,
        as a reciprocal planner does (a robot heading away from a standing one would otherwise
        see the standing one's half coming after it), so it announces none.
        """
        moving = self.goal is not None and not self.arrived
        return NeighbourAnnouncement(
            self.settings.radius, RECIPROCAL_SHARE if moving else UNANNOUNCED_SHARE)

    def receive_footprint(self, robot, radius):
        """Take neighbour ROBOT's announced RADIUS [m].

        A neighbour's first announcement counts at once; a change, from the next own
        measurement on (see `receive_share`). Raises ValueError naming the value if it is not
        finite and > 0; the neighbour then keeps what it had (its last valid announcement, else
        `unknown_neighbor_radius`).
        """
        self._take(robot, NeighbourAnnouncement(radius, UNANNOUNCED_SHARE).radius,
                   self._announced_radius, self._changed_radius)

    def receive_share(self, robot, avoidance_share):
        """Take neighbour ROBOT's announced share of the avoidance.

        A neighbour's first announcement counts at once; a change, from the next own
        measurement on: in lockstep every robot plans a step at the same time, and a change
        that a neighbour announces while planning one step then counts from the next step for
        every robot, whichever plan it reached first. Raises ValueError naming the value if it
        is not in [0, 1); the neighbour then keeps what it had (its last valid announcement,
        else not avoiding).
        """
        self._take(robot, validated_share(avoidance_share, 'avoidance_share'),
                   self._announced_share, self._changed_share)

    @staticmethod
    def _take(robot, value, announced, changed):
        if robot in announced:
            changed[robot] = value
        else:
            announced[robot] = value

    def forget_announcements(self, robot):
        """Drop what ROBOT announced (it left: a robot of that name may come back another)."""
        for values in (self._announced_radius, self._announced_share, self._changed_radius,
                       self._changed_share):
            values.pop(robot, None)

    def announcement_of(self, robot):
        """Return the `NeighbourAnnouncement` planned with for ROBOT, defaults filled in."""
        return NeighbourAnnouncement(
            self._announced_radius.get(robot, self.settings.unknown_neighbor_radius),
            self._announced_share.get(robot, UNANNOUNCED_SHARE))

    def forget_neighbours(self, now, wanted=None):
        """Drop neighbours silent longer than neighbor_timeout, or not in WANTED (if given).

        Returns [(robot, seconds silent)] of those dropped.
        """
        dropped = []
        for robot, track in list(self._neighbour_tracks.items()):
            silent = now - track.last_heard
            if (wanted is not None and robot not in wanted) or (
                    silent > self.settings.neighbor_timeout):
                del self._neighbour_tracks[robot]
                dropped.append((robot, silent))
        return dropped

    def _fuse(self, track, measurement, now):
        """Return (the track to keep, the `Fusion`) of MEASUREMENT fed to TRACK (None: new)."""
        stamp = measurement.stamp
        if track is None:
            track = _Track(self.settings.acceleration_std, now)
            return self._update(track, measurement, now, 'fused')
        last = track.tracker.stamp
        if track.superseded is not None and track.superseded.fits(stamp) and not track.fits(
                stamp):
            # A single stamp from the past replaced the track; time goes on from the old one.
            track = track.superseded
            return self._update(track, measurement, now, 'fused')
        if stamp == last:
            return track, Fusion('duplicate')
        if stamp < last:
            if last - stamp <= _TIME_RESET_SECONDS:
                return track, Fusion(
                    'stale', f'stamp {stamp:.3f} s is not after the last one ({last:.3f} s)')
            restarted = _Track(self.settings.acceleration_std, now, superseded=track)
            return self._update(
                restarted, measurement, now, 'restarted',
                f'time jumped back from {last:.3f} s to {stamp:.3f} s: restarting the track')
        if stamp - last > MAX_STAMP_JUMP_SECONDS:
            if now - track.last_heard <= self.settings.neighbor_timeout:
                return track, Fusion(
                    'refused', f'stamp {stamp:.3f} s is more than {MAX_STAMP_JUMP_SECONDS:g} s '
                    f'after the last one ({last:.3f} s)')
            # Nothing usable for a whole neighbour timeout: the source's time moved on for good.
            return self._update(
                _Track(self.settings.acceleration_std, now), measurement, now, 'restarted',
                f'time jumped ahead from {last:.3f} s to {stamp:.3f} s after '
                f'{now - track.last_heard:.1f} s without a usable stamp: restarting the track')
        track.superseded = None
        return self._update(track, measurement, now, 'fused')

    @staticmethod
    def _update(track, measurement, now, status, detail=''):
        """Feed MEASUREMENT to TRACK's filter; return (TRACK, Fusion(STATUS) or 'refused')."""
        try:
            track.tracker.update(measurement.stamp, measurement.position, measurement.velocity,
                                 measurement.covariance)
        except TrackFault as fault:
            return track, Fusion('refused', str(fault))
        track.last_heard = now
        return track, Fusion(status, detail)

    # Planning ---------------------------------------------------------------------------------

    def awaiting_listed(self, now):
        """Whether a listed neighbour has not been heard in full yet and may still turn up.

        In full: its odometry, its footprint and its share. Announcements travel apart from
        odometry; without this, a team's first plans would depend on which came first.
        """
        if (self.listed_neighbours is None or self._first_own_at is None
                or now - self._first_own_at > self.settings.neighbor_timeout):
            return False
        return any(name not in self._neighbour_tracks or name not in self._announced_radius
                   or name not in self._announced_share for name in self.listed_neighbours)

    def ready(self, now):
        """Whether a stamp is pending and every neighbour has been measured at or after it."""
        return (self._pending_stamp is not None and not self.awaiting_listed(now) and all(
            track.tracker.stamp >= self._pending_stamp
            for track in self._neighbour_tracks.values()))

    def plan(self):
        """Plan for the pending stamp (neighbours predicted to it); return the `Command`.

        Raises RuntimeError when no own measurement is pending.
        """
        request = self.plan_request()
        result = None if request.problem is None else plan_velocity(*request.problem)
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
        own = self._own_track.tracker.belief_at(stamp)
        max_speed = self.config.max_speed
        v_pref, self.arrived = preferred_velocity(
            own.mean[:2], self.goal, max_speed, self.settings.approach_time,
            self.settings.goal_tolerance)
        names = tuple(self._neighbour_tracks)
        neighbour_beliefs = tuple(
            self._neighbour_tracks[robot].tracker.belief_at(stamp) for robot in names)
        announcements = tuple(self.announcement_of(robot) for robot in names)
        problem = None
        if self.goal is not None:
            # At its goal the robot keeps planning, with v_pref = 0: it stands while nobody
            # comes and takes its share of the avoidance when someone does, over the whole
            # horizon (its neighbours count on that share).
            horizon = self.config.time_horizon if self.arrived else goal_horizon(
                float(np.hypot(*(self.goal - own.mean[:2]))), max_speed,
                self.settings.approach_time, self.config.time_horizon)
            problem = (
                AgentBelief(own.mean[:2], own.mean[2:], own.covariance, self.settings.radius),
                [AgentBelief(belief.mean[:2], belief.mean[2:], belief.covariance,
                             announcement.radius, announcement.avoidance_share)
                 for belief, announcement in zip(neighbour_beliefs, announcements,
                                                 strict=True)],
                v_pref, dataclasses.replace(self.config, time_horizon=horizon),
                self._previous_velocity)
            if self.arrived and nobody_comes(problem):
                problem = None
        return PlanRequest(stamp=stamp, own=own, neighbours=neighbour_beliefs,
                           neighbour_names=names, announcements=announcements,
                           problem=problem)

    def complete(self, request, result):
        """Return the `Command` of REQUEST given the core's RESULT (None: stand still)."""
        velocity = np.zeros(2) if result is None else result.velocity
        self._previous_velocity = None if result is None else velocity
        return Command(stamp=request.stamp, velocity=velocity, yaw=self._own_yaw, result=result,
                       arrived=self.arrived, own=request.own, neighbours=request.neighbours,
                       neighbour_names=request.neighbour_names,
                       announcements=request.announcements)

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


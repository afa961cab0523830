"""Where a robot's preferred velocity comes from, no ROS: a goal, a path or an upstream command.

The planner finds the velocity nearest to a preferred one that meets the chance constraints.
`preferred_source` names where that preferred velocity comes from:

* ``goal``: straight to a goal point (`prvo_planner.agent.preferred_velocity`).
* ``path``: along a path (a `PathFollower`), toward the carrot of pure pursuit at a lookahead
  distance, optionally scaled with the speed between a minimum and a maximum as Regulated Pure
  Pursuit does; the goal is the path's last waypoint.
* ``velocity``: an upstream command (`UpstreamCommand`, a Twist from a controller or a
  velocity smoother) is the preferred velocity: the planner is a safety filter between the
  controller and the base. `FilterGate` applies the output rules of the node it replaces
  (Nav2's collision monitor): one output per input, zero when the robot's own state is stale,
  zeros for `stop_pub_timeout` once the output is zero, then silence until it moves again.
"""

import dataclasses
import math

import numpy as np

from prvo_planner.path_following import carrot

GOAL = 'goal'
PATH = 'path'
VELOCITY = 'velocity'
SOURCES = (GOAL, PATH, VELOCITY)


@dataclasses.dataclass(frozen=True)
class LookaheadSettings:
    """The carrot's distance [m] on a path or route: `lookahead_dist`, or scaled with the speed.

    With `use_velocity_scaled_lookahead_dist` the distance is speed * `lookahead_time` within
    [`min_lookahead_dist`, `max_lookahead_dist`], as Regulated Pure Pursuit scales it.
    """

    lookahead_dist: float = 1.0
    use_velocity_scaled_lookahead_dist: bool = False
    min_lookahead_dist: float = 0.3
    max_lookahead_dist: float = 0.9
    lookahead_time: float = 1.5

    def distance(self, speed):
        """Return the lookahead distance [m] at SPEED [m/s] (the robot's estimated speed)."""
        if not self.use_velocity_scaled_lookahead_dist:
            return self.lookahead_dist
        return min(max(speed * self.lookahead_time, self.min_lookahead_dist),
                   self.max_lookahead_dist)


class PathFollower:
    """Progress along one path: the carrot and the way left, never going back along the path.

    Parameters
    ----------
    waypoints : array_like
        The path in the world frame, shape (K, 2), K >= 1, finite [m].

    Raises ValueError naming what is wrong with WAYPOINTS.
    """

    def __init__(self, waypoints):
        waypoints = np.asarray(waypoints, dtype=float)
        if waypoints.ndim != 2 or waypoints.shape[1] != 2 or len(waypoints) == 0:
            raise ValueError(f'path must be waypoints of shape (K, 2), K >= 1, got shape '
                             f'{waypoints.shape}')
        if not np.all(np.isfinite(waypoints)):
            raise ValueError('path waypoints must be finite')
        self.waypoints = waypoints
        # Length [m] of the path from each waypoint to the end, (K,).
        steps = np.linalg.norm(np.diff(waypoints, axis=0), axis=1)
        self._length_after = np.concatenate([np.cumsum(steps[::-1])[::-1], [0.0]])
        self.segment = 0
        self.last_carrot = None

    @property
    def goal(self):
        """The path's last waypoint (2,)."""
        return self.waypoints[-1]

    def advance(self, position, lookahead):
        """Move the progress to POSITION (2,); return (carrot (2,), way left [m]).

        The carrot is `path_following.carrot` at LOOKAHEAD [m]; the way left is the path's length
        from the robot's closest point to the end, plus the distance to that point.
        """
        position = np.asarray(position, dtype=float)
        point, self.segment = carrot(self.waypoints, position, lookahead, self.segment)
        self.last_carrot = point
        if len(self.waypoints) == 1:
            return point, float(np.hypot(*(self.goal - position)))
        start = self.waypoints[self.segment]
        end = self.waypoints[self.segment + 1]
        step = end - start
        length_squared = float(step @ step)
        fraction = 0.0 if length_squared == 0.0 else min(
            max(float((position - start) @ step) / length_squared, 0.0), 1.0)
        closest = start + fraction * step
        left = (self._length_after[self.segment + 1] + float(np.hypot(*(end - closest)))
                + float(np.hypot(*(closest - position))))
        return point, left


def path_preferred_velocity(position, follower, lookahead, max_speed, approach_time,
                            goal_tolerance, max_acceleration=math.inf):
    """Return (v_pref (2,), arrived, way left [m]) of a robot at POSITION following a path.

    Toward FOLLOWER's carrot at LOOKAHEAD [m], at the speed `agent.preferred_velocity` would
    take toward a goal as far away as the way left along the path (slowing over the last
    stretch, braking within MAX_ACCELERATION); arrived within GOAL_TOLERANCE of the last
    waypoint.
    """
    position = np.asarray(position, dtype=float)
    point, left = follower.advance(position, lookahead)
    if float(np.hypot(*(follower.goal - position))) <= goal_tolerance:
        return np.zeros(2), True, 0.0
    offset = point - position
    distance = float(np.hypot(*offset))
    if distance == 0.0:
        return np.zeros(2), False, left
    speed = min(max_speed, left / approach_time, math.sqrt(2.0 * max_acceleration * left))
    return offset * (speed / distance), False, left


@dataclasses.dataclass(frozen=True)
class UpstreamCommand:
    """One upstream velocity command, as a controller sends it: body frame, SI units.

    `linear` (x, y) [m/s] and `angular` (z) [rad/s]; `stamp` [s] its header's stamp (None
    unstamped); `message` is the message it came in, passed on unchanged when nothing
    constrains it (None outside ROS).
    """

    linear: tuple
    angular: float
    message: object = dataclasses.field(default=None, compare=False)
    stamp: float = None

    def __post_init__(self):
        linear = tuple(float(value) for value in self.linear)
        if len(linear) != 2 or not all(math.isfinite(value) for value in (*linear, self.angular)):
            raise ValueError(f'upstream command must be finite (linear x, y; angular z), got '
                             f'{[*linear, self.angular]}')
        object.__setattr__(self, 'linear', linear)
        object.__setattr__(self, 'angular', float(self.angular))

    @property
    def is_zero(self):
        """Whether the command stands still and does not turn."""
        return self.linear == (0.0, 0.0) and self.angular == 0.0

    def world_velocity(self, yaw, unicycle):
        """Return the command's velocity (2,) in the world frame for a robot at YAW [rad].

        A unicycle (UNICYCLE) moves along its heading only: linear.x.
        """
        x, y = (self.linear[0], 0.0) if unicycle else self.linear
        # The arithmetic of prvo_msgs_util.body_to_world (the agent imports no ROS).
        cos, sin = math.cos(yaw), math.sin(yaw)
        return np.array([cos * x - sin * y, sin * x + cos * y])


class FilterGate:
    """When a safety filter publishes: the rules of Nav2's collision monitor.

    Every input is answered by one output, except that once the output is zero it is published
    for STOP_PUB_TIMEOUT [s] (inf: for ever) and then no more, until a non-zero output comes.
    The base controller's own command timeout then holds the robot, and the filter does not
    flood a robot that stands.
    """

    def __init__(self, stop_pub_timeout):
        self.stop_pub_timeout = float(stop_pub_timeout)
        self._stopped_at = None
        self._previous_zero = False

    def publishes(self, output_is_zero, now):
        """Whether an output (OUTPUT_IS_ZERO: zero) answering at NOW [s] is to be published."""
        if not output_is_zero:
            self._previous_zero = False
            return True
        if not self._previous_zero:
            self._previous_zero, self._stopped_at = True, now
            return True
        return now - self._stopped_at <= self.stop_pub_timeout

"""A stand-in for Nav2's controller and velocity smoother, without ROS: pure pursuit, blind.

One robot follows its waypoints by pure pursuit (the carrot of `prvo_planner.path_following`
at a fixed lookahead), at a cruise speed that ramps down to zero over the last stretch
(braking at `deceleration`) and is zero once the robot is within `goal_tolerance` of the last
waypoint. It knows nothing of other robots: what keeps them apart is the velocity filter
between it and the base. A holonomic robot is commanded straight at the carrot; a unicycle
turns onto the arc through it (curvature 2 sin(alpha) / lookahead) and turns in place while the
carrot is behind it, as Regulated Pure Pursuit does.
"""

import math

import numpy as np

from prvo_msgs_util import world_to_body
from prvo_planner.preferred import PathFollower

# The controller's rate [Hz] (velocity_smoother's default smoothing_frequency).
RATE = 20.0
LOOKAHEAD = 0.6
DECELERATION = 1.0


class PurePursuitUpstream:
    """The upstream command of one robot along WAYPOINTS (K, 2) at SPEED [m/s].

    `kinematics` 'holonomic' or 'unicycle' (turning at most `max_angular_speed` [rad/s]).
    """

    def __init__(self, waypoints, speed, kinematics='holonomic', goal_tolerance=0.1,
                 max_angular_speed=2.0, lookahead=LOOKAHEAD, deceleration=DECELERATION):
        self._follower = PathFollower(waypoints)
        self.speed = float(speed)
        self.unicycle = kinematics == 'unicycle'
        self.goal_tolerance = float(goal_tolerance)
        self.max_angular_speed = float(max_angular_speed)
        self.lookahead = float(lookahead)
        self.deceleration = float(deceleration)

    def command(self, position, yaw):
        """Return ((linear x, y) [m/s], angular z [rad/s]) in the body frame at POSITION, YAW."""
        position = np.asarray(position, dtype=float)
        point, left = self._follower.advance(position, self.lookahead)
        if float(np.hypot(*(self._follower.goal - position))) <= self.goal_tolerance:
            return (0.0, 0.0), 0.0
        speed = min(self.speed, math.sqrt(2.0 * self.deceleration * left))
        offset = point - position
        distance = float(np.hypot(*offset))
        if distance == 0.0:
            return (0.0, 0.0), 0.0
        if not self.unicycle:
            body = world_to_body(offset * (speed / distance), yaw)
            return (float(body[0]), float(body[1])), 0.0
        alpha = math.remainder(math.atan2(offset[1], offset[0]) - yaw, 2.0 * math.pi)
        if abs(alpha) > 0.5 * math.pi:
            return (0.0, 0.0), math.copysign(self.max_angular_speed, alpha)
        turn = speed * 2.0 * math.sin(alpha) / max(distance, 1e-9)
        limit = self.max_angular_speed
        if abs(turn) > limit:
            # Slower on a tight arc, the curvature kept.
            speed *= limit / abs(turn)
            turn = math.copysign(limit, turn)
        return (speed, 0.0), turn

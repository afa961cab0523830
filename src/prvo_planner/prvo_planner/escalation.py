"""Escalation: a stalled robot turns its preferred velocity to the right, no ROS.

A local, reciprocal planner does not break the symmetry of robots that meet head-on where the
certified velocity nearest each one's preference is to stand, or to sidestep the same way as
the other: they can stay so for good (issue 38). Once the robot's `stalls.StallMonitor` finds it
stalled, its preferred velocity turns to the right by an angle that rises at `stall_turn_rate` to
`stall_turn_max` and falls back at the same rate to 0 (a sidestep of 2 cap / rate seconds), and
again while the stall lasts; the turn ends (back to the goal or the route) as soon as the stall
ends, that is on STALL_PROGRESS of progress toward the goal. As in B-UAVC (Zhu and Alonso-Mora,
which turns a stuck robot's goal to its right for a few steps) and IMPC-DR (Chen et al., a
right-hand term), every robot turns the same way in its own frame, so two robots facing each
other turn apart in the world. Falling back to 0 gives the robot a try of its route after each
sidestep: held at the cap, a robot queueing at a door turned away from it for good and wandered
off (`doorway8`: 2 of 8 robots home instead of 4 with the sidestep).

The cap stays below a right angle: the turned preference keeps a part toward the goal, so a robot
that stepped aside until a wall holds it slides along the wall toward its goal instead of pressing
sideways (at a right angle it would gain nothing).

Among walls (a map), a robot turns only where it has room on its right: its centre can move one
radius to its right through cells that keep its clearance (`route.RouteMap.in_sight`). Two equal
robots facing each other that each step one radius aside are a sum of radii apart sideways, and
pass. With the right blocked the robot keeps its route: a robot facing it from the other way has
room on its own right and steps aside for both; were the blocked robot to turn left instead, both
would move toward the same wall and stay face to face (its left is the other's right).

Only the preferred velocity changes: the chance constraints against robots and walls, and so the
guarantee, are those of every plan.

Off by default (`stall_escalation`): on the shipped wall worlds (seed 7, in process) it brought
no more robots home in `corridor8` (4 of 8 either way), fewer in `doorway8` (4 of 8 instead of
6: robots queueing at the door are stalled and step away from it), and a slower `pillars12`
(makespan 36.2 s instead of 23.9 s), though a faster `office` (45.4 s instead of 65.0 s). It
does part two robots exactly facing each other in open space, which stand for good without it
when nothing else breaks the tie (`passing_bias` 0).
"""

import dataclasses
import math

import numpy as np

# Defaults of the planner parameters (`prvo_planner.parameters`), and why.
# 0.2 rad/s: about 11 degrees per second, the cap in about 5 s (the time_horizon it was chosen
# at, now 2 s): a sidestep of about 10 s.
TURN_RATE = 0.2  # rad/s
# 60 degrees: half the speed still toward the goal, most of it to the side.
TURN_MAX = math.pi / 3.0  # rad
# The turn is taken only with room for this many of the robot's radii on its right.
ROOM_RADII = 1.0


@dataclasses.dataclass(frozen=True)
class EscalationSettings:
    """`enabled` turns escalation on; `rate` [rad/s] the angle's growth, `cap` [rad] its limit."""

    enabled: bool = False
    rate: float = TURN_RATE
    cap: float = TURN_MAX


def turn_angle(duration, settings):
    """Return the angle [rad, >= 0] to the right after a stall of DURATION [s] (0: none).

    A sidestep: the angle rises at the rate to the cap and falls back at the rate to 0, and
    again while the stall lasts (a triangle of period 2 cap / rate).
    """
    if not settings.enabled or duration <= 0.0:
        return 0.0
    rise = settings.cap / settings.rate
    phase = math.fmod(duration, 2.0 * rise)
    return settings.rate * (phase if phase <= rise else 2.0 * rise - phase)


def turned_right(velocity, angle):
    """Return VELOCITY (2,) turned clockwise (to the right) by ANGLE [rad]."""
    cos, sin = math.cos(angle), math.sin(angle)
    x, y = velocity
    return np.array([cos * x + sin * y, -sin * x + cos * y])


def right_of(velocity):
    """Return the unit vector (2,) to the right of VELOCITY (2,), nonzero."""
    x, y = velocity
    return np.array([y, -x]) / math.hypot(x, y)


class Escalation:
    """One robot's escalation (see the module), fed its stall status at every plan.

    Whether there is room on the right is decided once per stall, when it is first seen: the
    side does not flip while the robot steps aside.
    """

    def __init__(self):
        self._since = None  # s: the stall the room was decided for
        self._room = True
        self.angle = 0.0  # rad: the turn of the last `preferred`

    def preferred(self, v_pref, stall, settings, room_on_right=None):
        """Return the preferred velocity (2,) a robot with stall status STALL plans with.

        V_PREF (2,) [m/s] is the velocity toward its goal or route; STALL a
        `stalls.StallStatus` (None: none); SETTINGS the `EscalationSettings`; ROOM_ON_RIGHT a
        callable taking the unit vector to the right (2,) and returning whether the robot has
        room there (None: open space, always room). V_PREF itself comes back while not stalled,
        when escalation is off, or when V_PREF is zero.
        """
        self.angle = 0.0
        if (not settings.enabled or stall is None or not stall.stalled
                or not (v_pref[0] or v_pref[1])):
            self._since = None
            return v_pref
        if self._since != stall.since:
            self._since = stall.since
            self._room = room_on_right is None or bool(room_on_right(right_of(v_pref)))
        if not self._room:
            return v_pref
        self.angle = turn_angle(stall.duration, settings)
        return turned_right(v_pref, self.angle)

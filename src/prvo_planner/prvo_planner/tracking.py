"""Differential drive by tracking a holonomic velocity within a bounded error (no ROS).

A unicycle (forward speed `v`, turn rate `omega`, nothing sideways) cannot execute the planner's
holonomic velocity `v_h` directly. It tracks it: it turns toward `v_h`'s direction at
`omega = clamp(e / T, +-omega_max)`, `e` the heading error and `T` the tracking horizon (at
least the control period), and
drives at `|v_h| cos e` while `|e| < pi / 2` (else it turns in place). Held over each control
period, this moves the robot away from the straight path `t v_h` by at most a tracking error
that is proportional to `|v_h|` for a given initial heading error, so the largest speed whose
error stays within `E` is a function of that angle alone. The planner plans only such
velocities and with its radius grown by `E`: the robot then stays within `E` of a holonomic
robot that meets the chance constraint. The errors are tabulated by simulating the controller
for a bounded number of periods; an angle from which the robot is still turning at a limit by
then has no trackable speed.
"""

from dataclasses import dataclass
import functools
import math

import numpy as np

# Heading errors [rad] of the tabulated tracking errors, 0 to pi.
_TABLE_ANGLES = np.linspace(0.0, math.pi, 361)
# Samples of the path within each control period at which the error is measured.
_SAMPLES_PER_PERIOD = 8
# The tabulated runs last until every heading error is below this [rad] for good; later the
# path is parallel to the reference and the error barely grows (`_tail_bound`).
_ALIGNED = 1e-6
# Control periods the tabulated runs last at most (under a second of work), whatever the
# limits; a run still turning at a limit then is untrackable.
MAX_TABLE_PERIODS = 2000


def wrapped(angle):
    """Return ANGLE [rad] (scalar or array) in [-pi, pi)."""
    return (np.asarray(angle) + math.pi) % (2.0 * math.pi) - math.pi


def tracking_command(velocity, yaw, previous_forward, previous_turn, model, period):
    """Return (forward speed, turn rate) that track world-frame VELOCITY (2,) from YAW.

    MODEL is the `TrackingModel`; the previous command and PERIOD [s] bound the change by the
    accelerations. A velocity of (almost) zero length has no direction: the robot stops
    turning.
    """
    speed = math.hypot(velocity[0], velocity[1])
    error = float(wrapped(math.atan2(velocity[1], velocity[0]) - yaw)) if speed > 1e-9 else 0.0
    forward, turn = _control_law(speed, error, previous_forward, previous_turn, model, period)
    return float(forward), float(turn)


def _control_law(speed, error, previous_forward, previous_turn, model, period):
    """Return the (forward, turn) command for heading ERROR; scalars or arrays alike."""
    # A horizon shorter than the period would overshoot: then the turn closes the error in one.
    turn = np.clip(error / max(model.horizon, period), -model.max_angular_speed,
                   model.max_angular_speed)
    forward = np.where(np.abs(error) < 0.5 * math.pi,
                       np.minimum(speed * np.cos(error), model.max_speed), 0.0)
    forward = _toward(previous_forward, forward, _change(model.max_acceleration, period))
    turn = _toward(previous_turn, turn, _change(model.max_angular_acceleration, period))
    return forward, turn


def _change(acceleration, period):
    """Return the largest change over PERIOD of a rate limited by ACCELERATION (inf: none)."""
    return acceleration * period if math.isfinite(acceleration) else math.inf


def _toward(previous, target, max_change):
    if not math.isfinite(max_change):
        return target
    return np.clip(target, previous - max_change, previous + max_change)


class TrackingModel:
    """A unicycle's limits and its tracking controller's horizon and error bound.

    Parameters
    ----------
    max_speed, max_angular_speed : float
        Limits of the forward speed [m/s] and the turn rate [rad/s].
    max_acceleration, max_angular_acceleration : float
        Limits of their change [m/s^2, rad/s^2]; inf: none.
    horizon : float
        `T` [s]: the controller turns at the heading error / T.
    error : float
        `E` [m]: the tracking error every planned velocity keeps.

    """

    def __init__(self, max_speed, max_angular_speed, max_acceleration,
                 max_angular_acceleration, horizon, error):
        self.max_speed = float(max_speed)
        self.max_angular_speed = float(max_angular_speed)
        self.max_acceleration = float(max_acceleration)
        self.max_angular_acceleration = float(max_angular_acceleration)
        self.horizon = float(horizon)
        self.error = float(error)

    def trackable_speeds(self, relative_angles, period):
        """Largest speeds [m/s] trackable within `error` at RELATIVE_ANGLES (rad, array).

        PERIOD [s] is the control period the commands are held for.
        """
        unit_errors = _unit_error_table(self.max_angular_speed, self.max_angular_acceleration,
                                        self.horizon, round(float(period), 6))
        # The table rises with the angle; the grid point above an angle bounds its error.
        index = np.ceil(np.abs(wrapped(relative_angles)) / _TABLE_ANGLES[1]).astype(int)
        errors = unit_errors[np.minimum(index, _TABLE_ANGLES.size - 1)]
        with np.errstate(divide='ignore'):
            return np.minimum(self.max_speed, self.error / errors)

    def speed_function(self, period):
        """Return `trackable_speeds` with PERIOD fixed: relative angles -> speeds."""
        return functools.partial(self.trackable_speeds, period=period)


def largest_offsets(speed, heading_errors, model, period):
    """Return (largest offsets (A,), `RunEnd`) of unicycles tracking constant velocities.

    Each robot starts at the origin heading along +x, at rest and not turning; its velocity has
    length SPEED and points one of HEADING_ERRORS (A,) from +x. They are driven, noise-free, in
    control periods of PERIOD [s] (held commands, exact arcs) until every one has settled
    (`_settled`) within `_ALIGNED` of its velocity's heading, or for MAX_TABLE_PERIODS. A
    robot's offset is its position minus the straight path `t velocity`; the largest is over
    samples within every period. Memory does not grow with the periods.
    """
    heading_errors = np.asarray(heading_errors, dtype=float)
    velocities = speed * np.stack([np.cos(heading_errors), np.sin(heading_errors)], axis=1)
    positions = np.zeros_like(velocities)
    yaws = np.zeros_like(heading_errors)
    forward = turn = np.zeros_like(heading_errors)
    # Every sample of a period at once: (samples, A).
    fractions = (np.arange(1, _SAMPLES_PER_PERIOD + 1) / _SAMPLES_PER_PERIOD)[:, None]
    largest = np.zeros_like(heading_errors)
    for step in range(MAX_TABLE_PERIODS):
        forward, turn = _control_law(speed, wrapped(heading_errors - yaws), forward, turn,
                                     model, period)
        moved, turned = _arc(forward, turn, yaws, fractions * period)
        offsets = positions + moved - ((step + fractions) * period)[..., None] * velocities
        largest = np.maximum(largest, np.max(np.linalg.norm(offsets, axis=-1), axis=0))
        positions = positions + moved[-1]
        yaws = turned[-1]
        end = RunEnd(offsets[-1], wrapped(heading_errors - yaws), turn, step + 1)
        if np.all(np.abs(end.heading_errors) <= _ALIGNED) and np.all(
                _settled(end, model, period)):
            break
    return largest, end


@dataclass(frozen=True)
class RunEnd:
    """Where tracking runs are after their last period.

    `offsets` (A, 2) from their straight paths [m], `heading_errors` (A,) [rad],
    the turn rates `turn` (A,) [rad/s] commanded over the last period and the number of
    `periods` run.
    """

    offsets: np.ndarray
    heading_errors: np.ndarray
    turn: np.ndarray
    periods: int


def _arc(forward, turn, yaws, durations):
    """Return displacements (S, A, 2) and yaws (S, A) after DURATIONS (S, 1) of exact arcs."""
    half = 0.5 * turn * durations
    chord = forward * durations * np.sinc(half / math.pi)
    moved = np.stack([chord * np.cos(yaws + half), chord * np.sin(yaws + half)], axis=-1)
    return moved, yaws + 2.0 * half


def _settled(end, model, period):
    """Whether each run ending at END (a `RunEnd`) turns from now on at neither limit (A,).

    Its controller then turns at the heading error e / max(T, period) exactly, which shrinks e
    by a factor (1 - period / max(T, period)) per period without overshoot: the turn rate
    stays within the limit, and so does its change if |e| <= max_angular_acceleration
    max(T, period)^2 (the change is |e| period / max(T, period)^2).
    """
    horizon = max(model.horizon, period)
    error = np.abs(end.heading_errors)
    calm = (error < 0.5 * math.pi) & (error <= model.max_angular_speed * horizon)
    if not math.isfinite(model.max_angular_acceleration):
        return calm
    return calm & (np.abs(end.heading_errors / horizon - end.turn)
                   <= model.max_angular_acceleration * period) & (
                       error <= model.max_angular_acceleration * horizon ** 2)


def _tail_bound(end, model, period):
    """Return how much farther (A,) the runs ending at END may stray per unit speed.

    For a model without a forward acceleration limit (the table's). A settled run's heading
    error e shrinks geometrically; the robot drives at cos(e) along a heading within e of its
    velocity's, moving off its path at most at |e| (1 + |e| / 2) per unit speed: at most
    |e| (1 + |e| / 2) max(T, period) in all. Any other run may stray without a bound known
    here: inf.
    """
    error = np.abs(end.heading_errors)
    return np.where(_settled(end, model, period),
                    error * (1.0 + 0.5 * error) * max(model.horizon, period), math.inf)


@functools.lru_cache(maxsize=32)
def _unit_error_table(max_angular_speed, max_angular_acceleration, horizon, period):
    """Tracking error at speed 1 for every angle of _TABLE_ANGLES, made non-decreasing.

    Each angle's error is the largest of its run, or its error at the end plus `_tail_bound`
    if larger: inf for a run still turning at a limit when the period cap ends it.
    """
    model = TrackingModel(1.0, max_angular_speed, math.inf, max_angular_acceleration, horizon,
                          1.0)
    largest, end = largest_offsets(1.0, _TABLE_ANGLES, model, period)
    largest = np.maximum(largest, np.linalg.norm(end.offsets, axis=1)
                         + _tail_bound(end, model, period))
    return np.maximum.accumulate(largest)

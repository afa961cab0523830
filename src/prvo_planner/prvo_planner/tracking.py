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
robot that meets the chance constraint.
"""

import functools
import math

import numpy as np

# Heading errors [rad] of the tabulated tracking errors, 0 to pi.
_TABLE_ANGLES = np.linspace(0.0, math.pi, 361)
# Samples of the path within each control period at which the error is measured.
_SAMPLES_PER_PERIOD = 8
# The tabulated run lasts until the heading error is below this [rad]; later the path is
# parallel to the reference and the error no longer grows.
_ALIGNED = 1e-6


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


def tracked_path(speed, heading_errors, model, period, duration):
    """Return (times, offsets (A, K, 2)) of unicycles tracking constant velocities, noise-free.

    Each robot starts at the origin heading along +x, at rest and not turning; its velocity has
    length SPEED and points one of HEADING_ERRORS (A,) from +x. `offsets` are the robots'
    positions minus the straight paths `t velocity`, sampled within every control period (held
    commands, exact arcs) up to DURATION [s].
    """
    heading_errors = np.asarray(heading_errors, dtype=float)
    velocities = speed * np.stack([np.cos(heading_errors), np.sin(heading_errors)], axis=1)
    positions = np.zeros_like(velocities)
    yaws = np.zeros_like(heading_errors)
    forward = turn = np.zeros_like(heading_errors)
    fractions = np.arange(1, _SAMPLES_PER_PERIOD + 1) / _SAMPLES_PER_PERIOD
    times, offsets = [0.0], [np.zeros_like(velocities)]
    for step in range(math.ceil(duration / period - 1e-9)):
        forward, turn = _control_law(speed, wrapped(heading_errors - yaws), forward, turn,
                                     model, period)
        for fraction in fractions:
            moved, turned = _arc(forward, turn, yaws, fraction * period)
            times.append((step + fraction) * period)
            offsets.append(positions + moved - times[-1] * velocities)
        positions = positions + moved
        yaws = turned
    return np.array(times), np.stack(offsets, axis=1)


def _arc(forward, turn, yaws, duration):
    """Return displacements (A, 2) and yaws (A,) after DURATION of exact unicycle arcs."""
    half = 0.5 * turn * duration
    chord = forward * duration * np.sinc(half / math.pi)
    moved = np.stack([chord * np.cos(yaws + half), chord * np.sin(yaws + half)], axis=1)
    return moved, yaws + 2.0 * half


@functools.lru_cache(maxsize=32)
def _unit_error_table(max_angular_speed, max_angular_acceleration, horizon, period):
    """Tracking error at speed 1 for every angle of _TABLE_ANGLES, made non-decreasing."""
    model = TrackingModel(1.0, max_angular_speed, math.inf, max_angular_acceleration, horizon,
                          1.0)
    # Turning pi at the limits, then converging by a factor (1 - period / T) per period.
    convergence = math.log(_ALIGNED / math.pi) / math.log(
        max(abs(1.0 - min(period / horizon, 1.0)), 1e-12))
    duration = (math.pi / max_angular_speed + (
        max_angular_speed / max_angular_acceleration if math.isfinite(
            max_angular_acceleration) else 0.0) + max(convergence, 1.0) * period + period)
    offsets = tracked_path(1.0, _TABLE_ANGLES, model, period, duration)[1]
    return np.maximum.accumulate(np.max(np.linalg.norm(offsets, axis=2), axis=1))

"""Single-integrator kinematics of a team of disk robots with actuation and sensing noise.

Pure numpy. Every function that draws noise takes the generator and draws a fixed number of
samples whatever the values, so a seeded run is reproducible.
"""

import numpy as np


def clamp_speed(commands, max_speeds):
    """Return COMMANDS (N, 2) scaled down where their speed exceeds MAX_SPEEDS (N,)."""
    commands = np.asarray(commands, dtype=float)
    max_speeds = np.asarray(max_speeds, dtype=float)
    speeds = np.linalg.norm(commands, axis=1)
    too_fast = speeds > max_speeds
    scale = np.ones_like(speeds)
    scale[too_fast] = max_speeds[too_fast] / speeds[too_fast]
    return commands * scale[:, None]


def step(positions, commands, max_speeds, actuation_std, dt, rng):
    """Advance the team by DT; return (positions_next, executed_velocities), both (N, 2).

    Paper eqs. 1 and 5: executed = clamp(command) + N(0, actuation_std^2 I), and
    p(t + dt) = p(t) + executed * dt.
    """
    positions = np.asarray(positions, dtype=float)
    noise = rng.standard_normal(positions.shape) * np.asarray(actuation_std, dtype=float)[:, None]
    executed = clamp_speed(commands, max_speeds) + noise
    return positions + executed * dt, executed


def contact_pairs(positions, radii):
    """Return the set of index pairs (i, j), i < j, whose centres are closer than r_i + r_j."""
    positions = np.asarray(positions, dtype=float)
    radii = np.asarray(radii, dtype=float)
    distances = np.linalg.norm(positions[:, None, :] - positions[None, :, :], axis=2)
    touching = distances < radii[:, None] + radii[None, :]
    first, second = np.nonzero(np.triu(touching, k=1))
    return {(int(i), int(j)) for i, j in zip(first, second, strict=True)}


def noisy_odometry(positions, velocities, position_std, velocity_std, rng):
    """Return (positions, velocities) with N(0, std^2 I) per robot added; stds are (N,)."""
    positions = np.asarray(positions, dtype=float)
    velocities = np.asarray(velocities, dtype=float)
    position_noise = rng.standard_normal(positions.shape)
    velocity_noise = rng.standard_normal(velocities.shape)
    return (positions + position_noise * np.asarray(position_std, dtype=float)[:, None],
            velocities + velocity_noise * np.asarray(velocity_std, dtype=float)[:, None])


def rate_limited(commands, previous, max_changes):
    """Return COMMANDS (N, D) moved from PREVIOUS (N, D) by at most MAX_CHANGES (N,) each.

    The change of a row is scaled down as a vector (its direction kept); an infinite limit
    leaves the row as commanded.
    """
    commands = np.asarray(commands, dtype=float)
    previous = np.asarray(previous, dtype=float)
    max_changes = np.asarray(max_changes, dtype=float)
    change = commands - previous
    size = np.linalg.norm(change, axis=1)
    too_large = size > max_changes
    limited = commands.copy()
    # Rows within their limit stay the very numbers commanded.
    limited[too_large] = previous[too_large] + change[too_large] * (
        max_changes[too_large] / size[too_large])[:, None]
    return limited


def unicycle_commands(forward, turn, previous_forward, previous_turn, limits, dt):
    """Return (forward, turn), each (N,), clamped to LIMITS and rate limited over DT.

    LIMITS is a `UnicycleLimits`; the previous values are what the robots executed last
    (before noise). Forward speed lies in [-max_speed, max_speed], turn rate in
    [-max_angular_speed, max_angular_speed]; each changes by at most its acceleration times DT.
    """
    forward = np.clip(np.asarray(forward, dtype=float), -limits.max_speed, limits.max_speed)
    turn = np.clip(np.asarray(turn, dtype=float), -limits.max_angular_speed,
                   limits.max_angular_speed)
    forward_step = limits.max_acceleration * dt
    turn_step = limits.max_angular_acceleration * dt
    forward = np.clip(forward, previous_forward - forward_step, previous_forward + forward_step)
    turn = np.clip(turn, previous_turn - turn_step, previous_turn + turn_step)
    return forward, turn


class UnicycleLimits:
    """Per-robot limits (N,) of the unicycle model: speeds and accelerations (inf: none)."""

    def __init__(self, max_speed, max_angular_speed, max_acceleration, max_angular_acceleration):
        self.max_speed = np.asarray(max_speed, dtype=float)
        self.max_angular_speed = np.asarray(max_angular_speed, dtype=float)
        self.max_acceleration = np.asarray(max_acceleration, dtype=float)
        self.max_angular_acceleration = np.asarray(max_angular_acceleration, dtype=float)


def arc_step(positions, yaws, forward, turn, dt):
    """Return (positions, yaws) after driving FORWARD [m/s] and turning TURN [rad/s] for DT.

    Exact integration of the unicycle along its arc (a straight line where the turn rate is
    zero); arrays over robots, positions (N, 2).
    """
    positions = np.asarray(positions, dtype=float)
    yaws = np.asarray(yaws, dtype=float)
    turned = turn * dt
    # sin(x) / x and (1 - cos(x)) / x, written so that they stay exact as x -> 0.
    half = 0.5 * turned
    sinc_half = np.sinc(half / np.pi)
    along = forward * dt * sinc_half * np.cos(half)
    across = forward * dt * sinc_half * np.sin(half)
    cos_yaw, sin_yaw = np.cos(yaws), np.sin(yaws)
    moved = np.stack([along * cos_yaw - across * sin_yaw, along * sin_yaw + across * cos_yaw],
                     axis=1)
    return positions + moved, np.arctan2(np.sin(yaws + turned), np.cos(yaws + turned))


def unicycle_step(positions, yaws, forward, turn, noise, dt):
    """Advance unicycles by DT with noisy forward speeds and turn rates.

    NOISE (N, 2) is added to the forward speed [m/s] and the turn rate [rad/s]: nothing moves a
    unicycle sideways. Returns (positions, yaws, executed forward (N,), executed turn (N,)).
    """
    executed_forward = np.asarray(forward, dtype=float) + noise[:, 0]
    executed_turn = np.asarray(turn, dtype=float) + noise[:, 1]
    positions, yaws = arc_step(positions, yaws, executed_forward, executed_turn, dt)
    return positions, yaws, executed_forward, executed_turn

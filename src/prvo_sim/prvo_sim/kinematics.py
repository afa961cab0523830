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

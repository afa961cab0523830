"""The simulator's draw order, replayed with the kinematics functions alone.

This is the order in which the `sim` node drew its noise before `TeamWorld` existed: the t_0
odometry, then per step the actuation noise, the heading update and the odometry of the new
state. Comparing against it checks that a seed still gives the same run.
"""

import numpy as np

from prvo_sim import kinematics


def replay(scenario, seed, commands):
    """Return {quantity: array (steps + 1, N, ...)} of a run of COMMANDS (steps, N, 2).

    Quantities: 'positions', 'velocities', 'yaws' (ground truth), 'measured_positions',
    'measured_velocities' (odometry), each from t_0.
    """
    rng = np.random.default_rng(seed)
    specs = scenario.robots
    max_speeds = np.array([spec.max_speed for spec in specs])
    actuation_std = np.array([spec.noise.actuation_std for spec in specs])
    position_std = np.array([spec.noise.position_std for spec in specs])
    velocity_std = np.array([spec.noise.velocity_std for spec in specs])
    positions = np.array([spec.start for spec in specs], dtype=float)
    velocities = np.zeros_like(positions)
    to_goal = np.array([spec.goal for spec in specs]) - positions
    yaws = np.arctan2(to_goal[:, 1], to_goal[:, 0])
    run = {name: [] for name in ('positions', 'velocities', 'yaws', 'measured_positions',
                                 'measured_velocities')}

    def record():
        measured = kinematics.noisy_odometry(
            positions, velocities, position_std, velocity_std, rng)
        for name, value in zip(run, (positions, velocities, yaws, *measured), strict=True):
            run[name].append(np.array(value))

    record()
    for step_commands in commands:
        positions, velocities = kinematics.step(
            positions, step_commands, max_speeds, actuation_std, scenario.dt, rng)
        moving = np.linalg.norm(velocities, axis=1) > 1e-3
        yaws = yaws.copy()
        yaws[moving] = np.arctan2(velocities[moving, 1], velocities[moving, 0])
        record()
    return {name: np.array(values) for name, values in run.items()}

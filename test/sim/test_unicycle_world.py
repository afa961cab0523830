"""Unicycle kinematics and acceleration limits in the simulator's world."""

import dataclasses
import math

import numpy as np
import pytest

from prvo_sim import kinematics
from prvo_sim.scenario import load_scenario
from prvo_sim.world import TeamWorld

SCENARIO = """
name: drive
seed: 3
dt: 0.1
duration: 10.0
goal_tolerance: 0.2
noise: {position_std: 0.02, velocity_std: 0.03, actuation_std: 0.04}
robots:
  - {name: wheels, start: [0.0, 0.0], goal: [5.0, 0.0], radius: 0.3, max_speed: 1.0,
     kinematics: unicycle, max_angular_speed: 1.5, max_acceleration: 0.5,
     max_angular_acceleration: 3.0, start_yaw: 2.0}
  - {name: slider, start: [0.0, 3.0], goal: [5.0, 3.0], radius: 0.3, max_speed: 1.0,
     max_acceleration: 0.8}
  - {name: free, start: [0.0, -3.0], goal: [5.0, -3.0], radius: 0.3, max_speed: 1.0}
"""


def cross(first, second):
    """Return the z component of the cross product of 2-vectors (..., 2)."""
    return first[..., 0] * second[..., 1] - first[..., 1] * second[..., 0]


def euler_unicycle(position, yaw, forward, turn, duration, steps=200000):
    """Integrate a unicycle by many small Euler steps: an independent check of the arcs."""
    step = duration / steps
    x, y = position
    for _ in range(steps):
        x += forward * math.cos(yaw) * step
        y += forward * math.sin(yaw) * step
        yaw += turn * step
    return np.array([x, y]), yaw


@pytest.mark.parametrize('turn', [0.0, 1e-12, 0.7, -2.5, 9.0])
def test_arcs_are_integrated_exactly(turn):
    positions, yaws = kinematics.arc_step(np.array([[1.0, -2.0]]), np.array([0.4]),
                                          np.array([0.8]), np.array([turn]), 0.5)
    expected_position, expected_yaw = euler_unicycle((1.0, -2.0), 0.4, 0.8, turn, 0.5)
    assert np.allclose(positions[0], expected_position, atol=1e-5)
    assert math.isclose(math.cos(yaws[0]), math.cos(expected_yaw), abs_tol=1e-9)
    assert math.isclose(math.sin(yaws[0]), math.sin(expected_yaw), abs_tol=1e-9)


def test_rate_limit_moves_at_most_the_limit_and_leaves_the_rest_as_commanded():
    rng = np.random.default_rng(5)
    commands = rng.normal(size=(50, 2))
    previous = rng.normal(size=(50, 2))
    limits = np.where(np.arange(50) % 3 == 0, np.inf, 0.2)
    limited = kinematics.rate_limited(commands, previous, limits)
    changes = np.linalg.norm(limited - previous, axis=1)
    assert np.all(changes <= limits + 1e-12)
    within = np.linalg.norm(commands - previous, axis=1) <= limits
    assert np.array_equal(limited[within], commands[within])
    # A limited change keeps its direction.
    outside = ~within
    direction = (commands - previous)[outside]
    assert np.allclose(cross(limited[outside] - previous[outside], direction), 0.0)


@pytest.fixture
def world(tmp_path):
    path = tmp_path / 'drive.yaml'
    path.write_text(SCENARIO)
    return TeamWorld(load_scenario(path))


def test_a_unicycle_never_moves_sideways_and_keeps_its_limits(world):
    rng = np.random.default_rng(8)
    previous_forward = previous_turn = 0.0
    quiet = TeamWorld(dataclasses.replace(world.scenario, robots=tuple(
        dataclasses.replace(robot, noise=dataclasses.replace(robot.noise, actuation_std=0.0))
        for robot in world.scenario.robots)))
    for _ in range(60):
        commands = rng.normal(scale=3.0, size=(3, 2))
        yaw_before = quiet.yaws[0]
        quiet.step(commands)
        world.step(commands)
        for probe in (world, quiet):
            heading = np.array([math.cos(probe.yaws[0]), math.sin(probe.yaws[0])])
            # The ground truth velocity is along the heading: nothing sideways.
            assert abs(cross(heading, probe.velocities[0])) <= 1e-12
        # Without noise the executed forward speed and turn rate are the clamped, rate-limited
        # commands.
        forward = quiet.velocities[0] @ np.array([math.cos(quiet.yaws[0]),
                                                  math.sin(quiet.yaws[0])])
        turn = quiet.turn_rates[0]
        assert abs(forward) <= 1.0 + 1e-12 and abs(turn) <= 1.5 + 1e-12
        assert abs(forward - previous_forward) <= 0.5 * 0.1 + 1e-12
        assert abs(turn - previous_turn) <= 3.0 * 0.1 + 1e-12
        assert math.isclose(math.remainder(quiet.yaws[0] - yaw_before - turn * 0.1, math.tau),
                            0.0, abs_tol=1e-12)
        previous_forward, previous_turn = forward, turn


def test_the_start_yaw_and_a_holonomic_acceleration_limit(world):
    assert world.yaws[0] == 2.0
    assert world.yaws[1] == 0.0  # facing its goal
    quiet = TeamWorld(dataclasses.replace(world.scenario, robots=tuple(
        dataclasses.replace(robot, noise=dataclasses.replace(robot.noise, actuation_std=0.0))
        for robot in world.scenario.robots)))
    previous = np.zeros(2)
    rng = np.random.default_rng(2)
    for _ in range(40):
        commands = rng.normal(size=(3, 2))
        quiet.step(commands)
        assert np.linalg.norm(quiet.velocities[1] - previous) <= 0.8 * 0.1 + 1e-12
        previous = quiet.velocities[1]
        # The robot without limits executes its (clamped) command at once.
        assert np.allclose(quiet.velocities[2], kinematics.clamp_speed(commands[2:], [1.0])[0])


def test_unicycle_odometry_errs_along_the_heading_only(world):
    for _ in range(20):
        world.step(np.array([[0.8, 0.3], [0.5, 0.0], [0.5, 0.0]]))
        heading = np.array([math.cos(world.yaws[0]), math.sin(world.yaws[0])])
        assert abs(cross(heading, world.measured_velocities[0])) <= 1e-12
        assert world.measured_velocities[0] @ heading != world.velocities[0] @ heading
        assert world.measured_turn_rates[0] != world.turn_rates[0]


def test_a_holonomic_team_draws_and_moves_as_before(tmp_path):
    """The kinematics of a team without limits are the single integrator's, draw for draw."""
    path = tmp_path / 'holonomic.yaml'
    path.write_text(SCENARIO.split('robots:')[0] + """robots:
  - {name: a, start: [0.0, 0.0], goal: [5.0, 0.0], radius: 0.3, max_speed: 1.0}
  - {name: b, start: [0.0, 3.0], goal: [5.0, 3.0], radius: 0.3, max_speed: 0.5}
  - {name: c, start: [0.0, -3.0], goal: [5.0, -3.0], radius: 0.3, max_speed: 1.0}
""")
    scenario = load_scenario(path)
    world = TeamWorld(scenario)
    rng = np.random.default_rng(scenario.seed)
    std = np.array([robot.noise.actuation_std for robot in scenario.robots])
    kinematics.noisy_odometry(world.positions, np.zeros((3, 2)), std, std, rng)
    positions = world.positions.copy()
    commands = np.random.default_rng(4).normal(size=(30, 3, 2))
    for command in commands:
        world.step(command)
        positions, _ = kinematics.step(positions, command, world.max_speeds, std, 0.1, rng)
        kinematics.noisy_odometry(positions, positions, std, std, rng)
        assert np.array_equal(world.positions, positions)

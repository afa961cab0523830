"""Kinematics against hand computations and the actuation noise statistics."""

import numpy as np
import pytest

from prvo_sim import kinematics


def test_clamp_speed_scales_only_too_fast_commands():
    commands = np.array([[3.0, 4.0], [0.3, 0.4], [0.0, 0.0], [-2.0, 0.0]])
    clamped = kinematics.clamp_speed(commands, np.array([1.0, 1.0, 1.0, 0.5]))
    # |(3, 4)| = 5 > 1 -> (0.6, 0.8); (0.3, 0.4) has speed 0.5 <= 1; zero stays zero.
    np.testing.assert_allclose(clamped, [[0.6, 0.8], [0.3, 0.4], [0.0, 0.0], [-0.5, 0.0]])


def test_step_without_noise_is_the_single_integrator():
    positions = np.array([[0.0, 0.0], [1.0, 1.0]])
    commands = np.array([[2.0, 0.0], [0.0, -0.5]])
    positions_next, executed = kinematics.step(
        positions, commands, np.array([1.0, 1.0]), np.zeros(2), 0.1, np.random.default_rng(0))
    np.testing.assert_allclose(executed, [[1.0, 0.0], [0.0, -0.5]])
    np.testing.assert_allclose(positions_next, [[0.1, 0.0], [1.0, 0.95]])


def test_step_adds_actuation_noise_after_clamping():
    rng_seed = 5
    positions = np.zeros((2, 2))
    commands = np.array([[3.0, 0.0], [0.0, 0.2]])
    actuation_std = np.array([0.1, 0.3])
    _, executed = kinematics.step(positions, commands, np.array([1.0, 1.0]), actuation_std,
                                  0.1, np.random.default_rng(rng_seed))
    draws = np.random.default_rng(rng_seed).standard_normal((2, 2))
    np.testing.assert_allclose(
        executed, [[1.0, 0.0], [0.0, 0.2]] + draws * actuation_std[:, None])


def test_actuation_noise_has_the_configured_std():
    rng = np.random.default_rng(11)
    count = 20000
    commands = np.tile([0.5, -0.5], (count, 1))
    actuation_std = np.where(np.arange(count) % 2 == 0, 0.05, 0.2)
    _, executed = kinematics.step(np.zeros((count, 2)), commands, np.ones(count),
                                  actuation_std, 0.1, rng)
    errors = executed - commands
    for std in (0.05, 0.2):
        selected = errors[actuation_std == std]
        # Each axis holds 10000 draws: the sample std is within 3% (over 4 standard errors).
        np.testing.assert_allclose(selected.std(axis=0), [std, std], rtol=0.03)
        np.testing.assert_allclose(selected.mean(axis=0), [0.0, 0.0], atol=4 * std / 100)
    assert abs(np.corrcoef(errors[:, 0], errors[:, 1])[0, 1]) < 0.03


def test_contact_pairs_use_the_sum_of_radii():
    positions = np.array([[0.0, 0.0], [0.59, 0.0], [5.0, 0.0], [5.0, 0.7], [0.0, 0.6]])
    radii = np.array([0.3, 0.3, 0.3, 0.4, 0.3])
    # 0-1: 0.59 < 0.6; 2-3: 0.7 == 0.7 is touching, not overlapping; 0-4: 0.6 == 0.6 neither;
    # 1-4: hypot(0.59, 0.6) = 0.84 > 0.6.
    assert kinematics.contact_pairs(positions, radii) == {(0, 1)}
    radii[3] = 0.41
    assert kinematics.contact_pairs(positions, radii) == {(0, 1), (2, 3)}


def test_noisy_odometry_draws_positions_then_velocities():
    positions = np.array([[1.0, 2.0], [3.0, 4.0]])
    velocities = np.array([[0.5, 0.0], [0.0, -0.5]])
    position_std, velocity_std = np.array([0.1, 0.0]), np.array([0.2, 0.3])
    noisy_positions, noisy_velocities = kinematics.noisy_odometry(
        positions, velocities, position_std, velocity_std, np.random.default_rng(8))
    reference = np.random.default_rng(8)
    position_draws = reference.standard_normal((2, 2))
    velocity_draws = reference.standard_normal((2, 2))
    np.testing.assert_allclose(noisy_positions, positions + position_draws * [[0.1], [0.0]])
    np.testing.assert_allclose(noisy_velocities, velocities + velocity_draws * [[0.2], [0.3]])


@pytest.mark.parametrize('function', ['step', 'noisy_odometry'])
def test_noise_draws_do_not_depend_on_the_std_values(function):
    """Zero noise still consumes the generator: runs stay aligned whatever the config."""
    rng = np.random.default_rng(3)
    if function == 'step':
        kinematics.step(np.zeros((3, 2)), np.zeros((3, 2)), np.ones(3), np.zeros(3), 0.1, rng)
        expected_draws = 6
    else:
        kinematics.noisy_odometry(np.zeros((3, 2)), np.zeros((3, 2)), np.zeros(3), np.zeros(3),
                                  rng)
        expected_draws = 12
    reference = np.random.default_rng(3)
    reference.standard_normal(expected_draws)
    assert rng.standard_normal() == reference.standard_normal()

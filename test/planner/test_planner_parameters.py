"""Planner parameter validation and the preferred velocity, without ROS processes."""

import dataclasses
import math

import numpy as np
import pytest

from prvo_planner.agent import goal_horizon, preferred_velocity
from prvo_planner.core import AgentBelief, plan_velocity
from prvo_planner.planner_node import (
    _PARAMETERS,
    ParameterError,
    planner_config_from,
)

DEFAULTS = {name: default for name, (default, _) in _PARAMETERS.items()}


def test_defaults_give_a_valid_configuration():
    config = planner_config_from(DEFAULTS)
    # eta 0.8 is k = 2 by Cantelli: eta = k^2 / (1 + k^2).
    assert config.effective_k == pytest.approx(2.0)
    assert config.model == 'prvo' and config.method == 'exact'


@pytest.mark.parametrize('name, value, named', [
    ('eta', 1.5, 'eta'), ('eta', 0.0, 'eta'), ('k', -0.5, 'k'), ('time_horizon', 0.0,
                                                                'time_horizon'),
    ('model', 'magic', 'model'), ('method', 'newton', 'method'), ('risk', 'yolo', 'risk'),
    ('inertia', 1.0, 'inertia'), ('passing_bias', -1.0, 'passing_bias'),
])
def test_invalid_values_are_rejected_by_name(name, value, named):
    values = dict(DEFAULTS, **{name: value})
    with pytest.raises(ParameterError, match=named):
        planner_config_from(values)


def test_k_wins_over_eta_and_actuation_noise_becomes_a_covariance():
    config = planner_config_from(dict(DEFAULTS, k=3.0, actuation_std=0.1, time_horizon=math.inf))
    assert config.effective_k == 3.0
    np.testing.assert_allclose(config.actuation_cov, 0.01 * np.eye(2))
    assert config.time_horizon == math.inf


def test_preferred_velocity_heads_for_the_goal_and_slows_down():
    far, arrived = preferred_velocity(np.array([0.0, 0.0]), np.array([3.0, 4.0]), 1.0, 0.5, 0.1)
    np.testing.assert_allclose(far, [0.6, 0.8])
    assert not arrived
    near, _ = preferred_velocity(np.array([0.0, 0.0]), np.array([0.3, 0.0]), 1.0, 0.5, 0.1)
    np.testing.assert_allclose(near, [0.6, 0.0])  # 0.3 m in 0.5 s
    stopped, arrived = preferred_velocity(np.array([0.0, 0.0]), np.array([0.05, 0.0]), 1.0, 0.5,
                                          0.1)
    np.testing.assert_array_equal(stopped, [0.0, 0.0])
    assert arrived
    idle, arrived = preferred_velocity(np.array([0.0, 0.0]), None, 1.0, 0.5, 0.1)
    np.testing.assert_array_equal(idle, [0.0, 0.0])
    assert not arrived


def test_goal_horizon_caps_the_horizon_at_the_way_to_the_goal():
    assert goal_horizon(10.0, 1.0, 0.5, 5.0) == 5.0
    assert goal_horizon(1.2, 1.0, 0.5, 5.0) == pytest.approx(1.7)
    assert goal_horizon(1.2, 1.0, 0.5, math.inf) == pytest.approx(1.7)


def test_robots_standing_beyond_the_goal_do_not_block_it():
    """A robot 1.2 m short of its goal, with a row of stationary robots 8 m further on.

    Beyond the goal they cannot be reached: going straight is safe. With the full 5 s horizon
    the reciprocal cone of the robot ahead forbids it; with the goal horizon it is chosen.
    """
    covariance = np.diag([0.0016, 0.0016, 0.0016, 0.0016])
    ego = AgentBelief([-5.2, 0.0], [0.0, 0.0], covariance, 0.3)
    standing = [AgentBelief([4.0, y], [0.0, 0.0], covariance, 0.3) for y in (-1.0, 0.0, 1.0)]
    config = planner_config_from(dict(DEFAULTS, eta=0.9, actuation_std=0.05))
    goal = np.array([-4.0, 0.0])
    v_pref, _ = preferred_velocity(ego.position, goal, 1.0, 0.5, 0.1)
    horizon = goal_horizon(1.2, 1.0, 0.5, config.time_horizon)
    capped = plan_velocity(ego, standing, v_pref, dataclasses.replace(config,
                                                                      time_horizon=horizon))
    assert capped.feasible
    np.testing.assert_allclose(capped.velocity, v_pref, atol=1e-9)
    uncapped = plan_velocity(ego, standing, v_pref, config)
    assert np.linalg.norm(uncapped.velocity - v_pref) > 0.1

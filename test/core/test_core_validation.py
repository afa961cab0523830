"""Bad input raises ``ValueError`` naming the field and the value; good input is normalised."""

import dataclasses
import math

import numpy as np
import pytest

from prvo_planner.core import AgentBelief, PlannerConfig, eta_from_k, k_from_eta, plan_velocity

GOOD = {'position': [0.0, 0.0], 'velocity': [0.5, 0.0], 'covariance': 0.01 * np.eye(4),
        'radius': 0.3}


def belief(**changes):
    return AgentBelief(**{**GOOD, **changes})


@pytest.mark.parametrize('field, value, fragment', [
    ('position', [np.nan, 0.0], 'position'),
    ('position', [0.0, 0.0, 0.0], 'position'),
    ('velocity', [np.inf, 0.0], 'velocity'),
    ('velocity', 'fast', 'velocity'),
    ('covariance', np.eye(3), 'covariance'),
    ('covariance', np.eye(4) + np.triu(np.ones((4, 4)), 1), 'symmetric'),
    ('covariance', np.diag([1.0, 1.0, 1.0, -0.1]), 'positive semi-definite'),
    ('covariance', np.full((4, 4), np.nan), 'covariance'),
    ('radius', 0.0, 'radius'),
    ('radius', -1.0, 'radius'),
    ('radius', math.nan, 'radius'),
])
def test_belief_rejects_bad_fields(field, value, fragment):
    with pytest.raises(ValueError, match=fragment) as error:
        belief(**{field: value})
    assert f'AgentBelief.{field}' in str(error.value)


def test_belief_message_names_the_value():
    with pytest.raises(ValueError, match='-2.5'):
        belief(radius=-2.5)


def test_belief_clips_rounding_level_negative_eigenvalues_and_is_read_only():
    covariance = np.diag([1.0, 1.0, 1.0, -1e-13])
    accepted = belief(covariance=covariance, position=(1, 2))
    assert np.linalg.eigvalsh(accepted.covariance)[0] >= 0.0
    assert accepted.position.dtype == float and not accepted.position.flags.writeable
    with pytest.raises(ValueError):
        accepted.position[0] = 3.0
    with pytest.raises(dataclasses.FrozenInstanceError):
        accepted.radius = 1.0


@pytest.mark.parametrize('field, value', [
    ('eta', 0.0), ('eta', 1.0), ('eta', math.nan), ('k', -0.5), ('k', math.inf),
    ('max_speed', 0.0), ('max_speed', -1.0), ('max_speed', math.inf),
    ('num_directions', 0), ('num_directions', 2.5), ('time_horizon', 0.0),
    ('time_horizon', math.nan), ('neighbor_distance', -1.0), ('safety_margin', -0.1),
    ('actuation_cov', np.eye(3)), ('actuation_cov', [[1.0, 0.0], [0.0, -1.0]]),
    ('method', 'newton'), ('model', 'orca'), ('risk', 'total'), ('mc_samples', 0),
    ('receding_gate', 'yes'), ('seed', -3),
])
def test_config_rejects_bad_fields(field, value):
    with pytest.raises(ValueError, match=f'PlannerConfig.{field}') as error:
        PlannerConfig(**{field: value})
    assert str(value)[:3] in str(error.value) or 'shape' in str(error.value)


def test_config_defaults_and_effective_k():
    config = PlannerConfig()
    assert config.eta == 0.8 and config.max_speed == 1.0 and config.num_directions == 64
    assert config.effective_k == pytest.approx(2.0)
    assert PlannerConfig(eta=0.5, k=3.0).effective_k == 3.0
    assert PlannerConfig(time_horizon=math.inf).time_horizon == math.inf
    assert not PlannerConfig(actuation_cov=[[1, 0], [0, 1]]).actuation_cov.flags.writeable


def test_cantelli_mapping_matches_the_closed_form():
    for k, eta in [(1.0, 0.5), (1.5, 2.25 / 3.25), (2.0, 0.8), (3.0, 0.9)]:
        assert eta_from_k(k) == pytest.approx(eta)
        assert k_from_eta(eta) == pytest.approx(k)
    assert eta_from_k(math.inf) == 1.0
    # Margins whose square overflows (a plan at a neighbour with no noise left) still give 1.
    assert eta_from_k(3e160) == 1.0
    assert eta_from_k(np.array([3e160, 1e300])).tolist() == [1.0, 1.0]
    with pytest.raises(ValueError, match='k'):
        eta_from_k(-1.0)
    with pytest.raises(ValueError, match='eta'):
        k_from_eta(1.0)


@pytest.mark.parametrize('arguments, fragment', [
    ((belief(), [], [np.nan, 0.0], PlannerConfig()), 'v_pref'),
    ((belief(), [], [1.0], PlannerConfig()), 'v_pref'),
    (('ego', [], [1.0, 0.0], PlannerConfig()), 'ego'),
    ((belief(), ['robot'], [1.0, 0.0], PlannerConfig()), r'neighbours\[0\]'),
    ((belief(), [], [1.0, 0.0], {'eta': 0.8}), 'config'),
])
def test_plan_velocity_rejects_bad_arguments(arguments, fragment):
    with pytest.raises(ValueError, match=fragment):
        plan_velocity(*arguments)


def test_overlapping_neighbour_moves_apart_without_error():
    ego = belief(velocity=[0.0, 0.0])
    for gate in (True, False):
        neighbour = belief(position=[0.3, 0.1], velocity=[0.0, 0.0])
        result = plan_velocity(ego, [neighbour], [1.0, 0.0],
                               PlannerConfig(receding_gate=gate, time_horizon=math.inf))
        assert not result.feasible
        # Moving apart: the relative position and the relative velocity form an obtuse angle
        # with the direction to the neighbour, i.e. r . (2 v) > 0 with r = ego - neighbour.
        assert np.dot(ego.position - neighbour.position, result.velocity) > 0.0
        assert np.all(np.isfinite(result.velocity))

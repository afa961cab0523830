"""Planner parameter validation and the preferred velocity, without ROS processes."""

import array
import dataclasses
import math

import numpy as np
import pytest
from rclpy.parameter import Parameter

from prvo_planner.agent import goal_horizon, preferred_velocity
from prvo_planner.core import AgentBelief, plan_velocity
from prvo_planner.parameters import (
    DEFAULTS,
    MIN_ANGULAR_ACCELERATION,
    MIN_ANGULAR_SPEED,
    PARAMETERS,
    ParameterError,
    check_parameter,
    check_parameter_update,
    goal_array,
    is_dumped_unset,
    nearest_name,
    neighbour_names,
    planner_config_from,
)
from prvo_planner.planner_node import _PARAMETERS


def test_defaults_give_a_valid_configuration():
    config = planner_config_from(DEFAULTS)
    # eta 0.95, met by the certified Gaussian bound; Cantelli's k (eta = k^2 / (1 + k^2)) is
    # sqrt(19), where a velocity's certificate falls short.
    assert config.eta == 0.95 and config.certificate == 'certified'
    assert config.effective_k == pytest.approx(math.sqrt(19.0))
    assert config.model == 'prvo' and config.method == 'exact'


@pytest.mark.parametrize('name, value, named', [
    ('eta', 1.5, 'eta'), ('eta', 0.0, 'eta'), ('k', -0.5, 'k'), ('time_horizon', 0.0,
                                                                'time_horizon'),
    ('model', 'magic', 'model'), ('method', 'newton', 'method'), ('risk', 'yolo', 'risk'),
    ('certificate', 'gaussian', 'certificate'),
    ('inertia', 1.0, 'inertia'), ('passing_bias', -1.0, 'passing_bias'),
    ('progress_weight', 1.0, 'progress_weight'),
])
def test_invalid_values_are_rejected_by_name(name, value, named):
    values = dict(DEFAULTS, **{name: value})
    with pytest.raises(ParameterError, match=named):
        planner_config_from(values)


@pytest.mark.parametrize('values, changed, named, reason', [
    # At start-up the parameter set away from its default is named (defaults: 0.3, 0.9).
    ({'min_lookahead_dist': 0.95}, None, 'min_lookahead_dist',
     'must be <= max_lookahead_dist (0.9), got 0.95'),
    ({'max_lookahead_dist': 0.2}, None, 'max_lookahead_dist',
     'must be >= min_lookahead_dist (0.3), got 0.2'),
    # A change names the parameter changed, whatever was set before.
    ({'min_lookahead_dist': 2.5, 'max_lookahead_dist': 2.0}, {'min_lookahead_dist'},
     'min_lookahead_dist', 'must be <= max_lookahead_dist (2.0), got 2.5'),
    ({'min_lookahead_dist': 2.5, 'max_lookahead_dist': 2.0}, {'max_lookahead_dist'},
     'max_lookahead_dist', 'must be >= min_lookahead_dist (2.5), got 2.0'),
])
def test_crossed_lookahead_bounds_name_the_one_set(values, changed, named, reason):
    with pytest.raises(ParameterError) as raised:
        planner_config_from(dict(DEFAULTS, **values), changed)
    assert (raised.value.name, raised.value.reason) == (named, reason)


def test_the_certificate_parameter_reaches_the_configuration():
    assert planner_config_from(DEFAULTS).certificate == 'certified'
    assert planner_config_from(dict(DEFAULTS, certificate='cantelli')).certificate == 'cantelli'


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
    config = planner_config_from(dict(DEFAULTS, eta=0.9, actuation_std=0.05, time_horizon=5.0))
    goal = np.array([-4.0, 0.0])
    v_pref, _ = preferred_velocity(ego.position, goal, 1.0, 0.5, 0.1)
    horizon = goal_horizon(1.2, 1.0, 0.5, config.time_horizon)
    capped = plan_velocity(ego, standing, v_pref, dataclasses.replace(config,
                                                                      time_horizon=horizon))
    assert capped.feasible
    np.testing.assert_allclose(capped.velocity, v_pref, atol=1e-9)
    uncapped = plan_velocity(ego, standing, v_pref, config)
    assert np.linalg.norm(uncapped.velocity - v_pref) > 0.1


def test_goal_accepts_any_sequence_of_numbers():
    """Rclpy hands a double array set at runtime over as array.array('d')."""
    np.testing.assert_array_equal(goal_array(array.array('d', [2.0, -1.0])),
                                  [2.0, -1.0])
    np.testing.assert_array_equal(goal_array([4, 0]), [4.0, 0.0])
    assert goal_array(None) is None


@pytest.mark.parametrize('value, reason', [
    ([1.0, 2.0, 3.0], 'must be [x, y], got [1.0, 2.0, 3.0]'),
    ([1.0, math.nan], 'goal[1]: expected a number, got nan'),
    ([math.inf, 0.0], 'expected finite numbers'),
    ([2.0e6, 0.0], 'coordinates must be in [-1e+06, 1e+06]'),
    (4.0, 'expected a list, got a number'),
    (['a', 'b'], 'goal[0]: expected a number, got a string'),
])
def test_bad_goals_are_refused_naming_goal_and_value(value, reason):
    with pytest.raises(ParameterError) as raised:
        goal_array(value)
    assert str(raised.value).startswith('goal') and reason in str(raised.value)


def test_neighbour_names_must_be_robot_names():
    assert neighbour_names(['robot_1', '', 'robot_2']) == ['robot_1', 'robot_2']
    assert neighbour_names(None) is None
    with pytest.raises(ParameterError, match="neighbors: robot name '2bad' is not a valid"):
        neighbour_names(['robot_1', '2bad'])
    # A name no robot can have: its nodes' remap rule __ns:=/robot__2 does not parse.
    with pytest.raises(ParameterError, match="neighbors: robot name 'robot__2' holds '__'"):
        neighbour_names(['robot_1', 'robot__2'])
    with pytest.raises(ParameterError, match='neighbors: expected a list of strings'):
        neighbour_names([1, 2])


@pytest.mark.parametrize('value', [0.0, 0.4])
def test_the_retired_neighbour_radius_says_what_replaced_it(value):
    """Neighbours announce their footprints; a launch file still setting it is told so."""
    with pytest.raises(ParameterError, match=(
            rf'^neighbor_radius: retired \(got {value}\): neighbours announce their own '
            'footprints; set unknown_neighbor_radius for those that announce none$')):
        planner_config_from(dict(DEFAULTS, neighbor_radius=value))
    assert check_parameter('neighbor_radius', -1.0) == -1.0


@pytest.mark.parametrize('value', [0.0, -0.5, 101.0, float('nan'), float('inf')])
def test_the_unknown_neighbour_radius_must_be_a_size(value):
    with pytest.raises(ParameterError, match='^unknown_neighbor_radius: '):
        check_parameter('unknown_neighbor_radius', value)
    assert check_parameter('unknown_neighbor_radius', 0.8) == 0.8


@pytest.mark.parametrize('name, value, reason', [
    ('eta', 2.0, 'must be in (0, 1), got 2.0'),
    ('eta', math.nan, 'expected a number, got nan'),
    ('eta', 'high', 'expected a number, got a string'),
    ('eta', True, 'expected a number, got a boolean'),
    ('num_directions', 0, 'must be in [1, 4096], got 0'),
    ('num_directions', 8.0, 'expected an integer, got a number'),
    ('radius', 10 ** 400, 'too large a number'),
    ('radius', 0.0, 'must be in (0, 100], got 0.0'),
    ('neighbor_distance', math.inf, 'expected a finite number, got inf'),
    ('time_horizon', -math.inf, 'must be > 0'),
    ('model', 'magic', 'must be one of prvo, rvo, inflate, mc'),
    ('stamped_cmd_vel', 1, 'expected true or false'),
    ('frame_id', '', 'must not be empty'),
    ('eta', None, 'must be set'),
])
def test_check_parameter_names_the_parameter_and_value(name, value, reason):
    with pytest.raises(ParameterError) as raised:
        check_parameter(name, value)
    assert raised.value.name == name
    assert str(raised.value) == f'{name}: {raised.value.reason}'
    assert reason in raised.value.reason


@pytest.mark.parametrize('name, value, why', [
    ('max_angular_speed', 1e-9, 'slower, a half turn takes over 30 s'),
    ('max_angular_speed', 0.099, 'slower, a half turn takes over 30 s'),
    ('max_angular_acceleration', 1e-6, 'slower, reaching 1 rad/s takes over 10 s'),
    ('max_angular_acceleration', 0.0, 'slower, reaching 1 rad/s takes over 10 s'),
])
def test_turn_limits_too_slow_to_track_are_refused_at_start_and_live(name, value, why):
    reason = f'{name}: must be >= 0.1 ({why}), got {value!r}'
    for check in (check_parameter, check_parameter_update):
        with pytest.raises(ParameterError) as raised:
            check(name, value)
        assert str(raised.value) == reason
    with pytest.raises(ParameterError) as raised:
        planner_config_from({name: value})
    assert str(raised.value) == reason


def test_the_slowest_turn_limits_and_none_are_accepted():
    assert MIN_ANGULAR_SPEED == MIN_ANGULAR_ACCELERATION == 0.1
    assert check_parameter('max_angular_speed', MIN_ANGULAR_SPEED) == 0.1
    assert check_parameter('max_angular_acceleration', MIN_ANGULAR_ACCELERATION) == 0.1
    assert check_parameter('max_angular_acceleration', math.inf) == math.inf
    _, turn_rate = _PARAMETERS['max_angular_speed']
    assert (turn_rate.floating_point_range[0].from_value,
            turn_rate.floating_point_range[0].to_value) == (0.1, 1000.0)


def test_check_parameter_types_values():
    assert type(check_parameter('max_speed', 2)) is float
    assert check_parameter('time_horizon', math.inf) == math.inf
    assert check_parameter('neighbors', ('a',)) == ['a']
    assert check_parameter('goal', None) is None


def test_unknown_names_get_the_nearest_valid_one():
    with pytest.raises(ParameterError, match=r"etaa: unknown planner parameter \(did you mean "
                       r"'eta'\?\)"):
        check_parameter('etaa', 0.9)
    assert nearest_name('horizon') == 'time_horizon'
    assert nearest_name('num_direction') == 'num_directions'
    assert nearest_name('zzzzzz') is None


def test_every_default_passes_its_own_rules():
    for name, spec in PARAMETERS.items():
        assert check_parameter(name, spec.default) == spec.default


def test_descriptors_state_the_specs_types_and_ranges():
    """The node declares exactly the specified parameters, with their ROS types and ranges."""
    assert list(_PARAMETERS) == list(PARAMETERS)
    default, eta = _PARAMETERS['eta']
    assert default == 0.95 and eta.type == Parameter.Type.DOUBLE.value
    assert (eta.floating_point_range[0].from_value, eta.floating_point_range[0].to_value) == (
        0.0, 1.0)
    _, directions = _PARAMETERS['num_directions']
    assert directions.type == Parameter.Type.INTEGER.value
    assert (directions.integer_range[0].from_value, directions.integer_range[0].to_value) == (
        1, 4096)
    default, goal = _PARAMETERS['goal']
    assert default is None and goal.dynamic_typing
    _, neighbours = _PARAMETERS['neighbors']
    assert neighbours.read_only and neighbours.dynamic_typing
    _, horizon = _PARAMETERS['time_horizon']
    assert not horizon.floating_point_range


def test_a_dumped_null_reads_as_unset_only_for_parameters_that_may_be_unset():
    assert is_dumped_unset('neighbors', 'null') and is_dumped_unset('goal', '~')
    assert not is_dumped_unset('model', 'null')
    assert not is_dumped_unset('goal', None) and not is_dumped_unset('neighbors', ['null'])


def test_a_running_planner_refuses_unsetting_a_parameter():
    with pytest.raises(ParameterError, match='^goal: cannot be unset'):
        check_parameter_update('goal', None)
    assert check_parameter_update('goal', array.array('d', [2.0, -1.0])) == [2.0, -1.0]

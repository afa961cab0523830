"""Scenario loading: the shipped files load, every kind of bad file is named precisely."""

import pathlib
import re

import numpy as np
import pytest

from prvo_sim.scenario import ScenarioError, find_scenario, load_scenario

SHIPPED = ('circle8', 'crossing4', 'headon2', 'paper3')

VALID = """\
name: pair
seed: 3
dt: 0.1
duration: 5.0
goal_tolerance: 0.2
noise:
  position_std: 0.05
  actuation_std: 0.02
planner:
  eta: 0.8
  horizon: 2.0
robots:
  - name: robot_0
    start: [-2.0, 0.0]
    goal: [2.0, 0.0]
    radius: 0.3
    max_speed: 1.0
    noise: {actuation_std: 0.1}
    planner: {eta: 0.95}
  - name: robot_1
    start: [2.0, 0.0]
    goal: [-2.0, 0.0]
    radius: 0.25
    max_speed: 0.5
"""


def write(tmp_path, text):
    path = tmp_path / 'scenario.yaml'
    path.write_text(text)
    return path


@pytest.mark.parametrize('name', SHIPPED)
def test_shipped_scenarios_load(name):
    path = find_scenario(name)
    assert path.name == f'{name}.yaml'
    scenario = load_scenario(path)
    assert scenario.name == name
    assert scenario.robots and scenario.dt > 0


def test_find_scenario_keeps_paths(tmp_path):
    path = write(tmp_path, VALID)
    assert find_scenario(str(path)) == path
    with pytest.raises(ScenarioError, match='no_such_scenario: .*no such scenario'):
        find_scenario('no_such_scenario')


def test_valid_file_merges_blocks_under_robot_overrides(tmp_path):
    scenario = load_scenario(write(tmp_path, VALID))
    assert (scenario.name, scenario.seed, scenario.dt, scenario.duration) == ('pair', 3, 0.1, 5.0)
    assert scenario.description == ''
    first, second = scenario.robots
    np.testing.assert_array_equal(first.start, [-2.0, 0.0])
    np.testing.assert_array_equal(second.goal, [-2.0, 0.0])
    assert (first.noise.position_std, first.noise.velocity_std, first.noise.actuation_std) == (
        0.05, 0.0, 0.1)
    assert (second.noise.position_std, second.noise.velocity_std,
            second.noise.actuation_std) == (0.05, 0.0, 0.02)
    assert first.planner == {'eta': 0.95, 'horizon': 2.0}
    assert second.planner == {'eta': 0.8, 'horizon': 2.0}
    assert (second.radius, second.max_speed) == (0.25, 0.5)
    assert load_scenario(write(tmp_path, VALID), seed=99).seed == 99


@pytest.mark.parametrize(('old', 'new', 'key', 'reason'), [
    ('seed: 3\n', '', 'seed', 'missing required key'),
    ('    max_speed: 0.5\n', '', 'robots[1].max_speed', 'missing required key'),
    ('dt: 0.1\n', 'dt: 0.1\nspeed: 2\n', 'speed', 'unknown key'),
    ('    radius: 0.25\n', '    radius: 0.25\n    colour: red\n', 'robots[1].colour',
     'unknown key'),
    ('  position_std: 0.05\n', '  position_sd: 0.05\n', 'noise.position_sd', 'unknown key'),
    ('    radius: 0.25\n', '    radius: true\n', 'robots[1].radius',
     'expected a number, got a boolean'),
    ('    radius: 0.25\n', '    radius: "0.25"\n', 'robots[1].radius',
     'expected a number, got a string'),
    ('seed: 3\n', 'seed: 3.5\n', 'seed', 'expected an integer'),
    ('    radius: 0.25\n', '    radius: 0.0\n', 'robots[1].radius', 'must be > 0'),
    ('    max_speed: 0.5\n', '    max_speed: -1\n', 'robots[1].max_speed', 'must be > 0'),
    ('dt: 0.1\n', 'dt: 0\n', 'dt', 'must be > 0'),
    ('duration: 5.0\n', 'duration: -5.0\n', 'duration', 'must be > 0'),
    ('  actuation_std: 0.02\n', '  actuation_std: -0.02\n', 'noise.actuation_std',
     'must be >= 0'),
    ('{actuation_std: 0.1}', '{velocity_std: -0.1}', 'robots[0].noise.velocity_std',
     'must be >= 0'),
    ('dt: 0.1\n', 'dt: .nan\n', 'dt', 'finite'),
    ('name: pair\n', 'name: my pair\n', 'name', 'may only contain'),
    ('  - name: robot_1\n', '  - name: 1robot\n', 'robots[1].name', 'not a valid ROS name'),
    ('  - name: robot_1\n', '  - name: robot_0\n', 'robots[1].name',
     "duplicate robot name 'robot_0' (also robots[0])"),
    ('    start: [2.0, 0.0]\n', '    start: [-1.5, 0.0]\n', 'robots[1].start',
     'overlaps robots[0]'),
    ('    start: [2.0, 0.0]\n', '    start: [2.0]\n', 'robots[1].start', 'expected [x, y]'),
    ('    goal: [2.0, 0.0]\n', '    goal: [2.0, null]\n', 'robots[0].goal[1]',
     'expected a number, got nothing'),
    ('  eta: 0.8\n', '  eta: {a: 1}\n', 'planner.eta', 'expected a ROS parameter value'),
    ('seed: 3\n', 'seed: 3\nseed: 4\n', 'line 3, column 1', 'duplicate key'),
    ('dt: 0.1\n', 'dt: [0.1\n', 'line', 'YAML syntax error'),
])
def test_bad_file_names_file_key_and_reason(tmp_path, old, new, key, reason):
    assert old in VALID
    path = write(tmp_path, VALID.replace(old, new, 1))
    with pytest.raises(ScenarioError) as raised:
        load_scenario(path)
    message = str(raised.value)
    assert message.startswith(f'{path}: {key}'), message
    assert reason in message
    assert raised.value.file == str(path)


@pytest.mark.parametrize(('text', 'key', 'reason'), [
    ('- a\n- b\n', '(top level)', 'expected a mapping, got a list'),
    ('', '(top level)', 'expected a mapping, got nothing'),
    (VALID.split('robots:')[0] + 'robots: []\n', 'robots', 'expected a non-empty list'),
    (VALID.split('robots:')[0] + 'robots:\n  - 3\n', 'robots[0]', 'expected a mapping'),
])
def test_bad_structure_is_named(tmp_path, text, key, reason):
    path = write(tmp_path, text)
    with pytest.raises(ScenarioError, match=re.escape(f'{path}: {key}: {reason}')):
        load_scenario(path)


def test_unreadable_file_is_named(tmp_path):
    path = tmp_path / 'missing.yaml'
    with pytest.raises(ScenarioError, match=re.escape(f'{path}: (file): cannot read')):
        load_scenario(path)


def test_bad_seed_override(tmp_path):
    with pytest.raises(ScenarioError, match='seed: must be >= 0'):
        load_scenario(write(tmp_path, VALID), seed=-3)


def test_shipped_directory_is_found_from_the_source_tree_too():
    source_copy = pathlib.Path(__file__).resolve().parents[2] / 'src/prvo_sim/scenarios'
    for name in SHIPPED:
        assert (source_copy / f'{name}.yaml').read_text() == find_scenario(name).read_text()

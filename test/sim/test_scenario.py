"""Scenario loading: the shipped files load, every kind of bad file is named precisely."""

import dataclasses
import math
import pathlib
import re
import subprocess
import sys

import numpy as np
import pytest
import rclpy
from rclpy.context import Context
from rclpy.exceptions import NameValidationException
from std_msgs.msg import String
import yaml

from prvo_msgs_util import (
    AVOIDANCE_SHARE,
    CMD_VEL,
    FOOTPRINT,
    GOAL_POSE,
    GROUND_TRUTH,
    MARKERS,
    ODOM,
)
from prvo_sim.bench.crowds import circle_radius_of, crowd_circle_document
from prvo_sim.bench.team import write_scenario
from prvo_sim.scenario import (
    INPROCESS_MEMORY_MIB,
    INPROCESS_ROBOT_MEMORY_MIB,
    MAP_BYTES_PER_CELL,
    PLANNER_MEMORY_MIB,
    RUNNER_MEMORY_MIB,
    SIMULATOR_MEMORY_MIB,
    ScenarioError,
    available_memory_mib,
    check_team_memory,
    estimate_team_memory,
    find_scenario,
    load_scenario,
    ros_name_problem,
)

SHIPPED = ('circle8', 'crossing4', 'headon2', 'paper3', 'walkers', 'diffdrive_circle6',
           'mixed_drive', 'accel8', 'corridor8', 'doorway8', 'pillars12', 'office', 'u_trap',
           'mixed12', 'parked_large', 'nav2_crossing4', 'nav2_headon2', 'nav2_path_crossing4')

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
  time_horizon: 2.0
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
    assert first.planner == {'eta': 0.95, 'time_horizon': 2.0}
    assert second.planner == {'eta': 0.8, 'time_horizon': 2.0}
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
    ('    radius: 0.25\n', '    radius: 0.0\n', 'robots[1].radius',
     'must be in (0, 100], got 0.0'),
    ('    max_speed: 0.5\n', '    max_speed: -1\n', 'robots[1].max_speed',
     'must be in (0, 100], got -1.0'),
    ('dt: 0.1\n', 'dt: 0\n', 'dt', 'must be in [0.0001, 10], got 0'),
    ('duration: 5.0\n', 'duration: -5.0\n', 'duration', 'must be > 0'),
    ('  actuation_std: 0.02\n', '  actuation_std: -0.02\n', 'noise.actuation_std',
     'must be in [0, 1000], got -0.02'),
    ('{actuation_std: 0.1}', '{velocity_std: -0.1}', 'robots[0].noise.velocity_std',
     'must be in [0, 1000], got -0.1'),
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
    ('  eta: 0.8\n', '  eta: {a: 1}\n', 'planner.eta', 'expected a number, got a mapping'),
    ('seed: 3\n', 'seed: 3\nseed: 4\n', 'line 3, column 1', 'duplicate key'),
    ('dt: 0.1\n', 'dt: [0.1\n', 'line', 'YAML syntax error'),
    ('    max_speed: 0.5\n', '    max_speed: 0.5\n    kinematics: tank\n',
     'robots[1].kinematics', "must be one of holonomic, unicycle, got 'tank' (robot 'robot_1')"),
    ('    max_speed: 0.5\n', '    max_speed: 0.5\n    max_angular_speed: 1.0\n',
     'robots[1].max_angular_speed', "only for kinematics: unicycle (robot 'robot_1' is"),
    ('    max_speed: 0.5\n', '    max_speed: 0.5\n    max_angular_acceleration: 1.0\n',
     'robots[1].max_angular_acceleration', "only for kinematics: unicycle (robot 'robot_1'"),
    ('    max_speed: 0.5\n', '    max_speed: 0.5\n    max_acceleration: 0\n',
     'robots[1].max_acceleration', 'must be > 0, got 0.0'),
    ('    max_speed: 0.5\n', '    max_speed: 0.5\n    max_acceleration: 1001\n',
     'robots[1].max_acceleration', 'must be in (0, 1000], got 1001'),
    ('    max_speed: 0.5\n',
     '    max_speed: 0.5\n    kinematics: unicycle\n    max_angular_speed: -2\n',
     'robots[1].max_angular_speed', 'must be >= 0.1 (slower, a half turn takes over 30 s), '
     'got -2.0'),
    # The planner's lower bounds: slower turns cannot track a plan (and used to hang it).
    ('    max_speed: 0.5\n',
     '    max_speed: 0.5\n    kinematics: unicycle\n    max_angular_speed: 1e-9\n',
     'robots[1].max_angular_speed', 'must be >= 0.1 (slower, a half turn takes over 30 s), '
     'got 1e-09'),
    ('    max_speed: 0.5\n',
     '    max_speed: 0.5\n    kinematics: unicycle\n    max_angular_acceleration: 1e-6\n',
     'robots[1].max_angular_acceleration', 'must be >= 0.1 (slower, reaching 1 rad/s takes '
     'over 10 s), got 1e-06'),
    ('    max_speed: 0.5\n',
     '    max_speed: 0.5\n    kinematics: unicycle\n    max_angular_speed: 1001\n',
     'robots[1].max_angular_speed', 'must be in [0.1, 1000.0], got 1001.0'),
    ('    max_speed: 0.5\n',
     '    max_speed: 0.5\n    kinematics: unicycle\n    max_angular_acceleration: .inf\n',
     'robots[1].max_angular_acceleration', 'finite'),
    ('    max_speed: 0.5\n', '    max_speed: 0.5\n    start_yaw: 7.0\n',
     'robots[1].start_yaw', 'must be in [-6.28319, 6.28319], got 7.0'),
    ('  eta: 0.8\n', '  eta: 0.8\n  max_acceleration: 1.0\n', 'planner.max_acceleration',
     "set by the runner from each robot's max_acceleration"),
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
    with pytest.raises(ScenarioError, match=re.escape('seed: must be in [0, 2147483647], got -3')):
        load_scenario(write(tmp_path, VALID), seed=-3)


def test_every_shipped_scenario_is_tested():
    source_copy = pathlib.Path(__file__).resolve().parents[2] / 'src/prvo_sim/scenarios'
    assert sorted(path.stem for path in source_copy.glob('*.yaml')) == sorted(SHIPPED)


def test_shipped_directory_is_found_from_the_source_tree_too():
    source_copy = pathlib.Path(__file__).resolve().parents[2] / 'src/prvo_sim/scenarios'
    for name in SHIPPED:
        assert (source_copy / f'{name}.yaml').read_text() == find_scenario(name).read_text()


# Bad planner blocks and limits: (replace old, with new, key named, reason).
BAD_FILES = [
    ('  eta: 0.8\n', '  eta: 2.0\n', 'planner.eta', 'must be in (0, 1), got 2.0'),
    ('  eta: 0.8\n', '  eta: .nan\n', 'planner.eta', 'got nan'),
    ('  eta: 0.8\n', '  eta: high\n', 'planner.eta', 'expected a number, got a string'),
    ('  eta: 0.8\n', '  eta: 0.8\n  num_directions: 0\n', 'planner.num_directions',
     'must be in [1, 4096], got 0'),
    ('  eta: 0.8\n', '  etaa: 0.9\n', 'planner.etaa',
     "unknown planner parameter (did you mean 'eta'?)"),
    ('{eta: 0.95}', '{etaa: 0.9}', 'robots[0].planner.etaa',
     "unknown planner parameter (did you mean 'eta'?)"),
    ('{eta: 0.95}', '{eta: 1.0}', 'robots[0].planner.eta', 'must be in (0, 1)'),
    ('{eta: 0.95}', '{num_directions: 8.0}', 'robots[0].planner.num_directions',
     'expected an integer, got a number'),
    ('  eta: 0.8\n', '  eta: 0.8\n  radius: 0.5\n', 'planner.radius',
     "set by the runner from each robot's radius"),
    ('{eta: 0.95}', '{goal: [1.0, 1.0]}', 'robots[0].planner.goal',
     "set by the runner from each robot's goal"),
    ('  eta: 0.8\n', '  eta: 0.8\n  actuation_std: 0.1\n', 'planner.actuation_std',
     'noise.actuation_std'),
    ('  eta: 0.8\n', '  model: rvo\n', 'planner.model', '--method'),
    ('  eta: 0.8\n', '  eta: 0.8\n  max_speed: 2.0\n', 'planner.max_speed', 'max_speed'),
    ('  eta: 0.8\n', '  eta: 0.8\n  goal_tolerance: 0.1\n', 'planner.goal_tolerance',
     'top-level goal_tolerance'),
    ('  eta: 0.8\n', '  eta: 0.8\n  use_sim_time: false\n', 'planner.use_sim_time',
     'set by the runner'),
    ('  eta: 0.8\n', '  eta: 0.8\n  neighbors: [robot_1, 2bad]\n', 'planner.neighbors',
     'not a valid ROS name'),
    ('  eta: 0.8\n', '  eta: 0.8\n  neighbors: [robot_1, robot__1]\n', 'planner.neighbors',
     "robot name 'robot__1' holds '__'"),
    ('  eta: 0.8\n', '  eta: 0.8\n  neighbor_radius: 0.0\n', 'planner.neighbor_radius',
     'retired (got 0.0): neighbours announce their own footprints'),
    # Crossed lookahead bounds (defaults 0.3, 0.9): the one the file sets is named, where.
    ('  eta: 0.8\n', '  eta: 0.8\n  min_lookahead_dist: 0.95\n', 'planner.min_lookahead_dist',
     "must be <= max_lookahead_dist (0.9), got 0.95 (robot 'robot_0')"),
    ('{eta: 0.95}', '{max_lookahead_dist: 0.2}', 'robots[0].planner.max_lookahead_dist',
     "must be >= min_lookahead_dist (0.3), got 0.2 (robot 'robot_0')"),
    ('dt: 0.1\n', 'dt: 1e-300\n', 'dt', 'must be in [0.0001, 10], got 1e-300'),
    ('dt: 0.1\n', 'dt: 20.0\n', 'dt', 'must be in [0.0001, 10], got 20.0'),
    ('duration: 5.0\n', 'duration: 1.0e6\n', 'duration', 'more than 1000000 steps'),
    ('    radius: 0.25\n', '    radius: ' + '9' * 400 + '\n', 'robots[1].radius',
     'too large a number'),
    ('    radius: 0.25\n', '    radius: 101.0\n', 'robots[1].radius', 'must be in (0, 100]'),
    ('    max_speed: 0.5\n', '    max_speed: 1e3\n', 'robots[1].max_speed',
     'must be in (0, 100], got 1000.0'),
    ('    start: [2.0, 0.0]\n', '    start: [2.0e7, 0.0]\n', 'robots[1].start[0]',
     'must be in [-1e+06, 1e+06]'),
    ('    goal: [2.0, 0.0]\n', '    goal: [2.0, -1.0e9]\n', 'robots[0].goal[1]',
     'must be in [-1e+06, 1e+06]'),
    ('  position_std: 0.05\n', '  position_std: 5.0e3\n', 'noise.position_std',
     'must be in [0, 1000]'),
    ('{actuation_std: 0.1}', '{actuation_std: 1e4}', 'robots[0].noise.actuation_std',
     'must be in [0, 1000]'),
    ('goal_tolerance: 0.2\n', 'goal_tolerance: 200.0\n', 'goal_tolerance',
     'must be in (0, 100]'),
    ('seed: 3\n', 'seed: 4294967296\n', 'seed', 'must be in [0, 2147483647]'),
]


@pytest.mark.parametrize(('old', 'new', 'key', 'reason'), BAD_FILES)
def test_bad_values_are_refused_naming_the_key(tmp_path, old, new, key, reason):
    assert old in VALID
    path = write(tmp_path, VALID.replace(old, new, 1))
    with pytest.raises(ScenarioError) as raised:
        load_scenario(path)
    message = str(raised.value)
    assert message.startswith(f'{path}: {key}: '), message
    assert reason in message, message
    assert '\n' not in message


def test_too_many_robots_is_refused(tmp_path):
    robots = ''.join(
        f'  - {{name: r{index}, start: [{index}.0, 0.0], goal: [{index}.0, 5.0], radius: 0.3, '
        f'max_speed: 1.0}}\n' for index in range(257))
    path = write(tmp_path, VALID.split('robots:')[0] + 'robots:\n' + robots)
    with pytest.raises(ScenarioError, match=re.escape(
            f'{path}: robots: 257 robots, more than 256')):
        load_scenario(path)


def test_yaml_1_2_numbers_are_numbers(tmp_path):
    text = (VALID.replace('dt: 0.1\n', 'dt: 1e-2\n').replace('duration: 5.0\n', 'duration: 1E1\n')
            .replace('  eta: 0.8\n', '  eta: .5\n  num_directions: +32\n  inertia: 1.5e-1\n'))
    scenario = load_scenario(write(tmp_path, text))
    assert (scenario.dt, scenario.duration) == (0.01, 10.0)
    second = scenario.robots[1]
    assert second.planner == {'eta': 0.5, 'num_directions': 32, 'inertia': 0.15,
                              'time_horizon': 2.0}
    assert type(second.planner['num_directions']) is int
    assert type(second.planner['eta']) is float


def test_yaml_1_2_floats_do_not_change_the_shared_safe_loader():
    assert yaml.safe_load('x: 1e-2') == {'x': '1e-2'}


def test_per_robot_planner_block_is_merged_typed_and_complete(tmp_path):
    text = VALID.replace('{eta: 0.95}', '{eta: 0.5, k: 2}').replace(
        '  eta: 0.8\n', '  eta: 0.8\n  num_directions: 32\n')
    first, second = load_scenario(write(tmp_path, text)).robots
    assert first.planner == {'eta': 0.5, 'k': 2.0, 'num_directions': 32, 'time_horizon': 2.0}
    assert type(first.planner['k']) is float
    assert second.planner == {'eta': 0.8, 'num_directions': 32, 'time_horizon': 2.0}


def test_every_parameter_the_runner_sets_except_eta_is_refused_in_a_planner_block(tmp_path):
    from prvo_sim.runner.session import RUNNER_PARAMETERS

    for name in set(RUNNER_PARAMETERS) - {'eta'}:
        path = write(tmp_path, VALID.replace('{eta: 0.95}', f'{{{name}: 1.0}}'))
        with pytest.raises(ScenarioError, match=re.escape(
                f'robots[0].planner.{name}: set by the runner')):
            load_scenario(path)


def test_a_directory_named_like_a_shipped_scenario_is_not_a_scenario(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    (tmp_path / 'headon2').mkdir()
    assert find_scenario('headon2').name == 'headon2.yaml'
    assert load_scenario(find_scenario('headon2')).name == 'headon2'
    (tmp_path / 'circle8').write_text(VALID)
    assert find_scenario('circle8') == pathlib.Path('circle8')


def test_team_memory_estimate_grows_with_the_team():
    headon, circle = (load_scenario(find_scenario(name)) for name in ('headon2', 'circle8'))
    difference = estimate_team_memory(circle) - estimate_team_memory(headon)
    assert difference == 6 * PLANNER_MEMORY_MIB
    assert estimate_team_memory(headon) == (
        2 * PLANNER_MEMORY_MIB + SIMULATOR_MEMORY_MIB + RUNNER_MEMORY_MIB)


def test_team_memory_counts_a_map_for_every_planner(tmp_path):
    """Each planner builds its own map of a walled world (issue 36 item 2)."""
    path = tmp_path / 'hall.yaml'
    path.write_text(
        'name: hall\nseed: 1\ndt: 0.1\nduration: 5.0\ngoal_tolerance: 0.2\n'
        'walls:\n  - line: [[0.0, -2.0], [200.0, -2.0]]\n    thickness: 0.1\nrobots:\n'
        + ''.join(f'  - name: robot_{i}\n    start: [{2.0 * i}, 0.0]\n'
                  f'    goal: [{2.0 * i}, 5.0]\n    radius: 0.3\n    max_speed: 1.0\n'
                  for i in range(3)))
    hall = load_scenario(path)
    cells = hall.static_world.grid.cells.size
    per_map = cells * MAP_BYTES_PER_CELL / 2.0 ** 20
    assert per_map > 10.0
    for engine, without in (('ros', 3 * PLANNER_MEMORY_MIB + SIMULATOR_MEMORY_MIB
                             + RUNNER_MEMORY_MIB),
                            ('inprocess', INPROCESS_MEMORY_MIB + 3 * INPROCESS_ROBOT_MEMORY_MIB)):
        assert estimate_team_memory(hall, engine, bag=False) == math.ceil(without + 3 * per_map)
    with pytest.raises(ScenarioError, match=f'{math.ceil(per_map)} MiB per planner for its map'):
        check_team_memory(hall, available_mib=estimate_team_memory(hall) - 1)


def test_team_memory_check_against_available_memory(tmp_path):
    circle = load_scenario(find_scenario('circle8'))
    needed = estimate_team_memory(circle)
    check_team_memory(circle, available_mib=needed)
    with pytest.raises(ScenarioError) as raised:
        check_team_memory(circle, available_mib=needed - 1)
    message = str(raised.value)
    assert message.startswith(f'{circle.path}: robots: ')
    assert f'{needed} MiB' in message and f'{needed - 1} MiB available' in message
    meminfo = tmp_path / 'meminfo'
    meminfo.write_text('MemTotal:       24683060 kB\nMemFree:         1000 kB\n'
                       'MemAvailable:    2048000 kB\n')
    assert available_memory_mib(meminfo) == 2000
    assert available_memory_mib(tmp_path / 'no-such-file') is None


@pytest.fixture(scope='module')
def crowd_circle(tmp_path_factory):
    """Return a function of (count, duration): that crowd circle (`prvo_sim.bench.crowds`), loaded.

    Each team is written and loaded once (a large one takes seconds); DURATION [s] replaces its
    duration.
    """
    folder = tmp_path_factory.mktemp('circles')
    loaded = {}

    def circle(count, duration):
        if count not in loaded:
            loaded[count] = write_scenario(crowd_circle_document(count, circle_radius_of(count)),
                                           folder / f'circle{count}.yaml')
        return dataclasses.replace(loaded[count], duration=duration)

    return circle


# Peak resident sizes [MiB] of `prvo-run --engine inprocess` on crowd circles: robots, sim
# duration run [s], whether it recorded a bag (and drew the animation), the peak.
MEASURED_IN_PROCESS = [(8, 11.2, True, 274), (64, 15.0, True, 496), (64, 86.5, True, 1383),
                       (128, 22.0, True, 1272), (256, 9.9, True, 2001), (16, 20.4, False, 179),
                       (128, 30.0, False, 355), (256, 9.9, False, 374)]


@pytest.mark.parametrize(('count', 'duration', 'bag', 'peak'), MEASURED_IN_PROCESS)
def test_the_in_process_estimate_covers_the_measured_peaks(crowd_circle, count, duration, bag,
                                                          peak):
    estimate = estimate_team_memory(crowd_circle(count, duration), 'inprocess', bag)
    # Above the peak, and not by so much that it refuses what would fit.
    assert peak <= estimate <= 2.0 * peak


def test_the_in_process_bag_grows_with_the_steps_and_the_team_squared(crowd_circle):
    def bag(count, duration):
        scenario = crowd_circle(count, duration)
        return (estimate_team_memory(scenario, 'inprocess')
                - estimate_team_memory(scenario, 'inprocess', bag=False))

    # Every planner's status and markers name every other robot: per step ~ n^2 for a crowd.
    assert bag(64, 60.0) == pytest.approx(2.0 * bag(64, 30.0), rel=0.01)
    assert 3.0 < bag(128, 30.0) / bag(64, 30.0) < 4.0


def test_each_engine_checks_its_own_memory_estimate(crowd_circle):
    # The 256 robots against 23508 MiB: the ROS estimate refuses them, in process they fit
    # without a bag, and with one for a short run.
    team, available = crowd_circle(256, 10.0), 23508
    with pytest.raises(ScenarioError, match=r'256 robots need an estimated 38600 MiB \(150 MiB '
                       r'per planner, 80 MiB simulator, 120 MiB runner\), more than the 23508 '
                       'MiB available'):
        check_team_memory(team, available_mib=available)
    check_team_memory(team, available_mib=available, engine='inprocess')
    check_team_memory(team, available_mib=available, engine='inprocess', bag=False)
    # A long run's bag does not fit; without one it does.
    long_run = crowd_circle(256, 600.0)
    with pytest.raises(ScenarioError) as raised:
        check_team_memory(long_run, available_mib=available, engine='inprocess')
    message = str(raised.value)
    assert message.startswith(f'{long_run.path}: robots: 256 robots need an estimated ')
    assert 'in process: 320 MiB, 0.5 MiB per robot, ' in message
    assert 'MiB for the bag of 6001 steps (--no-bag: none)' in message
    check_team_memory(long_run, available_mib=available, engine='inprocess', bag=False)
    with pytest.raises(ValueError, match="^engine must be one of ros, inprocess, got 'dds'$"):
        check_team_memory(team, available_mib=available, engine='dds')


@pytest.mark.parametrize(('old', 'new', 'key'), [
    ('  eta: 0.8\n', '  etaa: 0.9\n', 'planner.etaa'),
    ('dt: 0.1\n', 'dt: 1e-300\n', 'dt'),
    ('    max_speed: 0.5\n', '    max_speed: 0.5\n    kinematics: tank\n',
     'robots[1].kinematics'),
    ('    max_speed: 0.5\n', '    max_speed: 0.5\n    max_angular_speed: 1.0\n',
     'robots[1].max_angular_speed'),
    ('    max_speed: 0.5\n', '    max_speed: 0.5\n    max_acceleration: -1\n',
     'robots[1].max_acceleration'),
])
def test_runner_exits_2_on_a_bad_file_before_starting_anything(tmp_path, old, new, key):
    marker = tmp_path / 'a-child-started'
    command = f'{sys.executable} -c "open({str(marker)!r}, \'w\').close()"'
    path = write(tmp_path, VALID.replace(old, new, 1))
    result = subprocess.run(
        [sys.executable, '-m', 'prvo_sim.run_scenario', str(path), '--out',
         str(tmp_path / 'out'), '--sim-command', command, '--planner-command', command],
        capture_output=True, text=True, timeout=120)
    assert result.returncode == 2, result.stderr
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1 and f'{path}: {key}: ' in lines[0], result.stderr
    assert not marker.exists()
    assert not (tmp_path / 'out').exists()


# Names ROS refuses for different reasons, and names it takes; 'a' * 215 passes as a namespace
# and as topics but not in the planner's parameter services, 'a' * 235 not even in the topics.
REFUSED_NAMES = {
    'robot__0': "holds '__': ROS cannot parse the remap rule __ns:=/robot__0",
    '__robot': "holds '__'",
    '0robot': 'not a valid ROS name segment',
    'robot-0': 'not a valid ROS name segment',
    'a' * 215: 'Invalid service name: topic length should not exceed',
    'a' * 235: 'Invalid topic name: topic length should not exceed',
}
ACCEPTED_NAMES = ('robot_', '_robot', 'Robot0', 'r', 'a' * 210)


@pytest.mark.parametrize('name', list(REFUSED_NAMES))
def test_a_robot_name_ros_refuses_is_refused_in_one_line(tmp_path, name):
    path = write(tmp_path, VALID.replace('  - name: robot_1\n', f'  - name: {name}\n'))
    with pytest.raises(ScenarioError) as raised:
        load_scenario(path)
    message = str(raised.value)
    assert message.startswith(f'{path}: robots[1].name: robot name {name!r}'), message
    assert REFUSED_NAMES[name] in message and '\n' not in message


@pytest.mark.parametrize('name', ACCEPTED_NAMES)
def test_a_robot_name_ros_takes_loads(tmp_path, name):
    path = write(tmp_path, VALID.replace('  - name: robot_1\n', f'  - name: {name}\n'))
    assert load_scenario(path).robots[1].name == name


def ros_starts_a_planner_as(name):
    """Whether rclpy starts a node 'planner' under `-r __ns:=/NAME` with every robot topic."""
    context = Context()
    try:
        rclpy.init(args=['--ros-args', '-r', f'__ns:=/{name}'], context=context)
        node = rclpy.create_node('planner', context=context)
        for leaf in (ODOM, GROUND_TRUTH, CMD_VEL, GOAL_POSE, MARKERS, FOOTPRINT, AVOIDANCE_SHARE):
            node.create_publisher(String, leaf, 1)
        node.destroy_node()
        return True
    except (RuntimeError, NameValidationException):
        # rcl's RCLError (a RuntimeError): the remap rule or the node's names.
        return False
    finally:
        rclpy.try_shutdown(context=context)


def test_the_schema_refuses_a_robot_name_exactly_when_ros_does(ros_domain, monkeypatch):
    monkeypatch.setenv('ROS_DOMAIN_ID', str(ros_domain))
    for name in (*REFUSED_NAMES, *ACCEPTED_NAMES):
        assert ros_starts_a_planner_as(name) == (ros_name_problem(name) is None), name


def test_robot_kinematics_and_limits_are_read_with_their_defaults(tmp_path):
    text = VALID.replace('    planner: {eta: 0.95}\n', '    planner: {eta: 0.95}\n'
                         '    kinematics: unicycle\n    max_angular_speed: 1.5\n'
                         '    max_acceleration: 1\n    max_angular_acceleration: 4\n'
                         '    start_yaw: -3.0\n')
    first, second = load_scenario(write(tmp_path, text)).robots
    assert (first.kinematics, first.max_angular_speed, first.max_acceleration,
            first.max_angular_acceleration, first.start_yaw) == ('unicycle', 1.5, 1.0, 4.0, -3.0)
    assert (second.kinematics, second.max_angular_speed, second.max_acceleration,
            second.max_angular_acceleration, second.start_yaw) == (
                'holonomic', 2.0, np.inf, np.inf, None)


def test_the_scenario_documentation_names_every_planner_parameter():
    from prvo_planner.parameters import PARAMETERS

    documentation = (pathlib.Path(__file__).resolve().parents[2] / 'docs/scenarios.md').read_text()
    missing = [name for name in PARAMETERS if f'`{name}`' not in documentation]
    assert not missing, missing


def test_runner_refuses_a_team_the_memory_cannot_hold(tmp_path, monkeypatch):
    from prvo_sim import run_scenario, scenario

    monkeypatch.setattr(scenario, 'available_memory_mib', lambda: 400)
    with pytest.raises(run_scenario.UsageError) as raised:
        run_scenario.parse_arguments(['headon2', '--out', str(tmp_path / 'out')])
    assert 'robots: 2 robots need an estimated 500 MiB' in str(raised.value)
    assert 'more than the 400 MiB available' in str(raised.value)
    assert not (tmp_path / 'out').exists()

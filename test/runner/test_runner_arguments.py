"""Bad input: a one-line error naming the problem, exit code 2, and no child ever started."""

import os
import pathlib
import subprocess
import sys

import numpy as np
from PIL import Image
import pytest

from prvo_sim import run_scenario

SCENARIOS = pathlib.Path(__file__).resolve().parents[2] / 'src/prvo_sim/scenarios'
HEADON = str(SCENARIOS / 'headon2.yaml')


@pytest.fixture
def marker_command(tmp_path):
    """Return a child command that leaves a marker file, and the marker's path."""
    marker = tmp_path / 'a-child-started'
    command = f'{sys.executable} -c "open({str(marker)!r}, \'w\').close()"'
    return command, marker


def run_main(argv, marker_command, capsys):
    command, marker = marker_command
    code = run_scenario.main([*argv, '--sim-command', command, '--planner-command', command])
    err = capsys.readouterr().err
    assert not marker.exists(), 'a child was started despite bad input'
    # A refused run writes nothing, not even its output folder.
    out = pathlib.Path(argv[argv.index('--out') + 1])
    assert not out.exists(), f'{out} was created by a refused run'
    return code, err


def assert_one_line_error(err, *names):
    lines = err.strip().splitlines()
    assert len(lines) == 1, err
    assert lines[0].startswith('run_scenario: error: ')
    for name in names:
        assert name in lines[0]


@pytest.mark.parametrize('eta', ['0', '1', '1.5', '-0.2', 'nan'])
def test_eta_outside_open_unit_interval(eta, tmp_path, marker_command, capsys):
    code, err = run_main([HEADON, '--out', str(tmp_path / 'out'), '--eta', eta],
                         marker_command, capsys)
    assert code == 2
    assert_one_line_error(err, '--eta', eta)


def test_unknown_method(tmp_path, marker_command, capsys):
    code, err = run_main([HEADON, '--out', str(tmp_path / 'out'), '--method', 'orca'],
                         marker_command, capsys)
    assert code == 2
    assert_one_line_error(err, '--method', 'orca')


def test_scenario_breaking_the_schema(tmp_path, marker_command, capsys):
    broken = tmp_path / 'broken.yaml'
    broken.write_text(open(HEADON).read().replace('radius: 0.3', 'radius: -0.3', 1))
    code, err = run_main([str(broken), '--out', str(tmp_path / 'out')], marker_command, capsys)
    assert code == 2
    assert_one_line_error(err, 'broken.yaml', 'robots[0].radius')


def test_missing_scenario_file(tmp_path, marker_command, capsys):
    missing = tmp_path / 'missing.yaml'
    code, err = run_main([str(missing), '--out', str(tmp_path / 'out')], marker_command, capsys)
    assert code == 2
    assert_one_line_error(err, 'missing.yaml')


def mapped_headon(tmp_path, image, resolution, origin):
    """Return headon2 with map.yaml of IMAGE (cells of RESOLUTION m, origin (ORIGIN, ORIGIN))."""
    (tmp_path / 'map.yaml').write_text(f'image: {image}\nresolution: {resolution}\n'
                                       f'origin: [{origin}, {origin}, 0.0]\n')
    scenario = tmp_path / 'mapped.yaml'
    scenario.write_text(open(HEADON).read() + 'map: map.yaml\n')
    return scenario


def test_map_image_declaring_too_many_pixels(tmp_path, marker_command, capsys):
    # A PGM header declaring 60000 x 60000 pixels, and no pixels.
    (tmp_path / 'huge.pgm').write_bytes(b'P5\n60000 60000\n255\n')
    scenario = mapped_headon(tmp_path, 'huge.pgm', 0.05, -10.0)
    code, err = run_main([str(scenario), '--out', str(tmp_path / 'out')], marker_command, capsys)
    assert code == 2
    assert_one_line_error(err, 'map.yaml', 'image', 'huge.pgm', 'more than 4e+07 pixels')


def test_a_map_of_cells_too_small_for_the_planners_is_refused(tmp_path, marker_command, capsys):
    # 160 x 160 cells of 1e-4 m: every planner would refuse to build a route on it (its reach
    # of 0.6 m is 6,000 cells), and plan as if there were no map.
    Image.fromarray(np.full((160, 160), 255, dtype=np.uint8)).save(tmp_path / 'tiny.pgm')
    scenario = mapped_headon(tmp_path, 'tiny.pgm', 0.0001, 10.0)
    code, err = run_main([str(scenario), '--out', str(tmp_path / 'out')], marker_command, capsys)
    assert code == 2
    assert_one_line_error(err, 'mapped.yaml: map: ', '160 x 160 cells of 0.0001 m',
                          'cells padded (at most 2.5e+07)')


@pytest.mark.parametrize('fifo', ['map.pgm', 'mapped.yaml'])
def test_a_fifo_for_a_file_is_refused_at_once(tmp_path, fifo):
    # Reading a FIFO waits for a writer that never comes: refused, not read.
    (tmp_path / 'map.yaml').write_text('image: map.pgm\nresolution: 0.05\n'
                                       'origin: [-10.0, -10.0, 0.0]\n')
    (tmp_path / 'map.pgm').write_bytes(b'P5\n2 2\n255\n\xff\xff\xff\xff')
    (tmp_path / 'mapped.yaml').write_text(open(HEADON).read() + 'map: map.yaml\n')
    (tmp_path / fifo).unlink()
    os.mkfifo(tmp_path / fifo)
    result = subprocess.run(
        [sys.executable, '-m', 'prvo_sim.run_scenario', str(tmp_path / 'mapped.yaml'),
         '--engine', 'inprocess', '--out', str(tmp_path / 'out')],
        capture_output=True, text=True, timeout=60)
    assert result.returncode == 2
    assert_one_line_error(result.stderr, fifo, 'not a regular file')


def test_output_folder_that_cannot_be_written(tmp_path, marker_command, capsys):
    blocker = tmp_path / 'a-file'
    blocker.write_text('not a folder')
    code, err = run_main([HEADON, '--out', str(blocker / 'out')], marker_command, capsys)
    assert code == 2
    assert_one_line_error(err, '--out', str(blocker / 'out'))


@pytest.mark.parametrize('option, value', [('--seeds', '0'), ('--timeout', '-1'),
                                           ('--domain-id', '300'), ('--seed', 'x')])
def test_other_bad_options(option, value, tmp_path, marker_command, capsys):
    code, err = run_main([HEADON, '--out', str(tmp_path / 'out'), option, value],
                         marker_command, capsys)
    assert code == 2
    assert_one_line_error(err, option)


def test_module_entry_point_reports_bad_input(tmp_path):
    result = subprocess.run(
        [sys.executable, '-m', 'prvo_sim.run_scenario', HEADON, '--eta', '2',
         '--out', str(tmp_path / 'out')], capture_output=True, text=True, timeout=60)
    assert result.returncode == 2
    assert_one_line_error(result.stderr, '--eta')


def test_planner_parameters_follow_method_and_robot():
    from prvo_sim.scenario import load_scenario

    scenario = load_scenario(HEADON)
    robot = scenario.robots[1]
    prvo = run_scenario.planner_parameters(robot, scenario, 'prvo', 0.9)
    assert prvo['goal'] == '[-4.0, 0.0]'
    assert prvo['model'] == 'prvo' and prvo['eta'] == '0.9'
    assert prvo['actuation_std'] == '0.05'
    assert float(prvo['goal_tolerance']) == pytest.approx(scenario.goal_tolerance / 2.0)
    no_ego = run_scenario.planner_parameters(robot, scenario, 'prvo-no-ego', 0.9)
    assert no_ego['model'] == 'prvo' and no_ego['actuation_std'] == '0.0'
    assert run_scenario.planner_parameters(robot, scenario, 'inflate', 0.8)['model'] == 'inflate'


def test_ros_parameter_keeps_types():
    assert run_scenario.ros_parameter(True) == 'true'
    assert run_scenario.ros_parameter(3) == '3'
    assert run_scenario.ros_parameter(4) != run_scenario.ros_parameter(4.0)
    assert run_scenario.ros_parameter([1, 2.5]) == '[1, 2.5]'


WALKER_SCENARIO = """\
name: walk
seed: 1
dt: 0.1
duration: 5.0
goal_tolerance: 0.2
robots:
  - name: robot_0
    start: [-2.0, 0.0]
    goal: [2.0, 0.0]
    radius: 0.3
    max_speed: 1.0
  - name: walker
    start: [0.0, -2.0]
    radius: 0.3
    max_speed: 1.0
"""


@pytest.mark.parametrize('entry, key', [
    ('    scripted: {speed: 0.5}', 'robots[1].scripted.waypoints'),
    ('    scripted: {waypoints: []}', 'robots[1].scripted.waypoints'),
    ('    scripted: {waypoints: [0.0, 2.0]}', 'robots[1].scripted.waypoints[0]'),
    ('    scripted: {waypoints: [[0.0, 2.0], [.nan, 1.0]]}', 'robots[1].scripted.waypoints[1][0]'),
    ('    scripted: {waypoints: [[0.0, .inf]]}', 'robots[1].scripted.waypoints[0][1]'),
    ('    scripted: {waypoints: [[0.0, 2.0]], speed: -0.5}', 'robots[1].scripted.speed'),
    ('    scripted: {waypoints: [[0.0, 2.0]], speed: 0}', 'robots[1].scripted.speed'),
    ('    scripted: {waypoints: [[0.0, 2.0]], speed: 1.5}', 'robots[1].scripted.speed'),
    ('    scripted: {waypoints: [[0.0, 2.0]], loop: yes please}', 'robots[1].scripted.loop'),
    ('    scripted: {waypoints: [[0.0, 2.0]], pace: 0.5}', 'robots[1].scripted.pace'),
    ('    scripted: [[0.0, 2.0]]', 'robots[1].scripted'),
    ('    goal: [0.0, 2.0]\n    scripted: {waypoints: [[0.0, 2.0]]}', 'robots[1].goal'),
    ('    planner: {eta: 0.9}\n    scripted: {waypoints: [[0.0, 2.0]]}', 'robots[1].planner'),
])
def test_bad_scripted_robot_is_named(entry, key, tmp_path, marker_command, capsys):
    broken = tmp_path / 'walk.yaml'
    broken.write_text(WALKER_SCENARIO + entry + '\n')
    code, err = run_main([str(broken), '--out', str(tmp_path / 'out')], marker_command, capsys)
    assert code == 2
    assert_one_line_error(err, 'walk.yaml', f'{key}:', 'walker')


def test_scripted_robot_gets_no_planner_but_is_every_planner_neighbour(tmp_path):
    from prvo_sim.runner.session import planner_values
    from prvo_sim.scenario import load_scenario

    path = tmp_path / 'walk.yaml'
    path.write_text(WALKER_SCENARIO + '    scripted: {waypoints: [[0.0, 2.0]]}\n')
    scenario = load_scenario(path)
    robot, walker = scenario.robots
    assert planner_values(walker, scenario, 'prvo', None) is None
    assert planner_values(robot, scenario, 'prvo', None)['neighbors'] == ['walker']

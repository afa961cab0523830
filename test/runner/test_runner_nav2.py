"""Robots driven by the Nav2 stand-in: both engines give the same trajectories."""

import csv
import json
import pathlib

import numpy as np
from runner_testing import output, start_runner
from test_runner_engines import rows_of

from prvo_sim.scenario import load_scenario

SCENARIOS = pathlib.Path(__file__).resolve().parents[2] / 'src/prvo_sim/scenarios'


def final_positions(path):
    """Return {robot: its last recorded position (2,)} of a trajectories.csv."""
    finals = {}
    with open(path) as csv_file:
        for row in csv.DictReader(csv_file):
            finals[row['robot']] = np.array([float(row['x']), float(row['y'])])
    return finals


def test_both_engines_drive_the_stand_in_team_alike(tmp_path, runners):
    outs = {}
    for engine in ('inprocess', 'ros'):
        outs[engine] = tmp_path / engine
        runner = start_runner([str(SCENARIOS / 'nav2_headon2.yaml'), '--engine', engine,
                               '--out', str(outs[engine]), '--quiet', '--no-bag',
                               '--no-animation'], tmp_path, label=engine)
        runners.append(runner)
        assert runner.wait(timeout=900) == 0, output(runner)
    inprocess, ros = (rows_of(outs[engine] / 'trajectories.csv') for engine in outs)
    assert inprocess and set(inprocess) == set(ros)
    for key, values in inprocess.items():
        pairs = [(value, other) for value, other in zip(values, ros[key], strict=True)
                 if value is not None and other is not None]
        assert max(abs(value - other) for value, other in pairs) <= 1e-9, (key, values, ros[key])


def test_both_engines_follow_the_path_stand_ins_alike_to_every_path_end(tmp_path, runners):
    outs = {}
    for engine in ('inprocess', 'ros'):
        outs[engine] = tmp_path / engine
        runner = start_runner([str(SCENARIOS / 'nav2_path_crossing4.yaml'), '--engine', engine,
                               '--out', str(outs[engine]), '--quiet', '--no-bag',
                               '--no-animation'], tmp_path, label=engine)
        runners.append(runner)
        assert runner.wait(timeout=900) == 0, output(runner)
    inprocess, ros = (rows_of(outs[engine] / 'trajectories.csv') for engine in outs)
    assert inprocess and set(inprocess) == set(ros)
    for key, values in inprocess.items():
        pairs = [(value, other) for value, other in zip(values, ros[key], strict=True)
                 if value is not None and other is not None]
        assert max(abs(value - other) for value, other in pairs) <= 1e-9, (key, values, ros[key])
    scenario = load_scenario(SCENARIOS / 'nav2_path_crossing4.yaml')
    ends = {robot.name: robot.followed_path.waypoints[-1] for robot in scenario.robots}
    metrics = json.loads((outs['ros'] / 'metrics.json').read_text())
    assert metrics['collisions'] == 0 and metrics['min_separation'] > 0.0
    finals = final_positions(outs['ros'] / 'trajectories.csv')
    for name, end in ends.items():
        assert metrics['robots'][name]['arrived'], name
        assert np.hypot(*(finals[name] - end)) <= scenario.goal_tolerance, name

"""Robots as they are built, judged from a run's recorded outputs (in-process engine).

The mixed team (mixed_drive) is judged in test_runner_engines, on the in-process run its
engines' identity test makes.
"""

import csv
import json
import math
import pathlib
import subprocess
import sys

import numpy as np

from prvo_sim.scenario import load_scenario

SCENARIOS = pathlib.Path(__file__).resolve().parents[2] / 'src/prvo_sim/scenarios'


def run_inprocess(scenario, out):
    result = subprocess.run(
        [sys.executable, '-m', 'prvo_sim.run_scenario', str(SCENARIOS / f'{scenario}.yaml'),
         '--engine', 'inprocess', '--out', str(out), '--quiet', '--no-bag', '--no-animation'],
        capture_output=True, text=True, timeout=1800)
    assert result.returncode == 0, result.stdout + result.stderr
    with open(out / 'trajectories.csv') as csv_file:
        rows = list(csv.DictReader(csv_file))
    return json.loads((out / 'metrics.json').read_text()), rows


def per_robot(rows, keys):
    """Return {robot: array (T, len(keys))} with '' read as NaN."""
    table = {}
    for row in rows:
        table.setdefault(row['robot'], []).append(
            [float(row[key]) if row[key] else math.nan for key in keys])
    return {robot: np.array(values) for robot, values in table.items()}


def test_differential_drive_circle_arrives_without_contact_or_sideways_motion(tmp_path):
    metrics, rows = run_inprocess('diffdrive_circle6', tmp_path)
    assert metrics['collisions'] == 0 and metrics['success_rate'] == 1.0, metrics
    scenario = load_scenario(SCENARIOS / 'diffdrive_circle6.yaml')
    assert all(robot.kinematics == 'unicycle' for robot in scenario.robots)
    turned_away = [robot for robot in scenario.robots if robot.start_yaw is not None and abs(
        math.remainder(robot.start_yaw - math.atan2(*(robot.goal - robot.start)[::-1]),
                       math.tau)) > math.pi / 2]
    assert len(turned_away) >= 3
    states = per_robot(rows, ('vx', 'vy', 'yaw'))
    for robot, (vx, vy, yaw) in ((name, values.T) for name, values in states.items()):
        sideways = -vx * np.sin(yaw) + vy * np.cos(yaw)
        assert np.max(np.abs(sideways)) <= 1e-12, robot
        # The robots do drive: forward speeds well above the noise.
        assert np.max(vx * np.cos(yaw) + vy * np.sin(yaw)) > 0.5, robot


def test_acceleration_limited_team_arrives_and_never_changes_its_command_too_fast(tmp_path):
    metrics, rows = run_inprocess('accel8', tmp_path)
    assert metrics['collisions'] == 0 and metrics['success_rate'] == 1.0, metrics
    scenario = load_scenario(SCENARIOS / 'accel8.yaml')
    assert len(scenario.robots) == 8
    assert all(robot.max_acceleration == 0.8 for robot in scenario.robots)
    commands = per_robot(rows, ('cmd_vx', 'cmd_vy'))
    for robot, command in commands.items():
        command = command[~np.isnan(command).any(axis=1)]
        changes = np.linalg.norm(np.diff(np.vstack([np.zeros(2), command]), axis=0), axis=1)
        assert np.max(changes) <= 0.8 * scenario.dt + 1e-9, (robot, np.max(changes))
        assert np.max(np.linalg.norm(command, axis=1)) > 0.5, robot

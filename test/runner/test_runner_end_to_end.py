"""The runner with the real simulator and planners on headon2."""

import csv
import json
import os
import signal
import subprocess
import sys
import uuid

import numpy as np
import pytest
from runner_testing import HEADON, TOKEN_VARIABLE, processes_with_token, wait_for

SCHEMA_KEYS = {'scenario', 'method', 'eta', 'seed', 'mode', 'robots', 'success_rate',
               'collisions', 'min_separation', 'makespan', 'mean_time_to_goal', 'planner_ms',
               'deadline_misses', 'sim_time', 'wall_time'}


def run_headon(tmp_path, ros_domain, *extra, timeout=240):
    out = tmp_path / 'out'
    result = subprocess.run(
        [sys.executable, '-m', 'prvo_sim.run_scenario', HEADON, '--out', str(out),
         '--domain-id', str(ros_domain), *extra],
        capture_output=True, text=True, timeout=timeout)
    return result, out


def test_headon2_both_arrive_without_contact(tmp_path, ros_domain):
    result, out = run_headon(tmp_path, ros_domain)
    assert result.returncode == 0, result.stderr + result.stdout
    recorded = json.loads((out / 'metrics.json').read_text())
    assert set(recorded) == SCHEMA_KEYS
    assert (recorded['scenario'], recorded['method'], recorded['eta'], recorded['seed'],
            recorded['mode']) == ('headon2', 'prvo', 0.8, 3, 'lockstep')
    assert recorded['success_rate'] == 1.0
    assert recorded['collisions'] == 0
    assert all(robot['arrived'] for robot in recorded['robots'].values())
    # Straight-line distance is 8 m, minus the 0.2 m tolerance.
    for robot in recorded['robots'].values():
        assert robot['path_length'] >= 7.8 - 1e-6
        assert 7.8 / 1.0 <= robot['time_to_goal'] <= recorded['makespan']
    assert recorded['planner_ms']['median'] > 0.0

    with open(out / 'trajectories.csv') as csv_file:
        rows = list(csv.DictReader(csv_file))
    positions = {}
    for row in rows:
        positions.setdefault(row['time'], {})[row['robot']] = (float(row['x']), float(row['y']))
    separation = min(np.hypot(*np.subtract(pair['robot_0'], pair['robot_1'])) - 0.6
                     for pair in positions.values())
    assert separation == pytest.approx(recorded['min_separation'], abs=1e-5)
    assert separation > 0.0
    last = positions[max(positions, key=float)]
    assert np.hypot(last['robot_0'][0] - 4.0, last['robot_0'][1]) <= 0.2
    assert np.hypot(last['robot_1'][0] + 4.0, last['robot_1'][1]) <= 0.2
    assert (out / 'trajectories.png').read_bytes()[:4] == b'\x89PNG'
    assert 'headon2' in result.stdout and str(out) in result.stdout


def test_sigint_during_a_real_run_leaves_no_process(tmp_path, ros_domain):
    token = uuid.uuid4().hex
    env = dict(os.environ, PYTHONUNBUFFERED='1', **{TOKEN_VARIABLE: token})
    err_path = tmp_path / 'runner.err'
    with open(err_path, 'w') as err_file:
        runner = subprocess.Popen(
            [sys.executable, '-m', 'prvo_sim.run_scenario', HEADON, '--out',
             str(tmp_path / 'out'), '--domain-id', str(ros_domain)],
            env=env, stdout=subprocess.DEVNULL, stderr=err_file, start_new_session=True)
    try:
        # The first progress line appears with the first ground truth of every robot.
        wait_for(lambda: 'arrived 0/2' in err_path.read_text(), 60, 'the run starting')
        runner.send_signal(signal.SIGINT)
        assert runner.wait(timeout=30) == 128 + signal.SIGINT
    finally:
        if runner.poll() is None:
            os.killpg(runner.pid, signal.SIGKILL)
            runner.wait()
    assert processes_with_token(token) == []
    recorded = json.loads((tmp_path / 'out' / 'metrics.json').read_text())
    assert recorded['failure'] == 'interrupted by SIGINT'
    assert recorded['sim_time'] >= 0.0

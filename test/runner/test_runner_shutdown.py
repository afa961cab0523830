"""Clean shutdown: whatever ends a run, no process the runner started (or theirs) survives.

Children are found by a token in their environment, which every descendant inherits.
"""

import json
import os
import re
import signal
import subprocess
import sys
import time
import uuid

import pytest
from runner_testing import (
    FAKE_CHILD,
    HEADON,
    TOKEN_VARIABLE,
    live_group_members,
    processes_with_token,
    wait_for,
)

from prvo_sim import run_scenario


def start_runner(argv, tmp_path, ros_domain):
    token = uuid.uuid4().hex
    env = dict(os.environ, PYTHONUNBUFFERED='1')
    env[TOKEN_VARIABLE] = token
    stderr = open(tmp_path / 'runner.err', 'w')
    process = subprocess.Popen(
        [sys.executable, '-m', 'prvo_sim.run_scenario', *argv, '--domain-id', str(ros_domain)],
        env=env, stdout=subprocess.DEVNULL, stderr=stderr, start_new_session=True)
    stderr.close()
    return process, token


@pytest.fixture
def runners():
    """Runner processes of a test; killed (whole group) at teardown should a test fail."""
    started = []
    yield started
    for process in started:
        if process.poll() is None:
            os.killpg(process.pid, signal.SIGKILL)
            process.wait()


def test_sigint_mid_run_stops_every_child_and_grandchild(tmp_path, ros_domain, runners):
    out = tmp_path / 'out'
    runner, token = start_runner(
        [HEADON, '--out', str(out), '--sim-command', f'{FAKE_CHILD} run',
         '--planner-command', f'{FAKE_CHILD} run'], tmp_path, ros_domain)
    runners.append(runner)
    # Two planners and the sim, each with a grandchild.
    wait_for(lambda: len(processes_with_token(token, exclude={runner.pid})) == 6, 30,
             'six descendants running')
    runner.send_signal(signal.SIGINT)
    assert runner.wait(timeout=30) == 128 + signal.SIGINT
    assert processes_with_token(token) == []
    recorded = json.loads((out / 'metrics.json').read_text())
    assert recorded['failure'] == 'interrupted by SIGINT'
    assert (out / 'trajectories.csv').read_text().startswith('time,robot,x,y,vx,vy,cmd_vx')


def test_sigterm_is_handled_like_ctrl_c(tmp_path, ros_domain, runners):
    runner, token = start_runner(
        [HEADON, '--out', str(tmp_path / 'out'), '--sim-command', f'{FAKE_CHILD} run',
         '--planner-command', f'{FAKE_CHILD} run'], tmp_path, ros_domain)
    runners.append(runner)
    wait_for(lambda: len(processes_with_token(token, exclude={runner.pid})) == 6, 30,
             'six descendants running')
    runner.send_signal(signal.SIGTERM)
    assert runner.wait(timeout=30) == 128 + signal.SIGTERM
    assert processes_with_token(token) == []


def test_crashed_child_fails_the_run_and_stops_the_others(tmp_path, ros_domain, runners):
    out = tmp_path / 'out'
    runner, token = start_runner(
        [HEADON, '--out', str(out), '--sim-command', f'{FAKE_CHILD} run',
         '--planner-command', f'{FAKE_CHILD} crash'], tmp_path, ros_domain)
    runners.append(runner)
    assert runner.wait(timeout=60) == 1
    assert processes_with_token(token) == []
    recorded = json.loads((out / 'metrics.json').read_text())
    # Both planners crash; whichever the runner noticed first is named.
    assert re.match(r'planner_robot_[01] exited with code 3 \(log: ', recorded['failure'])
    assert recorded['success_rate'] == 0.0
    assert set(recorded['robots']) == {'robot_0', 'robot_1'}
    assert (out / 'logs' / 'planner_robot_0.log').read_text().startswith('$ ')


def test_stop_escalates_to_sigkill_for_a_child_that_ignores_sigint(tmp_path):
    children = run_scenario.Children(dict(os.environ), tmp_path)
    stubborn = children.start('stubborn', [*FAKE_CHILD.split(), 'stubborn'])
    polite = children.start('polite', [*FAKE_CHILD.split(), 'run'])
    wait_for(lambda: all('ready' in (tmp_path / f'{label}.log').read_text()
                         for label in ('stubborn', 'polite')), 20, 'the children starting')
    assert len(live_group_members(polite.pid)) == 2  # the child and its grandchild
    started = time.monotonic()
    children.stop(grace=1.0)
    assert time.monotonic() - started < 5.0
    assert stubborn.returncode == -signal.SIGKILL
    assert polite.returncode is not None
    assert live_group_members(stubborn.pid) == []
    assert live_group_members(polite.pid) == []

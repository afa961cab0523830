"""Clean shutdown: whatever ends a run, no process the runner started (or theirs) survives.

Children are found by a token in their environment, which every descendant inherits.
"""

import json
import os
import re
import signal

from runner_testing import (
    FAKE_CHILD,
    FAKE_RUN_DESCENDANTS,
    HEADON,
    live_group_members,
    processes_with_token,
    start_runner,
    wait_for,
)

from prvo_sim import run_scenario

FAKE_TEAM = ['--sim-command', f'{FAKE_CHILD} run', '--planner-command', f'{FAKE_CHILD} planner']


def start_fake_run(tmp_path, runners):
    """Start a runner on headon2 with fake children; return it once every descendant runs."""
    runner = start_runner([HEADON, '--out', str(tmp_path / 'out'), *FAKE_TEAM], tmp_path)
    runners.append(runner)
    wait_for(lambda: len(processes_with_token(runner.token, exclude={runner.pid}))
             == FAKE_RUN_DESCENDANTS, 60, 'every descendant running')
    return runner


def test_sigint_mid_run_stops_every_child_and_grandchild(tmp_path, runners):
    runner = start_fake_run(tmp_path, runners)
    runner.send_signal(signal.SIGINT)
    assert runner.wait(timeout=30) == 128 + signal.SIGINT
    assert processes_with_token(runner.token) == []
    recorded = json.loads((tmp_path / 'out' / 'metrics.json').read_text())
    assert recorded['failure'] == 'interrupted by SIGINT'
    assert (tmp_path / 'out' / 'trajectories.csv').read_text().startswith(
        'time,robot,x,y,vx,vy,cmd_vx')


def test_sigterm_is_handled_like_ctrl_c(tmp_path, runners):
    runner = start_fake_run(tmp_path, runners)
    runner.send_signal(signal.SIGTERM)
    assert runner.wait(timeout=30) == 128 + signal.SIGTERM
    assert processes_with_token(runner.token) == []


def test_sighup_is_handled_like_ctrl_c(tmp_path, runners):
    runner = start_fake_run(tmp_path, runners)
    runner.send_signal(signal.SIGHUP)
    assert runner.wait(timeout=30) == 128 + signal.SIGHUP
    assert processes_with_token(runner.token) == []
    recorded = json.loads((tmp_path / 'out' / 'metrics.json').read_text())
    assert recorded['failure'] == 'interrupted by SIGHUP'


def test_sigkill_of_the_runner_leaves_no_child_or_grandchild(tmp_path, runners):
    runner = start_fake_run(tmp_path, runners)
    runner.kill()
    runner.wait(timeout=30)
    # Parent-death signal and the watchdog end them; the limit is for a loaded host.
    wait_for(lambda: processes_with_token(runner.token) == [], 30,
             'every child and grandchild of the killed runner ending')


def test_crashed_child_fails_the_run_and_stops_the_others(tmp_path, runners):
    out = tmp_path / 'out'
    runner = start_runner([HEADON, '--out', str(out), '--sim-command', f'{FAKE_CHILD} run',
                           '--planner-command', f'{FAKE_CHILD} crash'], tmp_path)
    runners.append(runner)
    assert runner.wait(timeout=60) == 1
    assert processes_with_token(runner.token) == []
    recorded = json.loads((out / 'metrics.json').read_text())
    # Both planners crash; whichever the runner noticed first is named.
    assert re.match(r'planner_robot_[01] exited with code 3 \(log: ', recorded['failure'])
    assert recorded['success_rate'] == 0.0
    assert set(recorded['robots']) == {'robot_0', 'robot_1'}
    assert (out / 'logs' / 'planner_robot_0.log').read_text().startswith('$ ')


def test_stop_escalates_to_sigkill_for_a_child_that_ignores_sigint(tmp_path):
    children = run_scenario.Children(dict(os.environ), tmp_path)
    try:
        stubborn = children.start('stubborn', [*FAKE_CHILD.split(), 'stubborn'])
        polite = children.start('polite', [*FAKE_CHILD.split(), 'run'])
        wait_for(lambda: all('ready' in (tmp_path / f'{label}.log').read_text()
                             for label in ('stubborn', 'polite')), 20, 'the children starting')
        assert len(live_group_members(polite.pid)) == 2  # the child and its grandchild
        children.stop(grace=1.0)
        assert stubborn.returncode == -signal.SIGKILL
        assert polite.returncode is not None
        assert live_group_members(stubborn.pid) == []
        assert live_group_members(polite.pid) == []
    finally:
        children.stop(grace=0.0)

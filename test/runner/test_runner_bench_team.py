"""The team benchmark's pieces, without running it: generated scenarios, /proc readings, rows."""

import itertools
import math
import os
import pathlib
import resource
import subprocess
import sys
import time

import numpy as np
import pytest

from prvo_sim.bench import team as bench_team
from prvo_sim.scenario import load_scenario

CIRCLE8 = pathlib.Path(__file__).resolve().parents[2] / 'src/prvo_sim/scenarios/circle8.yaml'


@pytest.mark.parametrize('team_size, radius', [(4, 4.0), (8, 4.0), (16, 6.0)])
def test_circle_scenario_is_an_antipodal_swap(team_size, radius, tmp_path):
    document = bench_team.circle_document(team_size)
    scenario = bench_team.write_scenario(document, tmp_path / 'circle.yaml')
    assert len(scenario.robots) == team_size
    starts = np.array([robot.start for robot in scenario.robots])
    goals = np.array([robot.goal for robot in scenario.robots])
    # Equally spaced on the circle, in order, and each goal the opposite point.
    np.testing.assert_allclose(np.linalg.norm(starts, axis=1), radius, atol=1e-3)
    angles = np.unwrap(np.arctan2(starts[:, 1], starts[:, 0]))
    np.testing.assert_allclose(angles, 2.0 * math.pi * np.arange(team_size) / team_size,
                               atol=1e-4)
    np.testing.assert_array_equal(goals, -starts)
    for first, second in itertools.combinations(scenario.robots, 2):
        assert np.linalg.norm(first.start - second.start) > first.radius + second.radius
    # Time for five straight crossings at full speed: enough to get through the congestion.
    assert scenario.duration >= 5.0 * 2.0 * radius / bench_team.MAX_SPEED


def test_eight_robots_are_circle8(tmp_path):
    shipped = load_scenario(CIRCLE8)
    generated = bench_team.write_scenario(bench_team.circle_document(8), tmp_path / 'c8.yaml')
    for field in ('seed', 'dt', 'duration', 'goal_tolerance'):
        assert getattr(generated, field) == getattr(shipped, field), field
    for mine, theirs in zip(generated.robots, shipped.robots, strict=True):
        assert mine.name == theirs.name
        np.testing.assert_array_equal(mine.start, theirs.start)
        np.testing.assert_array_equal(mine.goal, theirs.goal)
        assert (mine.radius, mine.max_speed) == (theirs.radius, theirs.max_speed)
        assert mine.noise == theirs.noise
        assert mine.planner == theirs.planner


def test_realtime_duration_is_kept(tmp_path):
    document = bench_team.circle_document(4, duration=20.0)
    assert bench_team.write_scenario(document, tmp_path / 'rt.yaml').duration == 20.0


def test_cpu_ticks_parsed_after_an_awkward_command_name():
    # proc(5) fields 14 and 15 (utime, stime) after a name holding spaces and parentheses.
    fields_after_name = ['S', '1', '2', '3', '0', '-1', '4194560', '10', '0', '0', '0',
                         '250', '17', '0', '0', '20', '0', '1', '0', '100']
    stat_text = '4242 (a) b (c)) ' + ' '.join(fields_after_name) + '\n'
    assert bench_team.parse_cpu_ticks(stat_text) == 250 + 17


def test_peak_rss_absent_for_a_zombie():
    status_text = 'Name:\tplanner\nState:\tZ (zombie)\nThreads:\t1\n'
    assert bench_team.parse_peak_rss_kib(status_text) is None


def test_own_cpu_time_matches_os_times():
    deadline = time.process_time() + 0.2
    while time.process_time() < deadline:
        pass
    before = os.times()
    measured = bench_team.cpu_seconds(os.getpid())
    after = os.times()
    # Both count whole clock ticks of every thread; allow one tick of drift per side.
    tick = 1.0 / bench_team.CLOCK_TICKS_PER_SECOND
    assert before.user + before.system - tick <= measured <= after.user + after.system + tick


def test_own_peak_rss_matches_getrusage():
    measured = bench_team.peak_rss_kib(os.getpid())
    # ru_maxrss is in KiB on Linux; nothing between the two reads allocates megabytes.
    assert abs(measured - resource.getrusage(resource.RUSAGE_SELF).ru_maxrss) <= 1024


def test_a_gone_process_reads_as_none():
    child = subprocess.run([sys.executable, '-c', 'import os; print(os.getpid())'],
                           capture_output=True, text=True, check=True)
    pid = int(child.stdout)
    assert bench_team.cpu_seconds(pid) is None
    assert bench_team.peak_rss_kib(pid) is None


def sim_status_message(step, deadline_misses=0):
    from prvo_msgs_util import make_diagnostic_array, make_diagnostic_status

    return make_diagnostic_array(step * 0.1, [
        make_diagnostic_status('prvo_planner/robot_0', 'ok', {'plan_time_ms': 1.0}),
        make_diagnostic_status('prvo_sim', 'running', {
            'sim_time': step * 0.1, 'step': step, 'finished': False, 'contacts': 0,
            'deadline_misses': deadline_misses, 'mode': 'realtime'})])


def test_monitor_counts_new_steps_and_this_process_cpu():
    monitor = bench_team.TeamMonitor()
    # This process stands in for a child: its CPU time and RSS are real.
    monitor.pids = {'planner_robot_0': os.getpid()}
    window_start = time.monotonic()
    for step in (0, 0, 1, 1, 2):
        monitor._on_diagnostics(sim_status_message(step))
    deadline = time.process_time() + 0.2
    while time.process_time() < deadline:
        pass
    for step in (3, 4, 5, 5):
        monitor._on_diagnostics(sim_status_message(step, deadline_misses=2))
    monitor.ending(None, None)
    window = time.monotonic() - window_start
    steps, wall = monitor.stepping()
    assert steps == 4 and wall > 0.0
    cpu_fraction, ms_per_step, rss_mib = monitor.process_use('planner_robot_0')
    # The monitor's window lies inside this one, in which at least 0.2 s of CPU was burnt,
    # less a clock tick (10 ms) at each end of the window, as /proc counts whole ticks: however
    # loaded the machine, the fraction is at least that share.
    assert (0.2 - 0.02) / window <= cpu_fraction <= 1.1
    # At least the 0.2 s burnt over the 4 steps, give or take those two ticks.
    assert ms_per_step >= (200.0 - 20.0) / 4
    assert rss_mib * 1024 == pytest.approx(bench_team.peak_rss_kib(os.getpid()), abs=1024)
    assert monitor.sim_status.deadline_misses == 2 and monitor.sim_status.step == 5


def test_miss_rate_is_per_robot_step():
    assert bench_team.deadline_miss_rate(4, 200, 8) == pytest.approx(0.0025)
    assert bench_team.deadline_miss_rate(0, 0, 8) is None


def test_table_has_one_row_per_team_and_marks_missing_values():
    row = {'robots': 8, 'lockstep_wall_s': 41.23, 'sim_s': 17.3, 'steps_per_s': 6.5,
           'all_arrived': True, 'collisions': 0, 'planner_cpu_pct_mean': 40.0,
           'planner_cpu_pct_max': 45.5, 'planner_cpu_ms_per_step': 60.2,
           'planner_rss_mib_mean': 140.2, 'planner_rss_mib_max': 141.0, 'sim_cpu_pct': 20.0,
           'sim_rss_mib': 80.0, 'realtime_miss_rate_pct': None}
    lines = bench_team.format_table([row, {'robots': 16}]).splitlines()
    assert len(lines) == 4
    cells = [[cell.strip() for cell in line.strip('|').split('|')] for line in lines[2:]]
    assert cells[0] == ['8', '41.2', '17.3', '6.50', 'yes', '0', '40.0/45.5', '60.2', '140/141',
                        '20.0', '80', 'n/a']
    assert cells[1][0] == '16'
    assert all(cell in ('n/a', 'n/a/n/a') for cell in cells[1][1:])

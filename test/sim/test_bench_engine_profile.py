"""The engine benchmark's profile: a robot-step's phases, against hand-made and real stats."""

import dataclasses

import pytest

from prvo_sim.bench.engine import PHASES, phase_times, profiled_team
from prvo_sim.scenario import find_scenario, load_scenario

ENGINE = '/src/prvo_sim/prvo_sim/engine.py'
AGENT = '/src/prvo_planner/prvo_planner/agent.py'
PLANNER = '/src/prvo_planner/prvo_planner/core/planner.py'


class HandMadeStats:
    """What `pstats.Stats` holds: {(file, line, name): (cc, nc, tt, ct, {caller: (..., ct)})}."""

    def __init__(self, entries):
        self.stats = entries


def entry(cumulative, callers=None):
    return (1, 1, 0.0, cumulative, {caller: (1, 1, 0.0, time) for caller, time in
                                    (callers or {}).items()})


def test_each_phase_counts_what_the_step_calls_and_the_rest_is_other():
    step = (ENGINE, 273, 'do_step')
    listcomp = (ENGINE, 296, '<listcomp>')
    request = (AGENT, 1207, 'plan_request')
    stats = HandMadeStats({
        step: entry(10.0),
        listcomp: entry(3.0, {step: 3.0}),
        # The team's plan (4 s) from the step; 1 s more from a request, which is the request's.
        (PLANNER, 135, 'plan_velocities'): entry(5.0, {step: 4.0, request: 1.0}),
        request: entry(3.0, {listcomp: 3.0}),
        (AGENT, 706, 'receive_own'): entry(0.5, {step: 0.5}),
        # Announced once at start-up too, from the constructor: not a step's.
        (ENGINE, 205, '_announce'): entry(0.3, {step: 0.2, (ENGINE, 135, '__init__'): 0.1}),
    })
    times = phase_times(stats, robot_steps=2)
    assert times['step_ms'] == pytest.approx(5000.0)
    assert times['core_ms'] == pytest.approx(2000.0)
    assert times['requests_ms'] == pytest.approx(1500.0)
    assert times['own_odometry_ms'] == pytest.approx(250.0)
    assert times['announcements_ms'] == pytest.approx(100.0)
    assert times['messages_ms'] == 0.0
    assert times['kernels_ms'] == 0.0
    assert times['other_ms'] == pytest.approx(5000.0 - 2000.0 - 1500.0 - 250.0 - 100.0)


def test_a_profiled_run_has_every_phase_within_its_step():
    scenario = dataclasses.replace(load_scenario(find_scenario('headon2')), duration=2.0)
    row = profiled_team(scenario)
    assert row['robots'] == 2 and row['robot_steps'] == 2 * 20
    phases = [row[key] for key, _ in PHASES]
    assert min(phases) >= 0.0 and row['core_ms'] > 0.0 and row['requests_ms'] > 0.0
    # Each phase is called by the step and none calls another: together within the step (the
    # rounding of each to the microsecond aside).
    assert sum(phases) <= row['step_ms'] + 1e-3 * len(phases)
    assert row['other_ms'] >= -1e-3 * len(phases)
    # The compiled kernels run within the plans: the team's, and a request's.
    assert 0.0 < row['kernels_ms'] <= row['core_ms'] + row['requests_ms'] + 1e-3

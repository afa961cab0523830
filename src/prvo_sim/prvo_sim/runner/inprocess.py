"""One run on the in-process engine: the same world and agents as the ROS lockstep run, no DDS.

The run ends as a ROS run does (every robot arrived and stayed, the scenario's duration, the
wall-clock limit) and writes the same results; there are no children, logs or domain. The
wall-clock limit holds also within a step that does not end: a timer signal interrupts it.
"""

import contextlib
import signal
import time

import numpy as np

from prvo_sim.engine import InProcessTeam
from prvo_sim.runner.bag import TeamMessages
from prvo_sim.runner.outputs import Ending, Recording, RunResult, write_outputs
from prvo_sim.runner.processes import INTERRUPTS, RunInterruptedError, untranslated
from prvo_sim.runner.session import (
    PROGRESS_PERIOD,
    ArrivalRule,
    ProgressLine,
    planner_values,
)
from prvo_sim.turns import Turns


class _TimedOutError(Exception):
    """The run's wall-clock limit passed."""


def _time_out(_signum, _frame):
    raise _TimedOutError


@contextlib.contextmanager
def wall_clock_limit(seconds):
    """Raise _TimedOutError in the block once SECONDS of wall time have passed (SIGALRM)."""
    previous = signal.signal(signal.SIGALRM, _time_out)
    signal.setitimer(signal.ITIMER_REAL, seconds)
    try:
        yield
    finally:
        signal.setitimer(signal.ITIMER_REAL, 0.0)
        signal.signal(signal.SIGALRM, previous)


def run_inprocess(spec):
    """Run SPEC once on the in-process engine; write its outputs; return its `RunResult`."""
    scenario = spec.scenario
    values = [planner_values(robot, scenario, spec.method, spec.planner_eta, 'lockstep')
              for robot in scenario.robots]
    team = InProcessTeam(scenario, values, seed=spec.seed)
    # The messages the ROS run would publish, for the run's bag.
    messages = (TeamMessages([robot.name for robot in scenario.robots], values, team)
                if spec.bag else None)
    steps = []
    ending, failure, interrupted = Ending.FAILED, None, None
    progress = ProgressLine(spec, quiet=spec.quiet)
    started = time.monotonic()
    try:
        # The engine deserializes messages, as a subscriber would: a signal's exception
        # raised in rclpy's conversion keeps its own type.
        with wall_clock_limit(spec.timeout), untranslated(RunInterruptedError, _TimedOutError):
            ending = run_steps(spec, team, messages, steps, progress)
    except _TimedOutError:
        failure = f'timed out after {spec.timeout:g} s of wall time'
    except RunInterruptedError as interruption:
        ending, interrupted = Ending.INTERRUPTED, interruption.signum
        failure = f'interrupted by {interruption}'
    with INTERRUPTS.teardown() as teardown:
        progress.finish()
        wall_time = time.monotonic() - started
        recording = recording_of(team, steps, messages) if steps else None
        spec.out_dir.mkdir(parents=True, exist_ok=True)
        run_metrics = write_outputs(spec, recording, ending, failure, wall_time)
        if interrupted is None:
            interrupted = teardown.last_signal
    return RunResult(ending, run_metrics, interrupted)


def recording_of(team, steps, messages=None):
    """Return the `Recording` of TEAM's STEPS (`engine.StepRecord`s, at least one).

    MESSAGES: the run's `TeamMessages` for its bag, None: no bag.
    """
    return Recording(
        np.array([step.time for step in steps]),
        np.array([step.states for step in steps]),
        np.array([step.commands for step in steps]),
        tuple(np.concatenate([step.plan_ms for step in steps]).tolist()),
        deadline_misses=0, yaws=np.array([step.yaws for step in steps]),
        bag_messages=None if messages is None else messages.bag_messages,
        plan_tallies={robot: (tally.plans, tally.infeasible, tally.min_achieved_eta)
                      for robot, tally in team.plan_tallies().items() if tally.plans},
        turns=Turns(np.array([step.turns for step in steps]),
                    np.array([step.turn_passages for step in steps]),
                    tuple(team.turn_book.shapes)))


def run_steps(spec, team, messages, steps, progress):
    """Step TEAM, appending each step to STEPS, until the run ends; return its `Ending`."""
    rule = ArrivalRule.of(spec.scenario)
    started = time.monotonic()
    next_progress = started
    while True:
        # The state at the duration is recorded with the plans that answer it, as on the ROS
        # engine, and the world is not moved past it.
        final = team.finished
        if messages is not None:
            messages.add_state()
        step = team.do_step(advance=not final)
        steps.append(step)
        if messages is not None:
            messages.add_step(step)
        ends = rule.step(step.time, step.states[:, :2])
        now = time.monotonic()
        if now >= next_progress:
            progress(step.time, rule.arrived_count, now - started)
            next_progress = now + PROGRESS_PERIOD
        if ends:
            return Ending.ARRIVED
        if final:
            return Ending.DURATION

"""When the simulator steps, counts deadline misses and stops silent robots, without ROS."""

import pytest

from prvo_sim.step_timing import REPUBLISH, REPUBLISH_PERIOD, STEP, StepTiming

# Three robots; robot 1 is scripted: nothing waits for it and it misses no deadline.
PLANNED = [0, 2]


def started_timing(realtime=False):
    """Return a timing started at t=0: step_timeout 1 s, cmd_timeout 0.5 s, startup 10 s."""
    timing = StepTiming(3, PLANNED, realtime, step_timeout=1.0, cmd_timeout=0.5,
                        startup_timeout=10.0, now=0.0)
    timing.start(0.0)
    return timing


def test_a_step_waits_for_every_planned_robot_and_no_scripted_one():
    timing = started_timing()
    timing.step_published(0.0)
    timing.command_received(0, True, 0.1)
    assert timing.due(0.2, first_step=False) is None
    # An answer to an earlier step counts as a command, not as this step's answer.
    timing.command_received(2, False, 0.3)
    assert timing.due(0.4, first_step=False) is None
    timing.command_received(2, True, 0.5)
    assert timing.due(0.6, first_step=False) == STEP
    assert timing.close_step(0.6) == ([], [])
    assert timing.deadline_misses == [0, 0, 0]


def test_the_first_step_resends_t0_until_the_startup_timeout():
    timing = started_timing()
    due = {round(0.1 * tick, 1): timing.due(0.1 * tick, first_step=True)
           for tick in range(1, 101)}
    # Every REPUBLISH_PERIOD, counted from the start, until the startup timeout steps.
    resent = [now for now, what in due.items() if what == REPUBLISH]
    assert resent == pytest.approx([REPUBLISH_PERIOD * n for n in range(1, 20)])
    assert due[10.0] == STEP and [now for now, what in due.items() if what == STEP] == [10.0]
    # Only the first step waits so long: a later one steps after step_timeout.
    assert timing.due(1.0, first_step=False) == STEP
    assert timing.due(0.9, first_step=False) is None


def test_republishing_before_the_start_is_due_once_a_period():
    timing = StepTiming(1, [0], False, 1.0, 0.5, 10.0, now=5.0)
    assert [timing.republish_due(now) for now in (5.2, 5.5, 5.6, 6.0)] == [
        False, True, False, True]


def test_late_robots_miss_deadlines_and_a_lockstep_silence_counts_from_the_first_miss():
    timing = started_timing()
    timing.command_received(0, True, 0.0)
    timing.command_received(2, True, 0.0)
    timing.close_step(0.0)
    timing.step_published(0.0)
    # Robot 0 answers, robot 2 does not: its first miss at t=1.
    timing.command_received(0, True, 0.5)
    assert timing.due(1.0, first_step=False) == STEP
    assert timing.close_step(1.0) == ([2], [])
    timing.step_published(1.0)
    timing.command_received(0, True, 1.2)
    # At t=1.4 robot 2 is 0.4 s past its first miss (cmd_timeout 0.5): not yet stopped.
    assert timing.close_step(1.4) == ([2], [])
    timing.step_published(1.4)
    timing.command_received(0, True, 1.5)
    late, stopped = timing.close_step(1.6)
    assert late == [2]
    # 0.6 s past its first miss; the silence reported is since its last command (t=0).
    assert stopped == [(2, pytest.approx(1.6))]
    assert timing.deadline_misses == [0, 0, 3]
    timing.step_published(1.6)
    timing.command_received(0, True, 1.7)
    # Stopped once: a further miss does not report it again.
    assert timing.close_step(2.7) == ([2], [])
    # Its next command counts again, and its silence starts anew at the next miss.
    timing.step_published(2.7)
    timing.command_received(0, True, 2.8)
    timing.command_received(2, True, 2.8)
    assert timing.due(2.8, first_step=False) == STEP
    assert timing.close_step(2.8) == ([], [])
    timing.step_published(2.8)
    timing.command_received(0, True, 2.9)
    assert timing.close_step(3.0) == ([2], [])
    assert timing.deadline_misses == [0, 0, 5]


def test_a_realtime_silence_counts_from_the_last_command():
    timing = started_timing(realtime=True)
    timing.command_received(0, True, 0.0)
    timing.command_received(2, True, 0.8)
    timing.step_published(0.9)
    # Robot 0 was last heard 1.0 s ago (> cmd_timeout) although it missed no deadline before.
    late, stopped = timing.close_step(1.0)
    assert late == [0, 2]
    assert stopped == [(0, pytest.approx(1.0))]


def test_a_robot_never_heard_from_is_not_stopped():
    # It executes zero already; nothing is to be said of a silence that never began.
    timing = started_timing()
    assert timing.close_step(100.0) == ([0, 2], [])


def test_timeouts_changed_while_running_apply_at_once():
    timing = started_timing()
    timing.step_published(0.0)
    assert timing.due(1.5, first_step=False) == STEP
    timing.step_timeout = 2.0
    assert timing.due(1.5, first_step=False) is None


def test_the_deadline_miss_message_says_what_each_late_robot_executes():
    names = ['robot_0', 'walker', 'robot_2']
    timing = started_timing(realtime=True)
    timing.command_received(0, True, 0.0)
    timing.command_received(2, True, 0.0)
    timing.close_step(0.1)
    timing.step_published(0.1)
    # Robot 2 keeps answering late; robot 0 falls silent for longer than cmd_timeout (0.5 s).
    timing.command_received(2, False, 0.55)
    late, stopped = timing.close_step(0.6)
    assert late == [0, 2] and stopped == [(0, pytest.approx(0.6))]
    assert timing.deadline_miss_message(late, names, 12.3) == (
        'deadline miss at t=12.300: no cmd_vel from robot_2: reusing the last command (within '
        'cmd_timeout 0.5 s); robot_0: executing zero velocity (past cmd_timeout 0.5 s)')
    # Once robot 0 is heard again, it reuses its new command when late.
    timing.step_published(0.6)
    timing.command_received(0, False, 0.65)
    late, _ = timing.close_step(0.7)
    assert timing.deadline_miss_message(late, names, 12.4).endswith(
        'no cmd_vel from robot_0, robot_2: reusing the last command (within cmd_timeout 0.5 s)')


def test_a_robot_never_heard_from_is_said_to_execute_zero():
    timing = started_timing()
    late, _ = timing.close_step(100.0)
    assert timing.deadline_miss_message(late, ['a', 'b', 'c'], 0.1) == (
        'deadline miss at t=0.100: no cmd_vel from a, c: executing zero velocity (no command '
        'yet)')

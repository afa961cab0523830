"""A ROS run ends at the step the end-of-run rule names on its whole recording.

The runner looks at the recording every 50 ms of wall time; on a loaded machine several steps
arrive between two looks, and one robot's ground truth lags another's. The rule must still see
every step, in order: a look at the newest positions alone ends a run at a step where a robot
that had left its goal in between seemed to have stayed (seen in CI: a ROS run of
nav2_path_crossing4 ended 1.5 s before the in-process run of the same team).
"""

import types

import numpy as np

from prvo_sim.runner.outputs import Ending
from prvo_sim.runner.session import RecordedSteps, wait_for_end

GOALS = np.array([[0.0, 0.0], [5.0, 0.0]])
TOLERANCE = 0.2
DT_NS = 100_000_000


def positions_at(step):
    """Robot 0 arrives at step 10, is pushed off its goal at step 16 only, back from 17 on."""
    away = np.array([1.0, 0.0]) if step < 10 or step == 16 else np.zeros(2)
    return GOALS + np.array([away, [0.0, 0.0]])


def ground_truth_until(steps_of_robot):
    """Return {robot: {stamp ns: (x, y, vx, vy, yaw)}} with STEPS_OF_ROBOT[robot] steps each."""
    return {f'robot_{robot}': {step * DT_NS: (*positions_at(step)[robot], 0.0, 0.0, 0.0)
                               for step in range(count)}
            for robot, count in enumerate(steps_of_robot)}


def first_end_by_hand():
    """Return the end by the rule's definition: 1 s after both are home and stay, in steps."""
    since = None
    for step in range(100):
        home = np.linalg.norm(positions_at(step) - GOALS, axis=1) <= TOLERANCE
        since = (since if since is not None else step) if home.all() else None
        if since is not None and step - since >= 10:
            return step * DT_NS * 1e-9
    return None


class LaggingRecorder:
    """A recorder whose every look finds seven more steps of robot 0, robot 1 three behind."""

    def __init__(self):
        self.looks = 0
        self.sim_status = None
        self.lost = None

    def spin_for(self, _duration):
        self.looks += 1

    @property
    def ground_truth(self):
        newest = 7 * self.looks
        return ground_truth_until([newest, max(newest - 3, 0)])


def test_completed_steps_come_once_each_in_order_and_only_when_final():
    steps = RecordedSteps(['robot_0', 'robot_1'])
    given = []
    truth = ground_truth_until([5, 3])
    del truth['robot_1'][DT_NS]  # robot 1's step 1 was lost
    given += [round(time / 0.1) for time, _ in steps.completed(truth)]
    assert given == [0, 2]
    truth = ground_truth_until([9, 8])
    del truth['robot_1'][DT_NS]
    given += [round(time / 0.1) for time, _ in steps.completed(truth)]
    assert given == [0, 2, 3, 4, 5, 6, 7]
    later = [(round(time / 0.1), positions) for time, positions in steps.completed(truth)]
    assert later == []


def test_a_ros_run_ends_where_the_rule_ends_its_whole_recording():
    expected = first_end_by_hand()
    assert expected is not None and expected > 1.7  # not before robot 0's return at 1.7 s
    spec = types.SimpleNamespace(scenario=types.SimpleNamespace(
        goal_tolerance=TOLERANCE, robots=[
            types.SimpleNamespace(name=f'robot_{robot}', goal=GOALS[robot], scripted=None)
            for robot in range(2)]))
    watch = types.SimpleNamespace(failure=lambda: None)
    ending, end_time = wait_for_end(LaggingRecorder(), watch, spec, lambda *_: None)
    assert ending is Ending.ARRIVED
    assert abs(end_time - expected) < 1e-9

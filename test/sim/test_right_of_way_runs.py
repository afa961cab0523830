"""Right of way in a run: two robots meet at a door one robot wide and take turns (issue 39).

A 1.2 m door between two rooms, one robot each way (noise 0.05, the planner's defaults,
certified 0.95, `right_of_way` on). Each robot decides from its neighbour's route on
<robot>/plan (held by the agents as a ROS run holds it): one goes through while the other waits
beside its entrance, and no robot's decision ever lets both be in the door going opposite ways.
"""

import numpy as np
import pytest

from prvo_sim.engine import InProcessTeam
from prvo_sim.runner.session import planner_values
from prvo_sim.scenario import load_scenario

DOOR = """name: door_turns
seed: 1
dt: 0.1
duration: 40.0
goal_tolerance: 0.2
noise:
  position_std: 0.05
  velocity_std: 0.05
  actuation_std: 0.05
walls:
  - line: [[-4.05, 2.05], [4.05, 2.05]]
    thickness: 0.1
  - line: [[-4.05, -2.05], [4.05, -2.05]]
    thickness: 0.1
  - line: [[-4.05, -2.05], [-4.05, 2.05]]
    thickness: 0.1
  - line: [[4.05, -2.05], [4.05, 2.05]]
    thickness: 0.1
  - line: [[0.0, 2.0], [0.0, 0.65]]
    thickness: 0.1
  - line: [[0.0, -2.0], [0.0, -0.65]]
    thickness: 0.1
robots:
  - {name: eastbound, start: [-2.5, 0.3], goal: [2.5, -0.3], radius: 0.25, max_speed: 1.0}
  - {name: westbound, start: [2.5, -0.3], goal: [-2.5, 0.3], radius: 0.25, max_speed: 1.0}
"""


@pytest.mark.parametrize('seed', [1, 2])
def test_two_robots_meeting_at_a_door_take_turns_and_both_arrive(tmp_path, seed):
    path = tmp_path / 'door.yaml'
    path.write_text(DOOR)
    scenario = load_scenario(path, seed=seed)
    values = [{**planner_values(robot, scenario, 'prvo', None), 'right_of_way': True}
              for robot in scenario.robots]
    team = InProcessTeam(scenario, values, seed=seed)
    goals = np.array([robot.goal for robot in scenario.robots])
    arrived = [None, None]
    waited = [0, 0]
    closest = np.inf
    while not team.finished and None in arrived:
        step = team.do_step()
        decisions = [agent.passage_decision for agent in team.agents]
        going = [decision is not None and decision.goes for decision in decisions]
        for index, decision in enumerate(decisions):
            if decision is not None and not decision.goes:
                waited[index] += 1
        # Both going at once only when both may: never head-on through the door.
        assert not all(going) or not any(
            decision.use.entry is None for decision in decisions), step.time
        positions = step.states[:, :2]
        closest = min(closest, float(np.hypot(*(positions[0] - positions[1]))) - 0.5)
        for index, distance in enumerate(np.hypot(*(positions - goals).T)):
            if arrived[index] is None and distance < scenario.goal_tolerance:
                arrived[index] = step.time
    assert None not in arrived, arrived
    assert closest > 0.0
    # Turns were taken: one of them waited, and it arrived after the other.
    (waiter,) = [index for index in range(2) if waited[index] > 0]
    assert arrived[waiter] > arrived[1 - waiter]

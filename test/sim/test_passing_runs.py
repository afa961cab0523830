"""Pass beside in a run: a robot goes round one standing at its goal, into a corridor's pocket.

A 2.4 m corridor closed at its west end: three robots stand at their goals, two 1.1 m apart
across it at 4.2 m from the end and one behind the lower, and a fourth comes along the upper
row to the goal behind the upper one (noise 0.05, the planner's defaults, certified 0.95). The
standing robot steps toward its wall (`give_way`); the passer aims beside it on the open side
(`passing`) and arrives in 10.8-11.4 s at seeds 1, 4 and 8 (12.1 s on average over seeds
1-12, each sooner). Following its route straight at the standing robot it took 12.1, 19.5 and
13.7 s (13.7 s on average). Only preferences change: a Monte Carlo check with a sampler of its
own finds every encounter plan safe within its horizon with at least eta.
"""

import numpy as np
import pytest
from sampled_safety import EncounterChecker

from prvo_sim.engine import InProcessTeam
from prvo_sim.runner.session import planner_values
from prvo_sim.scenario import load_scenario

POCKET = """name: pocket
seed: 1
dt: 0.1
duration: 30.0
goal_tolerance: 0.2
noise:
  position_std: 0.05
  velocity_std: 0.05
  actuation_std: 0.05
walls:
  - line: [[-6.05, 1.25], [3.0, 1.25]]
    thickness: 0.1
  - line: [[-6.05, -1.25], [3.0, -1.25]]
    thickness: 0.1
  - line: [[-6.05, -1.25], [-6.05, 1.25]]
    thickness: 0.1
robots:
  - {name: front_left, start: [-4.2, 0.55], goal: [-4.2, 0.55], radius: 0.3, max_speed: 1.0}
  - {name: front_right, start: [-4.2, -0.55], goal: [-4.2, -0.55], radius: 0.3, max_speed: 1.0}
  - {name: back_right, start: [-5.3, -0.55], goal: [-5.3, -0.55], radius: 0.3, max_speed: 1.0}
  - {name: passing, start: [1.5, 0.55], goal: [-5.3, 0.55], radius: 0.3, max_speed: 1.0}
"""
PASSING = 3
# The passer's straight way is 6.8 m, at 1 m/s.
ARRIVES_WITHIN = 13.0


def run(tmp_path, seed, on_step=None):
    """Return (the first time [s] the passer was at its goal, None: never; the team)."""
    path = tmp_path / 'pocket.yaml'
    path.write_text(POCKET)
    scenario = load_scenario(path, seed=seed)
    values = [planner_values(robot, scenario, 'prvo', None) for robot in scenario.robots]
    team = InProcessTeam(scenario, values, seed=seed)
    goal = np.array(scenario.robots[PASSING].goal)
    arrived = None
    while not team.finished:
        step = team.do_step()
        if on_step is not None:
            on_step(team, step.states)
        if arrived is None and np.hypot(*(step.states[PASSING, :2] - goal)) < (
                scenario.goal_tolerance):
            arrived = step.time
        if arrived is not None and all(command.arrived for command in team.last_commands):
            break
    return arrived, team


@pytest.fixture(scope='module')
def checked_seed_1(tmp_path_factory):
    """Return (arrived, team, checker) of seed 1's run, every plan sampled."""
    checker = EncounterChecker(np.random.default_rng(41))
    arrived, team = run(tmp_path_factory.mktemp('passing'), 1, checker.check)
    return arrived, team, checker


@pytest.mark.parametrize('seed', [1, 4, 8])
def test_the_passer_goes_round_the_standing_robot_and_arrives(request, tmp_path, seed):
    if seed == 1:
        arrived, team, _ = request.getfixturevalue('checked_seed_1')
    else:
        arrived, team = run(tmp_path, seed)
    assert arrived is not None and arrived <= ARRIVES_WITHIN
    assert all(command.arrived for command in team.last_commands)


def test_every_encounter_plan_going_round_keeps_its_probability(checked_seed_1):
    arrived, _, checker = checked_seed_1
    assert arrived is not None
    checker.assert_safe(at_least=100)

"""A lockstep run waits for every answer however slow the machine, and its waits nest.

Two 24-robot ROS runs started together beside busy processes: discovery among 50 planners took
longer than the 5 s a planner used to wait for its listed neighbours, three planners made their
first plan without some of them, and one run parted from the in-process run at its first step.
The planner waits (for its listed neighbours, for same-stamp odometry) must be long, and end
before the simulator's waits for the plans do, so that a plan made after a long wait still
answers its step.
"""

import numpy as np

from prvo_msgs_util import OdometryMeasurement
from prvo_sim.engine import agent_of
from prvo_sim.runner.session import planner_values, sim_parameters
from prvo_sim.scenario import find_scenario, load_scenario

HEARD_LATE = 20.0  # wall seconds after the first own odometry a neighbour is first heard
PLAN_MARGIN = 1.0  # wall seconds a plan may take once its wait is over


def measurement_of(robot):
    """Return ROBOT's t_0 measurement: at its start, standing, 5 cm std."""
    return OdometryMeasurement(0.0, 'map', f'{robot.name}/base_link',
                               np.asarray(robot.start, dtype=float), np.zeros(2),
                               np.diag([0.0025] * 4), 0.0)


def test_a_lockstep_planner_plans_its_first_step_with_a_neighbour_heard_late():
    scenario = load_scenario(find_scenario('circle8'))
    own, *others = scenario.robots
    agent = agent_of(own.name, planner_values(own, scenario, 'prvo', None))
    agent.receive_own(measurement_of(own), 0.0)
    # The nearest neighbour is the one heard late: it surely counts in the plan.
    others.sort(key=lambda robot: np.hypot(*np.subtract(robot.start, own.start)))
    late = others[0]
    for robot in others[1:]:
        agent.receive_neighbour(robot.name, measurement_of(robot), 0.0)
        agent.receive_footprint(robot.name, robot.radius, 0.0)
        agent.receive_share(robot.name, 0.5, 0.0)
    # Still waiting for the late neighbour, though every other one is in.
    assert agent.awaiting_listed(HEARD_LATE) and not agent.ready(HEARD_LATE)
    agent.receive_neighbour(late.name, measurement_of(late), HEARD_LATE)
    agent.receive_footprint(late.name, late.radius, 0.0)
    agent.receive_share(late.name, 0.5, 0.0)
    assert agent.ready(HEARD_LATE)
    command = agent.plan()
    assert late.name in command.neighbour_names


def test_the_planners_waits_end_before_the_simulators():
    scenario = load_scenario(find_scenario('circle8'))
    values = planner_values(scenario.robots[0], scenario, 'prvo', None)
    sim = sim_parameters(scenario, 'lockstep', scenario.seed)
    # The first step: the simulator waits for the plan made once the listed neighbours are in.
    assert float(sim['startup_timeout']) >= values['neighbor_timeout'] + PLAN_MARGIN
    # Every later step: it waits for the plan made once same-stamp odometry is in.
    assert float(sim['step_timeout']) >= values['sync_timeout'] + PLAN_MARGIN
    assert values['sync_timeout'] >= HEARD_LATE and values['neighbor_timeout'] >= HEARD_LATE

"""The team loop in one process: the scenario's world and one planner agent per robot, no DDS.

`InProcessTeam` is the ROS lockstep run without processes. Each `do_step` gives every agent
the odometry of the current state exactly as a planner node reads it (the simulator's
serialized message, decoded by the planner's decoder), lets every agent plan, turns each
command into the world frame exactly as the simulator does (body frame and back), and then
moves the world by one dt. Same code, same numbers: for a scenario and a seed the trajectories
equal the ROS lockstep run's.

    team = InProcessTeam(scenario, planner_values)
    while not team.finished:
        team.do_step()
"""

from dataclasses import dataclass
import time

import numpy as np

from prvo_msgs_util import (
    WORLD_FRAME,
    body_to_world,
    serialized_odometry_to_measurement,
    world_to_body,
)
from prvo_planner.agent import AgentSettings, PlannerAgent
from prvo_planner.core import plan_velocities
from prvo_planner.parameters import planner_config_from
from prvo_sim.world import TeamWorld
from prvo_sim.world_messages import serialized_odometry


@dataclass(frozen=True)
class StepRecord:
    """One step of a team: the state at `time` and the commands that answered it.

    `states` (N, 4) is every robot's ground truth [x, y, vx, vy] as a recorder reads it;
    `commands` (N, 2) the world-frame velocities commanded for the next dt; `plan_ms` (N,)
    each robot's share of the team's planning time [ms of wall time]; `contacts` the
    `world.Contact`s the step made; `feasible` (N,) whether each robot's command met every
    constraint (True for a robot standing still).
    """

    time: float
    states: np.ndarray
    commands: np.ndarray
    plan_ms: np.ndarray
    contacts: tuple
    feasible: np.ndarray


def agent_of(name, values):
    """Return the PlannerAgent that a planner node with parameter VALUES would run for NAME."""
    return PlannerAgent(name, planner_config_from(values), AgentSettings.from_parameters(values),
                        values['goal'], values['neighbors'])


class InProcessTeam:
    """A scenario's robots, each planned by its own agent, stepped in lockstep in one process.

    Parameters
    ----------
    scenario : prvo_sim.scenario.Scenario
        The world: robots, noise, dt, duration.
    planner_values : sequence of mapping
        Per robot, in the scenario's order, the complete planner parameters its node would
        have (`prvo_planner.parameters`; the runner's `planner_values`).
    seed : int or None
        Noise seed; None uses the scenario's.

    """

    def __init__(self, scenario, planner_values, seed=None):
        if len(planner_values) != len(scenario.robots):
            raise ValueError(f'planner_values has {len(planner_values)} entries for '
                             f'{len(scenario.robots)} robots')
        self.world = TeamWorld(scenario, seed)
        self.agents = [agent_of(robot.name, values)
                       for robot, values in zip(scenario.robots, planner_values, strict=True)]

    @property
    def finished(self):
        """Whether the scenario's duration has been reached."""
        return self.world.finished

    def observe(self):
        """Return (odometry measurements, ground-truth states (N, 4)) of the current state."""
        messages = serialized_odometry(self.world)
        measurements = [serialized_odometry_to_measurement(odometry, expected_frame=WORLD_FRAME)
                        for odometry, _ in messages]
        truths = [serialized_odometry_to_measurement(truth, expected_frame=WORLD_FRAME)
                  for _, truth in messages]
        states = np.array([[*truth.position, *truth.velocity] for truth in truths])
        return measurements, states

    def do_step(self):
        """Plan every robot on the current state, then move the world by one dt.

        Returns the `StepRecord` of the state planned on.
        """
        world = self.world
        now = world.time
        measurements, states = self.observe()
        names = world.names
        for index, agent in enumerate(self.agents):
            agent.receive_own(measurements[index], now)
            for other, measurement in enumerate(measurements):
                if other != index:
                    agent.receive_neighbour(names[other], measurement, now)
        started = time.perf_counter()
        requests = [agent.plan_request() for agent in self.agents]
        moving = [index for index, request in enumerate(requests) if request.problem is not None]
        results = [None] * len(requests)
        if moving:
            problems = [requests[index].problem for index in moving]
            solved = plan_velocities(*(list(column) for column in zip(*problems, strict=True)))
            for index, result in zip(moving, solved, strict=True):
                results[index] = result
        yaws = world.yaws_at(world.step_count)
        commands = np.empty((len(self.agents), 2))
        for index, agent in enumerate(self.agents):
            command = agent.complete(requests[index], results[index])
            # The node publishes in the body frame; the simulator turns it back by the heading
            # at the command's stamp.
            commands[index] = body_to_world(world_to_body(command.velocity, command.yaw),
                                            yaws[index])
        # One call plans the team: each robot is charged an equal share of it.
        plan_ms = np.full(len(self.agents), (time.perf_counter() - started) * 1e3
                          / len(self.agents))
        contacts = world.step(commands)
        feasible = np.array([result is None or result.feasible for result in results])
        return StepRecord(time=now, states=states, commands=commands, plan_ms=plan_ms,
                          contacts=tuple(contacts), feasible=feasible)

"""The team loop in one process: the scenario's world and one planner agent per robot, no DDS.

`InProcessTeam` is the ROS lockstep run without processes. Each `do_step` gives every agent
the odometry of the current state exactly as a planner node reads it (the simulator's
serialized message, decoded by the planner's decoder), lets every agent plan, gives every
agent what the others announced and published of their routes after their plans (through the
messages, stamped as the nodes stamp them), turns each command into the world frame exactly as
the simulator does (body frame and back), and then moves the world by one dt. Same code, same
numbers: for a scenario and a seed the trajectories equal the ROS lockstep run's.

    team = InProcessTeam(scenario, planner_values)
    while not team.finished:
        team.do_step()
"""

from dataclasses import dataclass
import time

import numpy as np
from rclpy.serialization import deserialize_message, serialize_message

from prvo_msgs_util import (
    MAP,
    WORLD_FRAME,
    AnnouncementChanges,
    announcement_stamp,
    body_to_world,
    make_occupancy_grid,
    make_path,
    occupancy_grid_to_parts,
    radius_of_footprint,
    serialized_odometry_to_measurement,
    serialized_path_to_waypoints,
    serialized_route,
    share_of,
    world_to_body,
)
from prvo_planner.agent import (
    ANNOUNCED_FROM_THE_START,
    DEPARTURE_TOLERANCES,
    UNANNOUNCED_SHARE,
    AgentSettings,
    NeighbourAnnouncement,
    PlannerAgent,
)
from prvo_planner.core import plan_velocities
from prvo_planner.heap import keep_freed_heap
from prvo_planner.maps import GridMap
from prvo_planner.parameters import planner_config_from
from prvo_planner.preferred import GOAL, UpstreamCommand
from prvo_planner.routes import RouteIntent, route_stamp
from prvo_planner.tracks import TrackTable
from prvo_sim.planned_path import PlannedPath
from prvo_sim.turns import TurnBook
from prvo_sim.upstream import PurePursuitUpstream
from prvo_sim.world import TeamWorld
from prvo_sim.world_messages import serialized_odometry


@dataclass(frozen=True)
class StepRecord:
    """One step of a team: the state at `time` and the commands that answered it.

    `states` (N, 4) is every robot's ground truth [x, y, vx, vy] as a recorder reads it;
    `commands` (N, 2) the world-frame velocities commanded for the next dt (a unicycle's
    forward speed along its heading; NaN for a scripted robot: it has none); `plan_ms` (one per
    planned robot) each planned robot's share of the team's planning time [ms of wall time];
    `contacts` the `world.Contact`s the step made; `feasible` (N,) whether each robot's command
    met every constraint (True for a robot standing still or scripted); `yaws` (N,) the
    ground-truth headings of the state; `turns` (N,) each robot's right of way at its passage
    (`turns.NONE`, `GOES` or `WAITS`) and `turn_passages` (N,) that passage's index in the
    team's `turn_book.shapes` (`turns.NO_PASSAGE`: none).
    """

    time: float
    states: np.ndarray
    commands: np.ndarray
    plan_ms: np.ndarray
    contacts: tuple
    feasible: np.ndarray = None
    yaws: np.ndarray = None
    turns: np.ndarray = None
    turn_passages: np.ndarray = None


def _received(message):
    """Return MESSAGE as a subscriber receives it: serialized and deserialized."""
    return deserialize_message(serialize_message(message), type(message))


def agent_of(name, values, neighbour_tracks=None):
    """Return the PlannerAgent that a planner node with parameter VALUES would run for NAME.

    NEIGHBOUR_TRACKS: a `TrackTable` shared with other agents, or None for the agent's own.
    """
    return PlannerAgent(name, planner_config_from(values), AgentSettings.from_parameters(values),
                        values['goal'], values['neighbors'], neighbour_tracks)


def upstream_of(robot, scenario):
    """Return the `PurePursuitUpstream` that drives ROBOT (its `upstream` path) in SCENARIO.

    It stops within half the scenario's goal tolerance, as the robot's planner would.
    """
    return PurePursuitUpstream(robot.upstream.waypoints, robot.upstream.speed, robot.kinematics,
                               scenario.goal_tolerance / 2.0, robot.max_angular_speed)


def path_of(robot):
    """Return the `PlannedPath` that gives ROBOT (its `path` block) the path it follows."""
    path = PlannedPath()
    path.replan(robot.followed_path.waypoints)
    return path


class InProcessTeam:
    """A scenario's robots, each planned by its own agent, stepped in lockstep in one process.

    Parameters
    ----------
    scenario : prvo_sim.scenario.Scenario
        The world: robots, noise, dt, duration.
    planner_values : sequence of mapping or None
        Per robot, in the scenario's order, the complete planner parameters its node would
        have (`prvo_planner.parameters`; the runner's `planner_values`); None for a scripted
        robot, which has no planner (the world moves it).
    seed : int or None
        Noise seed; None uses the scenario's.
    grid_map : prvo_planner.maps.GridMap or None
        The map on /map, given to the planners that listen there (`map_topic`) as a planner
        node receives it (through the message); None: the world's own, as the simulator
        publishes it (no map for a world without walls, obstacles or map file).

    """

    def __init__(self, scenario, planner_values, seed=None, grid_map=None):
        if len(planner_values) != len(scenario.robots):
            raise ValueError(f'planner_values has {len(planner_values)} entries for '
                             f'{len(scenario.robots)} robots')
        keep_freed_heap()
        self.world = TeamWorld(scenario, seed)
        for robot, values in zip(scenario.robots, planner_values, strict=True):
            if (values is None) != (robot.scripted is not None):
                raise ValueError(f'planner_values of robot {robot.name!r} must be '
                                 f'{"None: it is scripted" if values is not None else "given"}')
        # Every agent hears every robot at the same step, so agents with the same tracker
        # settings would run identical filters: one table per settings filters each robot once.
        self._track_tables = {}
        # None for a scripted robot.
        self.agents = []
        for robot, values in zip(scenario.robots, planner_values, strict=True):
            if values is None:
                self.agents.append(None)
                continue
            settings = (values['acceleration_std'], values['neighbor_timeout'])
            table = self._track_tables.setdefault(settings, TrackTable(*settings))
            self.agents.append(agent_of(robot.name, values, table))
        self._planned = [(index, agent) for index, agent in enumerate(self.agents)
                         if agent is not None]
        if grid_map is None:
            grid_map = self.world.static_world.grid
        if grid_map is not None:
            self._give_map(grid_map, planner_values)
        # The planner_server stand-ins' paths, through the message, as a planner node takes
        # them before its first plan (wait_for_path), and its neighbours as the robot's route,
        # from the start (the stand-in publishes it before the simulator's clock runs).
        for index, robot in enumerate(scenario.robots):
            if robot.followed_path is not None:
                sent = serialize_message(make_path(0.0, path_of(robot).poses, WORLD_FRAME))
                self.agents[index].set_path(serialized_path_to_waypoints(
                    sent, expected_frame=WORLD_FRAME))
                self._give_route(index, sent)
        # What each robot heading for a goal published of its way, by index.
        self._route_intents = {index: RouteIntent(DEPARTURE_TOLERANCES)
                               for index, agent in self._planned
                               if agent.settings.preferred_source == GOAL}
        # The Nav2 stand-ins of the robots driven upstream (their planners filter), by index.
        self._upstreams = {index: upstream_of(robot, scenario)
                           for index, robot in enumerate(scenario.robots)
                           if robot.upstream is not None}
        # What the ROS run publishes of the last step, kept for that step only (a recording
        # takes it): each robot's serialized (odometry, ground truth), each robot's `Command`
        # (None for a scripted robot).
        self.last_odometry = ()
        self.last_commands = ()
        # Each planned robot's `PlanRequest` of the last step: the beliefs it planned with.
        self.last_requests = ()
        # The passages the robots went or waited at, numbered for the whole run.
        self.turn_book = TurnBook()
        # What each robot announces: a planned one its agent's (it changes on arrival), a
        # scripted one, as the simulator announces it, its radius and no share of the avoidance.
        self._scripted_announcements = {
            index: NeighbourAnnouncement(robot.radius, UNANNOUNCED_SHARE)
            for index, robot in enumerate(scenario.robots) if robot.scripted is not None}
        self._announcement_changes = [AnnouncementChanges(name) for name in self.world.names]
        self._announce()

    def _give_map(self, grid_map, planner_values):
        """Give GRID_MAP to every agent whose node listens on /map, through the message."""
        received = _received(make_occupancy_grid(
            0.0, grid_map.cells, grid_map.resolution, grid_map.origin, WORLD_FRAME))
        grid = GridMap(*occupancy_grid_to_parts(received, expected_frame=WORLD_FRAME))
        for index, agent in self._planned:
            if planner_values[index]['map_topic'] == MAP:
                agent.set_map(grid)

    def _announce(self):
        """Give every agent what each other robot announces now, where it changed.

        As a planner node and the simulator do: at start-up, then after each plan, before its
        command, stamped alike; through the messages as they arrive (serialized:
        single-precision numbers).
        """
        names = self.world.names
        for index, agent in enumerate(self.agents):
            if agent is None:
                announcement, stamp = (self._scripted_announcements[index],
                                       ANNOUNCED_FROM_THE_START)
            else:
                announcement, stamp = agent.own_announcement, agent.own_announcement_stamp
            footprint, share = self._announcement_changes[index].messages(
                announcement.radius, announcement.avoidance_share, stamp)
            for message, convert, receive in (
                    (footprint, radius_of_footprint, PlannerAgent.receive_footprint),
                    (share, share_of, PlannerAgent.receive_share)):
                if message is None:
                    continue
                message = _received(message)
                value, value_stamp = convert(message), announcement_stamp(message)
                for _, other in self._planned:
                    if other is not agent:
                        receive(other, names[index], value, value_stamp)

    def _publish_routes(self, commands):
        """Give every agent the routes the others published after their plans, where changed.

        As a planner node does after its plan of COMMANDS (each robot's `Command`, by index):
        stamped with the plan's stamp, through the message.
        """
        for index, intent in self._route_intents.items():
            agent, command = self.agents[index], commands[index]
            route = intent.update(command, agent.goal, agent.settings.goal_tolerance)
            if route is not None:
                self._give_route(index, serialize_message(make_path(
                    route_stamp(command.stamp), route, WORLD_FRAME)))

    def _give_route(self, index, sent):
        """Give the route SENT (a serialized Path) of robot INDEX to every other planned agent.

        A scenario's goals stay: no route is withdrawn (an empty path, which agents refuse).
        """
        stamp, waypoints = serialized_route(sent, expected_frame=WORLD_FRAME)
        robot = self.world.names[index]
        for other_index, other in self._planned:
            if other_index != index:
                other.receive_route(robot, waypoints, stamp)

    @property
    def finished(self):
        """Whether the scenario's duration has been reached."""
        return self.world.finished

    def plan_tallies(self):
        """Return {robot name: its agent's `PlanTally`} of every planned robot, so far."""
        names = self.world.names
        return {names[index]: agent.tally for index, agent in self._planned}

    def observe(self):
        """Return (odometry measurements, ground-truth states (N, 5)) of the current state.

        A state is [x, y, vx, vy, yaw].
        """
        return _decoded(serialized_odometry(self.world))

    def do_step(self, advance=True):
        """Plan every robot on the current state, then move the world by one dt.

        Returns the `StepRecord` of the state planned on. With ADVANCE false the world stays
        where it is: the last step of a run that reaches its duration, whose state the ROS
        simulator publishes and its planners answer before the run ends.
        """
        world = self.world
        now = world.time
        odometry = serialized_odometry(world)
        measurements, states = _decoded(odometry)
        names = world.names
        for index, agent in self._planned:
            agent.receive_own(measurements[index], now)
            if index in self._upstreams:
                # The stand-in answers the same odometry the planner reads.
                measurement = measurements[index]
                agent.receive_upstream(UpstreamCommand(*self._upstreams[index].command(
                    measurement.position, measurement.yaw)), now)
        for table in self._track_tables.values():
            for name, measurement in zip(names, measurements, strict=True):
                table.receive(name, measurement, now)
        started = time.perf_counter()
        requests = [agent.plan_request() for _, agent in self._planned]
        moving = [index for index, request in enumerate(requests) if request.problem is not None]
        results = [None] * len(requests)
        if moving:
            problems = [requests[index].problem for index in moving]
            columns = [list(column) for column in zip(*problems, strict=True)]
            obstacles = [requests[index].obstacles for index in moving]
            # As each agent plans alone: with the obstacles of its map near it, if it has one.
            solved = (plan_velocities(*columns, obstacles=obstacles)
                      if any(near is not None for near in obstacles)
                      else plan_velocities(*columns))
            for index, result in zip(moving, solved, strict=True):
                results[index] = result
        yaws = world.yaws_at(world.step_count)
        # A scripted robot has no command (NaN, as a recording without one); the world moves it
        # and ignores its row of what is executed, which it wants finite.
        commands = np.full((len(self.agents), 2), np.nan)
        executed = np.zeros_like(commands)
        planned = [None] * len(self.agents)
        for request, result, (index, agent) in zip(requests, results, self._planned,
                                                   strict=True):
            command = agent.complete(request, result)
            planned[index] = command
            if command.drive is not None:
                # A unicycle's node publishes linear.x and angular.z, executed as they are; a
                # recorder sees the forward speed turned by the heading at the stamp.
                executed[index] = command.drive
                commands[index] = body_to_world((command.drive[0], 0.0), yaws[index])
                continue
            # The node publishes in the body frame (a filter passes its input on as it came);
            # the simulator turns it back by the heading at the command's stamp.
            body = (command.upstream.linear if command.passed_through
                    else world_to_body(command.velocity, command.yaw))
            commands[index] = body_to_world(body, yaws[index])
            executed[index] = commands[index]
        self._announce()
        self._publish_routes(planned)
        # One call plans the team: each planned robot is charged an equal share of it.
        plan_ms = np.full(len(self._planned), (time.perf_counter() - started) * 1e3
                          / max(len(self._planned), 1))
        contacts = world.step(executed) if advance else ()
        self.last_odometry, self.last_commands = tuple(odometry), tuple(planned)
        self.last_requests = tuple(requests)
        # Per robot: whether its command met every constraint (a scripted robot has none).
        feasible = np.ones(len(self.agents), dtype=bool)
        for result, (index, _) in zip(results, self._planned, strict=True):
            feasible[index] = result is None or result.feasible
        turns, turn_passages = self.turn_book.record(
            [None if command is None else command.right_of_way for command in planned],
            [None if agent is None else agent.passage_map for agent in self.agents],
            [None if agent is None else agent.grid_map for agent in self.agents])
        return StepRecord(time=now, states=states[:, :4], commands=commands, plan_ms=plan_ms,
                          contacts=tuple(contacts), feasible=feasible, yaws=states[:, 4],
                          turns=turns, turn_passages=turn_passages)


def _decoded(messages):
    """Return (odometry measurements, ground-truth states (N, 5)) of serialized MESSAGES.

    A state is [x, y, vx, vy, yaw].
    """
    measurements = [serialized_odometry_to_measurement(odometry, expected_frame=WORLD_FRAME)
                    for odometry, _ in messages]
    truths = [serialized_odometry_to_measurement(truth, expected_frame=WORLD_FRAME)
              for _, truth in messages]
    states = np.array([[*truth.position, *truth.velocity, truth.yaw] for truth in truths])
    return measurements, states

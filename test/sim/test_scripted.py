"""Scripted robots: the world moves them along their waypoints, whatever they are commanded."""

import dataclasses
import itertools
import math

import numpy as np
import pytest
import yaml

from prvo_sim import metrics
from prvo_sim.scenario import PLANNER_MEMORY_MIB, estimate_team_memory, load_scenario
from prvo_sim.scripted import WaypointFollower
from prvo_sim.world import TeamWorld

DT = 0.1


def scenario_file(tmp_path, walker, noise=0.0, duration=30.0):
    """Write a scenario of one planned robot and WALKER (a robot entry); return its path."""
    document = {
        'name': 'walk', 'seed': 4, 'dt': DT, 'duration': duration, 'goal_tolerance': 0.2,
        'noise': {'position_std': noise, 'velocity_std': noise, 'actuation_std': noise},
        'robots': [
            {'name': 'robot_0', 'start': [-20.0, -20.0], 'goal': [-20.0, -15.0],
             'radius': 0.3, 'max_speed': 1.0},
            {'name': 'walker', 'radius': 0.3, 'max_speed': 1.5, **walker}]}
    path = tmp_path / 'walk.yaml'
    path.write_text(yaml.safe_dump(document))
    return path


def expected_positions(start, waypoints, speed, loop, steps):
    """Return the positions (steps + 1, 2) of a walker, computed leg by leg.

    On a leg of length L the walker covers speed * dt per step and needs ceil(L / (speed dt))
    steps, the last of them landing on the waypoint; after the last waypoint it stands, or
    walks the legs again from the first waypoint if LOOP.
    """
    targets = itertools.chain(waypoints, itertools.cycle(waypoints) if loop else ())
    positions = [np.asarray(start, dtype=float)]
    while len(positions) <= steps:
        end = next(targets, None)
        if end is None:
            positions.append(positions[-1])
            continue
        begin, end = positions[-1], np.asarray(end, dtype=float)
        length = math.dist(begin, end)
        for step in range(1, math.ceil(length / (speed * DT)) + 1):
            positions.append(begin + (end - begin) * min(step * speed * DT / length, 1.0))
    return np.array(positions[:steps + 1])


@pytest.mark.parametrize('loop', [False, True])
def test_walker_follows_its_waypoints_at_its_speed_and_ignores_commands(tmp_path, loop):
    waypoints = [[3.05, 0.0], [3.05, 2.13], [0.4, 2.13]]
    path = scenario_file(tmp_path, {'start': [0.0, 0.0], 'scripted': {
        'waypoints': waypoints, 'speed': 0.7, 'loop': loop}})
    scenario = load_scenario(path)
    world = TeamWorld(scenario)
    rng = np.random.default_rng(3)
    steps = 250
    walked = [world.positions[1].copy()]
    for _ in range(steps):
        # Whatever the walker is commanded, it walks its path; robot_0 obeys.
        commands = rng.uniform(-2.0, 2.0, size=(2, 2))
        before = world.positions[0].copy()
        world.step(commands)
        np.testing.assert_allclose(world.positions[0], before + commands[0] * DT /
                                   max(1.0, np.linalg.norm(commands[0])), atol=1e-12)
        walked.append(world.positions[1].copy())
    expected = expected_positions([0.0, 0.0], waypoints, 0.7, loop, steps)
    np.testing.assert_allclose(np.array(walked), expected, atol=1e-9)
    # The path is long enough to see the end: standing at the last waypoint, or on a later lap.
    assert np.allclose(walked[-1], waypoints[-1]) != loop


def test_speed_defaults_to_max_speed_and_walker_heads_for_its_first_waypoint(tmp_path):
    path = scenario_file(tmp_path, {'start': [0.0, 0.0], 'scripted': {
        'waypoints': [[0.0, 5.55]]}})
    scenario = load_scenario(path)
    walker = scenario.robots[1]
    assert walker.scripted.speed == walker.max_speed == 1.5
    assert walker.scripted.loop is False
    np.testing.assert_array_equal(walker.goal, [0.0, 5.55])
    world = TeamWorld(scenario)
    assert world.yaws[1] == pytest.approx(math.pi / 2)
    walked = [world.positions[1].copy()]
    for _ in range(40):
        world.step(np.zeros((2, 2)))
        walked.append(world.positions[1].copy())
    np.testing.assert_allclose(np.array(walked),
                               expected_positions([0.0, 0.0], [[0.0, 5.55]], 1.5, False, 40),
                               atol=1e-9)


def test_walker_noise_comes_from_the_world_generator(tmp_path):
    """With noise, a walker moves as a robot commanded its noise-free path from outside does.

    Same seed, same draws in the same order: the actuation noise of a scripted robot is the
    scenario's, from the one generator, so the planned robot's noise is unchanged too.
    """
    walker = {'start': [0.0, 0.0], 'scripted': {'waypoints': [[4.0, 1.0], [0.0, 3.0]],
                                                'speed': 0.8, 'loop': True}}
    scripted = load_scenario(scenario_file(tmp_path, walker, noise=0.05))
    planned_walker = dataclasses.replace(scripted.robots[1], scripted=None)
    commanded = dataclasses.replace(scripted, robots=(scripted.robots[0], planned_walker))
    walking, driven = TeamWorld(scripted), TeamWorld(commanded)
    # The driver's own follower of the same path, outside the world.
    driver = WaypointFollower(scripted.robots[1].scripted)
    for _ in range(120):
        driven.step(np.array([[0.3, 0.1], driver.command(driven.positions[1], DT)]))
        walking.step(np.array([[0.3, 0.1], [9.0, 9.0]]))
        for name in ('positions', 'velocities', 'measured_positions', 'measured_velocities'):
            np.testing.assert_array_equal(getattr(walking, name), getattr(driven, name), name)
    assert np.any(walking.velocities[1] != 0.0)


def test_scripted_robots_count_in_contacts_not_in_arrivals():
    times = np.arange(0.0, 3.05, 0.5)
    positions = np.zeros((times.size, 3, 2))
    positions[:, 0, 0] = np.minimum(times, 2.0)          # arrives at (2, 0) at t = 2
    positions[:, 1, 1] = 5.0 + np.minimum(times, 1.0)    # arrives at (0, 6) at t = 1
    positions[:, 2] = [[2.0, 0.3]] * times.size          # a walker standing on robot_0's goal
    radii = np.array([0.2, 0.2, 0.2])
    goals = np.array([[2.0, 0.0], [0.0, 6.0], [9.0, 9.0]])
    names = ['robot_0', 'robot_1', 'walker']
    run = metrics.run_metrics(times, positions, radii, goals, 0.1, names,
                              scripted=[False, False, True])
    # Independent: robot_0 meets the walker (distance 0.3 < 0.4) from t = 1.5 on, once.
    distances = np.linalg.norm(positions[:, 0] - positions[:, 2], axis=1)
    assert run['collisions'] == 1
    assert run['min_separation'] == pytest.approx(distances.min() - 0.4)
    # The walker never reaches its "goal" but the run is a full success, made of the robots.
    assert run['success_rate'] == 1.0
    assert run['makespan'] == 2.0 and run['mean_time_to_goal'] == 1.5
    assert run['scripted_robots'] == ['walker']
    assert run['robots']['walker'] == {'arrived': None, 'time_to_goal': None,
                                       'path_length': 0.0, 'scripted': True}
    assert run['robots']['robot_0']['scripted'] is False
    # Counted as a robot, the walker would fail the run.
    as_robot = metrics.run_metrics(times, positions, radii, goals, 0.1, names)
    assert as_robot['success_rate'] == pytest.approx(2 / 3) and as_robot['makespan'] is None


def test_scripted_robots_need_no_planner_memory(tmp_path):
    scenario = load_scenario(scenario_file(tmp_path, {'start': [0.0, 0.0], 'scripted': {
        'waypoints': [[1.0, 0.0]]}}))
    as_planned = dataclasses.replace(scenario, robots=(
        scenario.robots[0], dataclasses.replace(scenario.robots[1], scripted=None)))
    assert estimate_team_memory(as_planned) - estimate_team_memory(scenario) == (
        PLANNER_MEMORY_MIB)

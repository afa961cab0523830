"""TeamWorld against the simulator's former draw order and hand computations."""

from kinematics_replay import replay
import numpy as np
import pytest

from prvo_sim.scenario import find_scenario, load_scenario
from prvo_sim.world import TeamWorld

CIRCLE8 = load_scenario(find_scenario('circle8'))
HEADON2 = load_scenario(find_scenario('headon2'))


def run_world(world, commands):
    """Step WORLD through COMMANDS; return the same quantities as `replay`, from t_0."""
    names = ('positions', 'velocities', 'yaws', 'measured_positions', 'measured_velocities')
    run = {name: [np.array(getattr(world, name))] for name in names}
    for step_commands in commands:
        world.step(step_commands)
        for name in names:
            run[name].append(np.array(getattr(world, name)))
    return {name: np.array(values) for name, values in run.items()}


@pytest.mark.parametrize('seed', [0, 5, 1234])
def test_world_draws_exactly_as_the_former_node(seed):
    rng = np.random.default_rng(seed)
    # Random commands, some beyond max speed (clamped) and some zero (heading kept).
    commands = rng.uniform(-1.5, 1.5, size=(60, len(CIRCLE8.robots), 2))
    commands[10:15, 2] = 0.0
    expected = replay(CIRCLE8, seed, commands)
    actual = run_world(TeamWorld(CIRCLE8, seed), commands)
    for name, values in expected.items():
        np.testing.assert_array_equal(actual[name], values, err_msg=name)


def test_world_uses_the_scenario_seed_by_default():
    commands = np.zeros((3, 2, 2))
    expected = replay(HEADON2, HEADON2.seed, commands)
    actual = run_world(TeamWorld(HEADON2), commands)
    np.testing.assert_array_equal(actual['measured_positions'], expected['measured_positions'])


def test_world_reports_each_contact_once_with_its_time_and_distance():
    world = TeamWorld(HEADON2, seed=1)
    # Noise-free: robot_0 from (-4, 0) and robot_1 from (4, 0) closing at 1.9 m/s.
    world.actuation_std[:] = 0.0
    head_on = [[0.95, 0.0], [-0.95, 0.0]]
    events = []
    while world.step_count < 45:
        events += world.step(head_on)
    # Centre distance 8 - 0.19 k after k steps; contact once below 0.3 + 0.3 m: k = 39.
    assert len(events) == 1 and world.contact_count == 1
    (contact,) = events
    assert (contact.first, contact.second) == (0, 1)
    assert contact.time == pytest.approx(39 * HEADON2.dt)
    assert contact.distance == pytest.approx(8.0 - 0.19 * 39)


def test_world_heading_history_and_arrival():
    world = TeamWorld(HEADON2, seed=1)
    world.actuation_std[:] = 0.0
    # Facing the goal at start: robot_0 towards +x, robot_1 towards -x.
    np.testing.assert_allclose(world.yaws, [0.0, np.pi])
    world.step([[0.0, 1.0], [0.0, 0.0]])
    # robot_0 turned to +y; robot_1 did not move and keeps its heading.
    np.testing.assert_allclose(world.yaws, [np.pi / 2, np.pi])
    np.testing.assert_allclose(world.yaws_at(0), [0.0, np.pi])
    np.testing.assert_allclose(world.yaws_at(1), world.yaws)
    assert not world.arrived().any()
    world.positions[1] = world.goals[1] + [HEADON2.goal_tolerance * 0.9, 0.0]
    np.testing.assert_array_equal(world.arrived(), [False, True])


def test_world_finishes_at_the_duration_and_refuses_bad_commands():
    world = TeamWorld(HEADON2, seed=1)
    assert world.final_step == round(HEADON2.duration / HEADON2.dt)
    with pytest.raises(ValueError, match='finite'):
        world.step([[np.nan, 0.0], [0.0, 0.0]])
    with pytest.raises(ValueError, match='shape'):
        world.step([[0.0, 0.0]])
    # A refused command leaves the world and its generator untouched.
    assert world.step_count == 0
    np.testing.assert_array_equal(run_world(world, np.zeros((2, 2, 2)))['measured_positions'],
                                  replay(HEADON2, 1, np.zeros((2, 2, 2)))['measured_positions'])
    while not world.finished:
        world.step(np.zeros((2, 2)))
    assert world.time == pytest.approx(HEADON2.duration)

"""cmd_vel acceptance and frames (command_velocity) and observer names, without processes."""

from geometry_msgs.msg import Twist
import numpy as np
import pytest

from prvo_msgs_util import MessageFault, make_twist, make_twist_stamped
from prvo_sim.commands import command_velocity, unicycle_command
from prvo_sim.observers import observer_name_fault
from prvo_sim.scenario import find_scenario, load_scenario
from prvo_sim.world import YAW_HISTORY, TeamWorld

HEADON2 = load_scenario(find_scenario('headon2'))


@pytest.fixture
def world():
    """headon2 after 40 noise-free steps, robot_0 turned to +y at step 35."""
    team = TeamWorld(HEADON2, seed=1)
    team.actuation_std[:] = 0.0
    for step in range(40):
        team.step([[0.0, 0.1] if step >= 35 else [0.1, 0.0], [0.0, 0.0]])
    return team


def stamped(world, steps_back, velocity, frame_id):
    return make_twist_stamped((world.step_count - steps_back) * HEADON2.dt, velocity, frame_id)


def test_frames_rotate_by_the_heading_at_the_stamp(world):
    base = 'robot_0/base_link'
    np.testing.assert_allclose(
        command_velocity(stamped(world, 0, (0.5, 0.2), 'map'), 0, base, world), [0.5, 0.2])
    np.testing.assert_allclose(
        command_velocity(stamped(world, 0, (0.5, 0.2), ''), 0, base, world), [0.5, 0.2])
    # Heading +y now (turned at step 35 -> state 36), +x at state 35 and before.
    np.testing.assert_allclose(
        command_velocity(stamped(world, 0, (1.0, 0.0), base), 0, base, world), [0.0, 1.0],
        atol=1e-12)
    np.testing.assert_allclose(
        command_velocity(stamped(world, 5, (1.0, 0.0), base), 0, base, world), [1.0, 0.0],
        atol=1e-12)
    # A plain Twist is in the body frame, at the current heading.
    np.testing.assert_allclose(
        command_velocity(make_twist((1.0, 0.0)), 0, base, world), [0.0, 1.0], atol=1e-12)
    assert isinstance(make_twist((1.0, 0.0)), Twist)


@pytest.mark.parametrize(('message', 'fault'), [
    (lambda w: stamped(w, 0, (float('nan'), 0.0), 'map'), 'twist.linear contains NaN'),
    (lambda w: stamped(w, 0, (0.0, float('inf')), 'map'), 'twist.linear contains NaN or inf'),
    (lambda w: stamped(w, 0, (600.0, 801.0), 'map'), 'speed 1000.800 m/s is above 1000'),
    (lambda w: make_twist((3000.0, 0.0)), 'speed 3000.000 m/s'),
    (lambda w: stamped(w, -1, (0.1, 0.0), 'map'), 'stamp 4.100 s is after the sim time 4.000'),
    (lambda w: stamped(w, YAW_HISTORY, (0.1, 0.0), 'map'),
     f'stamp 0.800 s is {YAW_HISTORY} steps or more before the sim time 4.000'),
    (lambda w: stamped(w, 0, (0.1, 0.0), 'odom'), "header.frame_id is 'odom'"),
])
def test_bad_commands_are_refused_naming_the_fault(world, message, fault):
    with pytest.raises(MessageFault, match=fault.replace('.', r'\.')):
        command_velocity(message(world), 0, 'robot_0/base_link', world)


def test_commands_within_the_window_are_accepted(world):
    for steps_back in (0, 1, YAW_HISTORY - 1):
        np.testing.assert_allclose(command_velocity(
            stamped(world, steps_back, (0.1, 0.0), 'map'), 0, 'robot_0/base_link', world),
            [0.1, 0.0])
    # Exactly the speed limit for corrupt messages is still a command.
    np.testing.assert_allclose(command_velocity(
        stamped(world, 0, (1000.0, 0.0), 'map'), 0, 'robot_0/base_link', world), [1000.0, 0.0])


@pytest.mark.parametrize('name', ['/prvo_run_recorder_1234', '/ns/node', '/a/b/c_d'])
def test_fully_qualified_observer_names_are_accepted(name):
    assert observer_name_fault(name) is None


@pytest.mark.parametrize(('name', 'fault'), [
    ('prvo_run_recorder', 'does not start with /'),
    ('/', 'is not a fully qualified node name'),
    ('/ns/', 'is not a fully qualified node name'),
    ('/bad-name', 'is not a fully qualified node name'),
    ('/9lives', 'is not a fully qualified node name'),
])
def test_bad_observer_names_are_named(name, fault):
    message = observer_name_fault(name)
    assert message.startswith(f'observers: {name!r}') and fault in message


def test_a_unicycle_takes_forward_speed_and_turn_rate_and_drops_sideways_speed(world):
    base = 'robot_0/base_link'
    message = stamped(world, 0, (0.5, 0.2), base)
    message.twist.angular.z = -0.7
    assert unicycle_command(message, base, world) == ((0.5, -0.7), 0.2)
    plain = make_twist((0.4, 0.0), 1.1)
    assert unicycle_command(plain, base, world) == ((0.4, 1.1), 0.0)
    with pytest.raises(MessageFault, match="'map'.*a unicycle takes body-frame commands"):
        unicycle_command(stamped(world, 0, (0.5, 0.0), 'map'), base, world)
    broken = make_twist((0.4, 0.0), float('nan'))
    with pytest.raises(MessageFault, match='angular.z is nan'):
        unicycle_command(broken, base, world)
    with pytest.raises(MessageFault, match='after the sim time'):
        unicycle_command(stamped(world, -1, (0.5, 0.0), base), base, world)

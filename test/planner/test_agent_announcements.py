"""Stamped announcements: a change counts from the plan after its stamp, in any order."""

import numpy as np
import pytest
from test_agent import CONFIG, GOAL, SETTINGS, standing, team

from prvo_planner.agent import (
    ANNOUNCED_FROM_THE_START,
    MAX_KEPT_ANNOUNCEMENTS,
    AnnouncedValues,
    NeighbourAnnouncement,
    PlannerAgent,
)

STEPS = 8
# Neighbour a's plan of this step changes its radius and share: it announces both stamped with
# that step's stamp.
CHANGE_STEP = 3
BEFORE, AFTER = NeighbourAnnouncement(0.3, 0.5), NeighbourAnnouncement(0.6, 0.0)
# When the change reaches the agent: (step, phase), the phase 'odometry' before the agent's own
# odometry of the step, 'plan' after it and before the plan, 'planned' after the plan.
ARRIVALS = {
    # A loaded planner: the neighbour planned the step before this one's odometry came.
    'before the own odometry of its step': (CHANGE_STEP, 'odometry'),
    'before the plan of its step': (CHANGE_STEP, 'plan'),
    'after the plan of its step': (CHANGE_STEP, 'planned'),
    'with the next odometry': (CHANGE_STEP + 1, 'plan'),
    'never': None,
}


def plans(arrival):
    """Return the agent's Commands of a crossing with a and b; a's change arrives at ARRIVAL."""
    data = team(STEPS)
    agent = PlannerAgent('self', CONFIG, SETTINGS, GOAL)
    for robot in ('a', 'b'):
        agent.receive_footprint(robot, BEFORE.radius, ANNOUNCED_FROM_THE_START)
        agent.receive_share(robot, BEFORE.avoidance_share, ANNOUNCED_FROM_THE_START)
    change_stamp = data['a'][CHANGE_STEP].stamp

    def deliver_if(step, phase):
        if ARRIVALS[arrival] == (step, phase):
            agent.receive_share('a', AFTER.avoidance_share, change_stamp)
            agent.receive_footprint('a', AFTER.radius, change_stamp)

    commands = []
    for step in range(STEPS):
        now = 0.1 * step
        deliver_if(step, 'odometry')
        for robot in ('a', 'b'):
            assert agent.receive_neighbour(robot, data[robot][step], now).accepted
        assert agent.receive_own(data['self'][step], now).accepted
        deliver_if(step, 'plan')
        assert agent.ready(now)
        commands.append(agent.plan())
        deliver_if(step, 'planned')
    return commands


def planned_with(command, robot):
    return command.announcements[command.neighbour_names.index(robot)]


@pytest.mark.parametrize('arrival', [name for name in ARRIVALS if name != 'never'])
def test_a_change_counts_from_the_step_after_its_stamp_whenever_it_arrives(arrival):
    commands = plans(arrival)
    in_order = plans('after the plan of its step')
    unchanged = plans('never')
    for step, command in enumerate(commands):
        assert planned_with(command, 'a') == (BEFORE if step <= CHANGE_STEP else AFTER), step
        assert planned_with(command, 'b') == BEFORE
        # The same plans, bit for bit, as when the change comes in order.
        np.testing.assert_array_equal(command.velocity, in_order[step].velocity)
        if step <= CHANGE_STEP:
            np.testing.assert_array_equal(command.velocity, unchanged[step].velocity)
    # The change reaches the plans: a larger neighbour that no longer avoids moves this robot.
    assert any(not np.array_equal(command.velocity, unchanged[step].velocity)
               for step, command in enumerate(commands) if step > CHANGE_STEP)


def test_a_change_made_by_the_plan_of_stamp_zero_counts_from_the_next_step():
    # The simulator's clock starts at 0. A robot that starts at its goal stops announcing a
    # share with its first plan; a zero stamp would make that hold from the start.
    parked = PlannerAgent('parked', CONFIG, SETTINGS, [0.0, 0.0])
    mover = PlannerAgent('mover', CONFIG, SETTINGS, GOAL)
    assert parked.own_announcement_stamp == ANNOUNCED_FROM_THE_START
    mover.receive_share('parked', parked.own_announcement.avoidance_share,
                        parked.own_announcement_stamp)
    parked.receive_own(standing(0.0, [0.05, 0.0]), 0.0)
    parked.plan()
    assert parked.arrived and parked.own_announcement.avoidance_share == 0.0
    assert parked.own_announcement_stamp > 0.0
    # It reaches the mover before the mover's own odometry of stamp 0.
    mover.receive_share('parked', parked.own_announcement.avoidance_share,
                        parked.own_announcement_stamp)
    shares = []
    for stamp in (0.0, 0.1):
        mover.receive_neighbour('parked', standing(stamp, [0.05, 0.0]), stamp)
        mover.receive_own(standing(stamp, [-3.0, 0.0]), stamp)
        shares.append(planned_with(mover.plan(), 'parked').avoidance_share)
    assert shares == [0.5, 0.0]
    parked.receive_own(standing(0.1, [0.05, 0.0]), 0.1)
    parked.plan()
    assert parked.own_announcement_stamp == 0.1


def test_an_announcement_stamped_ahead_holds_once_plans_pass_its_stamp():
    agent = PlannerAgent('self', CONFIG, SETTINGS, GOAL)
    agent.receive_footprint('a', 0.7, 5.0)
    agent.receive_share('a', 0.5, 5.0)
    # Until then the defaults: unknown_neighbor_radius, not avoiding.
    assert agent.announcement_of('a', 5.0) == NeighbourAnnouncement(0.4, 0.0)
    assert agent.announcement_of('a', 5.1) == NeighbourAnnouncement(0.7, 0.5)


def test_the_announced_values_are_those_an_unpruned_history_gives():
    # Announcements and plans interleaved at random, as they reach a planner: every plan gets
    # the newest value announced with an earlier stamp among all received so far, and after a
    # plan what is kept is the value of that plan and the announcements ahead of it.
    rng = np.random.default_rng(7)
    for _ in range(50):
        announced, received = AnnouncedValues(), [(ANNOUNCED_FROM_THE_START, 0)]
        announced.add(*received[0])
        plan_stamp, announce_stamp = 0.0, 0.0
        for _ in range(60):
            # Neighbours at most a few steps ahead (far fewer than MAX_KEPT_ANNOUNCEMENTS).
            if rng.random() < 0.5 and announce_stamp < plan_stamp + 0.5:
                announce_stamp += 0.1 * rng.integers(1, 3)
                received.append((round(announce_stamp, 9), len(received)))
                announced.add(*received[-1])
            else:
                plan_stamp = round(plan_stamp + 0.1, 9)
                expected = max((entry for entry in received if entry[0] < plan_stamp),
                               key=lambda entry: entry[0])[1]
                assert announced.value_at(plan_stamp) == expected
                assert announced.take(plan_stamp) == expected
                assert announced.value_at(plan_stamp) == expected
                ahead = sum(1 for stamp, _ in received if stamp >= plan_stamp)
                assert len(announced) <= ahead + 1


def test_a_restated_announcement_replaces_those_at_and_after_its_stamp():
    announced = AnnouncedValues()
    for stamp, value in ((0.0, 'start'), (0.5, 'a'), (1.0, 'b')):
        announced.add(stamp, value)
    assert [announced.value_at(stamp) for stamp in (0.0, 0.5, 0.6, 1.1)] == [
        'start', 'start', 'a', 'b']
    # Its clock went back: from 0.7 on it is c, and b is no more.
    announced.add(0.7, 'c')
    assert [announced.value_at(stamp) for stamp in (0.6, 0.8, 1.1)] == ['a', 'c', 'c']
    # It restarted: from the start it is d.
    announced.add(ANNOUNCED_FROM_THE_START, 'd')
    assert len(announced) == 1
    assert [announced.value_at(stamp) for stamp in (0.0, 0.6, 1.1)] == ['d', 'd', 'd']


def test_a_flood_of_changes_ahead_keeps_the_newest():
    announced = AnnouncedValues()
    for step in range(1, 1000):
        announced.add(0.1 * step, step)
    assert len(announced) == MAX_KEPT_ANNOUNCEMENTS
    assert announced.value_at(1000.0) == 999
    assert announced.value_at(0.1 * (1000 - MAX_KEPT_ANNOUNCEMENTS) + 0.05) == (
        1000 - MAX_KEPT_ANNOUNCEMENTS)

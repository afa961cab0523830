"""Plan quality: each agent's tally of its plans, the in-process team's, and the metrics of it."""

import math

import pytest

from prvo_planner.parameters import DEFAULTS
from prvo_sim.engine import InProcessTeam
from prvo_sim.metrics import plan_quality
from prvo_sim.scenario import find_scenario, load_scenario


def test_plan_quality_per_robot_and_overall_by_hand():
    quality = plan_quality({'a': (10, 3, 0.42), 'b': (30, 0, 0.9), 'idle': (0, 0, None)})
    assert quality['robots'] == {
        'a': {'plans': 10, 'infeasible_fraction': 0.3, 'min_achieved_eta': 0.42},
        'b': {'plans': 30, 'infeasible_fraction': 0.0, 'min_achieved_eta': 0.9},
        'idle': {'plans': 0, 'infeasible_fraction': None, 'min_achieved_eta': None}}
    # 3 of 40 plans, not the mean of the robots' fractions (0.15).
    assert quality['infeasible_fraction'] == pytest.approx(3 / 40)
    assert quality['min_achieved_eta'] == 0.42


def test_plan_quality_without_any_plan_has_no_fraction_or_eta():
    assert plan_quality({'idle': (0, 0, None)})['infeasible_fraction'] is None
    assert plan_quality({}) == {'robots': {}, 'infeasible_fraction': None,
                                'min_achieved_eta': None}


@pytest.mark.parametrize('tally', [(3, 4, 0.5), (2, -1, 0.5)])
def test_plan_quality_refuses_a_tally_with_more_infeasible_plans_than_plans(tally):
    with pytest.raises(ValueError, match=r'^a: -?\d infeasible plans of \d$'):
        plan_quality({'a': tally})


def headon_team(eta, certificate='cantelli'):
    """Return the in-process team of headon2, every planner at ETA by CERTIFICATE, else defaults.

    Cantelli's bound is the forcing one: at 0.9999 its margin k is about 100 standard
    deviations, which no velocity of a head-on pair meets.
    """
    scenario = load_scenario(find_scenario('headon2'))
    values = [{**DEFAULTS, 'goal': [float(value) for value in robot.goal],
               'radius': robot.radius, 'max_speed': robot.max_speed, 'eta': eta,
               'certificate': certificate,
               'actuation_std': robot.noise.actuation_std,
               'neighbors': [other.name for other in scenario.robots if other is not robot]}
              for robot in scenario.robots]
    return InProcessTeam(scenario, values)


def test_the_tally_counts_every_plan_of_a_run_forced_infeasible():
    """At eta 0.9999 head-on, many plans find no velocity that meets the chance constraint.

    Those made while the two are within the horizon of each other: 55 of 161 at 2 s.
    """
    team = headon_team(0.9999)
    # Counted independently, from every step's plans.
    plans, infeasible, lowest, last = {}, {}, {}, {}
    while not team.finished:
        team.do_step()
        for agent, command in zip(team.agents, team.last_commands, strict=True):
            if command.result is None:
                continue
            name = agent.name
            plans[name] = plans.get(name, 0) + 1
            infeasible[name] = infeasible.get(name, 0) + (not command.result.feasible)
            lowest[name] = min(lowest.get(name, math.inf), command.result.eta_bound)
            last[name] = command.stamp
            # Every command carries the tally with its own plan counted.
            assert command.tally == agent.tally and command.tally.plans == plans[name]
        if all(agent.arrived for agent in team.agents):
            break
    tallies = team.plan_tallies()
    assert set(tallies) == {'robot_0', 'robot_1'}
    for name, tally in tallies.items():
        assert (tally.plans, tally.infeasible, tally.min_achieved_eta, tally.last_stamp) == (
            plans[name], infeasible[name], lowest[name], last[name])
        # Forced: infeasible plans, with an achieved eta far below the one asked for (the
        # least about 0.94 against 0.9999: keeping right, the pair pass a little apart).
        assert tally.infeasible > tally.plans / 4 and tally.min_achieved_eta < 0.99
    quality = plan_quality({name: (tally.plans, tally.infeasible, tally.min_achieved_eta)
                            for name, tally in tallies.items()})
    assert quality['infeasible_fraction'] == pytest.approx(
        sum(infeasible.values()) / sum(plans.values()))
    assert quality['min_achieved_eta'] == min(lowest.values())


def test_a_new_goal_keeps_the_tally():
    team = headon_team(0.8)
    for _ in range(5):
        team.do_step()
    agent = team.agents[0]
    before = agent.tally
    assert before.plans == 5
    agent.set_goal([0.0, 3.0])
    team.do_step()
    assert agent.tally.plans == 6 and agent.tally.infeasible >= before.infeasible

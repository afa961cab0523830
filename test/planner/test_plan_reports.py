"""A plan's diagnostic status carries the planner's tally of its plans so far."""


from diagnostic_msgs.msg import DiagnosticStatus
import numpy as np
from planner_testing import Odometry

from prvo_msgs_util import diagnostic_values
from prvo_planner.agent import AgentSettings, PlannerAgent
from prvo_planner.core import PlannerConfig
from prvo_planner.reports import plan_status

# (robot, x at 0 s [m], velocity along x [m/s]): a neighbour comes head-on.
HEAD_ON = (('self', -2.0, 0.8), ('other', 2.0, -0.8))
# The robot is held in place (by its wheels, say) with a neighbour standing before it.
BLOCKED = (('self', -2.0, 0.0), ('other', -1.2, 0.0))


def head_on(agent, rng, steps, first=0, robots=HEAD_ON):
    """Feed AGENT measurements of ROBOTS on y = 0 from step FIRST, 0.1 s apart; plan each."""
    commands = []
    for step in range(first, first + steps):
        stamp = round(0.1 * step, 9)
        for robot, start, velocity in robots:
            position = np.array([start + velocity * stamp, 0.0]) + rng.normal(0.0, 0.02, 2)
            measurement = Odometry(stamp, position, np.array([velocity, 0.0]),
                                      4e-4 * np.eye(4))
            if robot == 'self':
                agent.receive_own(measurement, stamp)
            else:
                agent.receive_neighbour(robot, measurement, stamp)
        # Announced from the start (stamp 0).
        agent.receive_footprint('other', 0.3, 0.0)
        agent.receive_share('other', 0.5, 0.0)
        commands.append(agent.plan())
    return commands


def test_the_status_reports_the_plans_so_far_and_their_worst_eta():
    rng = np.random.default_rng(7)
    config = PlannerConfig(eta=0.9999, max_speed=1.0, actuation_cov=0.0025 * np.eye(2))
    agent = PlannerAgent('self', config, AgentSettings(), goal=None)
    idle = head_on(agent, rng, 2)[-1]
    values = diagnostic_values(plan_status('self', idle, 1.0, 'prvo', 0.3))
    # No goal: it stood still without planning.
    assert (values['plans'], values['infeasible_plans'], values['min_achieved_eta'],
            values['tally_stamp']) == ('0', '0', 'none', 'none')
    agent.set_goal([3.0, 0.0])
    commands = head_on(agent, rng, 12, first=2)
    results = [command.result for command in commands]
    values = diagnostic_values(plan_status('self', commands[-1], 1.0, 'prvo', 0.3))
    assert values['plans'] == '12'
    assert values['infeasible_plans'] == str(sum(not result.feasible for result in results))
    assert int(values['infeasible_plans']) > 0
    assert float(values['min_achieved_eta']) == min(result.eta_bound for result in results)
    assert float(values['tally_stamp']) == commands[-1].stamp


def test_the_status_reports_the_certificate_mode_and_the_lowest_certified_bound():
    rng = np.random.default_rng(8)
    values = {}
    for certificate in ('cantelli', 'certified'):
        config = PlannerConfig(eta=0.95, max_speed=1.0, actuation_cov=0.0025 * np.eye(2),
                               certificate=certificate)
        agent = PlannerAgent('self', config, AgentSettings(), goal=[3.0, 0.0])
        command = head_on(agent, rng, 4)[-1]
        values[certificate] = (command.result, diagnostic_values(
            plan_status('self', command, 1.0, 'prvo', 0.3)))
    result, status = values['cantelli']
    assert (status['certificate'], status['min_certified_probability']) == ('cantelli', 'none')
    result, status = values['certified']
    assert status['certificate'] == 'certified'
    assert result.bound_kinds == ('certified',)
    assert float(status['min_certified_probability']) == float(result.neighbour_bounds[0])
    assert float(status['eta_bound']) == result.eta_bound >= 0.95


def test_a_stalled_robot_warns_with_its_position_and_the_conditions_that_bind():
    rng = np.random.default_rng(9)
    config = PlannerConfig(eta=0.95, max_speed=1.0, actuation_cov=0.0025 * np.eye(2))
    agent = PlannerAgent('self', config, AgentSettings(), goal=[3.0, 0.0])
    commands = head_on(agent, rng, 121, robots=BLOCKED)
    began = [command.stamp for command in commands if command.stall.began]
    # Stalled once the 10 s window is full: 10 s without gaining 0.5 m toward the goal.
    assert began == [10.0]
    before = plan_status('self', commands[99], 1.0, 'prvo', 0.3)
    assert before.level == DiagnosticStatus.OK or not commands[99].result.feasible
    assert diagnostic_values(before)['stalled'] == 'false'
    assert 'stall_x' not in diagnostic_values(before)
    status = plan_status('self', commands[-1], 1.0, 'prvo', 0.3)
    values = diagnostic_values(status)
    assert status.level == DiagnosticStatus.WARN and 'stalled for 2.0 s' in status.message
    assert (values['stalled'], values['stalls']) == ('true', '1')
    assert float(values['stall_since']) == 10.0
    assert float(values['stall_duration']) == float(values['longest_stall']) == 2.0
    assert abs(float(values['stall_x']) + 2.0) < 0.05 and abs(float(values['stall_y'])) < 0.05
    assert abs(float(values['stall_distance_to_goal']) - 5.0) < 0.05
    assert abs(float(values['stall_gained'])) < 0.05
    # Near its spot since it started: 12 s.
    assert float(values['longest_dwell']) == 12.0
    # The neighbour in its way binds: its gap is the means' 0.8 m less the radii, 0.2 m.
    assert values['stall.binding.0.neighbour'] == 'other'
    assert abs(float(values['stall.binding.0.gap']) - 0.2) < 0.05
    result = commands[-1].result
    assert float(values['stall.binding.0.bound']) == round(float(result.neighbour_bounds[0]), 4)
    assert values['stall.binding.0.kind'] in ('cantelli', 'certified')


def test_a_node_s_cpu_times_are_reported_and_none_without():
    agent = PlannerAgent('self', PlannerConfig(), AgentSettings(), goal=[3.0, 0.0])
    command = head_on(agent, np.random.default_rng(3), 1)[-1]
    values = diagnostic_values(plan_status('self', command, 1.0, 'prvo', 0.3, (0.75, 2.5)))
    assert (float(values['plan_cpu_ms']), float(values['node_cpu_ms'])) == (0.75, 2.5)
    values = diagnostic_values(plan_status('self', command, 1.0, 'prvo', 0.3))
    assert (values['plan_cpu_ms'], values['node_cpu_ms']) == ('none', 'none')

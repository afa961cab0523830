"""The planners' beliefs in closed loop are as uncertain as they claim, against ground truth."""

import json

import numpy as np

from prvo_sim.bench.calibration import main
from prvo_sim.engine import InProcessTeam
from prvo_sim.runner.session import planner_values
from prvo_sim.scenario import find_scenario, load_scenario

# chi-squared with 2 degrees of freedom: P(x > 5.991) = 0.05.
CHI2_2_95 = 5.991


def own_position_errors(scenario):
    """Per plan, e' P^-1 e of each planner's own position belief against the truth."""
    team = InProcessTeam(scenario, [planner_values(robot, scenario, 'prvo', None)
                                    for robot in scenario.robots])
    errors = []
    while not team.finished:
        record = team.do_step()
        for index, request in enumerate(team.last_requests):
            error = request.own.mean[:2] - record.states[index, :2]
            errors.append(error @ np.linalg.inv(request.own.covariance[:2, :2]) @ error)
        if all(agent.arrived for agent in team.agents):
            break
    return np.array(errors)


def test_own_position_beliefs_are_calibrated_in_closed_loop(tmp_path):
    # Robots that turn and slow down as they avoid each other: a tracker whose process noise
    # understates how their positions move (the constant-acceleration discretisation) gives a
    # mean of 2.91 here, and 14% beyond the 95% ellipse.
    errors = own_position_errors(load_scenario(find_scenario('circle8'), 7))
    assert errors.size > 500
    assert 1.7 < errors.mean() < 2.4, errors.mean()
    assert 0.02 < np.mean(errors > CHI2_2_95) < 0.09, np.mean(errors > CHI2_2_95)
    # The command reports the same figure.
    report = tmp_path / 'calibration.json'
    assert main(['circle8', '--seeds', '7', '--json', str(report)]) == 0
    rows = json.loads(report.read_text())
    assert abs(rows['own']['position_mean_nees'] - errors.mean()) < 1e-3


def test_an_unknown_scenario_is_one_line_and_exit_2(capsys):
    assert main(['no_such_scenario']) == 2
    error = capsys.readouterr().err.strip()
    assert error.count('\n') == 0 and 'no_such_scenario' in error, error


def test_a_bad_eta_is_one_line_and_exit_2(capsys):
    assert main(['circle8', '--eta', '1.5', '--certificate', 'certified']) == 2
    error = capsys.readouterr().err.strip()
    assert error.count('\n') == 0 and '--eta: 1.5' in error, error

"""Who holds the door and who waits, recorded by an in-process run and drawn (issue 39).

`doorway8` as shipped (seed 7, right of way on), cut to its first 6 s: the robots reach the
door and take turns. The run's recording holds each robot's right of way at every step, as its
planner decided it; trajectories.csv has it, the plot and the GIF draw it, and a run without it
(a ROS run) draws nothing of it.
"""

import csv
import pathlib

import numpy as np
import pytest

from prvo_sim.animation import animate_run
from prvo_sim.engine import InProcessTeam
from prvo_sim.plotting import GOES_LABEL, WAITS_LABEL, draw_turns, plot_run, plt
from prvo_sim.runner.inprocess import recording_of
from prvo_sim.runner.outputs import write_trajectories_csv
from prvo_sim.runner.session import planner_values
from prvo_sim.scenario import load_scenario
from prvo_sim.turns import GOES, NO_PASSAGE, NONE, WAITS

SCENARIOS = pathlib.Path(__file__).resolve().parents[2] / 'src/prvo_sim/scenarios'
SEED = 7


@pytest.fixture(scope='module')
def doorway_run(tmp_path_factory):
    """Return (scenario, recording, each step's decisions by robot) of doorway8's first 6 s."""
    path = tmp_path_factory.mktemp('doorway') / 'doorway8.yaml'
    text = (SCENARIOS / 'doorway8.yaml').read_text()
    path.write_text(text.replace('duration: 90.0', 'duration: 6.0').replace(
        '  certificate: cantelli\n', '  certificate: cantelli\n  right_of_way: true\n'))
    scenario = load_scenario(path, seed=SEED)
    values = [planner_values(robot, scenario, 'prvo', None) for robot in scenario.robots]
    assert all(robot_values['right_of_way'] for robot_values in values)
    team = InProcessTeam(scenario, values, seed=SEED)
    steps, decisions = [], []
    while not team.finished:
        steps.append(team.do_step())
        decisions.append([command.right_of_way for command in team.last_commands])
    return scenario, recording_of(team, steps), decisions


def test_the_recording_holds_each_robots_decision_at_each_step(doorway_run):
    scenario, recording, decisions = doorway_run
    turns = recording.turns
    assert turns.states.shape == turns.passages.shape == recording.states.shape[:2]
    # One door: every robot that goes or waits does so at it.
    assert len(turns.shapes) == 1
    for step, by_robot in enumerate(decisions):
        for robot, decision in enumerate(by_robot):
            if decision is None:
                assert (turns.states[step, robot], turns.passages[step, robot]) == (
                    NONE, NO_PASSAGE)
            else:
                assert turns.states[step, robot] == (GOES if decision.goes else WAITS)
                assert turns.passages[step, robot] == 0
    # The door's cells are where the door is: between the walls' ends at x = 0.
    mask, (x0, _, y0, _) = turns.shapes[0].mask()
    resolution = turns.shapes[0].resolution
    assert mask[int((0.0 - y0) // resolution), int((0.0 - x0) // resolution)]


def test_trajectories_csv_has_each_robots_right_of_way(doorway_run, tmp_path):
    scenario, recording, decisions = doorway_run
    names = [robot.name for robot in scenario.robots]
    path = tmp_path / 'trajectories.csv'
    write_trajectories_csv(path, recording.times, names, recording.states, recording.commands,
                           recording.yaws, recording.turns)
    with open(path) as csv_file:
        rows = list(csv.DictReader(csv_file))
    assert len(rows) == len(decisions) * len(names)
    for row, decision in zip(rows, (decision for by_robot in decisions
                                    for decision in by_robot), strict=True):
        expected = (('none', '') if decision is None
                    else ('goes' if decision.goes else 'waits', '0'))
        assert (row['right_of_way'], row['passage']) == expected
    # Without turns (a ROS run) the columns are there, empty.
    write_trajectories_csv(path, recording.times, names, recording.states, recording.commands)
    with open(path) as csv_file:
        assert {(row['right_of_way'], row['passage'])
                for row in csv.DictReader(csv_file)} == {('', '')}


def test_at_one_step_a_robot_holds_the_door_while_others_wait(doorway_run):
    scenario, recording, _ = doorway_run
    turns = recording.turns
    both = np.flatnonzero(np.any(turns.states == GOES, axis=1)
                          & np.any(turns.states == WAITS, axis=1))
    assert both.size > 0
    step = int(both[0])
    names = [robot.name for robot in scenario.robots]
    ((passage, going, waiting),) = turns.at(step, names)
    assert passage == 0
    assert going == [names[robot] for robot in np.flatnonzero(turns.states[step] == GOES)]
    assert waiting == [names[robot] for robot in np.flatnonzero(turns.states[step] == WAITS)]
    assert going and waiting and not set(going) & set(waiting)


def test_the_plot_and_the_gif_draw_the_turns_and_runs_without_them(doorway_run, tmp_path):
    scenario, recording, _ = doorway_run
    names = [robot.name for robot in scenario.robots]
    starts = np.array([robot.start for robot in scenario.robots])
    goals = np.array([robot.goal for robot in scenario.robots])
    radii = np.array([robot.radius for robot in scenario.robots])
    positions = recording.states[..., :2]
    # The legend names both kinds of robot where a run went and waited, nothing where it
    # recorded no turns.
    figure, axes = plt.subplots()
    labels = [handle.get_label() for handle in draw_turns(axes, recording.times, positions,
                                                          recording.turns)]
    plt.close(figure)
    assert GOES_LABEL in labels and WAITS_LABEL in labels
    drawn = np.concatenate([recording.states, recording.yaws[..., None]], axis=-1)
    for turns in (recording.turns, None):
        folder = tmp_path / ('turns' if turns is not None else 'none')
        folder.mkdir()
        plot_run(folder / 'run.png', recording.times, positions, starts, goals, radii, names,
                 [], 'doorway8', yaws=recording.yaws, static_world=scenario.static_world,
                 turns=turns)
        frames = animate_run(folder / 'run.gif', recording.times, drawn, goals, radii, names,
                             'doorway8', static_world=scenario.static_world, turns=turns,
                             max_frames=10)
        assert frames == 10
        assert (folder / 'run.png').stat().st_size > 0
        assert (folder / 'run.gif').stat().st_size > 0

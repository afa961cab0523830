"""The in-process engine runs the ROS lockstep team's loop: same trajectories, same outputs."""

import csv
import json
import pathlib

from diagnostic_msgs.msg import DiagnosticArray
import pytest
from rclpy.serialization import deserialize_message
from rosbags.highlevel import AnyReader
from runner_testing import output, start_runner
import yaml

SCENARIOS = pathlib.Path(__file__).resolve().parents[2] / 'src/prvo_sim/scenarios'
# A robot and a walker that crosses its path, back and forth, avoiding nobody.
WALKER = """\
name: walker2
seed: 3
dt: 0.1
duration: 14.0
goal_tolerance: 0.2
noise: {position_std: 0.05, velocity_std: 0.05, actuation_std: 0.05}
robots:
  - name: robot_0
    start: [-3.0, 0.0]
    goal: [3.0, 0.0]
    radius: 0.3
    max_speed: 1.0
  - name: walker
    start: [0.5, -2.5]
    radius: 0.3
    max_speed: 1.0
    scripted: {waypoints: [[0.5, 2.5], [0.5, -2.5]], speed: 0.6, loop: true}
"""


def rows_of(path):
    """Return {(time, robot): [x, y, vx, vy, cmd_vx, cmd_vy]} of a trajectories.csv."""
    with open(path) as csv_file:
        return {(row['time'], row['robot']): [
            float(row[key]) if row[key] else None
            for key in ('x', 'y', 'vx', 'vy', 'cmd_vx', 'cmd_vy')]
            for row in csv.DictReader(csv_file)}


@pytest.fixture(scope='module')
def engine_run(tmp_path_factory, module_runners):
    """Return run(scenario, engine): the ended runner of SCENARIO on ENGINE and its output folder.

    Each scenario runs on each engine once a module, the first time a test asks for it: the
    engines' identity on mixed_drive and the mixed team's outcome share its in-process run.
    With its bag, which the identity compares, and without the animation, which no test here
    reads (drawing it cost more than the in-process run of circle8 itself).
    """
    folder = tmp_path_factory.mktemp('engine_runs')
    runs = {}

    def run(scenario, engine):
        if (scenario, engine) not in runs:
            path = SCENARIOS / f'{scenario}.yaml'
            if scenario == 'walker2':
                path = folder / 'walker2.yaml'
                path.write_text(WALKER)
            out = folder / scenario / engine
            runner = start_runner([str(path), '--engine', engine, '--out', str(out), '--quiet',
                                   '--no-animation'], folder, label=f'{scenario}_{engine}')
            module_runners.append(runner)
            runner.wait(timeout=900)
            runs[scenario, engine] = runner, out
        return runs[scenario, engine]

    return run


# In mixed_drive robots arrive (their shares change) near others still planning, and its robots
# at their goal switch their announced share every few steps; half are unicycles (yaw and
# body-frame commands). A switch is stamped with the step whose plan made it and counts from the
# next step, however early it reaches a loaded planner.
@pytest.mark.parametrize('scenario', ['crossing4', 'circle8', 'walker2', 'mixed_drive'])
def test_both_engines_give_the_same_trajectories(scenario, engine_run):
    scripted = {'walker'} if scenario == 'walker2' else set()
    outs = {}
    for engine in ('inprocess', 'ros'):
        runner, outs[engine] = engine_run(scenario, engine)
        assert runner.returncode == 0, output(runner)
    inprocess, ros = (rows_of(outs[engine] / 'trajectories.csv')
                      for engine in ('inprocess', 'ros'))
    # The end is the step at which every robot has been home for the settle time, on both
    # engines: the ROS runner noticing it later changes nothing recorded.
    assert inprocess and set(inprocess) == set(ros)
    # A run's last recorded state may have no command yet (the run ended with it).
    ros_end = max(float(time) for time, _ in ros)
    for key, values in inprocess.items():
        compared = values if ros[key][4] is not None else values[:4]
        if key[1] in scripted:
            # The simulator moves a scripted robot: nobody commands it.
            assert values[4] is None and ros[key][4] is None, (key, values, ros[key])
        elif ros[key][4] is None:
            assert float(key[0]) == ros_end, (key, ros[key])
        assert max(abs(value - ros_value) for value, ros_value in zip(
            compared, ros[key], strict=False)) <= 1e-9, (key, values, ros[key])
    metrics = {engine: json.loads((outs[engine] / 'metrics.json').read_text())
               for engine in outs}
    assert metrics['inprocess']['engine'] == 'inprocess' and metrics['ros']['engine'] == 'ros'
    for engine in outs:
        assert set(metrics[engine]['scripted_robots']) == scripted
        assert metrics[engine]['ending'] == 'arrived'
    # Makespans are first arrivals: within the common steps.
    for key in ('collisions', 'success_rate', 'makespan'):
        assert metrics['inprocess'][key] == pytest.approx(metrics['ros'][key], abs=1e-9)
    # Both bags have the same topics, and the same odometry and ground truth, byte for byte,
    # at every in-process step (the ROS run recorded every step, from t_0).
    bags = {engine: serialized_messages(outs[engine] / 'bag') for engine in outs}
    assert set(bags['inprocess']) == set(bags['ros'])
    robots = {robot for _, robot in inprocess}
    # Scripted robots publish no cmd_vel and no markers.
    assert len(bags['ros']) == 2 + 4 * len(robots) - 2 * len(scripted)
    step_count = len(inprocess) // len(robots)
    ros_output = output(engine_run(scenario, 'ros')[0])
    for topic, messages in bags['inprocess'].items():
        if topic.endswith('/ground_truth'):
            assert messages == bags['ros'][topic], topic
        elif topic.endswith('/odom'):
            # Under heavy load the middleware may drop a sample of a depth-10 publisher before
            # the recorder took it: what the ROS bag holds is the in-process odometry, and a
            # gap is one the runner reported (the ground truth, above, has none: a run that
            # misses one fails).
            held = dict(bags['ros'][topic])
            assert held.items() <= dict(messages).items(), topic
            if len(held) < len(messages):
                assert f'lacks {len(messages) - len(held)} odometry message(s) of ' \
                    f'{topic.split("/")[1]}' in ros_output, topic
        elif topic.endswith('/cmd_vel'):
            # Every step's command but perhaps the last (the ROS run may end before it).
            assert len(bags['ros'][topic]) >= step_count - 1, topic
        elif topic.endswith('/prvo_markers'):
            assert messages and bags['ros'][topic], topic
    # Every planner held the same routes of its neighbours at the same plans: what each
    # published after its plan of a step, from the next step on (statuses come every
    # status_period, of wall time on ROS: compared where both engines reported a plan).
    held = {engine: routes_held(bags[engine]['/diagnostics']) for engine in bags}
    common = set(held['inprocess']) & set(held['ros'])
    assert len(common) >= len(robots) - len(scripted), sorted(held['ros'])
    for key in sorted(common):
        assert held['inprocess'][key] == held['ros'][key], key
    # A scripted walker publishes no route: walker2's robot holds none.
    assert any(int(values[name]) for values in held['ros'].values() for name in values
               if name.endswith('.route_points')) == (len(robots) - len(scripted) > 1)


def routes_held(diagnostics):
    """Return {(robot, plan stamp [ns]): {neighbour route key: value}} of planner statuses.

    DIAGNOSTICS: the serialized DiagnosticArrays of a bag, [(log time ns, message)].
    """
    held = {}
    for _, data in diagnostics:
        message = deserialize_message(data, DiagnosticArray)
        stamp = message.header.stamp.sec * 1_000_000_000 + message.header.stamp.nanosec
        for status in message.status:
            if status.name.startswith('prvo_planner/'):
                held[status.name, stamp] = {
                    pair.key: pair.value for pair in status.values
                    if pair.key.endswith(('.route_points', '.route_stamp'))}
    return held


def serialized_messages(folder):
    """Return {topic: [(log time ns, serialized message)]} of the bag in FOLDER."""
    messages = {}
    with AnyReader([folder]) as reader:
        for connection in reader.connections:
            messages[connection.topic] = []
        for connection, timestamp, data in reader.messages():
            messages[connection.topic].append((timestamp, bytes(data)))
    return messages


def test_mixed_team_arrives_without_contact(engine_run):
    # Robots as they are built (test_runner_kinematics), on the in-process run of mixed_drive:
    # unicycles among holonomic robots, every one home, none touched, every yaw recorded.
    runner, out = engine_run('mixed_drive', 'inprocess')
    assert runner.returncode == 0, output(runner)
    metrics = json.loads((out / 'metrics.json').read_text())
    assert metrics['collisions'] == 0 and metrics['success_rate'] == 1.0, metrics
    with open(out / 'trajectories.csv') as csv_file:
        assert all(row['yaw'] for row in csv.DictReader(csv_file))


def test_a_run_that_reaches_its_duration_ends_at_the_same_step_on_both_engines(tmp_path,
                                                                                 runners):
    """Both engines record the state at the duration and the commands answering it.

    The ROS simulator publishes the state at t = duration and its planners answer it; the
    in-process engine stopped one step earlier (headon2 with duration 2.0 recorded t = 2.0 on
    ROS and ended at t = 1.9 in process).
    """
    document = yaml.safe_load((SCENARIOS / 'headon2.yaml').read_text())
    document['duration'] = 2.0
    path = tmp_path / 'short_headon2.yaml'
    path.write_text(yaml.safe_dump(document))
    rows, metrics = {}, {}
    for engine in ('inprocess', 'ros'):
        out = tmp_path / engine
        runner = start_runner([str(path), '--engine', engine, '--out', str(out), '--quiet',
                               '--no-animation', '--no-bag'], tmp_path, label=engine)
        runners.append(runner)
        assert runner.wait(timeout=300) == 0, output(runner)
        rows[engine] = rows_of(out / 'trajectories.csv')
        metrics[engine] = json.loads((out / 'metrics.json').read_text())
    assert set(rows['inprocess']) == set(rows['ros'])
    assert max(float(time) for time, _ in rows['inprocess']) == pytest.approx(2.0, abs=1e-9)
    for key, values in rows['inprocess'].items():
        assert None not in values and None not in rows['ros'][key], key
        assert max(abs(value - ros_value) for value, ros_value in zip(
            values, rows['ros'][key], strict=True)) <= 1e-9, (key, values, rows['ros'][key])
    for engine in metrics:
        assert metrics[engine]['ending'] == 'duration'
        assert metrics[engine]['sim_time'] == pytest.approx(2.0, abs=1e-9)

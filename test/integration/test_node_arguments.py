"""A node given a --ros-args value that rcl cannot parse says so in one line and exits 2."""

import pytest

pytestmark = pytest.mark.integration


@pytest.mark.parametrize('package, executable, override', [
    ('prvo_sim', 'sim', 'rate:=[nan, 0]'),
    ('prvo_sim', 'nav2_stand_in', 'waypoints:=[1.0, "a"]'),
    ('prvo_sim', 'planner_server_stand_in', 'waypoints:=[1.0, "a"]'),
    ('prvo_planner', 'planner', 'goal:=[nan, 0]'),
])
def test_a_malformed_parameter_override_is_one_line_and_exit_2(children, ros2_executable,
                                                               package, executable, override):
    # rcl rejects a list of mixed types while rclpy initialises, before any node exists.
    process = children.start(executable, [ros2_executable(package, executable), '--ros-args',
                                          '-p', override])
    assert process.wait(timeout=60.0) == 2, children.output(process)
    output = children.output(process)
    fatal = [line for line in output.splitlines() if '[FATAL]' in line]
    assert len(fatal) == 1 and 'invalid parameter' in fatal[0], output
    assert override in fatal[0] and 'Traceback' not in output, output

"""A running planner's parameters: bad values at startup stop it, bad updates are refused."""

import pytest
from rcl_interfaces.msg import Parameter, ParameterType, ParameterValue
from rcl_interfaces.srv import SetParameters

pytestmark = pytest.mark.integration


@pytest.mark.parametrize('argument, named', [
    ('eta:=1.5', 'eta'), ('radius:=-1.0', 'radius'), ('model:=magic', 'model'),
    ('goal:=[1.0, 2.0, 3.0]', 'goal'),
    # A list of mixed types fails in rcl's argument parser, before any parameter exists.
    ('goal:=[nan, 0]', 'goal'), ('goal:=[nan, 0.0]', 'goal'),
])
def test_invalid_parameter_at_startup_exits_non_zero_naming_it(children, ros2_executable,
                                                               argument, named):
    process = children.start('planner', [
        ros2_executable('prvo_planner', 'planner'), '--ros-args', '-r', '__ns:=/robot_0',
        '-p', argument])
    assert process.wait(timeout=30.0) == 2
    output = children.output(process)
    assert 'invalid parameter' in output and named in output, output
    assert 'Traceback' not in output


def _set(probe, client, name, value):
    request = SetParameters.Request(parameters=[Parameter(
        name=name, value=ParameterValue(type=ParameterType.PARAMETER_DOUBLE,
                                        double_value=value))])
    future = client.call_async(request)
    probe.wait_until(future.done, timeout=10.0, what=f'the answer to setting {name}')
    return future.result().results[0]


def test_set_parameters_rejects_bad_values_with_a_reason(children, ros2_executable, probe):
    children.start('planner', [ros2_executable('prvo_planner', 'planner'), '--ros-args',
                               '-r', '__ns:=/robot_0', '-p', 'goal:=[1.0, 0.0]'])
    client = probe.node.create_client(SetParameters, '/robot_0/planner/set_parameters')
    assert client.wait_for_service(timeout_sec=20.0)
    refused = _set(probe, client, 'eta', 1.5)
    assert not refused.successful and 'eta' in refused.reason
    refused = _set(probe, client, 'k', -2.0)
    assert not refused.successful and 'k' in refused.reason
    accepted = _set(probe, client, 'eta', 0.9)
    assert accepted.successful, accepted.reason

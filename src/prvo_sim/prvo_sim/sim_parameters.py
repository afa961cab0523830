"""The simulator node's parameters: their declarations and the rules its on-set callback applies.

Ranges are in the descriptors, which rclpy enforces; `parameter_fault` states the rest.
"""

from rclpy.parameter import Parameter

from prvo_msgs_util import parameter_descriptor
from prvo_sim.observers import observer_name_fault
from prvo_sim.step_timing import MODES

_SECONDS = 3600.0
# name: (default, descriptor), in declaration order.
PARAMETERS = {
    'scenario': ('', parameter_descriptor(
        'Scenario YAML path, or a packaged scenario name', 'str')),
    'mode': ('lockstep', parameter_descriptor(
        'lockstep: step once every robot answered; realtime: wall timer', 'str')),
    'rate': (0.0, parameter_descriptor(
        'Realtime step rate [Hz]; 0 means 1 / the scenario dt', 'float', (0.0, 1000.0))),
    'seed': (-1, parameter_descriptor(
        "Noise seed; -1 uses the scenario file's", 'int', (-1, 2**31 - 1))),
    'stamped_cmd_vel': (True, parameter_descriptor(
        'Subscribe to TwistStamped cmd_vel (false: plain Twist)', 'bool')),
    'step_timeout': (1.0, parameter_descriptor(
        'Lockstep: wall time [s] to wait for every cmd_vel before stepping', 'float',
        (0.001, _SECONDS), read_only=False)),
    'cmd_timeout': (0.5, parameter_descriptor(
        'Wall time [s] without cmd_vel after which a robot executes zero velocity (lockstep: '
        'counted from its first missed deadline)', 'float', (1e-6, _SECONDS), read_only=False)),
    'startup_timeout': (10.0, parameter_descriptor(
        'Wall time [s] the first step waits for every cmd_vel (both modes), re-sending the t_0 '
        'odometry, so that late joiners are in from t_0', 'float', (0.001, _SECONDS))),
    # Typed without a value: an empty list has no type of its own in a ROS parameter.
    'observers': (Parameter.Type.STRING_ARRAY, parameter_descriptor(
        'Fully qualified names of nodes that must subscribe to every ground truth and '
        '/diagnostics before the first step', 'str[]')),
}


def parameter_fault(name, value):
    """Return why VALUE of the simulator parameter NAME is refused, or None if it is not."""
    if name == 'mode' and value not in MODES:
        return f'mode must be one of {", ".join(MODES)}, got {value!r}'
    if name == 'scenario' and not value:
        return 'scenario is required (a YAML path or a name)'
    if name == 'observers':
        for observer in value or []:
            fault = observer_name_fault(observer)
            if fault:
                return fault
    return None

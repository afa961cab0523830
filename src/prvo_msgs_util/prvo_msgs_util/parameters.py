"""Declaring a node's ROS parameters: descriptors with their ranges, parameters left unset."""

import copy

from rcl_interfaces.msg import FloatingPointRange, IntegerRange, ParameterDescriptor
from rclpy.parameter import Parameter

# The ROS type of each kind of parameter, by the names prvo_planner.parameters gives the kinds.
PARAMETER_TYPES = {
    'bool': Parameter.Type.BOOL, 'int': Parameter.Type.INTEGER, 'float': Parameter.Type.DOUBLE,
    'str': Parameter.Type.STRING, 'float[]': Parameter.Type.DOUBLE_ARRAY,
    'str[]': Parameter.Type.STRING_ARRAY,
}


def parameter_descriptor(description, kind, bounds=None, read_only=True, dynamic_typing=False):
    """Return the ParameterDescriptor of a parameter of KIND (a key of PARAMETER_TYPES).

    BOUNDS, an inclusive (low, high) of a 'float' or 'int' parameter, becomes the descriptor's
    range, which rclpy enforces on every set; an integer range takes every integer in it.
    """
    parameter_type = PARAMETER_TYPES[kind]
    descriptor = ParameterDescriptor(description=description, read_only=read_only,
                                     dynamic_typing=dynamic_typing, type=parameter_type.value)
    if bounds is not None and parameter_type == Parameter.Type.DOUBLE:
        descriptor.floating_point_range = [FloatingPointRange(
            from_value=float(bounds[0]), to_value=float(bounds[1]), step=0.0)]
    if bounds is not None and parameter_type == Parameter.Type.INTEGER:
        descriptor.integer_range = [IntegerRange(
            from_value=bounds[0], to_value=bounds[1], step=1)]
    return descriptor


def declare_parameters(node, declarations, is_dumped_unset=None):
    """Declare DECLARATIONS, {name: (default, descriptor)}, on NODE in order; return the values.

    A default may be a Parameter.Type: the parameter is typed without a value. A default of None
    lets the parameter stay unset; `is_dumped_unset(name, value)` then says whether its start-up
    value is the null of a parameters file that `ros2 param dump` wrote, which leaves it unset
    too. A refused value raises rclpy's exception (the on-set callbacks already registered run).
    """
    values = {}
    for name, (default, descriptor) in declarations.items():
        if default is None and is_dumped_unset is not None:
            # Declared writable first, to be declared again: a read-only parameter cannot be
            # unset once declared with the dumped value.
            writable = copy.copy(descriptor)
            writable.read_only = False
            value = node.declare_parameter(name, default, writable).value
            node.undeclare_parameter(name)
            values[name] = node.declare_parameter(
                name, default, descriptor, ignore_override=is_dumped_unset(name, value)).value
        else:
            values[name] = node.declare_parameter(name, default, descriptor).value
    return values

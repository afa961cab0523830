"""Building and reading diagnostic_msgs messages."""

from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue

from prvo_msgs_util.conversions import seconds_to_stamp


def _value_text(value):
    # Lower-case booleans match the interface's `finished: true`; repr keeps floats exact.
    if isinstance(value, bool):
        return 'true' if value else 'false'
    if isinstance(value, float):
        return repr(value)
    return str(value)


def make_diagnostic_status(name, message, values, level=DiagnosticStatus.OK, hardware_id=''):
    """Return a DiagnosticStatus whose key/values are VALUES stringified (floats with repr)."""
    return DiagnosticStatus(
        level=level, name=name, message=message, hardware_id=hardware_id,
        values=[KeyValue(key=str(key), value=_value_text(value)) for key, value in values.items()])


def diagnostic_values(status):
    """Return the key/values of a DiagnosticStatus as a dict of strings."""
    return {pair.key: pair.value for pair in status.values}


def make_diagnostic_array(stamp_seconds, statuses):
    """Return a DiagnosticArray stamped STAMP_SECONDS holding STATUSES."""
    msg = DiagnosticArray(status=list(statuses))
    msg.header.stamp = seconds_to_stamp(stamp_seconds)
    return msg

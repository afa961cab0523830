"""Stop signals in a node's main(): held while it starts, ignored once it has stopped."""

import signal

STOP_SIGNALS = (signal.SIGINT, signal.SIGTERM)


def ignore_stop_signals():
    """
    Ignore SIGINT and SIGTERM from now on: call it last in main(), after rclpy.try_shutdown().

    The node is stopped, so a further signal (``ros2 launch`` and the terminal both pass Ctrl-C
    on) has nothing left to stop. A Python handler would not do: while the interpreter
    finalizes, Python gives such a signal its default action back, and one landing while the
    middleware tears down would kill the process (exit code -2). An ignored one stays ignored.
    """
    for signal_number in STOP_SIGNALS:
        signal.signal(signal_number, signal.SIG_IGN)


def hold_stop_signals():
    """
    Hold SIGINT and SIGTERM back until `release_stop_signals()`; call first in main().

    A stop signal landing while rcl initialises, or just after rclpy installed its handlers,
    was lost now and then, leaving a node that ignored it. Threads started meanwhile (DDS)
    inherit the mask, so afterwards the main thread receives every stop signal.

    The Python handlers of both signals are made to do nothing: rclpy's handlers, installed by
    init(), shut the context down (which ends spinning) and then call these. Python's default, a
    KeyboardInterrupt, would land inside whatever callback is running, which the events
    executor reports as a FATAL exception with a traceback.
    """
    for signal_number in STOP_SIGNALS:
        signal.signal(signal_number, lambda signal_number, frame: None)
    signal.pthread_sigmask(signal.SIG_BLOCK, STOP_SIGNALS)


def release_stop_signals():
    """Let stop signals in again; return False if one came while they were held.

    One that came is taken here, without a handler: the node is to stop before spinning, and
    the signals stay held.
    """
    if signal.sigtimedwait(STOP_SIGNALS, 0) is not None:
        return False
    signal.pthread_sigmask(signal.SIG_UNBLOCK, STOP_SIGNALS)
    return True

"""The planner's background worker: in order, one at a time, and never keeping a process alive."""

import subprocess
import sys
import threading

import pytest

from prvo_planner.background import BackgroundWorker


def test_calls_run_in_order_one_at_a_time_and_their_futures_carry_results_and_errors():
    worker = BackgroundWorker('test_worker')
    running, seen = [], []

    def record(value):
        running.append(value)
        assert len(running) == 1, 'two calls at once'
        seen.append(value)
        running.pop()
        return value * 2

    futures = [worker.submit(record, value) for value in range(20)]
    assert [future.result(timeout=60) for future in futures] == [2 * v for v in range(20)]
    assert seen == list(range(20))
    failing = worker.submit(int, 'not a number')
    with pytest.raises(ValueError):
        failing.result(timeout=60)


def test_shutdown_cancels_the_calls_not_started():
    worker = BackgroundWorker('test_worker')
    release = threading.Event()
    started = threading.Event()

    def block():
        started.set()
        release.wait()

    running = worker.submit(block)
    assert started.wait(timeout=60)
    waiting = worker.submit(int, '1')
    worker.shutdown()
    release.set()
    assert waiting.cancelled() and running.result(timeout=60) is None


def test_a_call_still_running_does_not_keep_the_process_alive():
    """A stopped planner building a large map waited for the build (16 s at 2500 x 2500)."""
    script = ('import threading\n'
              'from prvo_planner.background import BackgroundWorker\n'
              "worker = BackgroundWorker('map_builder')\n"
              'worker.submit(threading.Event().wait)\n'
              "print('main ends')\n")
    # With a ThreadPoolExecutor the interpreter joins its worker at exit: this never ends.
    finished = subprocess.run([sys.executable, '-c', script], capture_output=True, text=True,
                              timeout=120)
    assert finished.returncode == 0 and finished.stdout == 'main ends\n'

"""A planning process keeps the heap its plans free: no page faults per plan at 50 neighbours."""

import ctypes
import os
import subprocess
import sys

import pytest

from prvo_planner import heap

# Ten plans of the benchmark's 50-neighbour encounter after three warm-up plans, in a fresh
# process (what glibc returns to the kernel depends on the process's history); prints their
# minor page faults.
FAULTS_SCRIPT = """
import resource
import sys

from prvo_planner.bench import bench_encounter
from prvo_planner.core import PlannerConfig, plan_velocity
from prvo_planner.heap import keep_freed_heap

if sys.argv[1] == 'keep':
    assert keep_freed_heap()
config = PlannerConfig(model='prvo', method='exact')
ego, neighbours = bench_encounter(50)
for _ in range(3):
    plan_velocity(ego, neighbours, [1.0, 0.0], config)
before = resource.getrusage(resource.RUSAGE_SELF).ru_minflt
for _ in range(10):
    plan_velocity(ego, neighbours, [1.0, 0.0], config)
print(resource.getrusage(resource.RUSAGE_SELF).ru_minflt - before)
"""


def _faults_per_plan(mode):
    # glibc's own defaults in the child: no tunables from the caller's environment.
    env = {name: value for name, value in os.environ.items()
           if not name.startswith('MALLOC_') and name != 'GLIBC_TUNABLES'}
    finished = subprocess.run([sys.executable, '-c', FAULTS_SCRIPT, mode], capture_output=True,
                              text=True, timeout=120, check=True, env=env)
    return int(finished.stdout) / 10


@pytest.mark.skipif(not hasattr(ctypes.CDLL(None), 'mallopt'),
                    reason='this C library has no mallopt')
def test_plans_at_50_neighbours_fault_no_pages_in_once_the_heap_is_kept():
    kept, default = _faults_per_plan('keep'), _faults_per_plan('default')
    # glibc's defaults return a plan's arrays to the kernel and fault them in again, about
    # 1,000 pages per plan; kept, a plan touches only what the heap already holds.
    assert kept < 10
    assert default > 100


class _WithoutMallopt:
    """A C library without mallopt, as musl and macOS's are to ctypes."""


def test_without_mallopt_nothing_is_set(monkeypatch):
    monkeypatch.setattr(heap.ctypes, 'CDLL', lambda name: _WithoutMallopt())
    assert heap.keep_freed_heap() is False

"""A planner's warm-up loads every compiled kernel its first plans need (docs/interfaces.md)."""

import subprocess

# A fresh process: an agent with the planner node's defaults (the certified bound), warmed up as
# the node warms it before spinning. The kernels are numba functions compiled once by setup and
# loaded from its cache on their module's import: after the warm-up no plan imports one.
PROBE = """
import sys
from prvo_planner.agent import AgentSettings, PlannerAgent
from prvo_planner.parameters import DEFAULTS, planner_config_from
agent = PlannerAgent('self', planner_config_from({}), AgentSettings.from_parameters(DEFAULTS))
before = sorted(m for m in sys.modules if m.startswith('prvo_planner.core.'))
agent.warm_up()
print(sorted(m for m in ('prvo_planner.core.ray_search', 'prvo_planner.core.wedge_bound')
             if m in sys.modules and m not in before))
"""


def test_the_warm_up_loads_the_ray_search_and_the_wedge_bound(python_executable):
    output = subprocess.run([python_executable, '-c', PROBE], capture_output=True, text=True,
                            check=True).stdout
    assert output.strip() == "['prvo_planner.core.ray_search', 'prvo_planner.core.wedge_bound']"

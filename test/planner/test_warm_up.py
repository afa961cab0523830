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
kernels = ('prvo_planner.core.ray_search', 'prvo_planner.core.certificate_kernels')
print(sorted(m for m in kernels if m in sys.modules and m not in before))
"""


def test_the_warm_up_loads_the_ray_search_and_the_certificate(python_executable):
    output = subprocess.run([python_executable, '-c', PROBE], capture_output=True, text=True,
                            check=True).stdout
    assert output.strip() == str(['prvo_planner.core.certificate_kernels',
                                  'prvo_planner.core.ray_search'])

"""
Numerical core of PRVO: plain numpy, no ROS imports.

The public API is re-exported here; everything else in this package is internal.
"""

from .beliefs import AgentBelief
from .certificate import Certificate, receding_certificate, rvo_certificate
from .config import PlannerConfig, PlanResult
from .limits import VelocityLimits
from .moments import rvo_moments
from .planner import plan_velocities, plan_velocity
from .probability import eta_from_k, k_from_eta, rvo_satisfaction_probability

__all__ = ['AgentBelief', 'Certificate', 'PlanResult', 'PlannerConfig', 'eta_from_k',
           'k_from_eta', 'plan_velocities', 'plan_velocity', 'receding_certificate',
           'rvo_certificate', 'rvo_moments', 'rvo_satisfaction_probability', 'VelocityLimits']

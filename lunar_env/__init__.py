"""lunar_env: dynamics, scenarios and Gymnasium environments for lunar powered descent."""

from . import dynamics, envs, integrators
from .scaling import Scaling
from .scenarios import get_scenario, list_scenarios, register_scenario

__all__ = ["dynamics", "envs", "integrators", "Scaling", "get_scenario", "list_scenarios",
           "register_scenario"]

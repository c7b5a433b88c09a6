"""mslab: a numerical-methods workbench for mass-spring systems.

Public API (see DESIGN.md); this module only re-exports (and, on the command line, makes a
Ctrl-C during the imports below end with exit 130 and one line: :mod:`mslab.interrupts`).
"""

# ruff: noqa: E402  (the imports below come after the Ctrl-C handling of the command line)
from mslab import interrupts

interrupts.starting()

from mslab.errors import ConvergenceError, InstabilityError, MslabError, SceneError, StabilityWarning
from mslab.integrators import (
    COURSE_METHODS,
    ExplicitRK,
    ImplicitRK,
    Integrator,
    Splitting,
    get_method,
    methods,
)
from mslab.integrators.base import set_order_check
from mslab.scenes import Scene, SceneBuilder, Settings, load_scene, scene_names
from mslab.simulate import Simulation, SimulationInterrupted, simulate
from mslab.state import State
from mslab.stopping import set_stable_dt_predictor
from mslab.system import System
from mslab.trajectory import Energy, Stats, Trajectory

__version__ = "0.1.0"


def _check_declared_order(method: Integrator) -> None:
    """Check a declared order for the registry (mslab.derive sits above it: wired here, loaded on use)."""
    from mslab.derive.declared import check_declared_order

    check_declared_order(method)


set_order_check(_check_declared_order)


def _predicted_stable_dt(scene: Scene, method: Integrator) -> float | None:
    """Return the run pre-check's stable dt (mslab.stability sits above it: wired here, loaded on use)."""
    from mslab.stability import predicted_stable_dt

    return predicted_stable_dt(scene, method)


set_stable_dt_predictor(_predicted_stable_dt)


def __getattr__(name: str):
    """``mslab.stability``, ``mslab.derive``, ``mslab.precision``, ``mslab.plots`` on first use.

    They import scipy.linalg, sympy, scipy.integrate and matplotlib, which a plain run
    never needs (``import mslab`` stays cheap).
    """
    if name in ("stability", "derive", "precision", "plots"):
        import importlib

        return importlib.import_module(f"mslab.{name}")
    raise AttributeError(f"module 'mslab' has no attribute {name!r}")


__all__ = [
    "COURSE_METHODS", "ConvergenceError", "Energy", "ExplicitRK", "ImplicitRK", "InstabilityError",
    "Integrator", "Splitting",
    "MslabError", "Scene", "SceneBuilder", "SceneError", "Settings", "Simulation", "SimulationInterrupted",
    "StabilityWarning", "State", "Stats", "System", "Trajectory", "get_method", "load_scene", "methods",
    "scene_names", "simulate",
    "stability",
]

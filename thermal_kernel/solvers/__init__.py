"""Explicit, implicit and steady solvers on one assembled network (docs/solvers.md).

    run_explicit(problem, T0, times, ...)  forward Euler, numba, exact positivity bound
    run_implicit(problem, T0, times, dt=..., theta=1.0 | 0.5, ...)  theta-scheme, any dt
    solve_steady(problem, T0=None, ...)  one sparse solve

``problem`` is a :class:`~thermal_kernel.network.ThermalProblem` or an already assembled
:class:`~thermal_kernel.network.Network` (assemble once, run many). ``T0`` is an (N,) array or
the ``state`` of a previous result, to resume. All return a :class:`ThermalResult`.
"""
from .common import (  # noqa: F401  what callers and docstrings take from the package
    LEDGER_RTOL,
    MAX_PRINCIPLE_RTOL,
    TEMPERATURE_MAX_K,
    PhysicsCheck,
    PrincipleInputs,
    Recorder,
    SolverState,
    ThermalResult,
    UnstableTimeStepError,
    blas_threads,
    check_physics,
    interval_steps,
    max_principle_bounds,
    principle_inputs,
)
from .explicit import run_explicit, explicit_step_reference  # noqa: E402
from .implicit import run_implicit  # noqa: E402
from .steady import solve_steady  # noqa: E402

__all__ = ["run_explicit", "run_implicit", "solve_steady", "explicit_step_reference",
           "check_physics", "max_principle_bounds", "principle_inputs", "PrincipleInputs",
           "PhysicsCheck", "TEMPERATURE_MAX_K",
           "ThermalResult", "SolverState", "UnstableTimeStepError"]

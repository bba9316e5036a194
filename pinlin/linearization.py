"""``pinlin.linearize``: scene in, :class:`~pinlin.linear_model.LinearModel` out."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pinocchio as pin

from .derivatives import BACKENDS
from .equilibrium import require_equilibrium_support, solve_constrained
from .exceptions import PinlinError, ShapeError
from .formulations import (
    FORMULATIONS,
    linearize_canonical,
    linearize_independent,
    linearize_penalty,
    linearize_reduced,
)
from .formulations.constrained import penalty_parameters
from .linear_model import LinearModel
from .operating_point import OperatingPoint, configuration, hold_at_rest
from .scene import Scene
from .system import System


def operating_point(system: System, *, q: np.ndarray | None = None,
                    allow_non_equilibrium: bool | None = None,
                    mass_inverse: np.ndarray | None = None) -> OperatingPoint:
    """The operating point the scene asks for (``q`` replaces the whole configuration).

    ``mass_inverse`` is M(q0)^-1 when the caller has it already.
    """
    q0 = _configuration(system, q)
    spec = system.scene.operating_point
    allow = spec.allow_non_equilibrium if allow_non_equilibrium is None else allow_non_equilibrium
    return hold_at_rest(system, q0, allow_non_equilibrium=allow, mass_inverse=mass_inverse)


def _configuration(system: System, q: np.ndarray | None) -> np.ndarray:
    """q0 from the scene, or the validated override ``q``."""
    if q is None:
        q0 = configuration(system)
    else:
        q0 = np.asarray(q, dtype=float)
        if q0.shape != (system.nq,):
            raise ShapeError(f"q must have nq = {system.nq} entries for scene "
                             f"'{system.scene.name}', got shape {q0.shape}")
        if not np.all(np.isfinite(q0)):
            raise ShapeError("q contains NaN or inf")
        if not pin.isNormalized(system.model, q0, 1e-6):
            raise ShapeError("q is not normalized: its quaternion or (cos, sin) parts must have "
                             "unit norm")
    return q0


def linearize(scene: Scene | System | str | Path, *, formulation: str = "independent",
              derivatives: str = "analytic", step: float | None = None,
              q: np.ndarray | None = None, allow_non_equilibrium: bool | None = None,
              basis: str = "partitioned", alpha: float | None = None, mu: float | None = None,
              omega: float | None = None, estimate_error: bool = True) -> LinearModel:
    """Linear state-space model of a scene about its operating point.

    Args:
        scene: A :class:`Scene`, its :class:`System`, or a scene file / URDF / bundled scene /
            robot name. A scene caches its system, so repeated calls skip the model loading.
        formulation: ``"independent"`` (chapter 9.1.1), ``"penalty"`` (9.1.2, dependent
            coordinates) or ``"canonical"`` (9.1.3, momenta and dependent coordinates).
        derivatives: ``"analytic"`` (Pinocchio), ``"fd3"`` or ``"fd5"`` (chapter 9.2).
        step: Finite-difference step for ``fd3``/``fd5``: one number for all, or a table
            ``{"q": [rad or m], "v": [rad/s or m/s], "u": [N*m or N]}``; default
            ``pinlin.derivatives.DEFAULT_STEPS``.
        estimate_error: With ``fd3``/``fd5``, also evaluate the companion formula and report
            ``model.info["error_estimate"]`` (relative error of A; fd3 at 2x, fd5 at 1.5x cost).
        q: Full configuration (size nq) replacing the scene's operating point.
        allow_non_equilibrium: Override the scene's ``operating_point.allow_non_equilibrium``.
        basis: Independent coordinates of a constrained system: ``"partitioned"`` (the
            independent joints z) or ``"orthonormal"`` (an orthonormal nullspace basis of Phi_q).
        alpha, mu, omega: Penalty factor [kg (or kg*m^2) per constraint unit^2], damping ratio
            [-] and natural frequency [rad/s] of the constraint violation (penalty, canonical);
            defaults 1e7, 1.0, 10.0.

    Returns:
        The model, with x = [dq; v] (names ``q:<coordinate>``, ``v:<coordinate>``), inputs
        ``u:<coordinate>`` and the scene's outputs.
    """
    if isinstance(scene, str | Path):
        scene = Scene.resolve(scene)
    system = scene if isinstance(scene, System) else scene.system
    if formulation not in FORMULATIONS:
        raise PinlinError(f"unknown formulation '{formulation}'; expected one of "
                          f"{', '.join(FORMULATIONS)}")
    if derivatives not in BACKENDS:
        raise PinlinError(f"unknown derivatives '{derivatives}'; expected one of "
                          f"{', '.join(BACKENDS)}")
    if alpha is not None or mu is not None or omega is not None:
        penalty_parameters(alpha, mu, omega)  # bad values are errors whatever the formulation
        if formulation == "independent":
            raise PinlinError("alpha, mu and omega set the penalty and canonical formulations; "
                              "the independent formulation has no penalty")
    q0 = _configuration(system, q)
    if allow_non_equilibrium is None:
        allow_non_equilibrium = system.scene.operating_point.allow_non_equilibrium
    if (system.constraints or formulation != "independent"
            or system.scene.operating_point.solve != "inputs"):
        require_equilibrium_support(system)
        op, cp = solve_constrained(system, q0, allow_non_equilibrium=allow_non_equilibrium)
        if formulation == "independent":
            return linearize_reduced(system, op, cp, derivatives=derivatives, step=step,
                                     basis=basis, estimate_error=estimate_error)
        build = linearize_penalty if formulation == "penalty" else linearize_canonical
        return build(system, op, cp, derivatives=derivatives, step=step, alpha=alpha, mu=mu,
                     omega=omega, estimate_error=estimate_error)
    Minv = system.mass_inverse(q0)  # shared by the operating point and the model
    op = hold_at_rest(system, q0, allow_non_equilibrium=allow_non_equilibrium, mass_inverse=Minv)
    return linearize_independent(system, op, derivatives=derivatives, step=step,
                                 mass_inverse=Minv, estimate_error=estimate_error)

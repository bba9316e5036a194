"""How to linearize: the formulation and the derivatives, as small option objects.

Each option object carries exactly the settings that apply to it, so an option that does not
apply cannot be given (a penalty factor belongs to :class:`Penalty`, a step to
:class:`FiniteDifferences`). ``pinlin.linearize`` takes them, or the string shortcuts and
keyword arguments of earlier versions (``formulation="penalty", alpha=1e6``), which
:func:`formulation_from` and :func:`derivatives_from` turn into objects with the same checks::

    pinlin.linearize(scene, formulation=pinlin.Penalty(alpha=1e6, mu=0.5),
                     derivatives=pinlin.FiniteDifferences(order=5, step=1e-3))

Formulations (chapter 9.1): :class:`Independent` (9.1.1, with a ``basis`` for constrained
systems), :class:`Penalty` (9.1.2) and :class:`Canonical` (9.1.3). Derivatives (chapter 9.2):
:class:`Analytic` (Pinocchio) and :class:`FiniteDifferences` (3- or 5-point).
"""

from __future__ import annotations

import math
import numbers
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np

from .exceptions import ArgumentError
from .fields import show

#: Default penalty parameters: alpha [kg or kg*m^2 per row unit^2], Omega [rad/s], mu [-].
PENALTY_DEFAULTS = {"alpha": 1e7, "omega": 10.0, "mu": 1.0}
#: Largest alpha, alpha Omega^2 and 2 alpha mu Omega accepted (the penalty formulation keeps
#: its accuracy to alpha = 1e14, validation/reports/penalty_conditioning.md; beyond 1e100
#: products with the mass matrix and Phi_q^T Phi_q approach float overflow).
PENALTY_LIMIT = 1e100
BASES = ("partitioned", "orthonormal")


def _positive(name: str, value: Any) -> float:
    """A finite number > 0, or an ArgumentError naming ``name``."""
    try:
        if isinstance(value, bool | np.bool_ | str):
            raise TypeError
        out = float(value)
    except (TypeError, ValueError, OverflowError):
        raise ArgumentError(name, f"penalty {name} must be a number, got {show(value)}") \
            from None
    if not (math.isfinite(out) and out > 0):
        raise ArgumentError(name, f"penalty {name} must be a finite number > 0, got {show(value)}")
    return out


@dataclass(frozen=True)
class Independent:
    """Independent coordinates (chapter 9.1.1): q' = R z'.

    Attributes:
        basis: For constrained systems: ``"partitioned"`` (the independent joints z) or
            ``"orthonormal"`` (an orthonormal nullspace basis of Phi_q); None: partitioned
            where it applies (an open chain's joints are independent already).
    """

    basis: str | None = None
    name = "independent"

    def __post_init__(self) -> None:
        if self.basis is not None and (not isinstance(self.basis, str)
                                       or self.basis not in BASES):
            raise ArgumentError("basis", f"expected one of {', '.join(map(repr, BASES))}, got "
                                         f"{show(self.basis)}")


@dataclass(frozen=True)
class Penalty:
    """Dependent coordinates with the penalty formulation (chapter 9.1.2).

    Attributes:
        alpha: Penalty factor [kg or kg*m^2 per constraint unit^2], > 0.
        mu: Damping ratio of the constraint violation [-], > 0.
        omega: Natural frequency of the constraint violation [rad/s], > 0.
    """

    alpha: float = PENALTY_DEFAULTS["alpha"]
    mu: float = PENALTY_DEFAULTS["mu"]
    omega: float = PENALTY_DEFAULTS["omega"]
    name = "penalty"

    def __post_init__(self) -> None:
        for key in ("alpha", "mu", "omega"):
            object.__setattr__(self, key, _positive(key, getattr(self, key)))
        a, m, w = self.alpha, self.mu, self.omega
        # The penalty's mass, stiffness and damping per unit constraint: beyond the limit
        # their products with M and Phi_q overflow (and physics left long before, 1e14).
        for key, what, value in (("alpha", "alpha", a), ("omega", "alpha * omega^2", a * w * w),
                                 ("mu", "2 alpha mu omega", 2.0 * a * m * w)):
            if not value <= PENALTY_LIMIT:
                raise ArgumentError(key, f"the penalty terms must stay within "
                                         f"{PENALTY_LIMIT:g}: {what} = {value:.3g} with "
                                         f"alpha = {a:g}, mu = {m:g}, omega = {w:g}")


@dataclass(frozen=True)
class Canonical(Penalty):
    """Canonical (momentum) form of the penalty model (chapter 9.1.3): state [p; q]."""

    name = "canonical"


@dataclass(frozen=True)
class Analytic:
    """Pinocchio's analytic derivatives (RNEA derivatives, frame Jacobian variations)."""

    name = "analytic"
    step = None
    estimate_error = False


@dataclass(frozen=True)
class FiniteDifferences:
    """Central finite differences of the equations of motion (chapter 9.2).

    Attributes:
        order: 3 (eq. 9.54, O(h^2)) or 5 (eq. 9.55, O(h^4)) points.
        step: One step for all variables, or a table ``{"q": [rad or m], "v": [rad/s or
            m/s], "u": [N*m or N]}``, each in [1e-10, 0.1]; None: the defaults
            (``pinlin.derivatives.DEFAULT_STEPS``).
        estimate_error: Also report ``model.info["error_estimate"]`` (a bound on the relative
            error of A; costs the companion formula's evaluations).
    """

    order: int = 5
    step: float | Mapping[str, float] | None = None
    estimate_error: bool = True

    def __post_init__(self) -> None:
        from .derivatives import resolve_steps

        order = self.order          # 3 or np.int64(3); 3.0 and True are refused
        if isinstance(order, bool) or not isinstance(order, numbers.Integral) \
                or order not in (3, 5):
            raise ArgumentError("order", f"expected 3 or 5 points, got {show(order)}")
        object.__setattr__(self, "order", int(order))
        if not isinstance(self.estimate_error, bool):
            raise ArgumentError("estimate_error", f"expected True or False, got "
                                                  f"{show(self.estimate_error)}")
        resolve_steps(self.name, self.step)  # checks the step

    @property
    def name(self) -> str:
        return f"fd{self.order}"


Formulation = Independent | Penalty | Canonical
Derivatives = Analytic | FiniteDifferences
FORMULATIONS = {"independent": Independent, "penalty": Penalty, "canonical": Canonical}
DERIVATIVES = ("analytic", "fd3", "fd5")


def formulation_from(formulation: Any, basis: Any = None, alpha: Any = None, mu: Any = None,
                     omega: Any = None) -> Formulation:
    """An option object from ``linearize``'s arguments: an object as given, or a string
    shortcut with the keyword settings that apply to it (the others refused alike)."""
    given = {k: v for k, v in (("alpha", alpha), ("mu", mu), ("omega", omega))
             if v is not None}
    if isinstance(formulation, Independent | Penalty):
        extra = [k for k, v in (("basis", basis), *given.items()) if v is not None]
        if extra:
            raise ArgumentError(extra[0], f"set it on the {type(formulation).__name__} "
                                          "object given as formulation, not beside it")
        return formulation
    if not isinstance(formulation, str) or formulation not in FORMULATIONS:
        raise ArgumentError("formulation", f"expected one of "
                                           f"{', '.join(map(repr, FORMULATIONS))} or an option "
                                           f"object (pinlin.Penalty(...)), got {show(formulation)}")
    if formulation == "independent":
        for key, value in given.items():
            _positive(key, value)  # a bad value is reported as such first
            raise ArgumentError(key, "alpha, mu and omega set the penalty and canonical "
                                     "formulations; the independent formulation has no "
                                     "penalty")
        return Independent(basis)
    if basis is not None:
        Independent(basis)
        raise ArgumentError("basis", f"the {formulation} formulation keeps the dependent "
                                     "coordinates; a basis of independent coordinates applies "
                                     "to the independent formulation")
    return FORMULATIONS[formulation](**given)


def derivatives_from(derivatives: Any, step: Any = None, estimate_error: Any = True
                     ) -> Derivatives:
    """An option object from ``linearize``'s arguments (see :func:`formulation_from`)."""
    if isinstance(derivatives, Analytic | FiniteDifferences):
        if step is not None:
            raise ArgumentError("step", f"set it on the {type(derivatives).__name__} object "
                                        "given as derivatives, not beside it")
        if estimate_error is not True:
            raise ArgumentError("estimate_error", "set it on the FiniteDifferences object given "
                                                  "as derivatives, not beside it")
        return derivatives
    if not isinstance(derivatives, str) or derivatives not in DERIVATIVES:
        raise ArgumentError("derivatives", f"expected one of {', '.join(map(repr, DERIVATIVES))}"
                                           f" or an option object (pinlin.FiniteDifferences("
                                           f"...)), got {show(derivatives)}")
    if not isinstance(estimate_error, bool):
        raise ArgumentError("estimate_error", f"expected True or False, got {show(estimate_error)}")
    if derivatives == "analytic":
        if step is not None:
            raise ArgumentError("step", "a finite-difference step applies to derivatives "
                                        "'fd3' and 'fd5'; the analytic derivatives take none")
        return Analytic()
    return FiniteDifferences(order=int(derivatives[2]), step=step,
                             estimate_error=estimate_error)


__all__ = ["BASES", "PENALTY_DEFAULTS", "Analytic", "Canonical", "Derivatives",
           "FiniteDifferences", "Formulation", "Independent", "Penalty", "derivatives_from",
           "formulation_from"]

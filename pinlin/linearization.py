"""``pinlin.linearize`` and ``pinlin.operating_point``: scene in, model or point out.

Both resolve the operating point the same way (:func:`resolve_operating_point`): a scene with
constraints (loops, contacts, mimic couplings) or with ``solve = "positions"`` or ``"forces"``
goes through the assembly and the constrained statics of :mod:`pinlin.equilibrium` (on a
floating base too: a standing robot); an open chain held by its inputs through
:func:`pinlin.operating_point.hold_at_rest`.

Every argument is checked before any work: a wrong type, a value out of range or an option that
does not apply to the request (a step with analytic derivatives, a basis without loops, a
penalty with the independent formulation) is an :class:`~pinlin.exceptions.ArgumentError`.
"""

from __future__ import annotations

import math
import warnings
from collections.abc import Mapping
from os import PathLike
from pathlib import Path

import numpy as np
import pinocchio as pin

from .arrays import non_numbers, real_array
from .conditioning import AccuracyWarning, refuse_condition, singular_to_working_precision
from .equilibrium import ConstrainedPoint, input_vector, solve_constrained
from .exceptions import ArgumentError, ModelError, ShapeError
from .fields import show
from .formulations import (
    linearize_canonical,
    linearize_independent,
    linearize_penalty,
    linearize_reduced,
)
from .formulations.motion import (
    linearize_moving,
    linearize_moving_penalty,
    moving_point,
    refuse_unsupported,
    singular_dynamics,
)
from .linear_model import LinearModel
from .operating_point import (
    OperatingPoint,
    at_state,
    configuration,
    hold_at_rest,
    velocity_vector,
)
from .options import (
    PENALTY_DEFAULTS,
    Analytic,
    Canonical,
    Derivatives,
    Formulation,
    Independent,
    Penalty,
    derivatives_from,
    formulation_from,
)
from .scene import COEFFICIENT_LIMIT, POSITION_LIMIT, Scene
from .system import System

#: A numerical model whose estimated relative error of A exceeds this gets an AccuracyWarning
#: (fewer than ~6 significant digits, the level at which a condition estimate warns too).
WARN_ERROR_ESTIMATE = 1e-6
#: What ``formulation="independent", derivatives="analytic"`` (the defaults) stand for: option
#: objects are frozen, so one instance serves every call.
_INDEPENDENT = Independent()
_ANALYTIC = Analytic()


def _system(scene: object) -> System:
    """The system of a Scene, a System, or a scene file / URDF / bundled scene / robot name."""
    if isinstance(scene, System):
        return scene
    if isinstance(scene, Scene):
        return scene.system
    if isinstance(scene, str | PathLike):
        return Scene.resolve(scene).system
    raise ArgumentError("scene", "expected a pinlin.Scene, a pinlin.System, or a scene file, "
                                 "URDF, bundled scene or robot name (str or path), got "
                                 f"{type(scene).__name__}")


def _flag(name: str, value: object) -> bool | None:
    """A boolean option (None: not given); strings such as "no" are refused, not truthy."""
    if value is None or isinstance(value, bool | np.bool_):
        return None if value is None else bool(value)
    raise ArgumentError(name, f"expected True or False, got {show(value)}")


def _choice(name: str, value: object, choices: tuple[str, ...]) -> str:
    if not isinstance(value, str) or value not in choices:
        raise ArgumentError(name, f"expected one of {', '.join(repr(c) for c in choices)}, got "
                                  f"{show(value)}")
    return value


def _configuration(system: System, q: object) -> np.ndarray:
    """q0 from the scene, or the validated override ``q`` (size nq, finite, normalized)."""
    if q is None:
        return configuration(system)
    bad = non_numbers(q)
    if bad:
        raise ArgumentError("q", f"expected real numbers (the configuration), got {bad}")
    try:
        q0 = np.array(q, dtype=float)
    except (TypeError, ValueError, OverflowError):
        raise ArgumentError("q", f"expected {system.nq} numbers (the configuration of scene "
                                 f"'{system.scene.name}'), got {show(q)}") from None
    if q0.shape != (system.nq,):
        raise ShapeError(f"q must have nq = {system.nq} entries for scene "
                         f"'{system.scene.name}', got shape {q0.shape}")
    if not np.all(np.isfinite(q0)):
        raise ShapeError("q contains NaN or inf")
    if np.abs(q0).max(initial=0.0) > POSITION_LIMIT:
        raise ShapeError(f"q has an entry of size {np.abs(q0).max():.3g}; positions and angles "
                         f"are limited to |q| <= {POSITION_LIMIT:g} m or rad (beyond, float "
                         "spacing approaches the finite-difference steps)")
    if not pin.isNormalized(system.model, q0, 1e-6):
        raise ShapeError("q is not normalized: its quaternion or (cos, sin) parts must have "
                         "unit norm")
    return q0


def _given_state(system: System, v: object, u: object) -> tuple[np.ndarray, np.ndarray] | None:
    """(v0, u0) when the state is given rather than solved for: ``v`` or ``u`` passed, or the
    scene's ``solve = "none"`` (its ``v`` and ``u`` tables, zeros elsewhere); else None."""
    spec = system.scene.operating_point
    if v is None and u is None and spec.solve != "none":
        return None
    v0 = velocity_vector(system, spec.v) if v is None else _vector("v", v, system.nv,
                                                                   "velocities")
    if u is None:
        u0 = input_vector(system, spec.u) if spec.solve != "inputs" else \
            np.zeros(len(system.actuated))
    else:
        u0 = _vector("u", u, len(system.actuated), "inputs")
    return v0, u0


def _vector(name: str, value: object, size: int, what: str) -> np.ndarray:
    """A finite vector of ``size`` numbers, or an ArgumentError naming ``name``."""
    bad = non_numbers(value)
    if bad:
        raise ArgumentError(name, f"expected real numbers ({what}), got {bad}")
    try:
        out = np.array(value, dtype=float)
    except (TypeError, ValueError, OverflowError):
        raise ArgumentError(name, f"expected {size} numbers ({what}), got {show(value)}") \
            from None
    if out.shape != (size,):
        raise ArgumentError(name, f"expected {size} numbers ({what}), got shape {out.shape}")
    if not np.all(np.isfinite(out)) or np.abs(out).max(initial=0.0) > COEFFICIENT_LIMIT:
        raise ArgumentError(name, f"expected finite {what} within {COEFFICIENT_LIMIT:g}, got "
                                  f"{show(value)}")
    return out


def resolve_operating_point(system: System, q0: np.ndarray, *, allow_non_equilibrium: bool,
                            constrained: bool = False, mass_inverse: np.ndarray | None = None,
                            allow_ill_conditioned: bool = False,
                            state: tuple[np.ndarray, np.ndarray] | None = None
                            ) -> tuple[OperatingPoint, ConstrainedPoint | None]:
    """The operating point about q0 and, where the constrained path ran, what the constrained
    formulations need (``constrained``: take that path even for an open chain, as the penalty
    and canonical formulations need its constraint point). ``state`` = (v0, u0): the state is
    given, nothing is solved for (:func:`pinlin.operating_point.at_state`)."""
    if state is not None:
        if system.constraints:
            return moving_point(system, q0, *state)
        if constrained:
            raise ModelError(f"scene '{system.scene.name}': the penalty and canonical "
                             "formulations at a given (moving) state are not supported yet")
        if mass_inverse is None:
            mass_inverse = system.mass_inverse(q0, allow_ill_conditioned=allow_ill_conditioned)
        return at_state(system, q0, *state, mass_inverse=mass_inverse), None
    if system.constraints or constrained or system.scene.operating_point.solve != "inputs":
        return solve_constrained(system, q0, allow_non_equilibrium=allow_non_equilibrium,
                                 allow_ill_conditioned=allow_ill_conditioned)
    return hold_at_rest(system, q0, allow_non_equilibrium=allow_non_equilibrium,
                        mass_inverse=mass_inverse,
                        allow_ill_conditioned=allow_ill_conditioned), None


def operating_point(scene: Scene | System | str | Path, *, q: np.ndarray | None = None,
                    v: np.ndarray | None = None, u: np.ndarray | None = None,
                    allow_non_equilibrium: bool | None = None,
                    mass_inverse: np.ndarray | None = None,
                    allow_ill_conditioned: bool = False) -> OperatingPoint:
    """The operating point the scene asks for, resolved exactly as :func:`linearize` does
    (loops assembled, constraint and contact forces solved; ``q`` replaces the whole
    configuration and anchors the scene's contacts where it puts their frames; ``v``
    and ``u`` give the state, as for :func:`linearize`).

    ``mass_inverse`` is M(q0)^-1 when the caller has it already (nv x nv [1/kg, 1/(kg m^2)],
    finite, positive on its diagonal; used as given for the acceleration a0 off equilibrium);
    ``allow_ill_conditioned`` as for :func:`linearize` (M^-1 is needed off equilibrium, for
    the acceleration a0).
    """
    system = _system(scene)
    if mass_inverse is not None:
        mass_inverse = _mass_inverse_argument(system, mass_inverse)
    allow = _flag("allow_non_equilibrium", allow_non_equilibrium)
    ill = bool(_flag("allow_ill_conditioned", allow_ill_conditioned))
    q0 = _configuration(system, q)
    if q is not None:
        system = system.anchored_at(q0)
    state = _given_state(system, v, u)
    if allow is None:
        allow = system.scene.operating_point.allow_non_equilibrium
    return resolve_operating_point(system, q0, allow_non_equilibrium=allow,
                                   mass_inverse=mass_inverse, allow_ill_conditioned=ill,
                                   state=state)[0]


def _mass_inverse_argument(system: System, value: object) -> np.ndarray:
    """``value`` as M^-1 (nv x nv float64), or an ArgumentError: not real numbers, the wrong
    shape, NaN or inf, or a diagonal that is not positive (no inverse of a mass matrix has
    one)."""
    nv = system.nv
    arr = real_array(value, "mass_inverse", f"an {nv} x {nv} matrix M(q0)^-1")
    if arr.shape != (nv, nv):
        raise ArgumentError("mass_inverse", f"expected an {nv} x {nv} matrix M(q0)^-1 (scene "
                                            f"'{system.scene.name}'), got shape {arr.shape}")
    if not np.all(np.isfinite(arr)) or not np.all(arr.diagonal() > 0.0):
        raise ArgumentError("mass_inverse", "expected finite entries and a positive diagonal "
                                            "(the inverse of a mass matrix is positive "
                                            "definite)")
    return arr


def _check_basis(system: System, form: Formulation) -> None:
    """A basis of independent coordinates needs a constrained system."""
    if isinstance(form, Independent) and form.basis is not None and not system.constraints:
        raise ArgumentError("basis", f"scene '{system.scene.name}' has no loops or mimic "
                                     "couplings: its joint coordinates are independent "
                                     "already")


def linearize(scene: Scene | System | str | Path, *,
              formulation: str | Formulation = "independent",
              derivatives: str | Derivatives = "analytic",
              step: float | Mapping[str, float] | None = None,
              q: np.ndarray | None = None, v: np.ndarray | None = None,
              u: np.ndarray | None = None, allow_non_equilibrium: bool | None = None,
              basis: str | None = None, alpha: float | None = None, mu: float | None = None,
              omega: float | None = None, estimate_error: bool = True,
              allow_ill_conditioned: bool = False) -> LinearModel:
    """Linear state-space model of a scene about its operating point.

    Args:
        scene: A :class:`Scene`, its :class:`System`, or a scene file / URDF / bundled scene /
            robot name. A scene caches its system, so repeated calls skip the model loading.
        formulation: ``"independent"`` (chapter 9.1.1), ``"penalty"`` (9.1.2, dependent
            coordinates) or ``"canonical"`` (9.1.3, momenta and dependent coordinates), or an
            option object carrying its settings: ``pinlin.Independent(basis=...)``,
            ``pinlin.Penalty(alpha=..., mu=..., omega=...)``, ``pinlin.Canonical(...)``
            (:mod:`pinlin.options`); ``basis``, ``alpha``, ``mu``, ``omega`` below are the
            string shortcuts' settings.
        derivatives: ``"analytic"`` (Pinocchio), ``"fd3"`` or ``"fd5"`` (chapter 9.2), or
            ``pinlin.Analytic()`` / ``pinlin.FiniteDifferences(order=, step=,
            estimate_error=)``; ``step`` and ``estimate_error`` below are the shortcuts'.
        step: Finite-difference step for ``fd3``/``fd5`` only: one number for all, or a table
            ``{"q": [rad or m], "v": [rad/s or m/s], "u": [N*m or N]}``, each in
            [1e-10, 0.1]; default ``pinlin.derivatives.DEFAULT_STEPS``. The input step is
            taken times max(1, |u0|) per input (the dynamics are linear in u: only the
            rounding of u0 +- h counts).
        estimate_error: With ``fd3``/``fd5``, also report ``model.info["error_estimate"]``
            (relative error of A: truncation from the companion formula, rounding from the
            measured noise of the dynamics; fd3 at ~2x, fd5 at ~1.5x the cost). An estimate
            above 1e-6 gives an :class:`~pinlin.AccuracyWarning`.
        q: Full configuration (size nq) replacing the scene's operating point (the scene's
            contacts are anchored where it puts their frames). Loops are closed from it; with
            the scene's ``solve = "positions"`` it is the starting guess of the equilibrium
            search (a note says how far q0 moved).
        v, u: Velocity (nv) [rad/s or m/s] and inputs (nu) [N*m or N]: the state is taken as
            given (as with the scene's ``solve = "none"``; the one not passed is the scene's,
            else zero) and the model is affine, x' = f0 + A x + B u with f0 = [v0; a0]
            (``model.f0``; x and u deviations from the state). Open chains in the
            independent formulation; mechanisms (fixed base, point loops, mimic couplings) in
            the independent formulation (partitioned basis; analytic, fd3 or fd5 derivatives)
            or the penalty formulation (analytic), loops closed and v0 projected; floating
            bases on contacts and weld loops in the independent formulation (partitioned
            basis, analytic derivatives), and on point contacts in the penalty formulation.
        allow_non_equilibrium: Override the scene's ``operating_point.allow_non_equilibrium``.
        basis: Independent coordinates of a constrained system (independent formulation only):
            ``"partitioned"`` (the independent joints z, the default) or ``"orthonormal"`` (an
            orthonormal nullspace basis of Phi_q).
        alpha, mu, omega: Penalty factor [kg (or kg*m^2) per constraint unit^2], damping ratio
            [-] and natural frequency [rad/s] of the constraint violation (penalty, canonical
            only); defaults 1e7, 1.0, 10.0.
        allow_ill_conditioned: Linearize even when the (reduced) mass matrix is singular to
            working precision (scaled to unit diagonal, condition >= 0.1/(n eps); see
            :mod:`pinlin.conditioning`): the model is returned with an
            :class:`~pinlin.AccuracyWarning` instead of a :class:`~pinlin.ModelError`, but no
            digit of it is reliable. A coordinate that moves no inertia at all (M^-1 not
            finite) is refused either way.

    Returns:
        The model, with x = [dq; v] (names ``q:<coordinate>``, ``v:<coordinate>``), inputs
        ``u:<coordinate>`` and the scene's outputs.

    Raises:
        ArgumentError: a wrong type or value, or an option that does not apply.
        ModelError: the mass matrix is singular, or singular to working precision without
            ``allow_ill_conditioned`` (the message names the motion and bodies responsible).
        PinlinError: any other bad input (scene, URDF, operating point), by subclass.
    """
    if (type(formulation) is str and formulation == "independent"
            and type(derivatives) is str and derivatives == "analytic" and step is None
            and basis is None and alpha is None and mu is None and omega is None
            and estimate_error is True):  # the defaults: the objects they make, made once
        form, deriv = _INDEPENDENT, _ANALYTIC
    else:
        form = formulation_from(formulation, basis, alpha, mu, omega)
        deriv = derivatives_from(derivatives, step, estimate_error)
    allow = _flag("allow_non_equilibrium", allow_non_equilibrium)
    ill = bool(_flag("allow_ill_conditioned", allow_ill_conditioned))
    system = _system(scene)
    _check_basis(system, form)
    if not system.constraints:   # like basis: settings with nothing to act on are refused
        settings = (("alpha", alpha), ("mu", mu), ("omega", omega))
        if isinstance(form, Penalty):   # an option object set away from its defaults
            settings += tuple((f"formulation ({type(form).__name__}.{key})", value)
                              for key, value in ((k, getattr(form, k)) for k in PENALTY_DEFAULTS)
                              if value != PENALTY_DEFAULTS[key])
        for key, value in settings:
            if value is not None:
                raise ArgumentError(key, f"scene '{system.scene.name}' has no loops, contacts "
                                         "or mimic couplings: the penalty and canonical "
                                         "formulations' alpha, mu and omega have no "
                                         "constraint to act on")
    q0 = _configuration(system, q)
    if q is not None:  # contacts hold their frames where this configuration puts them
        system = system.anchored_at(q0)
    state = _given_state(system, v, u)
    if allow is None:
        allow = system.scene.operating_point.allow_non_equilibrium
    numeric = {"derivatives": deriv.name, "step": deriv.step,
               "estimate_error": deriv.estimate_error}
    independent = isinstance(form, Independent)
    if state is not None and system.constraints:
        refuse_unsupported(system, form.name, getattr(form, "basis", None), deriv.name)
        try:
            op, cp = resolve_operating_point(system, q0, allow_non_equilibrium=allow,
                                             state=state)
            assert cp is not None
            model = (linearize_moving(system, op, cp, **numeric) if independent else
                     linearize_moving_penalty(system, op, cp, alpha=form.alpha, mu=form.mu,
                                              omega=form.omega))
        except np.linalg.LinAlgError:
            raise singular_dynamics(system) from None
    elif state is not None:
        if not independent:
            resolve_operating_point(system, q0, allow_non_equilibrium=allow, state=state,
                                    constrained=True)  # raises: not supported yet
        Minv, check = _mass_inverse(system, q0, deriv.name, ill)
        op, _ = resolve_operating_point(system, q0, allow_non_equilibrium=allow,
                                        mass_inverse=Minv, allow_ill_conditioned=ill,
                                        state=state)
        model = linearize_independent(system, op, mass_inverse=Minv, check_mass=check,
                                      **numeric)
    elif system.constraints or not independent \
            or system.scene.operating_point.solve != "inputs":
        op, cp = resolve_operating_point(system, q0, allow_non_equilibrium=allow,
                                         constrained=True, allow_ill_conditioned=ill)
        assert cp is not None
        if independent:
            model = linearize_reduced(system, op, cp, basis=form.basis or "partitioned",
                                      **numeric)
            if not ill:
                _refuse_singular_reduced(model)
        else:
            build = linearize_canonical if isinstance(form, Canonical) else linearize_penalty
            model = build(system, op, cp, alpha=form.alpha, mu=form.mu, omega=form.omega,
                          **numeric)
    else:
        # Shared by the operating point and the model; refuses a singular M (unless ill).
        Minv, check = _mass_inverse(system, q0, deriv.name, ill)
        op, _ = resolve_operating_point(system, q0, allow_non_equilibrium=allow,
                                        mass_inverse=Minv, allow_ill_conditioned=ill)
        model = linearize_independent(system, op, mass_inverse=Minv, check_mass=check,
                                      **numeric)
    _warn_inaccurate(model)
    return model


def _mass_inverse(system: System, q0: np.ndarray, derivatives: str, ill: bool
                  ) -> tuple[np.ndarray, bool | None]:
    """(M(q0)^-1, the check the model still owes it). With analytic derivatives the check
    waits for the M that the RNEA derivatives give (one ``crba`` less): the model runs
    :meth:`System.check_mass_inverse` before it uses M^-1 beyond a0 and its derivatives,
    which an M singular to working precision leaves finite. Otherwise M^-1 comes checked
    (None)."""
    if derivatives == "analytic":
        Minv = system.unchecked_mass_inverse(q0)
        # A coordinate without inertia leaves inf or NaN on the diagonal: refused now, before
        # a0 = M^-1 r would spread them (and numpy warn about them).
        if Minv is not None and math.isfinite(Minv.trace()):
            return Minv, ill
    return system.mass_inverse(q0, allow_ill_conditioned=ill), None


def _refuse_singular_reduced(model: LinearModel) -> None:
    """ModelError when the reduced mass matrix of a constrained model is singular to working
    precision (the open-chain path refuses in ``System.mass_inverse``)."""
    estimate = model.info.get("condition", {}).get("mass_matrix")
    if estimate is None or model.M is None:
        return
    # The recorded 1-norm condition is >= cond_2 / n, and Jacobi scaling gains at most a
    # factor n (van der Sluis): n^2 times it bounds the scaled condition.
    n = model.M.shape[0]
    condition = singular_to_working_precision(model.M, n * n * estimate)
    if condition is not None:
        raise ModelError(
            f"model '{model.name}': the reduced mass matrix is singular to working precision "
            f"(scaled to unit diagonal, its condition number is {condition:.1e}, at or above "
            f"0.1/(n eps) = {refuse_condition(n):.1e}: not one digit of its inverse is reliable); "
            "give the bodies the independent coordinates move "
            "inertia (or the joints armature), choose other independent coordinates, or pass "
            "allow_ill_conditioned=True (--allow-ill-conditioned on the command line) to "
            "linearize anyway")


def _warn_inaccurate(model: LinearModel) -> None:
    """AccuracyWarning when a numerical model's error estimate exceeds WARN_ERROR_ESTIMATE."""
    est = model.info.get("error_estimate")
    if est is not None and est > WARN_ERROR_ESTIMATE:
        steps = ", ".join(f"{k} {v:g}" for k, v in model.info.get("step", {}).items())
        warnings.warn(AccuracyWarning(
            f"model '{model.name}': {model.info['derivatives']} derivatives with steps "
            f"({steps}) have an estimated relative error of {est:.1e} in A; the default steps "
            "or derivatives='analytic' (no --step, or --derivatives analytic on the command "
            "line) are more accurate", 1.0 / est), stacklevel=3)

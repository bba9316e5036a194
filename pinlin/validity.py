"""``pinlin.validity``: how large a motion the linear model of a scene stays accurate for.

For each non-rigid mode of the linear model (and for a direction the user gives), the scene's
nonlinear motion (:func:`pinlin.simulate`) and the linear model's (:func:`pinlin.response`,
``method="exact"``) start from the same initial deviation ``a d`` for growing amplitudes a and
are compared over a horizon T.

**One unit.** Angles count in radians and lengths in units of L, the robot's characteristic
length at the point (:func:`pinlin.coordinates.characteristic_length`, ``Validity.length``):
w_j = 1 for an angle, 1/L for a length. Amplitudes, radii and errors are in that unit
(``Case.unit`` ``"rad or L"``), so that a robot made smaller or larger has the same radius
(``tests/test_scale_invariance.py``): in metres beside radians, a 61 um mechanism's default
sweep began at 16 times its size. Where no coordinate of the model is a length, L plays no
part (``Validity.length`` None, unit ``"rad or m"``, as before).

**Initial state d.** The right eigenvector r of A, scaled so that its largest weighted
position entry is 1 (phase and size), gives d = Re(r) / max_j w_j |Re(r_qj)|: the largest
joint excursion of a d is exactly a [rad, or L for a length]. An undamped mode starts from
rest in its shape; a damped or real one with the velocity Re(lambda r_q). A direction (a
coordinate name or a state vector) is scaled the same way; one with no position part by its
largest weighted velocity (a then in [rad/s, or L/s]).

**Horizon T** (lambda = sigma + i w of the mode):

- oscillatory (w resolved: :meth:`pinlin.ModalAnalysis.oscillates`): ``periods`` periods,
  T = periods 2 pi / |w|, and at most ``time_constants / sigma`` when unstable (sigma > 0) or
  :data:`DECAY` / |sigma| when damped (as :meth:`~pinlin.ModalAnalysis.kind` says);
- real: T = time_constants / |sigma| (at most :data:`SLOW_LIMIT` periods of the fastest mode).

Why: an unstable solution e^{sigma t} a d leaves the neighbourhood the amplitude names (an
inverted pendulum falls); ending when the linear envelope has grown by e^time_constants (e^2 =
7.4 by default) keeps the whole comparison within ~7.4 a of the point, so the error still
measures the model at amplitude a, not where the fall ends. A stable real mode is compared
until it has decayed by the same factor, a damped one until its envelope is below e^-DECAY =
5e-5 of its start (under any useful tolerance; nothing beyond changes the maximum). A direction
mixes modes: T is the longest horizon of the model's non-rigid modes, capped by the shortest
horizon of an unstable one (or ``horizon`` [s], which overrides every case).

**Error.** With z_nl(t; x0) the nonlinear motion in the linear model's coordinates
(``Simulation.z``: [dq; v], or [dz; dz'] for a mechanism) and x_lin(t; x0) the linear one::

    Dnl(t)  = z_nl(t; a d) - z_nl(t; 0)
    Dlin(t) = x_lin(t; a d) - x_lin(t; 0) = a e^{A t} d
    e_q(a)  = max_t max_j w_j |Dnl_qj - Dlin_qj| / max_t max_j w_j |Dlin_qj|     (positions)
    e_v(a)  = the same over the velocities
    e(a)    = max(e_q, e_v)                                              (the relative error)

At an equilibrium both reference motions (from x0 = 0) are zero (the simulated one stays at
its rounding level, reported as ``reference_drift``) and e is the plain relative error. Away
from one (f0 != 0) both drift: subtracting them compares the model's response to the
perturbation, which is what its A claims to predict. The maxima are over the sample times:
:data:`SAMPLES_PER_PERIOD` per period of the fastest oscillation, so the sampled maximum of an
error oscillating at that period is below the true one by at most 1 - cos(pi / 100) = 5e-4 of
it.

**Radius.** The largest amplitude up to which every tabulated error is within ``tolerance``:
between the last amplitude within it and the first beyond, a is interpolated on log-log axes
(the error is locally a power law e ~ a^(p-1)), simulated there, and the bracket narrowed by
the same secant step (aimed at 0.985 tolerance) until 0.97 tolerance <= e <= tolerance (at
most :data:`~pinlin.validity_sweep.MAX_REFINE` steps; then the largest amplitude measured
within the tolerance). With
e ~ a^(p-1) near the radius, that 3% band in e is a band of 3% / (p - 1) in the radius: the
radius lies within 3% / (p - 1) below the exact crossing (1.5% for the pendulum's p = 3).
Bisection would need ~log2(2.15 / 0.015) = 7 simulations for the same; the secant, 1 or 2. The
default amplitudes are :data:`DEFAULT_AMPLITUDES`; the sweep stops once e exceeds
:data:`~pinlin.validity_sweep.STOP_FACTOR` tolerance, after at least
:data:`~pinlin.validity_sweep.ORDER_POINTS` amplitudes (given
amplitudes are all measured). A failed simulation (a mechanism past a toggle position) counts
as beyond the tolerance, its message kept.

**Order.** ``slope`` p = d log E / d log a of the error in the state's units, E = e max|Dlin|;
since max|Dlin| is proportional to a, p = 1 + the log-log slope of e, fitted by least squares
over the :data:`~pinlin.validity_sweep.ORDER_POINTS` smallest amplitudes whose e is above
the integration noise (:func:`pinlin.validity_sweep.noise_floor`): the order as a -> 0, which
is what tells the cases apart (the local slope grows with a as higher-order terms take over,
e.g. from 2 to 2.5 for the four-bar by a = 0.05):

- p ~ 2: quadratic terms, the general smooth system about an equilibrium;
- p ~ 3: no quadratic terms along the motion (an odd nonlinearity: a pendulum's sin(theta)
  about its hanging or inverted position: its period error gives e = 2 pi periods a^2 / 16);
- p ~ 1: the linear model misses a first-order effect: the point is not an equilibrium of the
  dynamics simulated (f0 != 0, an input u0 that does not hold q0), ``diagnosis`` says so.
"""

from __future__ import annotations

import math
import time
from collections.abc import Sequence

import numpy as np

from .arrays import non_numbers, read_only, real_array
from .closed_loop import model_gain
from .coordinates import characteristic_length, linear_coordinates
from .exceptions import ArgumentError, ModelError
from .linear_model import LinearModel
from .linearization import _system, linearize
from .modal import ModalAnalysis, modal
from .scene import POSITION_LIMIT
from .simulation import ATOL, MAX_CYCLES
from .system import System
from .validity_report import Bound, Case, Validity, notes
from .validity_sweep import FIRST_ORDER, NOISE_ATOL, NOISE_RTOL, Sweep

#: Default amplitudes [rad, or L for a length]: 1e-3 to 1, a factor 10^(1/3) = 2.15 apart.
DEFAULT_AMPLITUDES = tuple(float(a) for a in np.geomspace(1e-3, 1.0, 10))
#: The amplitudes' unit, in messages (module docstring: L the characteristic length).
UNIT = "[rad, or L for a length]"
#: Samples per period of the fastest oscillation (max-over-time undershoot <= 5e-4).
SAMPLES_PER_PERIOD = 100
#: Samples over the horizon of a real mode (and at least that many for any case).
MIN_SAMPLES = 401
#: At most this many samples (a direction mixing slow and fast modes may get fewer per period).
MAX_SAMPLES = 20001
#: A damped oscillation is compared until its envelope has decayed by e^-DECAY.
DECAY = 10.0
#: A real mode's horizon is at most SLOW_LIMIT periods of the model's fastest mode (a real
#: eigenvalue just above rigid_tol would otherwise ask for ~1e6 of the solver's steps).
SLOW_LIMIT = 1000.0
_EXCLUDED_KINDS = ("rigid", "constraint")


# --------------------------------------------------------------------------------------------
def _positive(name: str, value: object, unit: str, upper: float = math.inf) -> float:
    if isinstance(value, bool) or not isinstance(value, int | float | np.integer | np.floating):
        raise ArgumentError(name, f"expected a number {unit}, got {type(value).__name__}")
    if not (math.isfinite(value) and 0.0 < value < upper):
        bound = f" and < {upper:g}" if math.isfinite(upper) else ""
        raise ArgumentError(name, f"expected a finite number > 0{bound} {unit}, got {value!r}")
    return float(value)


def _check_integration(rtol: float, atol: float, tolerance: float, smallest: float,
                       scale: float) -> None:
    """Refuse solver tolerances whose noise (:func:`pinlin.validity_sweep.noise_floor`:
    NOISE_RTOL rtol + NOISE_ATOL atol scale / a) reaches the tolerance at the smallest
    amplitude: every error measured would be noise, and the radius a verdict on the solver
    rather than the model (``scale``: the largest weight w_j, which turns the atol given in
    rad and m into the amplitudes' unit; the advice is in the atol's own)."""
    if NOISE_RTOL * rtol >= tolerance:
        raise ArgumentError("rtol", f"the tolerance {tolerance:g} is within the integration "
                                    f"noise of rtol = {rtol:g} (~{NOISE_RTOL:g} rtol): use a "
                                    f"tolerance above {NOISE_RTOL * rtol:g} or rtol <= "
                                    f"{tolerance / NOISE_RTOL / 10:.1g}")
    if NOISE_ATOL * atol * scale / smallest >= tolerance:
        per = "" if scale == 1.0 else f" ({atol * scale:.3g} per L, L = {1 / scale:.3g} m)"
        raise ArgumentError("atol", f"at the smallest amplitude {smallest:g} the integration "
                                    f"noise of atol = {atol:g}{per} (~{NOISE_ATOL:g} atol / "
                                    f"amplitude) reaches the tolerance {tolerance:g}: use "
                                    "amplitudes >= "
                                    f"{NOISE_ATOL * atol * scale / tolerance * 10:.1g} or atol "
                                    f"<= {tolerance * smallest / NOISE_ATOL / 10 / scale:.1g}")


def _amplitudes(amplitudes: object) -> tuple[np.ndarray, bool]:
    if amplitudes is None:
        return np.array(DEFAULT_AMPLITUDES), True
    bad = "text" if isinstance(amplitudes, str) else non_numbers(amplitudes)
    if bad:
        raise ArgumentError("amplitudes", f"expected amplitudes {UNIT} as numbers, got "
                                          f"{bad}")
    try:
        arr = np.array(amplitudes, dtype=float).reshape(-1)
    except (TypeError, ValueError):
        raise ArgumentError("amplitudes", f"expected a sequence of amplitudes {UNIT}, got "
                                          f"{type(amplitudes).__name__}") from None
    if arr.size == 0:
        raise ArgumentError("amplitudes", f"expected at least one amplitude {UNIT}, got an "
                                          "empty sequence (or None for the default sweep)")
    ok = np.isfinite(arr) & (arr > 0.0) & (arr <= POSITION_LIMIT)
    if not ok.all():
        raise ArgumentError("amplitudes", f"expected finite amplitudes > 0 and <= "
                                          f"{POSITION_LIMIT:g} {UNIT}, got {arr[~ok][:3]}")
    return np.unique(arr), False


def _scene_system(scene: object) -> System:
    if isinstance(scene, LinearModel):
        if "domain" in scene.info:
            raise ModelError(f"model '{scene.name}' is a linear graph: it has no nonlinear "
                             "multibody motion to compare with; validity takes a scene")
        raise ArgumentError("scene", f"expected a scene, got the LinearModel '{scene.name}': "
                                     "validity linearizes and simulates the scene itself; pass "
                                     "the scene (file or name)")
    from .graph import Graph

    if isinstance(scene, Graph):
        raise ModelError("a linear graph has no nonlinear multibody motion to compare with; "
                         "validity takes a scene")
    return _system(scene)


def _select(ma: ModalAnalysis, modes: object, given_direction: bool) -> list[int]:
    """Eigenvalue indices of the modes to sweep (one per conjugate pair)."""
    keep = ma.modes()
    usable = [i for i in keep if ma.kind(i) not in _EXCLUDED_KINDS]
    if modes is None:
        if not usable and not given_direction:
            raise ModelError(f"model '{ma.model.name}' has no non-rigid mode (all "
                             f"{len(ma.eigenvalues)} eigenvalues rigid): give direction= "
                             "and horizon=")
        return [] if given_direction else usable
    items = [modes] if isinstance(modes, int | np.integer) else modes
    if isinstance(items, str) or not isinstance(items, Sequence | np.ndarray):
        raise ArgumentError("modes", f"expected eigenvalue indices (ints), got "
                                     f"{type(modes).__name__}")
    chosen: list[int] = []
    for k in items:
        if isinstance(k, bool) or not isinstance(k, int | np.integer):
            raise ArgumentError("modes", f"expected eigenvalue indices (ints), got {k!r:.40}")
        if not 0 <= k < len(ma.eigenvalues):
            raise ArgumentError("modes", f"no mode {k}: expected one of {usable} (indices of "
                                         "pinlin.modal(model).eigenvalues, one per pair)")
        i = int(k) if k in keep else int(k) - 1          # a conjugate: its pair's first
        if i not in usable:
            raise ArgumentError("modes", f"mode {k} is {ma.kind(i)}: nothing oscillates or "
                                         f"returns about the point; expected one of {usable}"
                                         " (or direction=)")
        if i not in chosen:
            chosen.append(i)
    if not chosen and not given_direction:
        raise ArgumentError("modes", f"expected at least one eigenvalue index (one of "
                                     f"{usable}) or a direction=, got none")
    return chosen


def _unit_weights(system: System, model: LinearModel) -> tuple[float | None, np.ndarray]:
    """(L [m] or None, w (n,)): the weights of the module docstring over the model's position
    coordinates, 1 per rad and 1/L per m, L the characteristic length at the model's point;
    (None, ones) where none of them is a length."""
    n = model.n_states // 2
    linear = linear_coordinates(system)
    index = {name: k for k, name in enumerate(system.state_names[:system.nv])}
    if any(name not in index for name in model.state_names[:n]):
        raise ModelError(f"the linear model's coordinates {model.state_names[:n]} are not the "
                         f"scene's {system.state_names[:system.nv]}")
    mask = np.array([linear[index[name]] for name in model.state_names[:n]], dtype=bool)
    if not mask.any():
        return None, np.ones(n)
    length = characteristic_length(system, model.operating_point.q)[0]
    return length, np.where(mask, 1.0 / length, 1.0)


def _units(length: float | None) -> tuple[str, str]:
    """The units of a position and of a velocity amplitude (module docstring)."""
    return ("rad or m", "rad/s or m/s") if length is None else ("rad or L", "rad/s or L/s")


def _direction(model: LinearModel, direction: object, w: np.ndarray,
               units: tuple[str, str]) -> tuple[np.ndarray, str, str]:
    """(d (2n,), label, unit) of a coordinate name or a state vector, its largest weighted
    position (else velocity) entry 1 (``w``: the weights of the module docstring, ``units``
    their position and velocity units, :func:`_units`)."""
    n, names = model.n_states // 2, model.state_names
    d = np.zeros(2 * n)
    if isinstance(direction, str):
        name = direction if direction[:2] in ("q:", "v:") else f"q:{direction}"
        if name not in names:
            raise ArgumentError("direction", f"no coordinate {direction!r:.60}; expected one "
                                             f"of {', '.join(names)}")
        d[names.index(name)] = 1.0
        label = f"direction {name}"
    else:
        vec = real_array(direction, "direction", "a coordinate name or a state vector of "
                                                 "real numbers").reshape(-1)
        if vec.size not in (n, 2 * n) or not np.all(np.isfinite(vec)) or not np.any(vec):
            raise ArgumentError("direction", f"expected {n} positions or {2 * n} states "
                                             f"({', '.join(names)}), finite and not all zero, "
                                             f"got {vec.size} numbers")
        d[:vec.size] = vec
        label = "direction"
    scale = np.abs(d[:n] * w).max()
    if scale > 0:
        return d / scale, label, units[0]
    return d / np.abs(d[n:] * w).max(), label, units[1]


def _mode_horizon(index: int, ma: ModalAnalysis, periods: float, time_constants: float
                  ) -> tuple[float, float, str]:
    """(T [s], its period [s] or 0, rule) of mode ``index`` (module docstring; oscillatory,
    growing and decaying as :meth:`ModalAnalysis.kind` says)."""
    lam = ma.eigenvalues[index]
    sigma, w = lam.real, abs(lam.imag)
    if ma.oscillates(index):
        T, rule = periods * 2 * np.pi / w, f"{periods:g} periods"
        kind = ma.kind(index)
        if kind == "unstable osc." and time_constants / sigma < T:
            T, rule = time_constants / sigma, f"growth e^{time_constants:g} (unstable)"
        elif kind == "oscillatory" and DECAY / -sigma < T:
            T, rule = DECAY / -sigma, f"decay e^-{DECAY:g}"
        return T, 2 * np.pi / w, rule
    verb = "growth e^" if sigma > 0 else "decay e^-"
    T, rule = time_constants / abs(sigma), f"{time_constants:g} time constants ({verb}" \
                                           f"{time_constants:g})"
    longest = SLOW_LIMIT * 2 * np.pi / float(np.max(ma.wn))
    if longest < T:
        T, rule = longest, f"{SLOW_LIMIT:g} periods of the fastest mode (a slow real mode)"
    return T, 0.0, rule


def _grid(T: float, period: float) -> np.ndarray:
    count = MIN_SAMPLES if period <= 0 else int(np.ceil(SAMPLES_PER_PERIOD * T / period)) + 1
    return np.linspace(0.0, T, int(np.clip(count, MIN_SAMPLES, MAX_SAMPLES)))


def validity(scene: object, amplitudes: Sequence[float] | np.ndarray | None = None,
             periods: float = 5, tolerance: float = 0.01, *, modes: object = None,
             direction: object = None, time_constants: float = 2.0,
             horizon: float | None = None, q: np.ndarray | None = None,
             v: np.ndarray | None = None, rtol: float = 1e-10, atol: float | None = None,
             feedback: object = None) -> Validity:
    """How large a motion the scene's linear model stays accurate for (module docstring).

    Args:
        scene: A :class:`~pinlin.Scene`, its System, or a scene file / bundled scene / robot
            name (not a LinearModel: the scene is linearized and simulated here).
        amplitudes: Amplitudes a [rad, or L for a length] (largest joint excursion of the
            initial state, module docstring); default :data:`DEFAULT_AMPLITUDES`, stopped past
            STOP_FACTOR (:mod:`pinlin.validity_sweep`) tolerance.
        periods: Horizon in periods of each oscillatory mode (> 0).
        tolerance: Bound on the relative error e (0 < tolerance < 1), e.g. 0.01 for 1%.
        modes: Eigenvalue indices of ``pinlin.modal(model)`` (``Validity.modes``; the closed
            loop's with ``feedback``) to sweep
            (a conjugate's index means its pair); default every non-rigid mode, none when
            ``direction`` is given.
        direction: A coordinate name (``"elbow"``, ``"q:elbow"``, ``"v:elbow"``) or a state
            vector (n positions, or 2n states) to sweep as well.
        time_constants: Horizon of real modes in time constants 1/|sigma| (> 0), and the
            growth e^time_constants that ends an unstable mode's comparison.
        horizon: T [s] for every case instead of the rules above (needed for a direction
            when every mode is rigid).
        q, v: The point instead of the scene's, as for :func:`pinlin.linearize` and
            :func:`pinlin.simulate` (q (nq); v (nv) [rad/s or m/s]: the state is given, u0 the
            scene's ``u`` or zero, so the point need not be an equilibrium).
        rtol, atol: Tolerances of the nonlinear simulation (:func:`pinlin.simulate`'s: atol
            None is 1e-12 per rad and 1e-12 L per m, L the robot's characteristic length).
        feedback: A gain K (n_inputs x n_states of the scene's linear model, as
            ``control.lqr`` returns it; for a mechanism on its independent coordinates
            [dz; dz'], or on all 2 nv coordinates: its linear model's gain is then
            [K_q R, K_v R]), or a pair (K, model) whose model's states are checked against
            those: the closed loop u = -K x is compared instead, its
            linear model ``model.closed_loop(K)`` (its modes are the closed loop's) against
            ``pinlin.simulate(..., feedback=K)``.

    Raises:
        ArgumentError: a bad argument (the message names it and what is expected).
        ModelError: a linear graph; a model with no non-rigid mode and no direction.
        PinlinError: as :func:`pinlin.linearize` for the scene or the point.
    """
    start = time.perf_counter()
    system = _scene_system(scene)
    amps, default = _amplitudes(amplitudes)
    periods = _positive("periods", periods, "of periods")
    if periods > MAX_CYCLES:  # what simulate refuses, said in this function's terms
        raise ArgumentError("periods", f"expected at most {MAX_CYCLES:g} periods (each takes "
                                       f"the integrator ~10 steps), got {periods:g}")
    tolerance = _positive("tolerance", tolerance, "(relative error)", upper=1.0)
    rtol = _positive("rtol", rtol, "(relative, of the nonlinear simulation)")
    if atol is not None:
        atol = _positive("atol", atol, "(absolute, of the nonlinear simulation)")
    time_constants = _positive("time_constants", time_constants, "of time constants")
    horizon = None if horizon is None else _positive("horizon", horizon, "[s]")
    model = linearize(system, q=q, v=v)
    length, w = _unit_weights(system, model)
    units = _units(length)
    # The noise floor's atol in the amplitudes' unit: simulate's default is ATOL per rad and
    # per L; an atol given in rad and m is atol w_j in it, at most atol max(w).
    scale = 1.0 if atol is None else float(w.max(initial=1.0))
    noise_atol = ATOL if atol is None else atol * scale
    _check_integration(rtol, ATOL if atol is None else atol, tolerance, float(amps.min()),
                       scale)
    gain = None
    if feedback is not None:
        if callable(feedback):
            raise ArgumentError("feedback", "expected a gain matrix K (the linear model of a "
                                            "law is its gain); a callable has none to compare")
        on_model, gain = model_gain(model, feedback, "feedback")
        model = model.closed_loop(on_model)   # simulate applies the gain as given
    ma = modal(model)
    chosen = _select(ma, modes, direction is not None)
    drift = 0.0 if model.f0 is None else float(np.abs(model.f0).max(initial=0.0))
    options = {"q0": None if q is None else model.operating_point.q,
               "v0": None if v is None else model.operating_point.v, "rtol": rtol, "atol": atol,
               "feedback": gain}
    n = model.n_states // 2
    horizons = {i: _mode_horizon(i, ma, periods, time_constants)
                for i in ma.modes() if ma.kind(i) not in _EXCLUDED_KINDS}
    jobs = []
    for i in chosen:
        r = ma.right_vectors[:, i]
        r = np.real(r / r[int(np.argmax(np.abs(r[:n]) * w))])
        jobs.append((f"mode {ma.modes().index(i) + 1}", i, r / np.abs(r[:n] * w).max(),
                     units[0], horizons[i]))
    if direction is not None:
        d, label, unit = _direction(model, direction, w, units)
        jobs.append((label, None, d, unit, _direction_horizon(ma, horizons, horizon)))
    cases, count = [], 0
    for label, i, d, unit, (T, period, rule) in jobs:
        if horizon is not None:
            T, rule = horizon, "given"
        sweep = Sweep(system, model, d, _grid(T, period), options, noise_atol, w)
        cases.append(sweep.case(amps, default, tolerance, label=label, index=i, unit=unit,
                                eigenvalue=None if i is None else complex(ma.eigenvalues[i]),
                                kind="direction" if i is None else ma.kind(i), horizon=T,
                                horizon_rule=rule))
        count += sweep.count
    return Validity(name=model.name, model=model, modes=ma, tolerance=tolerance,
                    periods=periods, time_constants=time_constants, cases=tuple(cases),
                    equilibrium=drift == 0.0, drift=drift,
                    notes=tuple(notes(cases, drift, tolerance, FIRST_ORDER)),
                    seconds=time.perf_counter() - start, simulations=count,
                    coordinate_names=tuple(s.removeprefix("q:") for s in model.state_names[:n]),
                    length=length, weights=read_only(w))


def _direction_horizon(ma: ModalAnalysis, horizons: dict[int, tuple[float, float, str]],
                       horizon: float | None) -> tuple[float, float, str]:
    """(T [s], fastest period [s], rule) of a direction: the longest mode horizon, capped by
    the shortest unstable one."""
    if not horizons:
        if horizon is None:
            raise ArgumentError("horizon", f"model '{ma.model.name}' has no non-rigid mode "
                                           "to set the direction's horizon: give horizon= [s]")
        return horizon, 0.0, "given"
    growing = ma.unstable
    unstable = [h[0] for j, h in horizons.items() if growing[j]]
    period = min((h[1] for h in horizons.values() if h[1] > 0), default=0.0)
    if unstable:
        return min(unstable), period, "the shortest unstable mode horizon"
    return max(h[0] for h in horizons.values()), period, "the longest mode horizon"


__all__ = ["DEFAULT_AMPLITUDES", "Bound", "Case", "Validity", "validity"]

"""The sweep of one case of :func:`pinlin.validity`: the error e(a) measured at growing
amplitudes, the radius refined between the last amplitude within the tolerance and the first
beyond, and the order p of the error (the definitions are :mod:`pinlin.validity`'s
docstring)."""

from __future__ import annotations

import math

import numpy as np

from .arrays import read_only
from .exceptions import ModelError, PinlinError
from .linear_model import LinearModel
from .response import response
from .simulation import Simulation, simulate
from .system import System
from .validity_report import Bound, Case

#: The default sweep stops beyond STOP_FACTOR * tolerance.
STOP_FACTOR = 10.0
MAX_REFINE = 4
#: The refinement aims at TARGET tolerance and accepts ACCEPT tolerance <= e <= tolerance.
TARGET, ACCEPT = 0.985, 0.97
#: Relative errors below NOISE_RTOL rtol + NOISE_ATOL atol / a are integration noise
#: (:func:`noise_floor`); the order is fitted over the ORDER_POINTS smallest amplitudes above it,
#: which the default sweep always measures. The atol term: measured at a = 1e-6 and 1e-5
#: (where the true error is far below) 2-9 atol / a on the pendulum, double pendulum and UR5
#: arm, but up to 200 atol / a on the four-bar and 130 on the upright double pendulum under
#: LQR (DOP853's long steps, whose dense output the comparison samples); 1e3 leaves 5x.
NOISE_RTOL, NOISE_ATOL = 1e3, 1e3
ORDER_POINTS = 3
#: Errors above SATURATION are left out of the order when two others remain (e ~ 1: the
#: motions have parted, e stops growing).
SATURATION = 0.3
#: Orders below FIRST_ORDER say "first order"; from THIRD_ORDER up "third order".
FIRST_ORDER, THIRD_ORDER = 1.5, 2.5


class Sweep:
    """One case: measures e(a) (keeping every motion for the histories) and builds its Case."""

    def __init__(self, system: System, model: LinearModel, d: np.ndarray, t: np.ndarray,
                 options: dict, noise_atol: float, w: np.ndarray) -> None:
        self.system, self.d, self.t, self.options = system, d, t, options
        self.noise_atol = noise_atol   # the atol of the noise floor (noise_floor), in a's unit
        self.n, self.names = model.n_states // 2, model.state_names
        self.w = np.concatenate([w, w])   # the weights of positions and velocities
        self.wraps: dict[float, str] = {}   # amplitude -> the first spring wrap it met
        ref_lin = response(model, t, method="exact").x
        self.unit_lin = response(model, t, x0=d, method="exact").x - ref_lin
        self.reference = np.asarray(self._simulate(np.zeros_like(d)).z)
        self.count = 1
        self.runs: dict[float, np.ndarray] = {}
        self.rows: dict[float, tuple[float, float, float, str]] = {}

    def _simulate(self, x0: np.ndarray) -> Simulation:
        sim = simulate(self.system, self.t, dx0=x0, **self.options)
        if sim.independent_names != self.names:
            raise ModelError(f"the simulated coordinates {sim.independent_names} are not the "
                             f"linear model's {self.names}")
        return sim

    def measure(self, a: float) -> float:
        """e at amplitude a (inf when the simulation fails); the row (e, e_q, e_v, failure)
        is kept."""
        self.count += 1
        try:
            sim = self._simulate(a * self.d)
            dnl = np.asarray(sim.z) - self.reference
            if sim.info["spring_wraps"]:
                self.wraps[a] = sim.info["spring_wraps"][0]
        except PinlinError as exc:
            self.rows[a] = (math.inf, math.inf, math.inf, str(exc))
            return math.inf
        self.runs[a] = dnl
        lin = a * self.unit_lin
        diff, size = np.abs(dnl - lin) * self.w, np.abs(lin) * self.w
        parts = []
        for cols in (slice(0, self.n), slice(self.n, 2 * self.n)):
            peak = size[:, cols].max()
            parts.append(diff[:, cols].max() / peak if peak > 0 else 0.0)
        self.rows[a] = (max(parts), parts[0], parts[1], "")
        return max(parts)

    def refine(self, lo: float, hi: float, tol: float) -> float:
        """The radius between lo (e <= tol) and hi (e > tol) by log-log secant steps."""
        radius = lo
        for _ in range(MAX_REFINE):
            elo, ehi = self.rows[lo][0], self.rows[hi][0]
            if elo > 0.0 and math.isfinite(ehi) and ehi > elo:
                guess = math.exp(math.log(lo) + math.log(TARGET * tol / elo)
                                 * math.log(hi / lo) / math.log(ehi / elo))
            else:                                   # a failure or a flat error: bisect
                guess = math.sqrt(lo * hi)
            guess = min(max(guess, lo * (hi / lo) ** 0.02), hi * (lo / hi) ** 0.02)
            e = self.measure(guess)
            if e > tol:
                hi = guess
                continue
            lo = radius = guess
            if e >= ACCEPT * tol:
                break
        return radius

    def case(self, amps: np.ndarray, default: bool, tol: float, **about: object) -> Case:
        """Sweep ``amps`` (stopping past STOP_FACTOR tol when ``default``), refine, and the
        :class:`Case` (``about``: label, index, eigenvalue, kind, unit, horizon, rule)."""
        for a in amps:
            e = self.measure(float(a))
            if default and len(self.rows) >= ORDER_POINTS and not e <= STOP_FACTOR * tol:
                break
        a = np.array(sorted(self.rows))
        k, bound = radius_index(a, np.array([self.rows[x][0] for x in a]), tol)
        radius = self.refine(float(a[k]), float(a[k + 1]), tol) if bound is Bound.FOUND \
            else float(a[k])
        a = np.array(sorted(self.rows))
        e, e_q, e_v = (read_only(np.array([self.rows[x][j] for x in a])) for j in range(3))
        p, diagnosis = order(a, e, self.options["rtol"], self.noise_atol)
        dnl, n = self.runs.get(radius), self.n
        return Case(
            **about, direction=read_only(self.d.copy()), amplitudes=read_only(a), errors=e,
            position_errors=e_q, velocity_errors=e_v,
            failures=tuple(self.rows[x][3] for x in a), radius=radius, bound=bound,
            error_at_radius=self.rows[radius][0],
            excursions=read_only(radius * np.abs(self.d[:n])),
            peak=math.nan if dnl is None else float((np.abs(dnl[:, :n]) * self.w[:n]).max()),
            slope=p, diagnosis=diagnosis, notes=_wrap_notes(self.wraps),
            reference_drift=float((np.abs(self.reference) * self.w).max()),
            t=read_only(self.t.copy()), nonlinear=None if dnl is None else read_only(dnl),
            linear=None if dnl is None else read_only(radius * self.unit_lin))


def _wrap_notes(wraps: dict[float, str]) -> tuple[str, ...]:
    """The case's note on the springs of continuous joints that its simulations wound past
    their wrap (from the smallest such amplitude on: the error there is the wrap's)."""
    if not wraps:
        return ()
    a = min(wraps)
    return (f"from a = {a:.4g} on, {wraps[a]}",)


def radius_index(a: np.ndarray, e: np.ndarray, tol: float) -> tuple[int, Bound]:
    """(index of the last amplitude before the first one beyond tol, bound)."""
    beyond = np.flatnonzero(~(e <= tol))
    if beyond.size == 0:
        return a.size - 1, Bound.ABOVE_RANGE
    if beyond[0] == 0:
        return 0, Bound.BELOW_RANGE
    return int(beyond[0]) - 1, Bound.FOUND


def order(a: np.ndarray, e: np.ndarray, rtol: float, atol: float) -> tuple[float, str]:
    """(p, diagnosis) from the ORDER_POINTS smallest amplitudes with e above the noise (and
    below SATURATION if two are)."""
    ok = np.isfinite(e) & (e > noise_floor(a, rtol, atol))
    saturated = ok & (e > SATURATION)
    if (ok & ~saturated).sum() >= 2:
        ok &= ~saturated
    elif saturated.any() and np.any(~ok[:int(np.argmax(saturated))]):
        # From the noise straight to parted motions: no power law to fit between.
        below = a[:int(np.argmax(saturated))][~ok[:int(np.argmax(saturated))]]
        return math.nan, (f"order unknown: the error is at the integration noise up to "
                          f"a = {below.max():.3g} and beyond {SATURATION:g} from "
                          f"a = {a[saturated].min():.3g}: the simulated dynamics change "
                          "abruptly between (the linear model holds to the noise below)")
    use = ok & (np.cumsum(ok) <= ORDER_POINTS)
    if use.sum() < 2:
        return math.nan, "order unknown: fewer than two errors above the integration noise"
    p = 1.0 + float(np.polyfit(np.log(a[use]), np.log(e[use]), 1)[0])
    if p < FIRST_ORDER:
        what = ("first order: the linear model misses a first-order effect here; the point "
                "is not an equilibrium of the simulated dynamics")
    elif p < THIRD_ORDER:
        what = "second order: quadratic terms, as expected of a smooth system at equilibrium"
    else:
        what = "third order: no quadratic terms along this motion (an odd nonlinearity)"
    shown = ", ".join(f"{x:.3g}" for x in a[use])
    note = f"; errors > {SATURATION:g}: the motions no longer alike" if np.any(
        saturated[use]) else ""
    return p, f"{what} (order {p:.2f} from a = {shown}{note})"


def noise_floor(a: np.ndarray, rtol: float, atol: float) -> np.ndarray:
    """Integration noise of e at amplitude a: NOISE_RTOL rtol + NOISE_ATOL atol / a (the
    measurements beside those constants, with a 5-10x margin)."""
    return NOISE_RTOL * rtol + NOISE_ATOL * atol / a

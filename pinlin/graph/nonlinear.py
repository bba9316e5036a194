"""Graphs with nonlinear elements (Rowell sections 6 and 7).

A nonlinear element carries a constitutive relation instead of a value:

- D-type: f = relation(v) (a damper F = c v|v|, an orifice Q = K sqrt|P| sgn P);
- A-type: q = relation(v), f = dq/dt (a tank volume as a function of base pressure);
- T-type: lam = relation(f), v = dlam/dt (a spring's displacement as a function of its force).

The normal tree and the constraint matrices are those of the linear method. f(x, u) solves the
dissipative primaries from their (possibly coupled) relations by Newton, then x' = sigma / q'(x)
for A-type and x' = sigma / lam'(x) for T-type states, where sigma is the storage element's
secondary variable. The equilibrium solves sigma(x0, u0) = 0 (the same points as f = 0, without
dividing by the slopes); the linear model is the matrix method applied to the incremental
graph, where a nonlinear D-type element becomes a resistance 1 / (df/dv) and a storage element
takes its incremental value q'(v0) or lam'(f0) (exact at an equilibrium, where the storage
secondaries vanish). Derivatives of the relations: 5-point central differences on the scalar
function.

Checks (each failure a :class:`GraphError` naming the file and the branch or field):

- a relation must return a finite real number; one that raises (an ``arcsin`` outside
  |x| <= scale, a ``math domain error``), overflows or returns NaN, inf, a complex number or an
  array is reported with the branch and the point where it was evaluated;
- the dissipative primaries and the equilibrium must converge: a point is accepted when each
  storage equation sigma_i = sum_j W_ij pi_j is negligible against its own terms
  (|sigma_i| <= 1e-9 sum_j |W_ij pi_j|), or when a Newton step from it is below 1e-8 of each
  state's scale (the largest of |x_j| and the change of x_j that moves some equation by its own
  terms), so that the test is free of units and time scales;
- excess storage must be linear and is combined first (``combine=True``): the split of an
  equilibrium between T-type elements in parallel or A-type elements in series is undetermined;
- incremental values must lie in [1e-100, 1e100] like the values of linear elements.
"""

from __future__ import annotations

import math
import numbers
from collections.abc import Mapping, Sequence
from dataclasses import replace

import numpy as np

from ..exceptions import ArgumentError
from .excess import combine_excess, excess_groups
from .matrix import matrix_method, state_space
from .model import RANGE, VALUE_MAX, VALUE_MIN, Branch, GraphError, clip, real, show


def _root(fun, x0: np.ndarray, **options):
    """``scipy.optimize.root``, imported on first use (scipy.optimize costs ~0.1-0.2 s to
    import, which every command would pay for the few graphs that are nonlinear)."""
    from scipy.optimize import root

    return root(fun, x0, **options)

_REL_TOL = 1e-9      # |sigma_i| against the sum of its terms
_STEP_TOL = 1e-8     # Newton step against the state's scale


def evaluate(graph, branch: Branch, x: float, context: str = "") -> float:
    """``branch.relation(x)`` as a finite float, every failure a GraphError naming the branch.

    Args:
        x: Across variable (D, A) or through variable (T) of the branch [its unit].
        context: Appended to messages, e.g. `` at the equilibrium``.
    """
    var = "f" if branch.type == "T" else "v"
    where = f"branches.{branch.name}.relation"
    at = f"at {var} = {x:.6g}{context}"
    try:
        y = branch.relation(float(x))
    except RecursionError:
        raise GraphError(graph.source, where, f"cannot be evaluated {at}: it recursed too "
                                              "deeply") from None
    except OverflowError:
        raise GraphError(graph.source, where, f"cannot be evaluated {at}: the result "
                                              "overflows double precision") from None
    except (ArithmeticError, ValueError) as exc:
        raise GraphError(graph.source, where, f"cannot be evaluated {at}: "
                                              f"{clip(exc) or type(exc).__name__}") from None
    except Exception as exc:  # a user function may raise anything: report, do not crash
        raise GraphError(graph.source, where, f"raised {type(exc).__name__} {at}: "
                                              f"{clip(exc)}") from None
    if isinstance(y, bool) or not isinstance(y, numbers.Real):
        raise GraphError(graph.source, where, f"returned {type(y).__name__} {show(y)} {at}; "
                                              "expected a real number (a float)")
    try:
        y = float(y)
    except (OverflowError, ValueError, TypeError):
        raise GraphError(graph.source, where, f"returned {show(y)} {at}, beyond double "
                                              "precision") from None
    if not math.isfinite(y):
        raise GraphError(graph.source, where, f"returned {y!r} {at}; expected a finite "
                                              "number")
    return y


def derivative(fn, x: float, h: float | None = None) -> float:
    """d fn / dx at x by the 5-point formula (fn: float -> float), with the step ``h`` [unit
    of x] or by default the relative step 1e-4 max(1, |x|)."""
    if h is None:
        h = 1e-4 * max(1.0, abs(x))
    return (fn(x - 2 * h) - 8 * fn(x - h) + 8 * fn(x + h) - fn(x + 2 * h)) / (12 * h)


def _refuse_kink(fn, x: float, h: float, slope: float, noise: float, graph, where: str,
                 at: str) -> None:
    """GraphError when the one-sided slopes at x differ by a jump: a kink, which the
    symmetric stencils of :func:`_slope` average into a slope of neither side (v for v > 0,
    3 v below: 2). For a smooth relation forward minus backward difference is h f'' and
    shrinks 8 times with the step; at a kink it stays the jump."""
    f0 = fn(x)

    def gap(step: float) -> float:
        return (fn(x + step) - f0) / step - (f0 - fn(x - step)) / step

    with np.errstate(all="ignore"):
        wide, narrow = gap(h), gap(h / 8)
    if abs(narrow) > 1e-5 * abs(slope) + 8 * noise and abs(narrow) > 0.5 * abs(wide):
        right = (fn(x + h / 8) - f0) / (h / 8)
        raise GraphError(graph.source, where, f"a kink at {at}: its slope is {right:.4g} on "
                                              f"the right and {right - narrow:.4g} on the left; "
                                              "no linear model there")


def _slope(graph, branch: Branch, x: float, context: str = "") -> float:
    """d relation / dx of a branch at x [output unit / input unit].

    5-point estimates with the step of :func:`derivative` and steps 8, 64, ... times smaller
    (six at most): the first two successive estimates that agree to 1e-5 (plus the rounding of
    the function values) give the slope. A relation with a kink or an infinite slope at x
    (sqrt|v| at v = 0) gives estimates that keep changing with the step, and is refused
    instead of returning one of them.

    Raises:
        GraphError: naming the branch, when the relation cannot be evaluated around x or has
            no well-defined finite slope there.
    """
    var = "f" if branch.type == "T" else "v"
    where = f"branches.{branch.name}.relation"

    def fn(z: float) -> float:
        return evaluate(graph, branch, z, context)

    h = 1e-4 * max(1.0, abs(x))
    center = abs(fn(x))   # a failure at x itself is the relation's own: raised
    for attempt in range(7):   # near the edge of its domain (arcsin at 0.9999 of its scale):
        try:                   # a stencil 8, 64, ... times narrower
            level = max(center, *(abs(fn(x + k * h)) for k in (-2, -1, 1, 2)))
            break
        except GraphError as exc:
            if attempt == 6:   # x is the relation's own point: x at the edge of its domain
                raise GraphError(graph.source, where, f"no slope at {var} = {x:.6g}{context}: "
                                 f"the relation cannot be evaluated within {2 * h:.2g} of "
                                 "that point, which lies on the edge of its domain; no linear "
                                 "model exists there") from exc
            h /= 8
    with np.errstate(all="ignore"):
        estimates = [derivative(fn, x, h)]
        for _ in range(6):
            h /= 8
            estimates.append(derivative(fn, x, h))
            prev, last = estimates[-2:]
            if not (math.isfinite(prev) and math.isfinite(last)):
                raise GraphError(graph.source, where, f"its slope at {var} = {x:.6g}{context} "
                                                      "is not finite")
            noise = 20 * np.finfo(float).eps * level / h
            if abs(last - prev) <= 1e-5 * max(abs(last), abs(prev)) + noise:
                _refuse_kink(fn, x, h, last, noise, graph, where, f"{var} = {x:.6g}{context}")
                return last
    # A zero slope (B v|v|^(e-1) at 0, e > 1): the quotients shrink with the step, like
    # h^(e-1), towards nothing; no relative agreement can be reached, but the slope is 0, not
    # undefined. Shrinking at every step, by 10 in all over the 8^6 range of steps: e >= 1.2.
    if all(abs(b) < 0.95 * abs(a) for a, b in zip(estimates, estimates[1:], strict=False)) \
            and abs(estimates[-1]) <= 0.1 * abs(estimates[0]):
        _refuse_kink(fn, x, h, 0.0, noise, graph, where, f"{var} = {x:.6g}{context}")
        return 0.0
    raise GraphError(graph.source, where, f"no well-defined finite slope at {var} = {x:.6g}"
                                          f"{context}: difference quotients keep changing "
                                          f"with the step ({estimates[0]:.4g} to "
                                          f"{estimates[-1]:.4g} as it shrinks 8^6 times: a "
                                          "kink or an infinite slope); no linear model there")


def _field(name: str) -> str:
    """The file's field of branch ``name``; an element pinlin combined (``K1+K2``, not in the
    file) is named by its first branch."""
    return f"branches.{name.split('+')[0]}"


class NonlinearGraph:
    """f(x, u) of a graph with nonlinear elements, on its normal tree."""

    def __init__(self, graph) -> None:
        self.graph = graph
        excess = excess_groups(graph, nonlinear=True)
        if excess:
            group = excess[0]
            kind = "T-type elements in parallel" if graph.branch(group[0]).type == "T" else \
                "A-type elements in series"
            raise GraphError(graph.source, _field(group[0]), f"excess energy storage "
                             f"({', '.join(group)}: {kind}) in a graph with nonlinear "
                             "elements: the split of the equilibrium between them is "
                             "undetermined; replace them by one element (linear ones are "
                             "combined unless combine=False)")
        linearized = _with_unit_values(graph)
        self.form = matrix_method(linearized)
        self.branches = graph.branches
        if self.form.d:
            names = [graph.branches[k].name for k in self.form.d]
            raise GraphError(graph.source, _field(names[0]), "nonlinear graphs with "
                                                                   "dependent energy storage "
                                                                   f"({', '.join(names)}) are "
                                                                   "not supported")
        self.in_tree = self.form.in_tree
        self.states = self.form.tree.states

    def primaries(self, x: np.ndarray, u: np.ndarray) -> np.ndarray:
        """All branch primaries at (x, u): dissipative ones solved from their relations."""
        form = self.form
        nb = len(self.branches)
        pi = np.zeros(nb)
        pi[form.x], pi[form.u] = x, u

        def residual(pv: np.ndarray, terms: bool = False) -> np.ndarray:
            pi[form.p] = pv
            out = np.zeros(len(form.p))
            size = np.zeros(len(form.p))
            for i, k in enumerate(form.p):
                b = self.branches[k]
                sigma = form.W[k] @ pi
                size[i] = np.abs(form.W[k]) @ np.abs(pi)
                if self.in_tree[k]:      # primary v, secondary f: relation(v) = f
                    y = evaluate(self.graph, b, pv[i]) if b.nonlinear else pv[i] / b.value
                    out[i] = y - sigma
                else:                    # primary f, secondary v: f = relation(v)
                    y = evaluate(self.graph, b, sigma) if b.nonlinear else sigma / b.value
                    out[i] = pv[i] - y
                size[i] += abs(y) + abs(pv[i])
            return size if terms else out

        def solved(sol) -> bool:
            res = residual(sol.x)
            size = residual(sol.x, terms=True)
            return bool(np.all(np.isfinite(sol.x)) and np.all(np.isfinite(res))
                        and (sol.success or np.all(np.abs(res) <= _REL_TOL * size)))

        if form.p:
            with np.errstate(all="ignore"):
                sol = _root(residual, np.zeros(len(form.p)), method="hybr")
                if not solved(sol):
                    # Far from zero (a 110 bar tank: hybr's first steps from 0 are too short):
                    # start where each link's relation puts its primary with the others at 0
                    # (exact when the links see only states and inputs).
                    start = -residual(np.zeros(len(form.p)))
                    start[[self.in_tree[k] for k in form.p]] = 0.0
                    retry = _root(residual, start, method="hybr")
                    if solved(retry):
                        sol = retry
            if not solved(sol):
                names = [self.branches[k].name for k in form.p]
                raise GraphError(self.graph.source, f"branches.{names[0]}" if len(names) == 1
                                 else "branches", f"the dissipative elements "
                                 f"({', '.join(names)}) have no solution at the state "
                                 f"{_point(self.states, x)} (Newton: {clip(sol.message)})")
            pi[form.p] = sol.x
        return pi

    def storage(self, x: np.ndarray, u: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(sigma, terms): the storage elements' secondary variables at (x, u) (zero at an
        equilibrium) and the sum of the magnitudes of the terms that make up each."""
        pi = self.primaries(x, u)
        W = self.form.W[self.form.x]
        return W @ pi, np.abs(W) @ np.abs(pi)

    def rate(self, x: np.ndarray, u: np.ndarray) -> np.ndarray:
        """x' = f(x, u)."""
        form = self.form
        pi = self.primaries(x, u)
        xdot = np.zeros(len(form.x))
        for i, k in enumerate(form.x):
            b = self.branches[k]
            sigma = form.W[k] @ pi
            slope = _slope(self.graph, b, x[i]) if b.nonlinear else b.value
            if slope == 0:
                raise GraphError(self.graph.source, f"branches.{b.name}.relation", "zero slope "
                                 f"at {self.states[i]} = {x[i]:.6g}: the rate is undefined")
            xdot[i] = sigma / slope
        return xdot

    def branch_values(self, x: np.ndarray, u: np.ndarray) -> dict[str, tuple[float, float]]:
        """(across, through) of every branch at (x, u)."""
        pi = self.primaries(x, u)
        out = {}
        for k, b in enumerate(self.branches):
            sec = self.form.W[k] @ pi
            out[b.name] = (pi[k], sec) if self.in_tree[k] else (sec, pi[k])
        return out

    def equilibrium(self, u: np.ndarray, guess: np.ndarray) -> np.ndarray:
        """x0 with sigma(x0, u) = 0, from ``guess`` (GraphError when none is found)."""
        try:
            with np.errstate(all="ignore"):
                sol = _root(lambda z: self.storage(z, u)[0], guess, method="hybr",
                           options={"xtol": 1e-13})
        except GraphError as exc:
            raise GraphError(exc.source, exc.field, f"{exc.reason} (while searching for the "
                             f"equilibrium from {_point(self.states, guess)} with inputs "
                             f"{self._inputs(u)}; if the relation is right, give a closer "
                             "[operating_point] guess or check that the inputs admit an "
                             "equilibrium)") from None
        x = sol.x
        if self.converged(x, u):
            return x
        sigma = self.storage(x, u)[0] if np.all(np.isfinite(x)) else x
        raise GraphError(self.graph.source, "operating_point.guess", f"graph "
                         f"'{self.graph.name}': no equilibrium found from "
                         f"{_point(self.states, guess)} with inputs {self._inputs(u)} (Newton "
                         f"stopped at {_point(self.states, x)} with residual "
                         f"{np.array2string(np.asarray(sigma), precision=3, threshold=8)}: "
                         f"{clip(sol.message)}); give a closer [operating_point] guess, or "
                         "the inputs admit no equilibrium")

    def _inputs(self, u: np.ndarray) -> str:
        names = [self.branches[k].name for k in self.form.u]
        return "{" + ", ".join(f"{n} = {v:.6g}" for n, v in zip(names, u, strict=True)) + "}"

    def converged(self, x: np.ndarray, u: np.ndarray) -> bool:
        """Whether x is an equilibrium to double precision (see the module docstring)."""
        if not np.all(np.isfinite(x)):
            return False
        sigma, terms = self.storage(x, u)
        if not (np.all(np.isfinite(sigma)) and np.all(np.isfinite(terms))):
            return False
        if np.all(np.abs(sigma) <= _REL_TOL * terms):
            return True
        n = len(x)
        J = np.zeros((n, n))
        with np.errstate(all="ignore"):
            for j in range(n):
                h = 1e-7 * max(1.0, abs(x[j]))
                e = np.zeros(n)
                e[j] = h
                J[:, j] = (self.storage(x + e, u)[0] - self.storage(x - e, u)[0]) / (2 * h)
            if not np.all(np.isfinite(J)):
                return False
            step = np.linalg.lstsq(J, sigma, rcond=None)[0]
            with_terms = np.where(J != 0, terms[:, None] / np.abs(np.where(J != 0, J, 1.0)), 0)
        scale = np.maximum(np.abs(x), with_terms.max(axis=0))
        return bool(np.all(np.abs(step) <= _STEP_TOL * scale)
                    and np.allclose(J @ step, sigma, rtol=1e-6, atol=0))


def _number(value: object) -> float | None:
    """``value`` as a float if it is a real number, finite and within [-1e100, 1e100]."""
    if isinstance(value, bool) or not isinstance(value, numbers.Real):
        return None
    try:
        x = float(value)
    except (OverflowError, ValueError, TypeError):
        return None
    return x if math.isfinite(x) and abs(x) <= VALUE_MAX else None


#: States named in a message's point; the rest are counted.
_POINT_SHOWN = 6


def _point(states: Sequence[str], x: np.ndarray) -> str:
    """``{name = value, ...}`` of the first :data:`_POINT_SHOWN` states (a message stays one
    readable line for a graph of many states)."""
    pairs = [f"{s} = {v:.6g}" for s, v in zip(states[:_POINT_SHOWN], x, strict=False)]
    more = len(states) - _POINT_SHOWN
    return "{" + ", ".join(pairs) + (f", ... ({more} more)" if more > 0 else "") + "}"


def _with_unit_values(graph):
    """Same topology with every nonlinear element given value 1 (for the tree and W)."""
    from .graph import Graph

    g = Graph(graph.name, graph.domain, source=graph.source)
    for b in graph.branches:
        g.branches.append(replace(b, value=1.0, relation=None) if b.nonlinear else b)
    g.outputs = graph.outputs
    return g


#: Most nonlinear elements a graph may have. The equilibrium search nests Newton on the
#: dissipative primaries inside Newton on the states, both with difference Jacobians: its time
#: grows about as the cube of the count (a ladder of 100 capacitors and cubic resistors: 13 s;
#: of 300: not done after 5 minutes).
MAX_NONLINEAR = 100


def linearize_nonlinear(graph, *, outputs: Sequence[str] | None, combine: bool,
                        u0: Mapping[str, float] | None, x0: Sequence[float] | None):
    """Equilibrium and linear model about it."""
    count = sum(b.nonlinear for b in graph.branches)
    if count > MAX_NONLINEAR:
        raise GraphError(graph.source, "branches", f"{count} nonlinear elements; pinlin "
                         f"linearizes graphs with at most {MAX_NONLINEAR} (its equilibrium "
                         "search takes time growing as the cube of their count: a ladder of "
                         "100 took 13 s, one of 300 did not end in 5 minutes)")
    # linear excess storage combined first (unless combine=False): the equilibrium is then
    # isolated; a combined copy keeps the graph's guess
    work, combined, aliases, _ = combine_excess(graph, combine)
    work.guess = graph.guess
    nl = NonlinearGraph(work)
    form = nl.form
    inputs = {b.name: b.input for b in work.branches if b.is_source}
    if u0 is not None:
        if not isinstance(u0, Mapping):
            raise ArgumentError("u0", f"expected a dict of source name -> operating input, "
                                      f"got {show(u0)}")
        for name, value in u0.items():
            if name not in inputs:
                raise ArgumentError("u0", f"{show(name)} is not a source of the graph; "
                                          f"sources: {', '.join(inputs) or 'none'}")
            number = _number(value)
            if number is None:
                raise ArgumentError("u0", f"{name}: expected a finite number within [-1e100, "
                                          f"1e100], got {show(value)}")
            inputs[name] = number
    u = np.array([inputs[work.branches[k].name] for k in form.u])
    states = nl.states
    if x0 is None:
        unknown = set(work.guess) - set(states)
        if unknown:
            raise GraphError(graph.source, "operating_point.guess", f"{sorted(unknown)} are not "
                                                                    f"state variables; the "
                                                                    f"states are {states}")
        guess = np.array([real(graph.source, f"operating_point.guess.{s}",
                               work.guess.get(s, 0.0)) for s in states])
    else:
        if isinstance(x0, str | bytes | Mapping) or not isinstance(x0, Sequence | np.ndarray):
            raise ArgumentError("x0", f"expected a list of {len(states)} numbers (states "
                                      f"{', '.join(states)}), got {show(x0)}")
        if len(x0) != len(states):
            raise ArgumentError("x0", f"expected one number per state ({len(states)}: "
                                      f"{', '.join(states)}), got {len(x0)}")
        guess = np.array([_number(v) for v in x0], dtype=object)
        for i, v in enumerate(x0):
            if guess[i] is None:
                raise ArgumentError("x0", f"entry {i} ({states[i]}): expected a finite number "
                                          f"within [-1e100, 1e100], got {show(v)}")
        guess = guess.astype(float)
    xe = nl.equilibrium(u, guess)
    values = nl.branch_values(xe, u)
    from .graph import Graph

    inc = Graph(graph.name, graph.domain, source=graph.source)
    increments = {}
    for b in work.branches:
        if not b.nonlinear:
            inc.branches.append(b)
            continue
        v0, f0 = values[b.name]
        where = f"branches.{b.name}"
        context = f" (at the equilibrium {_point(nl.states, xe)})"
        evaluate(graph, b, f0 if b.type == "T" else v0, context)
        if b.type == "D":
            g = _slope(graph, b, v0, context)
            if not g > 0:
                raise GraphError(graph.source, where, "the incremental conductance df/dv = "
                                 f"{g:.3g} at v = {v0:.6g} is not positive and finite: no "
                                 "linear model at this operating point")
            value = 1.0 / g
            what = "incremental resistance 1/(df/dv)"
        elif b.type == "A":
            value = _slope(graph, b, v0, context)
            what = f"incremental capacitance dq/dv at v = {v0:.6g}"
        else:
            value = _slope(graph, b, f0, context)
            what = f"incremental inductance dlam/df at f = {f0:.6g}"
        if not VALUE_MIN <= value <= VALUE_MAX:
            raise GraphError(graph.source, where, f"{what} = {value:.3g} is outside "
                                                  f"{RANGE}: no linear model at this "
                                                  "operating point")
        increments[b.name] = value
        inc.branches.append(Branch(b.name, b.type, b.from_, b.to, value))
    inc.outputs = graph.outputs
    form_inc = matrix_method(inc)    # inc's branches were checked (or merged from checked ones)
    form_inc.aliases = aliases
    form_inc.tree.combined = combined
    form_inc.tree.excess = []
    model = state_space(graph, form_inc, outputs, info={
        "operating_point": {"x0": dict(zip(form_inc.tree.states, xe.tolist(), strict=True)),
                            "u0": inputs},
        "incremental_values": increments})
    return model

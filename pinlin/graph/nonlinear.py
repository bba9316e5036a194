"""Graphs with nonlinear elements (Rowell sections 6 and 7).

A nonlinear element carries a constitutive relation instead of a value:

- D-type: f = relation(v) (a damper F = c v|v|, an orifice Q = K sqrt|P| sgn P);
- A-type: q = relation(v), f = dq/dt (a tank volume as a function of base pressure);
- T-type: lam = relation(f), v = dlam/dt (a spring's displacement as a function of its force).

The normal tree and the constraint matrices are those of the linear method. f(x, u) solves the
dissipative primaries from their (possibly coupled) relations by Newton, then x' = sigma / q'(x)
for A-type and x' = sigma / lam'(x) for T-type states. The equilibrium solves f(x0, u0) = 0; the
linear model is the matrix method applied to the incremental graph, where a nonlinear D-type
element becomes a resistance 1 / (df/dv) and a storage element takes its incremental value
q'(v0) or lam'(f0) (exact at an equilibrium, where the storage secondaries vanish).
Derivatives of the relations: 5-point central differences on the scalar function.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import replace

import numpy as np
from scipy.optimize import root

from ..exceptions import EquilibriumError
from .model import Branch, GraphError


def derivative(fn, x: float) -> float:
    """d fn / dx at x by the 5-point formula with a relative step."""
    h = 1e-4 * max(1.0, abs(x))
    return (fn(x - 2 * h) - 8 * fn(x - h) + 8 * fn(x + h) - fn(x + 2 * h)) / (12 * h)


def _inverse(fn, target: float, guess: float) -> float:
    """x with fn(x) = target (scalar Newton from guess, then a bracketing fallback)."""
    sol = root(lambda z: fn(z[0]) - target, [guess], method="hybr")
    if sol.success:
        return float(sol.x[0])
    raise EquilibriumError(f"cannot invert a nonlinear relation for the value {target:.6g}")


class NonlinearGraph:
    """f(x, u) of a graph with nonlinear elements, on its normal tree."""

    def __init__(self, graph) -> None:
        self.graph = graph
        linearized = _with_unit_values(graph)
        self.form = linearized._formulate()
        self.branches = graph.branches
        if self.form.d:
            names = [graph.branches[k].name for k in self.form.d]
            raise GraphError(graph.source, "branches", "nonlinear graphs with dependent energy "
                                                       f"storage ({', '.join(names)}) are not "
                                                       "supported")
        self.in_tree = linearized._in_tree

    def primaries(self, x: np.ndarray, u: np.ndarray) -> np.ndarray:
        """All branch primaries at (x, u): dissipative ones solved from their relations."""
        form = self.form
        nb = len(self.branches)
        pi = np.zeros(nb)
        pi[form.x], pi[form.u] = x, u

        def residual(pv: np.ndarray) -> np.ndarray:
            pi[form.p] = pv
            out = np.zeros(len(form.p))
            for i, k in enumerate(form.p):
                b = self.branches[k]
                sigma = form.W[k] @ pi
                if self.in_tree[k]:      # primary v, secondary f: relation(v) = f
                    out[i] = (b.relation(pv[i]) - sigma if b.nonlinear
                              else pv[i] - b.value * sigma)
                else:                    # primary f, secondary v: f = relation(v)
                    out[i] = (pv[i] - b.relation(sigma) if b.nonlinear
                              else pv[i] - sigma / b.value)
            return out

        if form.p:
            sol = root(residual, np.zeros(len(form.p)), method="hybr")
            if not sol.success:
                raise EquilibriumError(f"graph '{self.graph.name}': the dissipative elements "
                                       f"have no solution at this state ({sol.message})")
            pi[form.p] = sol.x
        return pi

    def rate(self, x: np.ndarray, u: np.ndarray) -> np.ndarray:
        """x' = f(x, u)."""
        form = self.form
        pi = self.primaries(x, u)
        xdot = np.zeros(len(form.x))
        for i, k in enumerate(form.x):
            b = self.branches[k]
            sigma = form.W[k] @ pi
            slope = derivative(b.relation, x[i]) if b.nonlinear else b.value
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


def _with_unit_values(graph):
    """Same topology with every nonlinear element given value 1 (for the tree and W)."""
    from .graph import Graph

    g = Graph(graph.name, graph.domain, source=graph.source)
    for b in graph.branches:
        g.branches.append(replace(b, value=1.0, relation=None) if b.nonlinear else b)
    g.outputs = graph.outputs
    return g


def linearize_nonlinear(graph, *, outputs: Sequence[str] | None, combine: bool,
                        u0: dict[str, float] | None, x0: Sequence[float] | None):
    """Equilibrium and linear model about it."""
    nl = NonlinearGraph(graph)
    form = nl.form
    inputs = {graph.branches[k].name: graph.branches[k].input for k in form.u}
    for name, value in (u0 or {}).items():
        if name not in inputs:
            raise GraphError(graph.source, f"u0.{name}", f"'{name}' is not a source of the graph")
        inputs[name] = float(value)
    u = np.array([inputs[graph.branches[k].name] for k in form.u])
    if x0 is None:
        states = graph.normal_tree(combine=False).states
        unknown = set(graph.guess) - set(states)
        if unknown:
            raise GraphError(graph.source, "operating_point.guess", f"{sorted(unknown)} are not "
                                                                    f"state variables {states}")
        guess = np.array([graph.guess.get(s, 0.0) for s in states])
    else:
        guess = np.asarray(x0, float)
    sol = root(lambda x: nl.rate(x, u), guess, method="hybr", options={"xtol": 1e-13})
    scale = max(1.0, float(np.abs(sol.x).max()))
    if np.abs(nl.rate(sol.x, u)).max() > 1e-9 * scale:
        raise EquilibriumError(f"graph '{graph.name}': no equilibrium found from x0 = "
                               f"{guess.tolist()} ({sol.message})")
    xe = sol.x
    values = nl.branch_values(xe, u)
    from .graph import Graph

    inc = Graph(graph.name, graph.domain, source=graph.source)
    increments = {}
    for b in graph.branches:
        if not b.nonlinear:
            inc.branches.append(b)
            continue
        v0, f0 = values[b.name]
        if b.type == "D":
            g = derivative(b.relation, v0)
            if not np.isfinite(g) or g <= 0:
                raise GraphError(graph.source, f"branches.{b.name}", "the incremental "
                                 f"conductance df/dv = {g:.3g} at v = {v0:.6g} is not positive "
                                 "and finite: no linear model at this operating point")
            value = 1.0 / g
        elif b.type == "A":
            value = derivative(b.relation, v0)
        else:
            value = derivative(b.relation, f0)
        if not np.isfinite(value) or value <= 0:
            raise GraphError(graph.source, f"branches.{b.name}", f"incremental value "
                                                                 f"{value:.3g} is not positive")
        increments[b.name] = value
        inc.branches.append(Branch(b.name, b.type, b.from_, b.to, value))
    inc.outputs = graph.outputs
    model = inc._linear_model(inc.formulate(combine), outputs, info={
        "operating_point": {"x0": dict(zip(inc.normal_tree(combine).states, xe.tolist(),
                                           strict=True)),
                            "u0": inputs},
        "incremental_values": increments})
    return model

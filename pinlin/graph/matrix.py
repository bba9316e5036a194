"""The matrix method (Rowell, eqs. 109-128) on a normal tree, output rows, and standard form.

With the loop matrix Bf (v_links = Bf v_tree) the secondary variables follow from the
primary ones: f_tree = -Bf^T f_links. The elemental equations in primary form split the
primaries into states x, dependent storage d and dissipative p:
x' = P x + Q p + R d + S u, d = M x' + N u', p = H x + J p + K d + L u, solved as in eq. 128
for x' = A x + B u + E u'. Outputs are any branch variables, y = C x + D u + F u'; the
standard form removes E with x' = x - E u (eqs. 90-93).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from ..linear_model import LinearModel
from .excess import Aliases
from .model import GraphError
from .solve import check_finite, solve
from .tree import NormalTree, find_normal_tree, loop_matrix

if TYPE_CHECKING:
    from .graph import Graph


@dataclass
class Formulation:
    """Matrices of eqs. 109-128 and how to read any branch variable.

    ``graph`` is the graph formulated (excess storage combined); ``x``, ``d``, ``p``, ``u``
    index its branches that are states, dependent storage, dissipative elements and sources.
    """

    tree: NormalTree
    graph: Graph
    in_tree: list[bool]      # per branch of graph: whether it is a tree branch
    x: list[int]
    d: list[int]
    p: list[int]
    u: list[int]
    W: np.ndarray            # secondary variable of branch k = W[k] @ primaries
    A: np.ndarray
    B: np.ndarray
    E: np.ndarray
    Hp: np.ndarray           # p = Hp x + Kp d + Lp u
    Kp: np.ndarray
    Lp: np.ndarray
    M: np.ndarray
    N: np.ndarray
    aliases: Aliases         # combined member variable -> (equivalent var, factor)
    error: float = 0.0       # estimated relative error of the solves (see solve)


def matrix_method(graph: Graph) -> Formulation:
    """The state equations of ``graph`` as it stands (excess storage not combined, linear
    elements only) on its normal tree.

    Raises:
        GraphError: the normal tree cannot be built, a dependent storage element couples to
            dissipative or other dependent ones, or a solve is singular or cannot be trusted
            in double precision (see :func:`~pinlin.graph.solve.solve`).
    """
    tree, in_tree = find_normal_tree(graph)
    nb = len(graph.branches)
    tree_idx = [k for k in range(nb) if in_tree[k]]
    link_idx = [k for k in range(nb) if not in_tree[k]]
    Bf = loop_matrix(graph.branches, in_tree)
    # W: secondary of branch k in terms of the primaries of all branches.
    W = np.zeros((nb, nb))
    for row, l_ in enumerate(link_idx):
        for col, t in enumerate(tree_idx):
            W[l_, t] = Bf[row, col]          # v_link = Bf v_tree
            W[t, l_] = -Bf[row, col]         # f_tree = -Bf^T f_link
    x, d, p, u = [], [], [], []
    for k, b in enumerate(graph.branches):
        if b.is_source:
            u.append(k)
        elif b.type == "D":
            p.append(k)
        elif (b.type == "A") == in_tree[k]:
            x.append(k)
        else:
            d.append(k)

    def split(row: np.ndarray) -> tuple[np.ndarray, ...]:
        """(x, d, p, u) parts of a row over the primaries."""
        return row[x], row[d], row[p], row[u]

    n, nd, npp, m = len(x), len(d), len(p), len(u)
    P, Q, R, S = np.zeros((n, n)), np.zeros((n, npp)), np.zeros((n, nd)), np.zeros((n, m))
    for i, k in enumerate(x):
        c = 1.0 / graph.branches[k].value   # x' = f / C (A) or v / L (T)
        P[i], R[i], Q[i], S[i] = (c * part for part in split(W[k]))
    H, J, K, L = (np.zeros((npp, n)), np.zeros((npp, npp)), np.zeros((npp, nd)),
                  np.zeros((npp, m)))
    for i, k in enumerate(p):
        val = graph.branches[k].value
        c = val if in_tree[k] else 1.0 / val   # tree: v = R f; link: f = v / R
        H[i], K[i], J[i], L[i] = (c * part for part in split(W[k]))
    M, N = np.zeros((nd, n)), np.zeros((nd, m))
    for i, k in enumerate(d):
        wx, wd, wp, wu = split(W[k])
        if np.any(wd) or np.any(wp):
            raise GraphError(graph.source, f"branches.{graph.branches[k].name}",
                             f"dependent energy-storage element '{graph.branches[k].name}' "
                             "couples to dissipative or other dependent elements; the "
                             "matrix method (eqs. 109-128) does not apply")
        M[i], N[i] = graph.branches[k].value * wx, graph.branches[k].value * wu
    names = [graph.branches[k].name for k in p]
    with np.errstate(all="ignore"):
        HKL, err_p = solve(graph, np.eye(npp) - J, np.hstack([H, K, L]), names,
                           "the dissipative elements form an algebraic loop with no "
                           "unique solution")
        Hp, Kp, Lp = HKL[:, :n], HKL[:, n:n + nd], HKL[:, n + nd:]
        QKR = Q @ Kp + R
        G = np.eye(n) - QKR @ M
        rhs = np.hstack([P + Q @ Hp, S + Q @ Lp, QKR @ N])
        sol, err_d = solve(graph, G, rhs, [graph.branches[k].name for k in d],
                           "the dependent energy storage makes the state equations "
                           "singular")
    A, B, E = sol[:, :n], sol[:, n:n + m], sol[:, n + m:]
    return Formulation(tree, graph, in_tree, x, d, p, u, W, A, B, E, Hp, Kp, Lp, M, N, {},
                       max(err_p, err_d))


def output_row(form: Formulation, var: str) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(C row, D row, F row) of one branch variable."""
    if var in form.aliases:
        target, factor = form.aliases[var]
        c, dr, f = output_row(form, target)
        return factor * c, factor * dr, factor * f
    kind, _, name = var.partition(":")
    g = form.graph
    try:
        k = next(i for i, b in enumerate(g.branches) if b.name == name)
    except StopIteration:
        raise GraphError(g.source, "outputs.variables", f"no branch named '{name}'") from None
    in_tree = form.in_tree[k]
    nb = len(g.branches)
    if kind not in ("v", "f"):
        raise GraphError(g.source, "outputs.variables", f"'{var}': expected v: or f:")
    is_primary = (kind == "v") == in_tree
    branch = g.branches[k]
    if branch.type == "D" and not is_primary:
        # elemental law on the primary (f = v / R in the tree, v = R f as a link) instead of
        # the constraint sum, which cancels when a tiny flow meets large ones (1e50 ohm
        # beside 1 ohm: f = 1 - (1 - 1e-50) = 0)
        c, dr, f = output_row(form, f"{'v' if in_tree else 'f'}:{name}")
        factor = 1.0 / branch.value if in_tree else branch.value
        return factor * c, factor * dr, factor * f
    states = form.tree.states
    state = f"{'v' if in_tree else 'f'}:{name}"     # the element's own state variable
    if branch.type in ("A", "T") and not is_primary and state in states:
        # elemental law on the state, f = C v' or v = L f', with x' = A x + B u + E u' (a row
        # of the state equations): the constraint sum would take a small capacitor's share of
        # a current as the difference of large ones (1e-5 F beside 1.6e-2 F: ~1e-13 lost)
        i = states.index(state)
        return (branch.value * form.A[i], branch.value * form.B[i],
                branch.value * form.E[i])
    w = np.zeros(nb)
    if is_primary:
        w[k] = 1.0
    else:
        w = form.W[k].copy()
    cx, cd, cp, cu = w[form.x], w[form.d], w[form.p], w[form.u]
    C = cx + cp @ form.Hp
    Dm = cu + cp @ form.Lp
    cdd = cd + cp @ form.Kp                      # coefficient of d = M x' + N u'
    C = C + cdd @ form.M @ form.A
    Dm = Dm + cdd @ form.M @ form.B
    F = cdd @ (form.M @ form.E + form.N)
    return C, Dm, F


def state_space(graph: Graph, form: Formulation, outputs: Sequence[str] | None,
                info: dict | None = None) -> LinearModel:
    """The LinearModel of ``form`` for ``graph`` (the graph as given, before combining).

    Args:
        outputs: Branch variables to output (checked by the caller); None: the graph's
            ``outputs``, else the states.
        info: Entries added to the model's ``info``.

    Raises:
        GraphError: a matrix entry is not finite or is subnormal (naming the row's branch).
    """
    states = form.tree.states
    names = list(outputs if outputs is not None else (graph.outputs or states))
    with np.errstate(all="ignore"):   # overflow is reported by check_finite below
        rows = [output_row(form, var) for var in names]
    n, m = len(states), len(form.u)
    C = np.array([r[0] for r in rows]).reshape(len(rows), n)
    D = np.array([r[1] for r in rows]).reshape(len(rows), m)
    F = np.array([r[2] for r in rows]).reshape(len(rows), m)
    inputs = tuple(form.graph.branches[k].name for k in form.u)
    check_finite(graph, {"A": (form.A, states, states), "B": (form.B, states, inputs),
                         "E": (form.E, states, inputs), "C": (C, names, states),
                         "D": (D, names, inputs), "F": (F, names, inputs)})
    E = form.E if np.any(form.E) else None
    meta = {"formulation": "linear graph (Rowell, matrix method)", "domain": graph.domain,
            "normal_tree": form.tree.tree, "links": form.tree.links,
            "dependent": form.tree.dependent, "combined": form.tree.combined,
            "excess": form.tree.excess, "solve_error_estimate": form.error}
    meta.update(info or {})
    return LinearModel(A=form.A, B=form.B, C=C, D=D, state_names=tuple(states),
                       input_names=inputs, output_names=tuple(names), E=E,
                       F=F if (E is not None or np.any(F)) else None, name=graph.name,
                       info=meta)


def to_standard_form(graph: Graph, model: LinearModel) -> LinearModel:
    """``model`` without E: x' = x - E u, B' = B + A E, D' = D + C E (eqs. 90-93); the model
    itself when it has no E.

    Raises:
        GraphError: an entry of B' or D' is not finite or is subnormal.
    """
    if model.E is None:
        return model
    with np.errstate(all="ignore"):
        check_finite(graph, {"B'": (model.B + model.A @ model.E, model.state_names,
                                    model.input_names),
                             "D'": (model.D + model.C @ model.E, model.output_names,
                                    model.input_names)})
    return model.standard_form()

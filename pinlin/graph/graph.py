"""State equations of a linear graph by Rowell's normal tree and matrix method (eqs. 109-128).

1. Excess storage is combined first (A-type elements directly in series, T-type elements
   directly in parallel), unless ``combine=False``, in which case it is reported.
2. Normal tree (steps 1-6): across sources, then A-type, D-type, T-type elements enter the tree
   greedily (file order within a type) while they close no loop; an across source that cannot
   enter means a loop of across sources, a through source that must enter means a cut-set of
   through sources: both are errors. A-type links and T-type tree branches are dependent.
3. Primary variables: across variables of tree branches, through variables of links. With the
   loop matrix Bf (v_links = Bf v_tree) the secondary ones follow: f_tree = -Bf^T f_links.
4. Elemental equations in primary form split the primaries into states x, dependent storage d
   and dissipative p: x' = P x + Q p + R d + S u, d = M x' + N u', p = H x + J p + K d + L u,
   solved as in eq. 128 for x' = A x + B u + E u'. Outputs are any branch variables,
   y = C x + D u + F u'.

Nonlinear elements (Python API) give f(x, u); :meth:`Graph.linearize` finds the equilibrium
f(x0, u0) = 0 and linearizes (Rowell section 7) by formulating the incremental graph, in which
each nonlinear element takes its incremental value at the operating point.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..exceptions import PinlinError
from ..linear_model import LinearModel
from .model import PASSIVE, SOURCES, TYPES, Branch, GraphError, load_graph_file

_PRIORITY = {"across_source": 0, "A": 1, "D": 2, "T": 3, "through_source": 4}


@dataclass
class NormalTree:
    """A normal tree and what it defines.

    Attributes:
        tree, links: Branch names in the tree and among the links.
        states: State variable names (``v:`` of A-type tree branches, ``f:`` of T-type links).
        dependent: Dependent energy-storage elements (A-type links, T-type tree branches).
        primary, secondary: Variable names by class.
        order: System order n.
        combined: Equivalent elements formed from excess storage: name -> member names.
        excess: Groups of excess storage found but not combined (``combine=False``).
    """

    tree: list[str]
    links: list[str]
    states: list[str]
    dependent: list[str]
    primary: list[str]
    secondary: list[str]
    order: int
    combined: dict[str, list[str]] = field(default_factory=dict)
    excess: list[list[str]] = field(default_factory=list)

    def describe(self) -> str:
        lines = [f"normal tree: {', '.join(self.tree)}",
                 f"links: {', '.join(self.links)}",
                 f"primary variables: {', '.join(self.primary)}",
                 f"secondary variables: {', '.join(self.secondary)}",
                 f"system order: {self.order}",
                 f"state variables: {', '.join(self.states) or 'none'}"]
        if self.dependent:
            lines.append(f"dependent energy storage: {', '.join(self.dependent)}")
        for eq, members in self.combined.items():
            lines.append(f"combined excess storage: {eq} = {' + '.join(members)}")
        for group in self.excess:
            lines.append(f"excess state variables (not combined): {', '.join(group)}")
        return "\n".join(lines)


@dataclass
class _Formulation:
    """Matrices of eqs. 109-128 and how to read any branch variable."""

    tree: NormalTree
    graph: Graph
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
    aliases: dict[str, tuple[str, float]]  # combined member variable -> (equivalent var, factor)


class Graph:
    """A linear graph of lumped elements.

    Build with :meth:`load` (TOML) or in Python with :meth:`add_branch`; outputs are branch
    variables ``v:<branch>`` (across) and ``f:<branch>`` (through).
    """

    def __init__(self, name: str, domain: str = "electrical", *, source: Path | None = None
                 ) -> None:
        self.name = name
        self.domain = domain
        self.source = source
        self.branches: list[Branch] = []
        self.outputs: list[str] = []
        self.guess: dict[str, float] = {}

    # ----------------------------------------------------------------------------------------
    @classmethod
    def load(cls, path: str | Path) -> Graph:
        """Read a graph TOML file (format in the README and :mod:`pinlin.graph.model`)."""
        return load_graph_file(path)

    def add_branch(self, name: str, type: str, from_: str, to: str, value: float | None = None,
                   *, relation: Callable[[float], float] | None = None, input: float = 0.0,
                   field: str | None = None) -> Graph:
        """Add a branch; ``relation`` makes a passive element nonlinear (see :class:`Branch`).

        Raises:
            GraphError: duplicate name, unknown type, missing or non-positive value.
        """
        fld = field or f"branches.{name}"
        if any(b.name == name for b in self.branches):
            raise GraphError(self.source, f"{fld}.name", f"branch name '{name}' is used twice")
        if type not in TYPES:
            raise GraphError(self.source, f"{fld}.type", f"unknown element type {type!r}; "
                                                         f"expected one of {', '.join(TYPES)}")
        if from_ == to:
            raise GraphError(self.source, f"{fld}.to", f"branch '{name}' starts and ends at "
                                                       f"node '{to}'")
        if type in SOURCES and (value is not None or relation is not None):
            raise GraphError(self.source, f"{fld}.value", "a source takes no value")
        if type in PASSIVE and relation is None and (
                value is None or not np.isfinite(value) or value <= 0):
            raise GraphError(self.source, f"{fld}.value", f"a {type}-type element needs a "
                                                          f"value > 0, got {value!r}")
        self.branches.append(Branch(name, type, from_, to, None if value is None
                                    else float(value), relation, float(input)))
        return self

    def branch(self, name: str) -> Branch:
        for b in self.branches:
            if b.name == name:
                return b
        raise GraphError(self.source, "outputs.variables", f"no branch named '{name}'")

    def check_outputs(self) -> None:
        for var in self.outputs:
            kind, _, name = var.partition(":")
            if kind not in ("v", "f") or not name:
                raise GraphError(self.source, "outputs.variables",
                                 f"'{var}': expected 'v:<branch>' or 'f:<branch>'")
            self.branch(name)

    @property
    def inputs(self) -> list[str]:
        """Input names: the source branches, in file order."""
        return [b.name for b in self.branches if b.is_source]

    # ----------------------------------------------------------------------------------------
    def normal_tree(self, combine: bool = True) -> NormalTree:
        """The normal tree of the graph (after combining excess storage unless told not to)."""
        graph, combined, _ = self._combined() if combine else (self, {}, {})
        tree = graph._normal_tree()
        tree.combined = combined
        if not combine:
            tree.excess = [g for g in self._excess_groups() if len(g) > 1]
        return tree

    def formulate(self, combine: bool = True) -> _Formulation:
        """State-equation matrices by the matrix method (linear elements only)."""
        for b in self.branches:
            if b.nonlinear:
                raise GraphError(self.source, f"branches.{b.name}", "nonlinear element: use "
                                                                     "Graph.linearize()")
        graph, combined, aliases = self._combined() if combine else (self, {}, {})
        form = graph._formulate()
        form.tree.combined = combined
        form.aliases = aliases
        if not combine:
            form.tree.excess = [g for g in self._excess_groups() if len(g) > 1]
        form.graph = graph
        return form

    def linearize(self, *, outputs: Sequence[str] | None = None, combine: bool = True,
                  standard_form: bool = False, u0: dict[str, float] | None = None,
                  x0: Sequence[float] | None = None) -> LinearModel:
        """The state-space model: x' = A x + B u + E u', y = C x + D u + F u'.

        Args:
            outputs: Branch variables to output (default: the graph's ``outputs``, else the
                states).
            combine: Combine excess storage (A in series, T in parallel) before the tree.
            standard_form: Remove E with x' = x - E u (eqs. 90-93).
            u0: Operating inputs by source name (nonlinear graphs; default: each source's
                ``input``).
            x0: Starting guess for the equilibrium state (nonlinear graphs; default: the
                graph's ``operating_point.guess``, zeros elsewhere).
        """
        if any(b.nonlinear for b in self.branches):
            from .nonlinear import linearize_nonlinear

            model = linearize_nonlinear(self, outputs=outputs, combine=combine, u0=u0, x0=x0)
        else:
            model = self._linear_model(self.formulate(combine), outputs)
        return model.standard_form() if standard_form else model

    # ----------------------------------------------------------------------------------------
    def _linear_model(self, form: _Formulation, outputs: Sequence[str] | None,
                      info: dict | None = None) -> LinearModel:
        states = form.tree.states
        names = list(outputs if outputs is not None else (self.outputs or states))
        rows = [output_row(form, var) for var in names]
        n, m = len(states), len(form.u)
        C = np.array([r[0] for r in rows]).reshape(len(rows), n)
        D = np.array([r[1] for r in rows]).reshape(len(rows), m)
        F = np.array([r[2] for r in rows]).reshape(len(rows), m)
        E = form.E if np.any(form.E) else None
        meta = {"formulation": "linear graph (Rowell, matrix method)", "domain": self.domain,
                "normal_tree": form.tree.tree, "links": form.tree.links,
                "dependent": form.tree.dependent, "combined": form.tree.combined,
                "excess": form.tree.excess}
        meta.update(info or {})
        return LinearModel(A=form.A, B=form.B, C=C, D=D, state_names=tuple(states),
                           input_names=tuple(form.graph.branches[k].name for k in form.u),
                           output_names=tuple(names), E=E,
                           F=F if (E is not None or np.any(F)) else None, name=self.name,
                           info=meta)

    def _check_connected(self) -> list[str]:
        nodes: list[str] = []
        for b in self.branches:
            for node in (b.from_, b.to):
                if node not in nodes:
                    nodes.append(node)
        uf = _UnionFind(nodes)
        for b in self.branches:
            uf.union(b.from_, b.to)
        groups = {uf.find(n) for n in nodes}
        if len(groups) > 1:
            first = next(n for n in nodes if uf.find(n) != uf.find(nodes[0]))
            raise GraphError(self.source, "branches", f"the graph is not connected: node "
                                                      f"'{first}' has no path to node "
                                                      f"'{nodes[0]}'")
        return nodes

    def _normal_tree(self) -> NormalTree:
        if not self.branches:
            raise GraphError(self.source, "branches", "the graph has no branches")
        nodes = self._check_connected()
        uf = _UnionFind(nodes)
        order = sorted(range(len(self.branches)),
                       key=lambda k: (_PRIORITY[self.branches[k].type], k))
        in_tree = [False] * len(self.branches)
        for k in order:
            b = self.branches[k]
            if uf.find(b.from_) != uf.find(b.to):
                uf.union(b.from_, b.to)
                in_tree[k] = True
            elif b.type == "across_source":
                raise GraphError(self.source, f"branches.{b.name}", "across-variable sources "
                                 f"form a loop: '{b.name}' closes a loop of sources "
                                 "(compatibility would be violated)")
        for k, b in enumerate(self.branches):
            if in_tree[k] and b.type == "through_source":
                raise GraphError(self.source, f"branches.{b.name}", "through-variable sources "
                                 f"form a cut-set: '{b.name}' is needed in the normal tree "
                                 "(continuity would be violated)")
        tree = [b.name for k, b in enumerate(self.branches) if in_tree[k]]
        links = [b.name for k, b in enumerate(self.branches) if not in_tree[k]]
        states, dependent, primary, secondary = [], [], [], []
        for k, b in enumerate(self.branches):
            across, through = f"v:{b.name}", f"f:{b.name}"
            primary.append(across if in_tree[k] else through)
            secondary.append(through if in_tree[k] else across)
            if b.type == "A":
                (states if in_tree[k] else dependent).append(across if in_tree[k] else b.name)
            elif b.type == "T":
                (dependent if in_tree[k] else states).append(b.name if in_tree[k] else through)
        self._in_tree = in_tree
        return NormalTree(tree, links, states, dependent, primary, secondary, len(states))

    def _loop_matrix(self, in_tree: list[bool]) -> np.ndarray:
        """Bf[l, t]: v_link_l = sum_t Bf[l, t] v_tree_t (tree path from 'from' to 'to')."""
        tree_idx = [k for k in range(len(self.branches)) if in_tree[k]]
        adj: dict[str, list[tuple[str, int, float]]] = {}
        for col, k in enumerate(tree_idx):
            b = self.branches[k]
            adj.setdefault(b.from_, []).append((b.to, col, 1.0))
            adj.setdefault(b.to, []).append((b.from_, col, -1.0))
        link_idx = [k for k in range(len(self.branches)) if not in_tree[k]]
        Bf = np.zeros((len(link_idx), len(tree_idx)))
        for row, k in enumerate(link_idx):
            b = self.branches[k]
            path = _tree_path(adj, b.from_, b.to)
            for col, sign in path:
                Bf[row, col] += sign
        return Bf

    def _formulate(self) -> _Formulation:
        tree = self._normal_tree()
        in_tree = self._in_tree
        nb = len(self.branches)
        tree_idx = [k for k in range(nb) if in_tree[k]]
        link_idx = [k for k in range(nb) if not in_tree[k]]
        Bf = self._loop_matrix(in_tree)
        # W: secondary of branch k in terms of the primaries of all branches.
        W = np.zeros((nb, nb))
        for row, l_ in enumerate(link_idx):
            for col, t in enumerate(tree_idx):
                W[l_, t] = Bf[row, col]          # v_link = Bf v_tree
                W[t, l_] = -Bf[row, col]         # f_tree = -Bf^T f_link
        x, d, p, u = [], [], [], []
        for k, b in enumerate(self.branches):
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
            c = 1.0 / self.branches[k].value   # x' = f / C (A) or v / L (T)
            P[i], R[i], Q[i], S[i] = (c * part for part in split(W[k]))
        H, J, K, L = (np.zeros((npp, n)), np.zeros((npp, npp)), np.zeros((npp, nd)),
                      np.zeros((npp, m)))
        for i, k in enumerate(p):
            val = self.branches[k].value
            c = val if in_tree[k] else 1.0 / val   # tree: v = R f; link: f = v / R
            H[i], K[i], J[i], L[i] = (c * part for part in split(W[k]))
        M, N = np.zeros((nd, n)), np.zeros((nd, m))
        for i, k in enumerate(d):
            wx, wd, wp, wu = split(W[k])
            if np.any(wd) or np.any(wp):
                raise PinlinError(f"graph '{self.name}': dependent element "
                                  f"'{self.branches[k].name}' couples to dissipative or other "
                                  "dependent elements; the matrix method does not apply")
            M[i], N[i] = self.branches[k].value * wx, self.branches[k].value * wu
        try:
            Ij = np.linalg.inv(np.eye(npp) - J)
        except np.linalg.LinAlgError:
            raise GraphError(self.source, "branches", "the dissipative elements form an "
                                                      "algebraic loop with no solution") from None
        Hp, Kp, Lp = Ij @ H, Ij @ K, Ij @ L
        QKR = Q @ Kp + R
        G = np.eye(n) - QKR @ M
        A = np.linalg.solve(G, P + Q @ Hp)
        B = np.linalg.solve(G, S + Q @ Lp)
        E = np.linalg.solve(G, QKR @ N)
        return _Formulation(tree, self, x, d, p, u, W, A, B, E, Hp, Kp, Lp, M, N, {})

    # ----------------------------------------------------------------------------------------
    def _excess_groups(self) -> list[list[str]]:
        """T-type elements directly in parallel and A-type elements directly in series."""
        groups: dict[frozenset, list[str]] = {}
        for b in self.branches:
            if b.type == "T" and not b.nonlinear:
                groups.setdefault(frozenset((b.from_, b.to)), []).append(b.name)
        out = [g for g in groups.values() if len(g) > 1]
        for chain in self._series_a_chains():
            out.append(chain)
        return out

    def _series_a_chains(self) -> list[list[str]]:
        degree: dict[str, list[Branch]] = {}
        for b in self.branches:
            degree.setdefault(b.from_, []).append(b)
            degree.setdefault(b.to, []).append(b)
        chains = []
        for bs in degree.values():
            if len(bs) == 2 and all(b.type == "A" and not b.nonlinear for b in bs):
                chains.append([bs[0].name, bs[1].name])
        return chains

    def _combined(self) -> tuple[Graph, dict[str, list[str]], dict[str, tuple[str, float]]]:
        """A copy with excess storage combined; variable aliases for the members."""
        g = self
        combined: dict[str, list[str]] = {}
        aliases: dict[str, tuple[str, float]] = {}
        changed = True
        while changed:
            changed = False
            for group in g._excess_groups():
                members = [g.branch(n) for n in group]
                new = _merge(g, members, combined, aliases)
                if new is not None:
                    g, changed = new, True
                    break
        return g, combined, aliases


def _merge(g: Graph, members: list[Branch], combined, aliases) -> Graph | None:
    first = members[0]
    inv = sum(1.0 / b.value for b in members)
    value = 1.0 / inv
    name = "+".join(b.name for b in members)
    out = Graph(g.name, g.domain, source=g.source)
    out.outputs = g.outputs
    if first.type == "T":   # parallel: same across, through divides as value_eq / value_i
        start, end = first.from_, first.to
        for b in members:
            sign = 1.0 if (b.from_, b.to) == (start, end) else -1.0
            aliases[f"v:{b.name}"] = (f"v:{name}", sign)
            aliases[f"f:{b.name}"] = (f"f:{name}", sign * value / b.value)
    else:                   # series A: same through, across divides as value_eq / value_i
        b1, b2 = members
        shared = ({b1.from_, b1.to} & {b2.from_, b2.to}).pop()
        start = b1.to if b1.from_ == shared else b1.from_
        end = b2.to if b2.from_ == shared else b2.from_
        for b in members:
            # orientation along the path start -> shared -> end
            forward = (b.from_, b.to) in ((start, shared), (shared, end))
            sign = 1.0 if forward else -1.0
            aliases[f"f:{b.name}"] = (f"f:{name}", sign)
            aliases[f"v:{b.name}"] = (f"v:{name}", sign * value / b.value)
    for key, (target, factor) in list(aliases.items()):
        # members of earlier combinations now inside this one
        for b in members:
            if target in (f"v:{b.name}", f"f:{b.name}") and key not in (f"v:{b.name}",
                                                                        f"f:{b.name}"):
                t2, f2 = aliases[target]
                aliases[key] = (t2, factor * f2)
    combined[name] = [m for b in members for m in combined.pop(b.name, [b.name])]
    member_names = {b.name for b in members}
    placed = False
    for b in g.branches:
        if b.name in member_names:
            if not placed:
                out.branches.append(Branch(name, first.type, start, end, value))
                placed = True
            continue
        out.branches.append(b)
    return out


def output_row(form: _Formulation, var: str) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
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
    in_tree = g._in_tree[k]
    nb = len(g.branches)
    if kind not in ("v", "f"):
        raise GraphError(g.source, "outputs.variables", f"'{var}': expected v: or f:")
    is_primary = (kind == "v") == in_tree
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


def _tree_path(adj, start: str, goal: str) -> list[tuple[int, float]]:
    """Tree branches (column, sign) along the unique tree path from ``start`` to ``goal``."""
    stack = [(start, None, [])]
    seen = {start}
    while stack:
        node, _, path = stack.pop()
        if node == goal:
            return path
        for nxt, col, sign in adj.get(node, []):
            if nxt not in seen:
                seen.add(nxt)
                stack.append((nxt, col, path + [(col, sign)]))
    raise PinlinError(f"no tree path from {start} to {goal}")


class _UnionFind:
    def __init__(self, items) -> None:
        self.parent = {i: i for i in items}

    def find(self, a):
        while self.parent[a] != a:
            self.parent[a] = self.parent[self.parent[a]]
            a = self.parent[a]
        return a

    def union(self, a, b) -> None:
        self.parent[self.find(a)] = self.find(b)

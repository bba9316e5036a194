"""The normal tree of a linear graph (Rowell, steps 1-6) and its loop matrix.

Across sources, then A-type, D-type and T-type elements enter the tree greedily (within a
type the largest admittance first, :func:`_tree_rank`) while they close no loop;
an across source that cannot enter means a loop of across sources, a through source that must
enter means a cut-set of through sources: both are errors. A-type links and T-type tree
branches are dependent energy storage. Primary variables are the across variables of tree
branches and the through variables of links; the loop matrix Bf (v_links = Bf v_tree,
:func:`loop_matrix`) gives the secondary ones.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np

from ..exceptions import PinlinError
from .model import Branch, GraphError

if TYPE_CHECKING:
    from .graph import Graph

_PRIORITY = {"across_source": 0, "A": 1, "D": 2, "T": 3, "through_source": 4}
"""Order in which branch types enter the normal tree (within a type: :func:`_tree_rank`)."""


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
        """The tree, one fact a line (as ``pinlin graph`` prints it)."""
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


def find_normal_tree(graph: Graph) -> tuple[NormalTree, list[bool]]:
    """The normal tree of ``graph`` as it stands (excess storage not combined) and, per
    branch in file order, whether it is a tree branch.

    Raises:
        GraphError: no branches, a graph that is not connected, a loop of across sources or a
            cut-set of through sources.
    """
    if not graph.branches:
        raise GraphError(graph.source, "branches", "the graph has no branches")
    nodes = _check_connected(graph)
    uf = _UnionFind(nodes)
    order = sorted(range(len(graph.branches)), key=lambda k: _tree_rank(graph.branches[k], k))
    in_tree = [False] * len(graph.branches)
    for k in order:
        b = graph.branches[k]
        if uf.find(b.from_) != uf.find(b.to):
            uf.union(b.from_, b.to)
            in_tree[k] = True
        elif b.type == "across_source":
            raise GraphError(graph.source, f"branches.{b.name}", "across-variable sources "
                             f"form a loop: '{b.name}' closes a loop of sources "
                             "(compatibility would be violated)")
    for k, b in enumerate(graph.branches):
        if in_tree[k] and b.type == "through_source":
            raise GraphError(graph.source, f"branches.{b.name}", "through-variable sources "
                             f"form a cut-set: '{b.name}' is needed in the normal tree "
                             "(continuity would be violated)")
    tree = [b.name for k, b in enumerate(graph.branches) if in_tree[k]]
    links = [b.name for k, b in enumerate(graph.branches) if not in_tree[k]]
    states, dependent, primary, secondary = [], [], [], []
    for k, b in enumerate(graph.branches):
        across, through = f"v:{b.name}", f"f:{b.name}"
        primary.append(across if in_tree[k] else through)
        secondary.append(through if in_tree[k] else across)
        if b.type == "A":
            (states if in_tree[k] else dependent).append(across if in_tree[k] else b.name)
        elif b.type == "T":
            (dependent if in_tree[k] else states).append(b.name if in_tree[k] else through)
    return NormalTree(tree, links, states, dependent, primary, secondary, len(states)), in_tree


def _tree_rank(b: Branch, k: int) -> tuple[int, float, int]:
    """Sort key of the greedy tree: type priority, then within a type the largest admittance
    first (file order among equals; nonlinear elements, value None here, after the linear
    ones): the maximum-admittance tree.

    Resistances (D), the smallest first: a link's across variable is the sum of tree across
    variables around its loop. With a large resistance in the tree beside a small one among
    the links, that sum cancels: a 1 ohm resistor in the tree and 1e-17 ohm across the
    inductor it feeds leave v_L = Vs - v_R, both ~Vs, and lose every digit of v_L ~ 1e-17 Vs.
    With the small resistances in the tree no sum cancels.

    Capacitances (A), the largest first, and inductances (T), the smallest first: where storage
    elements form a loop (A) or a cut-set (T), those left out (A links, T tree branches) are
    dependent, and the state equations add their values, relative to the independent ones
    they are tied to, to an identity (I - Q K R M in :mod:`pinlin.graph.solve`). A 1e8 F
    capacitor dependent on a 1e-8 F one adds 1e16 to 1 and rounds away the answer (B and H
    with the wrong sign, measured); the same loop with the 1e8 F one in the tree adds 1e-16.
    """
    if b.type in ("A", "T", "D"):
        if b.value is None:
            return _PRIORITY[b.type], math.inf, k
        value = float(b.value)
        return _PRIORITY[b.type], -value if b.type == "A" else value, k
    return _PRIORITY[b.type], 0.0, k


def loop_matrix(branches: Sequence[Branch], in_tree: list[bool]) -> np.ndarray:
    """Bf[l, t]: v_link_l = sum_t Bf[l, t] v_tree_t (tree path from 'from' to 'to')."""
    tree_idx = [k for k in range(len(branches)) if in_tree[k]]
    adj: dict[str, list[tuple[str, int, float]]] = {}
    for col, k in enumerate(tree_idx):
        b = branches[k]
        adj.setdefault(b.from_, []).append((b.to, col, 1.0))
        adj.setdefault(b.to, []).append((b.from_, col, -1.0))
    link_idx = [k for k in range(len(branches)) if not in_tree[k]]
    Bf = np.zeros((len(link_idx), len(tree_idx)))
    for row, k in enumerate(link_idx):
        b = branches[k]
        path = _tree_path(adj, b.from_, b.to)
        for col, sign in path:
            Bf[row, col] += sign
    return Bf


def _check_connected(graph: Graph) -> list[str]:
    """The nodes in order of first appearance; a GraphError if the graph is not connected."""
    nodes: list[str] = []
    for b in graph.branches:
        for node in (b.from_, b.to):
            if node not in nodes:
                nodes.append(node)
    uf = _UnionFind(nodes)
    for b in graph.branches:
        uf.union(b.from_, b.to)
    groups = {uf.find(n) for n in nodes}
    if len(groups) > 1:
        first = next(n for n in nodes if uf.find(n) != uf.find(nodes[0]))
        raise GraphError(graph.source, "branches", f"the graph is not connected: node "
                                                   f"'{first}' has no path to node "
                                                   f"'{nodes[0]}'")
    return nodes


def _tree_path(adj, start: str, goal: str) -> list[tuple[int, float]]:
    """Tree branches (column, sign) along the unique tree path from ``start`` to ``goal`` (a
    depth-first search that records how it reached each node, then walks back from the goal:
    linear in the tree's size; copying the path at every step made large graphs cubic)."""
    came: dict[str, tuple[str, int, float] | None] = {start: None}
    stack = [start]
    while stack:
        node = stack.pop()
        if node == goal:
            path = []
            while came[node] is not None:
                node, col, sign = came[node]
                path.append((col, sign))
            return path[::-1]
        for nxt, col, sign in adj.get(node, []):
            if nxt not in came:
                came[nxt] = (node, col, sign)
                stack.append(nxt)
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


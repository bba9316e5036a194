"""Excess energy storage (Rowell): T-type elements directly in parallel and A-type elements
directly in series have dependent states. They are combined into one equivalent element
before the normal tree is built (``K1+K2``, value 1 / sum(1 / value_i)), and the variables of
the members are read from the equivalent one through aliases: variable -> (variable of the
equivalent element, factor). With ``combine=False`` the groups are only reported.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from .model import Branch

if TYPE_CHECKING:
    from .graph import Graph

Aliases = dict[str, tuple[str, float]]
"""Variable of a combined member -> (variable of the equivalent element, factor)."""


def combine_excess(graph: Graph, combine: bool = True
                   ) -> tuple[Graph, dict[str, list[str]], Aliases, list[list[str]]]:
    """(graph to formulate, combined elements: equivalent name -> member names, aliases of the
    members' variables, excess groups left as they are).

    ``combine=True``: a copy with excess storage combined (``graph`` itself when it has none),
    no groups left; ``combine=False``: ``graph`` itself and the groups it holds.
    """
    if not combine:
        return graph, {}, {}, excess_groups(graph)
    g = graph
    combined: dict[str, list[str]] = {}
    aliases: Aliases = {}
    while groups := excess_groups(g):   # one at a time: a merge can form a new group
        g = _merge(g, [g.branch(n) for n in groups[0]], combined, aliases)
    return g, combined, aliases, []


def excess_groups(graph: Graph, nonlinear: bool = False) -> list[list[str]]:
    """T-type elements directly in parallel and A-type elements directly in series (linear
    ones only, unless ``nonlinear``), by branch name."""
    groups: dict[frozenset, list[str]] = {}
    for b in graph.branches:
        if b.type == "T" and (nonlinear or not b.nonlinear):
            groups.setdefault(frozenset((b.from_, b.to)), []).append(b.name)
    out = [g for g in groups.values() if len(g) > 1]
    for chain in _series_a_chains(graph, nonlinear):
        out.append(chain)
    return out


def _series_a_chains(graph: Graph, nonlinear: bool = False) -> list[list[str]]:
    """Pairs of A-type elements in series: the two branches at a node of degree 2."""
    degree: dict[str, list[Branch]] = {}
    for b in graph.branches:
        degree.setdefault(b.from_, []).append(b)
        degree.setdefault(b.to, []).append(b)
    chains = []
    for bs in degree.values():
        if len(bs) == 2 and all(b.type == "A" and (nonlinear or not b.nonlinear)
                                for b in bs) and \
                {bs[0].from_, bs[0].to} != {bs[1].from_, bs[1].to}:
            # two A-type elements meeting at a node of degree 2 and sharing only that
            # node are in series; sharing both nodes they are in parallel (not excess)
            chains.append([bs[0].name, bs[1].name])
    return chains


def _merge(g: Graph, members: list[Branch], combined: dict[str, list[str]],
           aliases: Aliases) -> Graph:
    """A copy of ``g`` with ``members`` replaced by their equivalent element (placed where
    the first member was); ``combined`` and ``aliases`` updated in place."""
    from .graph import Graph

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


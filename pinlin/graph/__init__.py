"""``pinlin.graph``: state equations of lumped linear graphs (Rowell), as LinearModels.

Example::

    from pinlin.graph import Graph
    g = Graph.load("validation/graphs/series_rlc.toml")
    print(g.normal_tree().describe())
    model = g.linearize()          # A, B, C, D (E, F when the graph needs them)
"""

from .graph import Graph, NormalTree
from .model import DOMAINS, TYPES, Branch, GraphError
from .nonlinear import NonlinearGraph

__all__ = ["DOMAINS", "TYPES", "Branch", "Graph", "GraphError", "NonlinearGraph", "NormalTree"]

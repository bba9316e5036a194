"""The :class:`Graph` of lumped elements, the checks of its Python arguments, and the route to
its state equations by Rowell's normal tree and matrix method (eqs. 109-128):

1. excess storage (A-type elements directly in series, T-type elements directly in parallel)
   is combined first, or only reported with ``combine=False`` (:mod:`pinlin.graph.excess`);
2. the normal tree (steps 1-6) fixes the states, the dependent storage and the primary
   variables (:mod:`pinlin.graph.tree`);
3. the matrix method gives x' = A x + B u + E u' and any branch variable as
   y = C x + D u + F u' (:mod:`pinlin.graph.matrix`), with solves and checks of every matrix
   that hold in double precision (:mod:`pinlin.graph.solve`);
4. a graph with nonlinear elements (Python API) is linearized about its equilibrium
   f(x0, u0) = 0 by formulating the incremental graph (Rowell section 7,
   :mod:`pinlin.graph.nonlinear`).

The file format, the element types and the value ranges are in :mod:`pinlin.graph.model`.
"""

from __future__ import annotations

import numbers
import os
from collections.abc import Callable, Mapping, Sequence

import numpy as np

from ..exceptions import ArgumentError
from ..linear_model import LinearModel
from .excess import _merge as _merge
from .excess import combine_excess
from .matrix import Formulation, matrix_method, state_space, to_standard_form
from .matrix import output_row as output_row
from .model import (
    DOMAINS,
    MAX_BRANCHES,
    PASSIVE,
    SOURCES,
    TYPES,
    Branch,
    GraphError,
    check_name,
    load_graph_file,
    positive,
    real,
    show,
)
from .nonlinear import linearize_nonlinear
from .solve import _AGREE as _AGREE
from .solve import _REFINE as _REFINE
from .solve import _power2 as _power2
from .solve import check_finite, solve
from .tree import _PRIORITY as _PRIORITY
from .tree import NormalTree, find_normal_tree
from .tree import _tree_path as _tree_path
from .tree import _UnionFind as _UnionFind

# Names of this module before it was split by concept (tree, excess, matrix, solve), kept
# importable from here; the `X as X` imports above re-export the others.
_Formulation, _solve, _check_finite = Formulation, solve, check_finite


class Graph:
    """A linear graph of lumped elements.

    Build with :meth:`load` (TOML) or in Python with :meth:`add_branch`; outputs are branch
    variables ``v:<branch>`` (across) and ``f:<branch>`` (through). Wrong-typed Python
    arguments raise :class:`~pinlin.exceptions.ArgumentError`; bad graph content (values out of
    range, duplicate names, impossible topology) raises :class:`GraphError`.
    """

    def __init__(self, name: str, domain: str = "electrical", *,
                 source: str | os.PathLike[str] | None = None) -> None:
        if not isinstance(name, str) or not name.strip() or not name.isprintable():
            raise ArgumentError("name", f"expected a non-empty string without control "
                                        f"characters, got {show(name)}")
        if not isinstance(domain, str) or domain not in DOMAINS:
            raise ArgumentError("domain", f"expected one of {', '.join(DOMAINS)}, got "
                                          f"{show(domain)}")
        if source is not None and (isinstance(source, bytes)
                                   or not isinstance(source, str | os.PathLike)):
            raise ArgumentError("source", f"expected a file path or None, got {show(source)}")
        self.name = name
        self.domain = domain
        self.source = source
        self.branches: list[Branch] = []
        self.outputs: list[str] = []
        self.guess: dict[str, float] = {}

    # ----------------------------------------------------------------------------------------
    @classmethod
    def load(cls, path: str | os.PathLike[str]) -> Graph:
        """Read a graph TOML file (format in the README and :mod:`pinlin.graph.model`).

        Raises:
            ArgumentError: ``path`` is not a str or path-like object.
            GraphError: the file is missing, unreadable or malformed, or its graph is bad.
        """
        return load_graph_file(path)

    def add_branch(self, name: str, type: str, from_: str, to: str, value: float | None = None,
                   *, relation: Callable[[float], float] | None = None, input: float = 0.0,
                   field: str | None = None) -> Graph:
        """Add a branch; ``relation`` makes a passive element nonlinear (see :class:`Branch`).

        Args:
            name: Branch name (no ``+``: reserved for combined elements).
            type: One of ``across_source``, ``through_source``, ``A``, ``T``, ``D``.
            from_, to: Node names.
            value: Element value in [1e-100, 1e100] [SI unit of the element: F, kg, H, m/N,
                ohm, ...]; None for sources and nonlinear elements.
            relation: Constitutive relation of a nonlinear passive element: a function of one
                float returning a finite float.
            input: Operating value of a source [across or through unit], finite.
            field: Field name used in messages (the file reader passes ``branches[i]``).

        Raises:
            ArgumentError: an argument of the wrong type (a non-string name, a non-callable
                relation, a non-numeric value).
            GraphError: duplicate name, unknown type, value missing or out of range.
        """
        branch = self._make_branch(name, type, from_, to, value, relation, input, field)
        fld = field or f"branches.{name}"
        if len(self.branches) >= MAX_BRANCHES:
            raise GraphError(self.source, "branches", f"more than {MAX_BRANCHES} branches (the "
                                                      "dense matrix method's time grows as the "
                                                      "cube of the branch count)")
        if any(b.name == name for b in self.branches):
            raise GraphError(self.source, f"{fld}.name", f"branch name '{name}' is used twice")
        self.branches.append(branch)
        return self

    def _make_branch(self, name: str, type: str, from_: str, to: str, value: float | None,
                     relation: Callable[[float], float] | None, input: float,
                     field: str | None) -> Branch:
        """A checked :class:`Branch` (see :meth:`add_branch` for the arguments and errors)."""
        if field is not None and not isinstance(field, str):
            raise ArgumentError("field", f"expected a string or None, got {show(field)}")
        for arg, val in (("name", name), ("type", type), ("from_", from_), ("to", to)):
            if not isinstance(val, str):
                raise ArgumentError(arg, f"expected a string, got {_tname(val)} {show(val)}")
        fld = field or f"branches.{name}"
        check_name(self.source, f"{fld}.name", name, branch=True)
        check_name(self.source, f"{fld}.from", from_)
        check_name(self.source, f"{fld}.to", to)
        if type not in TYPES:
            raise GraphError(self.source, f"{fld}.type", f"unknown element type {type!r}; "
                                                         f"expected one of {', '.join(TYPES)}")
        if type == "T" and self.domain == "thermal":
            raise GraphError(self.source, f"{fld}.type", "the thermal domain has no T-type "
                                                         "(inductance-like) element: heat flow "
                                                         "stores no energy (Rowell); use A "
                                                         "(thermal capacitance) and D (thermal "
                                                         "resistance)")
        if from_ == to:
            raise GraphError(self.source, f"{fld}.to", f"branch '{name}' starts and ends at "
                                                       f"node '{to}'")
        if relation is not None and not callable(relation):
            raise ArgumentError("relation", f"expected a function of one float or None, got "
                                            f"{_tname(relation)} {show(relation)}")
        if value is not None and (isinstance(value, bool)
                                  or not isinstance(value, numbers.Real)):
            raise ArgumentError("value", f"expected a number or None, got {_tname(value)} "
                                         f"{show(value)}")
        if isinstance(input, bool) or not isinstance(input, numbers.Real):
            raise ArgumentError("input", f"expected a number, got {_tname(input)} "
                                         f"{show(input)}")
        if type in SOURCES and (value is not None or relation is not None):
            raise GraphError(self.source, f"{fld}.value", "a source takes no value")
        if type in PASSIVE and relation is not None and value is not None:
            raise GraphError(self.source, f"{fld}.relation", "a relation replaces the value "
                                                             "of a passive element: give one "
                                                             "of them")
        if type in PASSIVE and relation is None:
            if value is None:
                raise GraphError(self.source, f"{fld}.value", f"a {type}-type element needs "
                                                              "a value > 0, got None")
            value = positive(self.source, f"{fld}.value", value)
        inp = real(self.source, f"{fld}.input", input)
        if type not in SOURCES and inp != 0:
            raise GraphError(self.source, f"{fld}.input", f"a {type}-type element takes no "
                                                          "input; only sources have an "
                                                          "operating value")
        return Branch(name, type, from_, to, None if value is None else float(value),
                      relation, inp)

    def check(self) -> None:
        """Check the domain and every branch again (for graphs whose ``domain`` or ``branches``
        list was edited directly).

        Raises:
            ArgumentError: an unknown domain; an entry that is not a :class:`Branch`, or holds
                wrong types.
            GraphError: a duplicate name, too many branches, or a bad value.
        """
        if not isinstance(self.domain, str) or self.domain not in DOMAINS:
            raise ArgumentError("domain", f"expected one of {', '.join(DOMAINS)}, got "
                                          f"{show(self.domain)}")
        if not isinstance(self.branches, list):
            raise ArgumentError("branches", f"expected a list of Branch, got {show(self.branches)}")
        if len(self.branches) > MAX_BRANCHES:
            raise GraphError(self.source, "branches", f"{len(self.branches)} branches: expected "
                                                      f"at most {MAX_BRANCHES}")
        seen: set[str] = set()
        for i, b in enumerate(self.branches):
            if not isinstance(b, Branch):
                raise ArgumentError("branches", f"entry {i}: expected a Branch, got "
                                                f"{_tname(b)} {show(b)}")
            self._make_branch(b.name, b.type, b.from_, b.to, b.value, b.relation, b.input, None)
            if b.name in seen:
                raise GraphError(self.source, f"branches.{b.name}.name", f"branch name "
                                                                          f"'{b.name}' is used "
                                                                          "twice")
            seen.add(b.name)

    def branch(self, name: str) -> Branch:
        """The branch called ``name``.

        Raises:
            GraphError: no such branch (field ``outputs.variables``).
        """
        if not isinstance(name, str):
            raise ArgumentError("name", f"expected a branch name (str), got {show(name)}")
        for b in self.branches:
            if b.name == name:
                return b
        raise GraphError(self.source, "outputs.variables", f"no branch named '{name}'")

    def check_outputs(self) -> None:
        """Check :attr:`outputs`: a list of distinct ``v:<branch>`` / ``f:<branch>`` names."""
        _output_names(self, self.outputs, None)

    @property
    def inputs(self) -> list[str]:
        """Input names: the source branches, in file order."""
        return [b.name for b in self.branches if b.is_source]

    # ----------------------------------------------------------------------------------------
    def normal_tree(self, combine: bool = True) -> NormalTree:
        """The normal tree of the graph (after combining excess storage unless told not to)."""
        _flag("combine", combine)
        self.check()
        graph, combined, _, excess = combine_excess(self, combine)
        tree = find_normal_tree(graph)[0]
        tree.combined, tree.excess = combined, excess
        return tree

    def formulate(self, combine: bool = True) -> Formulation:
        """State-equation matrices by the matrix method (linear elements only)."""
        _flag("combine", combine)
        self.check()
        for b in self.branches:
            if b.nonlinear:
                raise GraphError(self.source, f"branches.{b.name}", "nonlinear element: use "
                                                                     "Graph.linearize()")
        graph, combined, aliases, excess = combine_excess(self, combine)
        form = matrix_method(graph)
        form.tree.combined, form.tree.excess, form.aliases = combined, excess, aliases
        return form

    def linearize(self, *, outputs: Sequence[str] | None = None, combine: bool = True,
                  standard_form: bool = False, u0: Mapping[str, float] | None = None,
                  x0: Sequence[float] | None = None) -> LinearModel:
        """The state-space model: x' = A x + B u + E u', y = C x + D u + F u'.

        Args:
            outputs: Branch variables to output (default: the graph's ``outputs``, else the
                states): a list of distinct ``v:<branch>`` / ``f:<branch>`` strings.
            combine: Combine excess storage (A in series, T in parallel) before the tree.
            standard_form: Remove E with x' = x - E u (eqs. 90-93).
            u0: Operating inputs by source name [across or through unit] (nonlinear graphs
                only; default: each source's ``input``).
            x0: Starting guess for the equilibrium state, one finite number per state in
                normal-tree order [state units] (nonlinear graphs only; default: the graph's
                ``operating_point.guess``, zeros elsewhere).

        Raises:
            ArgumentError: an argument of the wrong type or size, or ``u0`` / ``x0`` given for
                a linear graph (they would be ignored).
            GraphError: the graph cannot be formulated, the matrices would not be finite, or
                a nonlinear graph has no equilibrium that pinlin can find and linearize.
        """
        _flag("combine", combine)
        _flag("standard_form", standard_form)
        self.check()
        if outputs is not None:
            if isinstance(outputs, str) or not isinstance(outputs, Sequence):
                raise ArgumentError("outputs", "expected a list of branch variables like "
                                               f"[\"v:C\", \"f:L\"] or None, got {show(outputs)}")
            outputs = list(outputs)
            _output_names(self, outputs, "outputs")
        self.check_outputs()
        if not self.branches:
            raise GraphError(self.source, "branches", "the graph has no branches")
        if any(b.nonlinear for b in self.branches):
            model = linearize_nonlinear(self, outputs=outputs, combine=combine, u0=u0, x0=x0)
        else:
            for arg, val in (("u0", u0), ("x0", x0)):
                if val is not None:
                    raise ArgumentError(arg, "applies only to graphs with nonlinear elements; "
                                             "a linear graph's model does not depend on it")
            model = state_space(self, self.formulate(combine), outputs)
        return to_standard_form(self, model) if standard_form else model


# ---------------------------------------------------------------------------------------------
# Argument checks


def _tname(value: object) -> str:
    """The type name of ``value``, for messages."""
    return type(value).__name__


def _flag(argument: str, value: object) -> None:
    """``value`` must be a bool (``combine="yes"`` is refused, not read as true)."""
    if not isinstance(value, bool | np.bool_):
        raise ArgumentError(argument, f"expected True or False, got {_tname(value)} "
                                      f"{show(value)}")


def _output_names(graph: Graph, names: object, argument: str | None) -> None:
    """Check output variable names; ``argument`` None: the graph's ``outputs`` (GraphError),
    else a Python argument (ArgumentError)."""

    def fail(reason: str) -> None:
        if argument is None:
            raise GraphError(graph.source, "outputs.variables", reason)
        raise ArgumentError(argument, reason)

    if isinstance(names, str) or not isinstance(names, list | tuple):
        fail(f"expected a list like [\"v:L1\", \"f:C1\"], got {show(names)}")
    seen: set[str] = set()
    for var in names:
        if not isinstance(var, str):
            fail(f"expected a branch variable string like \"v:C\", got {show(var)}")
        kind, _, name = var.partition(":")
        if kind not in ("v", "f") or not name:
            fail(f"'{var}': expected 'v:<branch>' or 'f:<branch>'")
        if not any(b.name == name for b in graph.branches):
            fail(f"no branch named '{name}'")
        if var in seen:
            fail(f"'{var}' is listed twice")
        seen.add(var)

"""Linear graphs of lumped elements (Rowell): branches, the graph file, and its checks.

Sign convention: the across variable of a branch is v = value(from) - value(to); its through
variable flows from -> to, so that v f is the power into the element. Element types:

- ``across_source`` / ``through_source``: ideal sources, the inputs (named by branch name);
- ``A``: capacitance-like, f = value dv/dt (C, mass m, fluid C, thermal C);
- ``T``: inductance-like, v = value df/dt (L, 1/K, fluid inertance I);
- ``D``: resistance-like, v = value f (R, 1/B, fluid R, thermal R).

A mass (or any A-type element of the mechanical and thermal domains) is connected to the
reference node, as in Rowell's graphs.
"""

from __future__ import annotations

import math
import tomllib
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from ..exceptions import PinlinError, SceneError

SOURCES = ("across_source", "through_source")
PASSIVE = ("A", "T", "D")
TYPES = SOURCES + PASSIVE
DOMAINS = ("electrical", "translational", "rotational", "fluid", "thermal")
_BRANCH_KEYS = ("name", "type", "from", "to", "value", "input", "relation")
RELATION_KINDS = ("power", "polynomial", "arcsin")


class GraphError(SceneError):
    """A linear graph is malformed or violates compatibility/continuity (message names the file
    and the branch)."""


@dataclass(frozen=True)
class Branch:
    """One element of a linear graph.

    Attributes:
        name: Branch name (variables are ``v:<name>`` and ``f:<name>``).
        type: One of :data:`TYPES`.
        from_, to: Node names; v = value(from) - value(to), f flows from -> to.
        value: Element value (A: capacitance-like, T: inductance-like, D: resistance-like),
            > 0; None for sources and nonlinear elements.
        relation: Nonlinear constitutive relation (Python API), or None for a linear element:
            D: f = relation(v); A: q = relation(v) with f = dq/dt; T: lam = relation(f) with
            v = dlam/dt.
        input: Operating value of a source for nonlinear equilibria [across or through unit].
    """

    name: str
    type: str
    from_: str
    to: str
    value: float | None = None
    relation: Callable[[float], float] | None = None
    input: float = 0.0

    @property
    def is_source(self) -> bool:
        return self.type in SOURCES

    @property
    def nonlinear(self) -> bool:
        return self.relation is not None


def parse_graph(data: Mapping[str, Any], source: Path | None):
    """Graph from the TOML's dict form; every field checked."""
    from .graph import Graph

    if not isinstance(data, Mapping):
        raise GraphError(source, None, "expected a table")
    for key in data:
        if key not in ("name", "domain", "branches", "outputs", "operating_point"):
            raise GraphError(source, key, "unknown key; expected one of name, domain, "
                                          "branches, outputs, operating_point")
    name = data.get("name", source.stem if source else "graph")
    if not isinstance(name, str) or not name:
        raise GraphError(source, "name", f"expected a non-empty string, got {name!r}")
    domain = data.get("domain", "electrical")
    if domain not in DOMAINS:
        raise GraphError(source, "domain", f"expected one of {', '.join(DOMAINS)}, got "
                                           f"{domain!r}")
    raw = data.get("branches")
    if not isinstance(raw, list) or not raw:
        raise GraphError(source, "branches", "expected a non-empty array of tables "
                                             "([[branches]])")
    graph = Graph(name, domain, source=source)
    for i, entry in enumerate(raw):
        fld = f"branches[{i}]"
        if not isinstance(entry, Mapping):
            raise GraphError(source, fld, "expected a table")
        for key in entry:
            if key not in _BRANCH_KEYS:
                raise GraphError(source, f"{fld}.{key}", "unknown key; expected one of "
                                                         f"{', '.join(_BRANCH_KEYS)}")
        for key in ("name", "type", "from", "to"):
            if not isinstance(entry.get(key), str) or not entry[key]:
                raise GraphError(source, f"{fld}.{key}", "missing; expected a non-empty string")
        if entry["type"] not in TYPES:
            raise GraphError(source, f"{fld}.type", f"unknown element type "
                                                    f"{entry['type']!r}; expected one of "
                                                    f"{', '.join(TYPES)}")
        value = entry.get("value")
        relation = None
        if "relation" in entry:
            if entry["type"] not in PASSIVE or value is not None:
                raise GraphError(source, f"{fld}.relation", "a relation replaces the value of "
                                                            "a passive (A, T, D) element")
            relation = _relation(source, f"{fld}.relation", entry["relation"])
        elif entry["type"] in PASSIVE:
            if value is None:
                raise GraphError(source, f"{fld}.value", f"missing: a {entry['type']}-type "
                                                         "element needs a value > 0")
            value = _positive(source, f"{fld}.value", value)
        elif value is not None:
            raise GraphError(source, f"{fld}.value", "a source takes no value (its variable "
                                                     "is an input); use 'input' for an "
                                                     "operating value")
        inp = entry.get("input", 0.0)
        if isinstance(inp, bool) or not isinstance(inp, int | float) or not math.isfinite(inp):
            raise GraphError(source, f"{fld}.input", f"expected a finite number, got {inp!r}")
        graph.add_branch(entry["name"], entry["type"], entry["from"], entry["to"], value,
                         relation=relation, input=float(inp), field=fld)
    outputs = data.get("outputs", {})
    if not isinstance(outputs, Mapping) or set(outputs) - {"variables"}:
        raise GraphError(source, "outputs", "expected a table with 'variables'")
    variables = outputs.get("variables", [])
    if not isinstance(variables, list) or not all(isinstance(v, str) for v in variables):
        raise GraphError(source, "outputs.variables", "expected a list like [\"v:L1\", \"f:C1\"]")
    graph.outputs = list(variables)
    graph.check_outputs()
    op = data.get("operating_point", {})
    if not isinstance(op, Mapping) or set(op) - {"guess"}:
        raise GraphError(source, "operating_point", "expected a table with 'guess' (starting "
                                                    "values of the state variables)")
    guess = op.get("guess", {})
    if not isinstance(guess, Mapping):
        raise GraphError(source, "operating_point.guess", "expected a table like "
                                                          "{ \"v:C\" = 1.0 }")
    for key, value in guess.items():
        if isinstance(value, bool) or not isinstance(value, int | float) or \
                not math.isfinite(value):
            raise GraphError(source, f"operating_point.guess.{key}", "expected a finite number")
    graph.guess = {str(k): float(v) for k, v in guess.items()}
    return graph


def _relation(source, fld: str, spec: Any) -> Callable[[float], float]:
    """A nonlinear relation from its table: ``power`` y = coefficient |x|^exponent sgn(x),
    ``polynomial`` y = sum_i c_i x^(i+1), ``arcsin`` y = asin(x / scale)."""
    if not isinstance(spec, Mapping) or spec.get("kind") not in RELATION_KINDS:
        raise GraphError(source, f"{fld}.kind", f"expected one of {', '.join(RELATION_KINDS)}")
    kind = spec["kind"]
    if kind == "power":
        c = _positive(source, f"{fld}.coefficient", spec.get("coefficient"))
        n = _positive(source, f"{fld}.exponent", spec.get("exponent"))
        return lambda x: c * abs(x) ** n * math.copysign(1.0, x)
    if kind == "polynomial":
        coeffs = spec.get("coefficients")
        if not isinstance(coeffs, list) or not coeffs or not all(
                isinstance(c, int | float) and not isinstance(c, bool) for c in coeffs):
            raise GraphError(source, f"{fld}.coefficients", "expected a list of numbers")
        return lambda x: sum(c * x ** (i + 1) for i, c in enumerate(coeffs))
    scale = _positive(source, f"{fld}.scale", spec.get("scale"))
    return lambda x: math.asin(x / scale)


def _positive(source, fld: str, value: Any) -> float:
    if isinstance(value, bool) or not isinstance(value, int | float):
        raise GraphError(source, fld, f"expected a number > 0, got {value!r}")
    value = float(value)
    if not math.isfinite(value) or value <= 0:
        raise GraphError(source, fld, f"expected a finite number > 0, got {value!r}")
    return value


def load_graph_file(path: str | Path):
    path = Path(path)
    if not path.is_file():
        raise GraphError(path, None, "graph file not found")
    try:
        data = tomllib.loads(path.read_text(encoding="utf-8"))
    except (tomllib.TOMLDecodeError, UnicodeDecodeError) as exc:
        raise GraphError(path, None, f"malformed TOML: {exc}") from None
    return parse_graph(data, path)


__all__ = ["Branch", "DOMAINS", "GraphError", "PASSIVE", "PinlinError", "SOURCES", "TYPES",
           "load_graph_file", "parse_graph"]

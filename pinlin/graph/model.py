"""Linear graphs of lumped elements (Rowell): branches, the graph file, and its checks.

Sign convention: the across variable of a branch is v = value(from) - value(to); its through
variable flows from -> to, so that v f is the power into the element. Element types:

- ``across_source`` / ``through_source``: ideal sources, the inputs (named by branch name);
- ``A``: capacitance-like, f = value dv/dt (C [F], mass m [kg], fluid C [m^3/Pa], thermal C
  [J/K]);
- ``T``: inductance-like, v = value df/dt (L [H], 1/K [m/N], fluid inertance I [Pa s^2/m^3]);
- ``D``: resistance-like, v = value f (R [ohm], 1/B [m/(N s)], fluid R [Pa s/m^3], thermal R
  [K/W]).

A mass (or any A-type element of the mechanical and thermal domains) is connected to the
reference node, as in Rowell's graphs.

What a graph may hold (every violation is a :class:`GraphError` that names the file, the field
or branch, and what was expected):

- Element values and the parameters of nonlinear relations (``coefficient``, ``exponent``,
  ``scale``, the nonzero polynomial ``coefficients``) lie in [:data:`VALUE_MIN`,
  :data:`VALUE_MAX`] = [1e-100, 1e100] in magnitude (SI units). The rule is derived from the
  matrix method: every entry of A, B and E is built from products and quotients of at most
  three element values (1/(R C), R/L, C1/(C1 + C2), ...), so with values inside 1e-100..1e100
  no entry can overflow (|x| > 1.8e308) nor underflow into the subnormal range (|x| < 2.2e-308,
  where a double keeps fewer than 16 significant digits) or to zero (a false pole at the
  origin). The range bounds the spread of the values to 200 decades, far more than any physical
  network needs (1 fF to 1e10 Pa s^2/m^3 is 25). Subnormal values such as 1e-320 fall outside
  it. Output rows (C, D, F) can multiply in one value more, so every computed matrix is checked
  again before a model is returned (all entries finite, none subnormal); a failure names the
  branch of the offending row. Incremental values of nonlinear elements obey the same range.
  The two linear solves of the matrix method (dissipative loop, dependent storage) are
  equilibrated and checked after the fact (``pinlin.graph.solve.solve``): values that leave
  fewer than five significant digits are refused, naming the branches involved.
- Operating inputs and ``[operating_point] guess`` values are finite numbers within
  [-1e100, 1e100]. Integers too large for a double (TOML allows any number of digits) are
  refused, never rounded to infinity.
- Names are non-empty strings without control characters; branch names may not contain ``+``
  (reserved for the combined elements, e.g. ``K1+K2``).
- A graph file is UTF-8 TOML (a leading byte-order mark is accepted) of at most
  :data:`MAX_FILE_BYTES`, nested at most a few hundred levels, with at most
  :data:`MAX_BRANCHES` branches (the matrix method is dense: time grows as the cube of the
  branch count), at most :data:`pinlin.graph.nonlinear.MAX_NONLINEAR` of them nonlinear.
"""

from __future__ import annotations

import math
import numbers
import os
import re
import stat
import sys
import tomllib
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from ..exceptions import ArgumentError, PinlinError, SceneError

SOURCES = ("across_source", "through_source")
PASSIVE = ("A", "T", "D")
TYPES = SOURCES + PASSIVE
DOMAINS = ("electrical", "translational", "rotational", "fluid", "thermal")
_BRANCH_KEYS = ("name", "type", "from", "to", "value", "input", "relation")
RELATION_KINDS = ("power", "polynomial", "arcsin")
_RELATION_KEYS = {"power": ("kind", "coefficient", "exponent"),
                  "polynomial": ("kind", "coefficients"),
                  "arcsin": ("kind", "scale")}

VALUE_MIN = 1e-100
"""Smallest element value or relation parameter accepted [SI unit of the element]."""
VALUE_MAX = 1e100
"""Largest element value, relation parameter, input or guess magnitude accepted [SI unit]."""
RANGE = "[1e-100, 1e100]"
"""The accepted range of element values, as printed in messages."""
MAX_FILE_BYTES = 16 * 2**20
"""Largest graph file read [bytes]."""
MAX_BRANCHES = 5000
"""Most branches in one graph (the dense matrix method's time grows as the cube of the branch
count: an LC ladder of 2001 branches took 23 s, so this many takes some 6 minutes)."""


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
            in [:data:`VALUE_MIN`, :data:`VALUE_MAX`] [SI unit of the element]; None for
            sources and nonlinear elements.
        relation: Nonlinear constitutive relation (Python API), or None for a linear element:
            D: f = relation(v); A: q = relation(v) with f = dq/dt; T: lam = relation(f) with
            v = dlam/dt. It takes and returns a real number (a float).
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


# ---------------------------------------------------------------------------------------------
# Checks shared by the file reader and the Python API


def show(value: Any, limit: int = 60) -> str:
    """A short ``repr`` for messages (long or deeply nested values cut, never an error)."""
    try:
        text = repr(value)
    except Exception:  # a hostile __repr__ or a deeply nested value must not hide the error
        text = f"<{type(value).__name__}>"
    return clip(text, limit)


def _digits(value: int) -> int:
    """Decimal digits of a (huge) integer without converting it to a string."""
    return int(abs(value).bit_length() * math.log10(2)) + 1


def clip(text: str, limit: int = 120) -> str:
    """``text`` on one line, cut to ``limit`` characters."""
    text = " ".join(str(text).split())
    return text if len(text) <= limit else text[:limit - 3] + "..."


def real(source: str | Path | None, fld: str, value: Any, what: str = "a finite number",
         *, bounded: bool = True) -> float:
    """``value`` as a finite float (within [-VALUE_MAX, VALUE_MAX] if ``bounded``), else a
    GraphError.

    Booleans, strings, arrays and integers beyond the double range are refused (never rounded).
    """
    if isinstance(value, bool) or not isinstance(value, numbers.Real):
        raise GraphError(source, fld, f"expected {what}, got {show(value)}")
    try:
        x = float(value)
    except (OverflowError, ValueError, TypeError):
        digits = f"an integer of {_digits(value)} digits" if isinstance(value, int) else \
            show(value)
        raise GraphError(source, fld, f"expected {what}, got {digits}, beyond the "
                                      "double-precision range (about 1.8e308)") from None
    if not math.isfinite(x):
        raise GraphError(source, fld, f"expected {what}, got {x!r}")
    if bounded and abs(x) > VALUE_MAX:
        raise GraphError(source, fld, f"expected {what} within [-1e100, 1e100], got {x!r}")
    return x


def positive(source: str | Path | None, fld: str, value: Any) -> float:
    """An element value or relation parameter: a number in [VALUE_MIN, VALUE_MAX]."""
    what = f"a finite number > 0 within {RANGE}"
    if value is None:
        raise GraphError(source, fld, f"missing; expected {what}")
    x = real(source, fld, value, what, bounded=False)
    if x <= 0 or x > VALUE_MAX:
        raise GraphError(source, fld, f"expected {what}, got {x!r}")
    if x < VALUE_MIN:
        kind = (" (a subnormal number, fewer than 16 significant digits)"
                if x < sys.float_info.min else "")
        raise GraphError(source, fld, f"expected {what}, got {x!r}{kind}: products of such "
                                      "values under- or overflow double precision")
    return x


def check_name(source: str | Path | None, fld: str, value: Any, *, branch: bool = False
               ) -> str:
    """A non-empty name (branch names without ``+``)."""
    if not isinstance(value, str) or not value.strip():
        raise GraphError(source, fld, f"expected a non-empty string, got {show(value)}")
    if not value.isprintable():
        raise GraphError(source, fld, f"expected a name without control characters (line "
                                      f"breaks, tabs), got {show(value)}")
    if branch and "+" in value:
        raise GraphError(source, fld, f"branch name {show(value)} contains '+', which is "
                                      "reserved for combined elements (e.g. 'K1+K2')")
    return value


# ---------------------------------------------------------------------------------------------
# The graph file


def parse_graph(data: Mapping[str, Any], source: Path | None):
    """Graph from the TOML's dict form; every field checked."""
    from .graph import Graph

    if not isinstance(data, Mapping):
        raise GraphError(source, None, "expected a table")
    for key in data:
        if key not in ("name", "domain", "branches", "outputs", "operating_point"):
            raise GraphError(source, key, "unknown key; expected one of name, domain, "
                                          "branches, outputs, operating_point")
    name = check_name(source, "name", data.get("name", source.stem if source else "graph"))
    domain = data.get("domain", "electrical")
    if not isinstance(domain, str) or domain not in DOMAINS:
        raise GraphError(source, "domain", f"expected one of {', '.join(DOMAINS)}, got "
                                           f"{show(domain)}")
    raw = data.get("branches")
    if not isinstance(raw, list) or not raw:
        raise GraphError(source, "branches", "expected a non-empty array of tables "
                                             "([[branches]])")
    if len(raw) > MAX_BRANCHES:
        raise GraphError(source, "branches", f"{len(raw)} branches: expected at most "
                                             f"{MAX_BRANCHES} (the dense matrix method's time "
                                             "grows as the cube of the branch count)")
    graph = Graph(name, domain, source=source)
    for i, entry in enumerate(raw):
        _parse_branch(graph, source, f"branches[{i}]", entry)
    outputs = data.get("outputs", {})
    if not isinstance(outputs, Mapping) or set(outputs) - {"variables"}:
        raise GraphError(source, "outputs", "expected a table with 'variables'")
    if "variables" in outputs:
        variables = outputs["variables"]
        if not isinstance(variables, list) or not variables or \
                not all(isinstance(v, str) for v in variables):
            raise GraphError(source, "outputs.variables", "expected a non-empty list like "
                                                          "[\"v:L1\", \"f:C1\"] (leave out "
                                                          "[outputs] to output the states), "
                                                          f"got {show(variables)}")
        graph.outputs = list(variables)
    graph.check_outputs()
    op = data.get("operating_point", {})
    if not isinstance(op, Mapping) or set(op) - {"guess"}:
        raise GraphError(source, "operating_point", "expected a table with 'guess' (starting "
                                                    "values of the state variables)")
    if op and not any(b.nonlinear for b in graph.branches):
        raise GraphError(source, "operating_point", "applies only to graphs with nonlinear "
                                                    "elements (a 'relation'); a linear graph "
                                                    "has no operating point to solve for")
    guess = op.get("guess", {})
    if not isinstance(guess, Mapping):
        raise GraphError(source, "operating_point.guess", "expected a table like "
                                                          "{ \"v:C\" = 1.0 }")
    graph.guess = {str(k): real(source, f"operating_point.guess.{k}", v)
                   for k, v in guess.items()}
    return graph


def _parse_branch(graph, source: Path | None, fld: str, entry: Any) -> None:
    if not isinstance(entry, Mapping):
        raise GraphError(source, fld, f"expected a table, got {show(entry)}")
    for key in entry:
        if key not in _BRANCH_KEYS:
            raise GraphError(source, f"{fld}.{key}", "unknown key; expected one of "
                                                     f"{', '.join(_BRANCH_KEYS)}")
    for key in ("name", "type", "from", "to"):
        if key not in entry:
            raise GraphError(source, f"{fld}.{key}", "missing; expected a non-empty string")
        check_name(source, f"{fld}.{key}", entry[key], branch=key == "name")
    kind = entry["type"]
    if kind not in TYPES:
        raise GraphError(source, f"{fld}.type", f"unknown element type {show(kind)}; expected "
                                                f"one of {', '.join(TYPES)}")
    value = entry.get("value")
    relation = None
    if "relation" in entry:
        if kind not in PASSIVE or value is not None:
            raise GraphError(source, f"{fld}.relation", "a relation replaces the value of a "
                                                        "passive (A, T, D) element")
        relation = _relation(source, f"{fld}.relation", entry["relation"])
    elif kind in PASSIVE:
        if value is None:
            raise GraphError(source, f"{fld}.value", f"missing: a {kind}-type element needs "
                                                     "a value > 0")
        value = positive(source, f"{fld}.value", value)
    elif value is not None:
        raise GraphError(source, f"{fld}.value", "a source takes no value (its variable is an "
                                                 "input); use 'input' for an operating value")
    if "input" in entry and kind not in SOURCES:
        raise GraphError(source, f"{fld}.input", f"a {kind}-type element takes no input; only "
                                                 "sources have an operating value")
    inp = real(source, f"{fld}.input", entry.get("input", 0.0))
    graph.add_branch(entry["name"], kind, entry["from"], entry["to"], value,
                     relation=relation, input=inp, field=fld)


def _relation(source: Path | None, fld: str, spec: Any) -> Callable[[float], float]:
    """A nonlinear relation from its table: ``power`` y = coefficient |x|^exponent sgn(x),
    ``polynomial`` y = sum_i c_i x^(i+1), ``arcsin`` y = asin(x / scale) (defined for
    |x| <= scale; evaluating it outside raises ValueError, reported with the branch)."""
    if not isinstance(spec, Mapping):
        raise GraphError(source, fld, "expected a table like { kind = \"power\", coefficient "
                                      f"= 0.4, exponent = 2.0 }}, got {show(spec)}")
    kind = spec.get("kind")
    if not isinstance(kind, str) or kind not in RELATION_KINDS:
        raise GraphError(source, f"{fld}.kind", f"expected one of {', '.join(RELATION_KINDS)}, "
                                                f"got {show(kind)}")
    for key in spec:
        if key not in _RELATION_KEYS[kind]:
            raise GraphError(source, f"{fld}.{key}", f"unknown key for a {kind} relation; "
                                                     "expected "
                                                     f"{', '.join(_RELATION_KEYS[kind])}")
    if kind == "power":
        c = positive(source, f"{fld}.coefficient", spec.get("coefficient"))
        n = positive(source, f"{fld}.exponent", spec.get("exponent"))

        def power(x: float) -> float:
            return c * abs(x) ** n * math.copysign(1.0, x)

        return power
    if kind == "polynomial":
        raw = spec.get("coefficients")
        if not isinstance(raw, list) or not raw:
            raise GraphError(source, f"{fld}.coefficients", "expected a non-empty list of "
                                                            f"numbers, got {show(raw)}")
        coeffs = []
        for i, c in enumerate(raw):
            c = real(source, f"{fld}.coefficients[{i}]", c)
            if c != 0 and abs(c) < VALUE_MIN:
                raise GraphError(source, f"{fld}.coefficients[{i}]", "expected 0 or a "
                                 f"magnitude within {RANGE}, got {c!r}")
            coeffs.append(c)
        if not any(coeffs):
            raise GraphError(source, f"{fld}.coefficients", "all coefficients are zero: the "
                                                            "element would carry nothing")

        def polynomial(x: float) -> float:
            y = 0.0
            for c in reversed(coeffs):   # Horner: sum_i c_i x^(i+1)
                y = (y + c) * x
            return y

        return polynomial
    scale = positive(source, f"{fld}.scale", spec.get("scale"))

    def arcsin(x: float) -> float:
        if not abs(x) <= scale:
            raise ValueError(f"arcsin relation evaluated at {x:.6g}, outside its domain "
                             f"|x| <= scale = {scale:g}")
        return math.asin(x / scale)

    return arcsin


def _read_text(path: Path) -> str:
    """The file's text, every failure a GraphError naming it."""
    try:
        info = path.stat()
    except FileNotFoundError:
        raise GraphError(path, None, "graph file not found") from None
    except (OSError, ValueError) as exc:
        raise GraphError(path, None, f"cannot read the graph file: "
                                     f"{getattr(exc, 'strerror', None) or exc}") from None
    if stat.S_ISDIR(info.st_mode):
        raise GraphError(path, None, "is a folder; expected a graph .toml file")
    if not stat.S_ISREG(info.st_mode):
        raise GraphError(path, None, "is not a regular file; expected a graph .toml file")
    if info.st_size > MAX_FILE_BYTES:
        raise GraphError(path, None, f"graph file of {info.st_size} bytes; expected at most "
                                     f"{MAX_FILE_BYTES} bytes")
    try:
        raw = path.read_bytes()
    except OSError as exc:
        raise GraphError(path, None, f"cannot read the graph file: {exc.strerror or exc}"
                         ) from None
    try:
        return raw.decode("utf-8-sig")
    except UnicodeDecodeError as exc:
        line = raw[:exc.start].count(b"\n") + 1
        raise GraphError(path, None, f"not UTF-8 text: byte 0x{raw[exc.start]:02x} at line "
                                     f"{line} (offset {exc.start}); save the file as UTF-8"
                         ) from None


def load_graph_file(path: str | os.PathLike[str]):
    """Read and check a graph TOML file (format in the README and this module's docstring).

    Raises:
        ArgumentError: ``path`` is not a str or path-like object.
        GraphError: the file is missing, unreadable, not UTF-8 TOML, or holds a bad graph.
    """
    if isinstance(path, bytes) or not isinstance(path, str | os.PathLike):
        raise ArgumentError("path", f"expected a file path (str or pathlib.Path), got "
                                    f"{type(path).__name__} {show(path)}")
    if isinstance(path, str) and not path.strip():
        raise ArgumentError("path", "empty file name; expected a graph .toml file")
    try:
        path = Path(path)
    except TypeError:  # an os.PathLike whose __fspath__ gives bytes
        raise ArgumentError("path", "expected a file path whose os.fspath() is a str, got "
                                    f"{type(path).__name__}") from None
    text = _read_text(path)
    if not text.strip():
        raise GraphError(path, None, "the graph file is empty; expected [[branches]] tables")
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise GraphError(path, None, f"malformed TOML: {exc}") from None
    except RecursionError:
        raise GraphError(path, None, "malformed TOML: arrays or tables nested too deeply "
                                     "(a graph file needs at most three levels)") from None
    except ValueError as exc:   # e.g. an integer beyond Python's digit limit
        long = re.search(r"[0-9_]{4000,}", text)
        if long:
            line = text.count("\n", 0, long.start()) + 1
            digits = long.end() - long.start()
            raise GraphError(path, None, f"malformed TOML: a number of {digits} digits at line "
                                         f"{line}; expected a number within [-1e100, 1e100]"
                             ) from None
        raise GraphError(path, None, f"malformed TOML: {clip(str(exc), 160)}") from None
    return parse_graph(data, path)


__all__ = ["Branch", "DOMAINS", "GraphError", "MAX_BRANCHES", "MAX_FILE_BYTES", "PASSIVE",
           "PinlinError", "RANGE", "SOURCES", "TYPES", "VALUE_MAX", "VALUE_MIN", "check_name",
           "clip", "load_graph_file", "parse_graph", "positive", "real", "show"]

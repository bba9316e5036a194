"""Hostile input to pinlin.graph: every bad graph file or argument gives a PinlinError whose
one-line message names the file and the field or branch, and ``pinlin graph`` exits 2 with one
``pinlin: error:`` line and no traceback. No model with a non-finite matrix is ever returned.
"""

from __future__ import annotations

import math
import os
import random
from fractions import Fraction
from pathlib import Path

import numpy as np
import pytest

from pinlin.cli import main
from pinlin.exceptions import ArgumentError, PinlinError
from pinlin.graph import Branch, Graph, GraphError


def branch(name: str, type_: str, from_: str, to: str, **fields: str) -> str:
    """One [[branches]] table; ``fields`` are TOML value literals (e.g. value="1e-320")."""
    extra = "".join(f"{k} = {v}\n" for k, v in fields.items())
    return (f"[[branches]]\nname = '{name}'\ntype = '{type_}'\nfrom = '{from_}'\n"
            f"to = '{to}'\n{extra}")


def rc(r: str = "1.0", c: str = "1.0") -> str:
    """Voltage source, resistor R [ohm], capacitor C [F] (literals)."""
    return (branch("Vs", "across_source", "a", "g") + branch("R", "D", "a", "b", value=r)
            + branch("C", "A", "b", "g", value=c))


def tank(relation: str, flow: str = "1.0", extra: str = "") -> str:
    """Flow source into a linear capacitance C, drained by a nonlinear D-type element R."""
    return (branch("Qs", "through_source", "g", "1", input=flow)
            + branch("C", "A", "1", "g", value="1.0")
            + branch("R", "D", "1", "g", relation=relation) + extra)


PENDULUM = (branch("Ts", "through_source", "g", "1", input="{torque}")
            + branch("J", "A", "1", "g", value="0.05")
            + branch("K", "T", "1", "g", relation="{{ kind = 'arcsin', scale = 0.981 }}")
            + branch("B", "D", "1", "g", value="50.0"))


def write(tmp_path: Path, name: str, text: str) -> Path:
    path = tmp_path / f"{name}.toml"
    path.write_text(text, encoding="utf-8")
    return path


def assert_cli(path: Path, capfd, *fragments: str) -> None:
    """``pinlin graph PATH`` exits 2 with one stderr line naming the file and the fragments."""
    capfd.readouterr()
    assert main(["graph", str(path)]) == 2
    err = capfd.readouterr().err
    assert err.count("\n") == 1 and err.startswith("pinlin: error: "), err
    assert "Traceback" not in err and path.name in err, err
    for fragment in fragments:
        assert fragment in err, (fragment, err)


def assert_bad_file(tmp_path: Path, capfd, name: str, text: str, *fragments: str,
                    error: type[PinlinError] = GraphError) -> PinlinError:
    """Graph.load(...).linearize() raises ``error`` naming the file and ``fragments``; the CLI
    reports the same in one line."""
    path = write(tmp_path, name, text)
    with pytest.raises(error) as info:
        Graph.load(path).linearize()
    message = str(info.value)
    assert str(path) in message and "\n" not in message, message
    for fragment in fragments:
        assert fragment in message, (fragment, message)
    assert_cli(path, capfd, *fragments)
    return info.value


def assert_finite(model) -> None:
    for key in ("A", "B", "C", "D", "E", "F"):
        value = getattr(model, key)
        assert value is None or np.all(np.isfinite(value)), key


# ---------------------------------------------------------------------------------------------
# Numbers: denormal, out of range, huge integers, NaN and inf


@pytest.mark.parametrize("value, fragment", [
    ("1e-320", "subnormal"),          # used to give all-NaN matrices with exit 0
    ("1e-101", "within [1e-100, 1e100]"),
    ("1e101", "within [1e-100, 1e100]"),
    ("0", "expected a finite number > 0"),
    ("-2.0", "expected a finite number > 0"),
    ("inf", "got inf"),
    ("nan", "got nan"),
    ("1" + "0" * 400, "an integer of 401 digits"),   # used to raise OverflowError
    ("true", "got True"),
    ("'1.0'", "got '1.0'"),
    ("1979-05-27", "datetime.date"),
    ("[1.0]", "got [1.0]"),
])
def test_element_value_out_of_range_or_wrong_type(tmp_path, capfd, value, fragment):
    assert_bad_file(tmp_path, capfd, "value", rc(c=value), "field 'branches[2].value'", fragment)


def test_integer_beyond_pythons_digit_limit(tmp_path, capfd):
    """tomllib raises ValueError (not TOMLDecodeError) for more than 4300 digits."""
    assert_bad_file(tmp_path, capfd, "digits", rc(r="7" * 5000), "a number of 5000 digits at "
                    "line 11", "[-1e100, 1e100]")


@pytest.mark.parametrize("field, text", [
    ("branches[0].input", branch("Qs", "through_source", "g", "1", input="9" * 500)
     + branch("C", "A", "1", "g", value="1.0")),
    ("operating_point.guess.v:C", tank("{ kind = 'power', coefficient = 1.0, exponent = 0.5 }",
                                       extra="[operating_point]\nguess = { 'v:C' = "
                                             + "9" * 400 + " }\n")),
    ("branches[2].relation.coefficients[1]", tank("{ kind = 'polynomial', coefficients = "
                                                  "[1.0, " + "9" * 400 + "] }")),
    ("branches[2].relation.coefficient", tank("{ kind = 'power', coefficient = " + "9" * 400
                                              + ", exponent = 2.0 }")),
])
def test_huge_integers_in_every_numeric_field(tmp_path, capfd, field, text):
    assert_bad_file(tmp_path, capfd, "huge", text, f"field '{field}'", "digits")


@pytest.mark.parametrize("relation, field, fragment", [
    ("{ kind = 'power', coefficient = nan, exponent = 2.0 }", "coefficient", "got nan"),
    ("{ kind = 'power', coefficient = 1.0, exponent = inf }", "exponent", "got inf"),
    ("{ kind = 'polynomial', coefficients = [1.0, nan] }", "coefficients[1]", "got nan"),
    ("{ kind = 'polynomial', coefficients = [1.0, -inf] }", "coefficients[1]", "got -inf"),
    ("{ kind = 'polynomial', coefficients = [0.0, 0] }", "coefficients", "all coefficients are "
                                                                         "zero"),
    ("{ kind = 'polynomial', coefficients = [] }", "coefficients", "non-empty list"),
    ("{ kind = 'arcsin', scale = nan }", "scale", "got nan"),
    ("{ kind = 'arcsin', scale = -1.0 }", "scale", "> 0"),
    ("{ kind = 'power', coefficient = 1.0, exponent = 2.0, offset = 1.0 }", "offset",
     "unknown key for a power relation"),
    ("{ kind = 'exp' }", "kind", "expected one of power, polynomial, arcsin"),
    ("'power'", "", "expected a table like"),
])
def test_bad_relation_parameters(tmp_path, capfd, relation, field, fragment):
    name = f"branches[2].relation{'.' + field if field else ''}"
    assert_bad_file(tmp_path, capfd, "relation", tank(relation), f"field '{name}'", fragment)


def test_values_that_overflow_together_are_refused_or_finite():
    """Values inside the range never give a non-finite model: 1e100 ohm with 1e100 F gives
    A = -1e-200 exactly, 1e-100 with 1e-100 gives -1e200."""
    for r, c, a in (("1e100", "1e100", -1e-200), ("1e-100", "1e-100", -1e200)):
        g = Graph("rc")
        g.add_branch("Vs", "across_source", "a", "g")
        g.add_branch("R", "D", "a", "b", float(r))
        g.add_branch("C", "A", "b", "g", float(c))
        model = g.linearize(outputs=["v:R", "f:C", "v:C"])
        assert_finite(model)
        assert model.A[0, 0] == pytest.approx(a, rel=1e-12)


def test_random_extreme_graphs_never_give_non_finite_models():
    """Random graphs with values anywhere in 1e-100..1e100: a PinlinError or a finite model,
    never another exception."""
    types = ["across_source", "through_source", "A", "T", "D", "A", "T", "D"]
    outcomes = {"model": 0, "error": 0}
    for seed in range(400):
        rnd = random.Random(seed)
        nodes, count = rnd.randint(2, 5), rnd.randint(2, 7)
        g = Graph(f"fuzz{seed}")
        try:
            for i in range(count):
                a, b = rnd.sample(range(nodes), 2)
                kind = rnd.choice(types)
                value = None if "source" in kind else 10 ** rnd.uniform(-100, 100)
                g.add_branch(f"b{i}", kind, f"n{a}", f"n{b}", value)
            outputs = [f"{k}:b{i}" for i in range(count) for k in "vf"]
            assert_finite(g.linearize(outputs=outputs))
            assert_finite(g.linearize(outputs=outputs, standard_form=True))
            outcomes["model"] += 1
        except PinlinError:
            outcomes["error"] += 1
    assert outcomes["model"] > 200


def test_ill_conditioned_dissipative_loop_is_exact_or_refused(tmp_path, capfd):
    """A flow source across 1, 1e-100 and 1e-100 ohm in parallel: v = Is / (1 + 2e100).
    Gaussian elimination in double precision loses the 1e-100 terms; pinlin must either get
    the value right or refuse, naming the branches, never return a wrong number."""
    text = (branch("I", "through_source", "n0", "n1") + branch("R0", "D", "n0", "n1",
                                                               value="1.0")
            + branch("R1", "D", "n1", "n0", value="1e-100")
            + branch("R2", "D", "n0", "n1", value="1e-100")
            + "[outputs]\nvariables = ['v:R0']\n")
    path = write(tmp_path, "loop", text)
    exact = float(Fraction(1) / (1 + 2 * Fraction(10) ** 100))
    try:
        model = Graph.load(path).linearize()
    except GraphError as exc:
        assert "singular to double precision" in str(exc) and "R0" in str(exc)
        assert_cli(path, capfd, "singular to double precision")
    else:
        assert abs(model.D[0, 0]) == pytest.approx(exact, rel=1e-6)


def test_badly_scaled_but_well_posed_resistors_are_solved_exactly():
    """1e50 ohm beside 1 ohm: plain elimination returned v = 0 for the 1e50 ohm branch; the
    equilibrated solve gets the exact -1 (flow of the source times ~1 ohm)."""
    g = Graph("scaled")
    g.add_branch("Is", "through_source", "n0", "n1")
    g.add_branch("R1", "D", "n0", "n1", 1e50)
    g.add_branch("R2", "D", "n0", "n1", 1.0)
    model = g.linearize(outputs=["v:R1", "f:R2", "f:R1"])
    np.testing.assert_allclose(model.D, [[-1.0], [-1.0], [-1e-50]], rtol=1e-12)


# ---------------------------------------------------------------------------------------------
# Nonlinear relations: domains, evaluation failures, Newton


def test_arcsin_outside_its_domain_at_the_equilibrium(tmp_path, capfd):
    """A torque above m g l = 0.981 N m: the spring force at equilibrium is out of the arcsin
    relation's domain (used to raise a bare ValueError 'math domain error')."""
    assert_bad_file(tmp_path, capfd, "torque", PENDULUM.format(torque="2.0"),
                    "field 'branches.K.relation'", "outside its domain |x| <= scale = 0.981",
                    "at the equilibrium")


def test_arcsin_at_the_edge_of_its_domain_at_the_equilibrium(tmp_path, capfd):
    """A torque of exactly m g l = 0.981 N m: the equilibrium lies on the edge of the arcsin
    relation's domain, where the slope is infinite. The message said the relation was
    evaluated 'at 0.981, outside its domain |x| <= 0.981' (the stencil beside it, printed to
    six digits)."""
    error = assert_bad_file(tmp_path, capfd, "edge", PENDULUM.format(torque="0.981"),
                            "field 'branches.K.relation'", "no slope at f = 0.981",
                            "lies on the edge of its domain")
    assert "outside its domain" not in str(error)


def test_arcsin_damper_with_no_equilibrium(tmp_path, capfd):
    """f = asin(v) never reaches 5: the search leaves the domain and says so."""
    assert_bad_file(tmp_path, capfd, "asin", tank("{ kind = 'arcsin', scale = 1.0 }", "5.0"),
                    "field 'branches.R.relation'", "outside its domain",
                    "while searching for the equilibrium")


def test_no_equilibrium_is_reported_with_the_guess(tmp_path, capfd):
    """f = v - v^3 carries at most 0.385: a source of 1 has no equilibrium."""
    assert_bad_file(tmp_path, capfd, "noeq", tank("{ kind = 'polynomial', coefficients = "
                                                  "[1.0, 0.0, -1.0] }"),
                    "field 'operating_point.guess'", "no equilibrium found from {v:C = 0}")


def test_infinite_slope_at_the_operating_point(tmp_path, capfd):
    """An orifice Q = sqrt|P| at zero flow has an infinite slope: the 5-point formula gave a
    finite number that depended on its step (110 with h = 1e-4)."""
    assert_bad_file(tmp_path, capfd, "orifice",
                    tank("{ kind = 'power', coefficient = 1.0, exponent = 0.5 }", "0.0"),
                    "field 'branches.R.relation'", "no well-defined finite slope at v = 0")


def test_relation_overflow(tmp_path, capfd):
    assert_bad_file(tmp_path, capfd, "overflow",
                    tank("{ kind = 'power', coefficient = 1.0, exponent = 1e99 }"),
                    "field 'branches.R.relation'", "overflows double precision")


def _python_tank(relation, flow: float = 1.0) -> Graph:
    g = Graph("tank", "fluid")
    g.add_branch("Qs", "through_source", "g", "1", input=flow)
    g.add_branch("C", "A", "1", "g", 2.0)
    g.add_branch("R", "D", "1", "g", relation=relation)
    return g


def _raise(exc: Exception):
    def relation(v: float) -> float:
        raise exc
    return relation


@pytest.mark.parametrize("relation, fragment", [
    (_raise(ZeroDivisionError("division by zero")), "cannot be evaluated at v = 0: division "
                                                    "by zero"),
    (_raise(KeyError("x")), "raised KeyError at v = 0"),
    (_raise(RecursionError()), "recursed too deeply"),
    (lambda v: math.nan, "returned nan at v = 0"),
    (lambda v: math.inf if v > 0.5 else v, "returned inf at v = "),
    (lambda v: np.array([v, v]), "returned ndarray"),
    (lambda v: [v], "returned list"),
    (lambda v: complex(v, 1.0), "returned complex"),
    (lambda v: None, "returned NoneType"),
    (lambda v: "1.0", "returned str"),
    (lambda v: 10**400, "beyond double precision"),
])
def test_python_relations_that_fail(relation, fragment):
    with pytest.raises(GraphError, match="branches.R.relation") as info:
        _python_tank(relation).linearize()
    assert fragment in str(info.value)


def test_dissipative_newton_that_does_not_converge():
    """atan carries at most pi/2 < 2: with the inductor's flow at 0 the resistor in the tree
    has no solution; from a guess at the equilibrium (f_L = 2) it converges."""
    g = Graph("prim")
    g.add_branch("Is", "through_source", "g", "a", input=2.0)
    g.add_branch("R", "D", "a", "g", relation=math.atan)
    g.add_branch("L", "T", "a", "g", 1.0)
    with pytest.raises(GraphError, match=r"dissipative elements \(R\) have no solution"):
        g.linearize()
    model = g.linearize(x0=[2.0])
    assert model.info["operating_point"]["x0"]["f:L"] == pytest.approx(2.0)


def test_false_equilibrium_of_a_slow_system_is_refused():
    """tanh carries at most 1 < 2, so there is no equilibrium; with C = 1e12 F the rate
    (2 - tanh v) / C is below 1e-9 everywhere and the old test accepted v = 15."""
    g = Graph("sat")
    g.add_branch("Is", "through_source", "g", "a", input=2.0)
    g.add_branch("C", "A", "a", "g", 1e12)
    g.add_branch("R", "D", "a", "g", relation=math.tanh)
    with pytest.raises(GraphError, match="no equilibrium found from {v:C = 0.5}"):
        g.linearize(x0=[0.5])


def test_excess_storage_in_a_nonlinear_graph(tmp_path, capfd):
    """Two springs in parallel with a nonlinear one: the split of the static force is
    undetermined. Linear ones alone are combined first (this used to raise a ValueError from
    zip(strict=True) or refuse the combined state's guess)."""
    head = (branch("Fs", "through_source", "g", "a", input="2.0")
            + branch("m", "A", "a", "g", value="1.0") + branch("K1", "T", "a", "g", value="1.0"))
    damper = branch("R", "D", "a", "g", relation="{ kind = 'polynomial', coefficients = "
                                                 "[1.0, 0.0, 1.0] }")
    assert_bad_file(tmp_path, capfd, "excess", head + branch(
        "K2", "T", "a", "g", relation="{ kind = 'polynomial', coefficients = [1.0, 0.0, 0.1] }")
        + damper, "field 'branches.K1'", "excess energy storage (K1, K2")
    path = write(tmp_path, "combined", head + branch("K2", "T", "a", "g", value="2.0") + damper
                 + "[outputs]\nvariables = ['f:K1', 'v:m']\n[operating_point]\n"
                   "guess = { 'f:K1+K2' = 1.0 }\n")
    model = Graph.load(path).linearize()
    assert model.state_names == ("v:m", "f:K1+K2")
    np.testing.assert_allclose(model.A, [[-1.0, -1.0], [1.5, 0.0]], rtol=1e-9)
    np.testing.assert_allclose(model.C, [[0.0, 2.0 / 3.0], [1.0, 0.0]], rtol=1e-12)


# ---------------------------------------------------------------------------------------------
# The file itself


def test_arrays_nested_thousands_deep(tmp_path, capfd):
    """tomllib recurses once per level: RecursionError used to escape."""
    assert_bad_file(tmp_path, capfd, "deep", "x = " + "[" * 5000 + "]" * 5000 + "\n",
                    "nested too deeply")


@pytest.mark.parametrize("text, fragment", [
    ("", "the graph file is empty"),
    ("  \n\t\n", "the graph file is empty"),
    ("# only a comment\n", "field 'branches': expected a non-empty array of tables"),
    (rc() + "value = 2.0\n", "malformed TOML: Cannot overwrite a value"),   # duplicate key
    ("[branches]\nname = 'x'\n", "expected a non-empty array of tables"),
    ("branches = [1, 2]\n", "field 'branches[0]': expected a table, got 1"),
])
def test_empty_and_malformed_files(tmp_path, capfd, text, fragment):
    assert_bad_file(tmp_path, capfd, "bad", text, fragment)


def test_non_utf8_bytes(tmp_path, capfd):
    path = tmp_path / "latin1.toml"
    path.write_bytes(rc().encode() + b"# r\xe9sistance\n")
    with pytest.raises(GraphError, match="not UTF-8 text: byte 0xe9 at line 18"):
        Graph.load(path)
    assert_cli(path, capfd, "not UTF-8")


def test_byte_order_mark_is_accepted(tmp_path):
    path = tmp_path / "bom.toml"
    path.write_bytes(b"\xef\xbb\xbf" + rc().encode())
    assert Graph.load(path).linearize().A[0, 0] == pytest.approx(-1.0)


def test_folder_missing_file_fifo_and_symlink_loop(tmp_path, capfd):
    folder = tmp_path / "graph.toml"
    folder.mkdir()
    with pytest.raises(GraphError, match="is a folder"):
        Graph.load(folder)
    assert_cli(folder, capfd, "is a folder")
    with pytest.raises(GraphError, match="graph file not found"):
        Graph.load(tmp_path / "missing.toml")
    assert_cli(tmp_path / "missing.toml", capfd, "not found")
    fifo = tmp_path / "fifo.toml"
    os.mkfifo(fifo)    # reading it would block forever
    with pytest.raises(GraphError, match="not a regular file"):
        Graph.load(fifo)
    loop = tmp_path / "loop.toml"
    loop.symlink_to(loop)
    with pytest.raises(GraphError, match="cannot read the graph file"):
        Graph.load(loop)


@pytest.mark.parametrize("text, field, fragment", [
    ("nmae = 'x'\n" + rc(), "nmae", "unknown key"),
    (rc().replace("value = 1.0", "valeu = 1.0", 1), "branches[1].valeu", "unknown key"),
    ("name = 5\n" + rc(), "name", "expected a non-empty string, got 5"),
    ("domain = 'nuclear'\n" + rc(), "domain", "expected one of electrical"),
    ("domain = ['electrical']\n" + rc(), "domain", "expected one of electrical"),
    (rc().replace("name = 'R'", "name = 3"), "branches[1].name", "got 3"),
    (rc().replace("name = 'R'", "name = '  '"), "branches[1].name", "non-empty string"),
    (rc().replace("name = 'R'", "name = 'R+1'"), "branches[1].name", "reserved for combined"),
    (rc().replace("name = 'R'", 'name = "R\\n1"'), "branches[1].name", "control characters"),
    (rc().replace("to = 'b'", "to = \"b\\tc\""), "branches[1].to", "control characters"),
    (rc().replace("from = 'a'\nto = 'b'", "from = 1\nto = 'b'"), "branches[1].from", "got 1"),
    (rc().replace("type = 'D'", "type = 4"), "branches[1].type", "got 4"),
    (rc().replace("type = 'D'", "type = 'd'"), "branches[1].type", "unknown element type 'd'"),
    (rc() + branch("R", "D", "a", "g", value="1.0"), "branches[3].name", "used twice"),
    ("domain = 'thermal'\n" + rc() + branch("L", "T", "b", "g", value="1.0"),
     "branches[3].type", "the thermal domain has no T-type"),
    (rc().replace("value = 1.0\n", "value = 1.0\ninput = 3.0\n", 1), "branches[1].input",
     "a D-type element takes no input"),
    (rc().replace("to = 'g'\n", "to = 'g'\ninput = 'x'\n", 1), "branches[0].input",
     "expected a finite number, got 'x'"),
    (rc().replace("to = 'g'\n", "to = 'g'\nvalue = 2.0\n", 1), "branches[0].value",
     "a source takes no value"),
    (rc() + "[outputs]\nvariables = []\n", "outputs.variables", "non-empty list"),
    (rc() + "[outputs]\nvariables = ['v:C', 'v:C']\n", "outputs.variables", "listed twice"),
    (rc() + "[outputs]\nvariables = 'v:C'\n", "outputs.variables", "non-empty list"),
    (rc() + "[outputs]\nvariables = ['q:C']\n", "outputs.variables", "expected 'v:<branch>'"),
    (rc() + "[operating_point]\nguess = { 'v:C' = 1.0 }\n", "operating_point",
     "applies only to graphs with nonlinear elements"),
    (tank("{ kind = 'power', coefficient = 1.0, exponent = 0.5 }",
          extra="[operating_point]\nguess = { 'v:X' = 1.0 }\n"), "operating_point.guess",
     "['v:X'] are not state variables"),
    (tank("{ kind = 'power', coefficient = 1.0, exponent = 0.5 }",
          extra="[operating_point]\nguess = { 'v:C' = 'a' }\n"), "operating_point.guess.v:C",
     "expected a finite number, got 'a'"),
    (tank("{ kind = 'power', coefficient = 1.0, exponent = 0.5 }",
          extra="[operating_point]\nx0 = 1.0\n"), "operating_point", "expected a table with "
                                                                    "'guess'"),
])
def test_bad_fields(tmp_path, capfd, text, field, fragment):
    assert_bad_file(tmp_path, capfd, "field", text, f"field '{field}'", fragment)


def test_parallel_capacitors_are_not_combined_as_series(tmp_path):
    """Two capacitors sharing both nodes were taken for a series chain: the merge made a
    self-loop, and the loader looped forever or dropped the state (order 0)."""
    text = (branch("Vs", "across_source", "b", "g") + branch("R", "D", "b", "g", value="1.0")
            + branch("C1", "A", "a", "g", value="1.0") + branch("C2", "A", "a", "g", value="2.0"))
    tree = Graph.load(write(tmp_path, "caps", text)).normal_tree()
    assert tree.order == 1 and tree.dependent == ["C1"] and not tree.combined   # C2 the larger


# ---------------------------------------------------------------------------------------------
# Python API: wrong-typed arguments


def _rc_graph() -> Graph:
    g = Graph("rc")
    g.add_branch("Vs", "across_source", "a", "g")
    g.add_branch("R", "D", "a", "b", 1.0)
    g.add_branch("C", "A", "b", "g", 1.0)
    return g


@pytest.mark.parametrize("call, argument, fragment", [
    (lambda: Graph.load(123), "path", "got int 123"),
    (lambda: Graph.load(None), "path", "got NoneType None"),
    (lambda: Graph.load(b"graph.toml"), "path", "got bytes"),
    (lambda: Graph.load(""), "path", "empty file name"),
    (lambda: Graph(3), "name", "expected a non-empty string"),
    (lambda: Graph("a\nb"), "name", "without control characters"),
    (lambda: Graph("g", "nuclear"), "domain", "expected one of electrical"),
    (lambda: Graph("g", source=5), "source", "expected a file path or None"),
    (lambda: _rc_graph().linearize(combine="yes"), "combine", "expected True or False"),
    (lambda: _rc_graph().linearize(standard_form=1), "standard_form", "expected True or False"),
    (lambda: _rc_graph().normal_tree(combine="no"), "combine", "expected True or False"),
    (lambda: _rc_graph().linearize(outputs="v:C"), "outputs", "expected a list"),
    (lambda: _rc_graph().linearize(outputs=[1]), "outputs", "got 1"),
    (lambda: _rc_graph().linearize(outputs=["v:C", "v:C"]), "outputs", "listed twice"),
    (lambda: _rc_graph().linearize(outputs=["v:X"]), "outputs", "no branch named 'X'"),
    (lambda: _rc_graph().linearize(x0=[1.0]), "x0", "applies only to graphs with nonlinear"),
    (lambda: _rc_graph().linearize(u0={"Vs": 1.0}), "u0", "applies only to graphs with "),
    (lambda: Graph("g").add_branch("R", 3, "a", "b", 1.0), "type", "got int 3"),
    (lambda: Graph("g").add_branch("R", "D", 1, 2, 1.0), "from_", "got int 1"),
    (lambda: Graph("g").add_branch(7, "D", "a", "b", 1.0), "name", "got int 7"),
    (lambda: Graph("g").add_branch("R", "D", "a", "b", "1.0"), "value", "got str '1.0'"),
    (lambda: Graph("g").add_branch("R", "D", "a", "b", True), "value", "got bool True"),
    (lambda: Graph("g").add_branch("R", "D", "a", "b", relation=3.0), "relation",
     "expected a function"),
    (lambda: Graph("g").add_branch("V", "across_source", "a", "b", input="1"), "input",
     "got str '1'"),
    (lambda: _rc_graph().branch(3), "name", "expected a branch name"),
])
def test_wrong_typed_arguments(call, argument, fragment):
    with pytest.raises(ArgumentError) as info:
        call()
    assert info.value.argument == argument and fragment in str(info.value), str(info.value)


@pytest.mark.parametrize("kwargs, fragment", [
    ({"x0": []}, "one number per state (1: v:C), got 0"),
    ({"x0": [1.0, 2.0]}, "one number per state (1: v:C), got 2"),
    ({"x0": [math.nan]}, "entry 0 (v:C): expected a finite number"),
    ({"x0": [10**400]}, "entry 0 (v:C): expected a finite number"),
    ({"x0": "1"}, "expected a list of 1 numbers"),
    ({"u0": [1.0]}, "expected a dict"),
    ({"u0": {"X": 1.0}}, "'X' is not a source of the graph; sources: Qs"),
    ({"u0": {"Qs": math.inf}}, "Qs: expected a finite number"),
])
def test_nonlinear_arguments(kwargs, fragment):
    with pytest.raises(ArgumentError, match=r"argument '(x0|u0)'") as info:
        _python_tank(lambda v: v + v**3).linearize(**kwargs)
    assert fragment in str(info.value)


@pytest.mark.parametrize("value, fragment", [
    (1e-320, "subnormal"), (10**400, "401 digits"), (math.nan, "got nan"), (-1.0, "> 0"),
    (None, "needs a value > 0"),
])
def test_bad_values_through_the_python_api(value, fragment):
    with pytest.raises(GraphError, match=r"branches\.R\.value") as info:
        Graph("g").add_branch("R", "D", "a", "b", value)
    assert fragment in str(info.value)


def test_branches_edited_directly_are_checked_again():
    g = _rc_graph()
    g.branches.append(Branch("R2", "D", "b", "g", -5.0))
    with pytest.raises(GraphError, match=r"branches\.R2\.value.*expected a finite number > 0"):
        g.linearize()
    g.branches[-1] = "R3"
    with pytest.raises(ArgumentError, match="entry 3: expected a Branch"):
        g.normal_tree()
    g.branches[-1] = Branch("R", "D", "b", "g", 1.0)
    with pytest.raises(GraphError, match="'R' is used twice"):
        g.formulate()
    g.branches.pop()
    g.outputs = "v:C"
    with pytest.raises(GraphError, match="outputs.variables"):
        g.linearize()


def test_empty_graph():
    with pytest.raises(GraphError, match="the graph has no branches"):
        Graph("g").linearize()


def test_size_limits(tmp_path, capfd):
    """A 17 MiB file is refused before it is read; 5001 branches before any matrix is built
    (the dense method would take minutes and gigabytes)."""
    big = tmp_path / "big.toml"
    big.write_bytes(b"")
    os.truncate(big, 17 * 2**20)    # sparse: nothing is written
    with pytest.raises(GraphError, match="expected at most 16777216 bytes"):
        Graph.load(big)
    assert_cli(big, capfd, "expected at most 16777216 bytes")
    many = "".join(branch(f"R{i}", "D", f"n{i}", f"n{i + 1}", value="1.0") for i in range(5001))
    assert_bad_file(tmp_path, capfd, "many", many, "field 'branches'", "5001 branches: "
                    "expected at most 5000")


def test_path_like_giving_bytes_is_an_argument_error():
    class BytesPath:
        def __fspath__(self) -> bytes:
            return b"graph.toml"

    assert isinstance(BytesPath(), os.PathLike)
    with pytest.raises(ArgumentError, match="argument 'path'"):
        Graph.load(BytesPath())


def test_check_applies_the_domain_rules_to_an_edited_graph():
    """Graph.check() (run by linearize) refuses what add_branch refuses, also after the
    graph's domain or branch list was edited directly."""
    g = Graph("heat", "thermal")
    g.add_branch("Q", "through_source", "a", "g")
    g.add_branch("C", "A", "a", "g", 1.0)
    g.branches.append(Branch("L", "T", "a", "g", 1.0))
    with pytest.raises(GraphError, match="thermal domain has no T-type"):
        g.linearize()
    h = Graph("rc")
    h.add_branch("V", "across_source", "a", "g")
    h.add_branch("R", "D", "a", "g", 1.0)
    h.domain = "nope"
    with pytest.raises(ArgumentError, match="argument 'domain': expected one of"):
        h.linearize()


def test_too_many_nonlinear_elements_are_refused_before_the_search(tmp_path, capfd):
    """A ladder of 101 capacitors and cubic resistors: the equilibrium search (nested Newton,
    difference Jacobians) took minutes from 300 such rungs; more than 100 are refused at
    once, naming the count."""
    from conftest import deadline

    def ladder(n: int) -> str:
        text = branch("Is", "through_source", "g", "n0", input="1.0")
        for i in range(n):
            text += (branch(f"C{i}", "A", f"n{i}", "g", value="1.0")
                     + branch(f"R{i}", "D", f"n{i}", f"n{i + 1}",
                              relation="{ kind = 'power', coefficient = 1.0, exponent = 3.0 }"))
        return text + branch("Rend", "D", f"n{n}", "g", value="1.0")

    with deadline(10):
        assert_bad_file(tmp_path, capfd, "ladder", ladder(101), "field 'branches'",
                        "101 nonlinear elements", "at most 100")


def test_an_error_about_a_combined_element_names_a_branch_of_the_file(tmp_path, capfd):
    """Linear springs K0 and K4 in parallel are combined into 'K0+K4' before a nonlinear
    spring beside them is found in excess: the field named 'branches.K0+K4', which is not in
    the file; it now names K0 (the message still lists the combined element)."""
    text = (branch("Ts", "through_source", "g", "1", input="0.1")
            + branch("J", "A", "1", "g", value="0.05")
            + branch("K0", "T", "1", "g", value="2.0")
            + branch("K4", "T", "1", "g", value="3.0")
            + branch("Kn", "T", "1", "g",
                     relation="{ kind = 'arcsin', scale = 0.981 }")
            + branch("B", "D", "1", "g", value="5.0"))
    assert_bad_file(tmp_path, capfd, "combined", text, "field 'branches.K0'", "K0+K4",
                    "excess energy storage")

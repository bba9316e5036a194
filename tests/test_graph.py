"""Linear graphs (Rowell): every worked example of the handout from validation/graphs/.

Two independent references: (1) the expected matrices derived by hand in each test (the
handout's printed results carry misprints, noted where they occur); (2) the full set of element
and constraint equations (KCL at every node, v = e_from - e_to, elemental laws in s) solved at
complex frequencies s and compared with C (sI - A)^-1 (B + sE) + D + sF.
"""

from __future__ import annotations

import math
from fractions import Fraction
from pathlib import Path

import numpy as np
import pytest

from pinlin.cli import main
from pinlin.graph import Graph, GraphError

GRAPHS = Path(__file__).resolve().parent.parent / "validation" / "graphs"
LINEAR = ["rc_lr_parallel", "mass_spring", "mass_spring_damper", "rotational", "series_rlc",
          "fluid", "thermal", "lead_lag", "two_springs", "matrix_method"]
S_POINTS = (0.7 + 1.3j, 3.1j, -0.2 + 0.05j)


def full_solution(graph: Graph, s: complex, outputs: list[str]) -> np.ndarray:
    """Outputs per unit input (columns) from all branch equations at frequency s.

    Unknowns: node potentials (reference: the first node of the first branch's 'to') and every
    branch through variable. Equations: KCL at the other nodes; one elemental law per branch
    in terms of v = e_from - e_to: A: f = value s v; T: v = value s f; D: v = value f;
    across source: v = U; through source: f = U.
    """
    nodes = []
    for b in graph.branches:
        for n in (b.from_, b.to):
            if n not in nodes:
                nodes.append(n)
    ref = graph.branches[0].to
    free = [n for n in nodes if n != ref]
    ne, nb = len(free), len(graph.branches)
    sources = [b.name for b in graph.branches if b.is_source]
    cols = []
    for src in sources:
        Mtx = np.zeros((ne + nb, ne + nb), dtype=complex)
        rhs = np.zeros(ne + nb, dtype=complex)
        for j, b in enumerate(graph.branches):
            f_col = ne + j
            for n, sign in ((b.from_, -1.0), (b.to, 1.0)):   # flow leaves 'from', enters 'to'
                if n != ref:
                    Mtx[free.index(n), f_col] += sign
            row = ne + j
            v = np.zeros(ne + nb, dtype=complex)
            if b.from_ != ref:
                v[free.index(b.from_)] += 1.0
            if b.to != ref:
                v[free.index(b.to)] -= 1.0
            f = np.zeros(ne + nb, dtype=complex)
            f[f_col] = 1.0
            if b.type == "A":
                Mtx[row] = f - b.value * s * v
            elif b.type == "T":
                Mtx[row] = v - b.value * s * f
            elif b.type == "D":
                Mtx[row] = v - b.value * f
            elif b.type == "across_source":
                Mtx[row], rhs[row] = v, 1.0 if b.name == src else 0.0
            else:
                Mtx[row], rhs[row] = f, 1.0 if b.name == src else 0.0
        z = np.linalg.solve(Mtx, rhs)
        out = []
        for var in outputs:
            kind, _, name = var.partition(":")
            j = next(i for i, b in enumerate(graph.branches) if b.name == name)
            b = graph.branches[j]
            if kind == "f":
                out.append(z[ne + j])
            else:
                ef = z[free.index(b.from_)] if b.from_ != ref else 0.0
                et = z[free.index(b.to)] if b.to != ref else 0.0
                out.append(ef - et)
        cols.append(out)
    return np.array(cols).T


def model_response(model, s: complex) -> np.ndarray:
    n = model.n_states
    E = model.E if model.E is not None else np.zeros_like(model.B)
    F = model.F if model.F is not None else np.zeros_like(model.D)
    X = np.linalg.solve(s * np.eye(n) - model.A, model.B + s * E)
    return model.C @ X + model.D + s * F


@pytest.mark.parametrize("name", LINEAR)
def test_state_equations_match_the_full_equations_at_complex_s(name):
    graph = Graph.load(GRAPHS / f"{name}.toml")
    model = graph.linearize()
    for s in S_POINTS:
        ref = full_solution(graph, s, list(model.output_names))
        got = model_response(model, s)
        np.testing.assert_allclose(got, ref, rtol=1e-10, atol=1e-12 * np.abs(ref).max())


@pytest.mark.parametrize("name", LINEAR)
def test_standard_form_has_the_same_response(name):
    graph = Graph.load(GRAPHS / f"{name}.toml")
    model = graph.linearize(standard_form=True)
    assert model.E is None or not np.any(model.E)
    for s in S_POINTS:
        ref = full_solution(graph, s, list(model.output_names))
        np.testing.assert_allclose(model_response(model, s), ref, rtol=1e-10,
                                   atol=1e-12 * np.abs(ref).max())


def _m(name):
    return Graph.load(GRAPHS / f"{name}.toml").linearize()


def test_rc_lr_parallel_eq_11_and_16():
    R, C, L = 2.0, 0.5, 0.25
    m = _m("rc_lr_parallel")
    assert m.state_names == ("v:C", "f:L")
    np.testing.assert_allclose(m.A, [[-1 / (R * C), -1 / C], [1 / L, 0]])
    np.testing.assert_allclose(m.B, [[1 / (R * C)], [0]])
    np.testing.assert_allclose(m.C, [[-1 / R, 0], [-1, 0], [1, 0], [-1 / R, -1]])
    np.testing.assert_allclose(m.D, [[1 / R], [1], [0], [1 / R]])


def test_mechanical_examples():
    m = _m("mass_spring")                       # eq. 23
    np.testing.assert_allclose(m.A, [[0, -1 / 2.0], [40.0, 0]])
    m = _m("mass_spring_damper")                # eq. 35 with K = K1 + K2
    assert m.state_names == ("v:m", "f:K1+K2")
    np.testing.assert_allclose(m.A, [[-5.0 / 2.0, -1 / 2.0], [100.0, 0]])
    np.testing.assert_allclose(m.C[1:], [[0, 0.4], [0, 0.6]])   # K1, K2 share the force


def test_rotational_example_with_the_printed_swap_corrected():
    """Omega_J' = (-(B1 + B2) Omega_J + B1 Omega_s) / J. The handout prints B2 Omega_s: its
    elemental equations swap B1 and B2 against its own compatibility equations."""
    J, B1, B2 = 0.5, 2.0, 0.5
    m = _m("rotational")
    np.testing.assert_allclose(m.A, [[-(B1 + B2) / J]])
    np.testing.assert_allclose(m.B, [[B1 / J]])


def test_series_rlc_eq_52_and_56():
    R, C, L = 3.0, 0.2, 0.5
    m = _m("series_rlc")
    np.testing.assert_allclose(m.A, [[0, 1 / C], [-1 / L, -R / L]])
    np.testing.assert_allclose(m.B, [[0], [1 / L]])
    np.testing.assert_allclose(m.C, [[-1, -R], [0, 1], [1, 0]])
    np.testing.assert_allclose(m.D, [[1], [0], [0]])


def test_fluid_eq_66():
    Rp, Ip, C, Rf = 2e6, 5e5, 1e-6, 4e6
    m = _m("fluid")
    assert m.state_names == ("f:Ip", "v:C")   # file order; eq. 66 lists (P_C, Q_Ip)
    np.testing.assert_allclose(m.A, [[-Rp / Ip, -1 / Ip], [1 / C, -1 / (Rf * C)]])
    np.testing.assert_allclose(m.B, [[1 / Ip], [0]])


def test_thermal_eq_75():
    C, R1, R2 = 400.0, 0.1, 0.5
    m = _m("thermal")
    np.testing.assert_allclose(m.A, [[-1 / (C * (R1 + R2))]])
    np.testing.assert_allclose(m.B, [[R2 / (C * (R1 + R2))]])


def test_lead_lag_with_input_derivative_eq_87_89():
    R1, R2, C1, C2 = 1e5, 2e4, 1e-6, 2e-6
    m = _m("lead_lag")
    assert m.state_names == ("v:C2",)
    a = -(R1 + R2) / (R1 * R2 * (C1 + C2))
    np.testing.assert_allclose(m.A, [[a]])
    np.testing.assert_allclose(m.B, [[1 / (R1 * (C1 + C2))]])
    np.testing.assert_allclose(m.E, [[C1 / (C1 + C2)]])
    np.testing.assert_allclose(m.C, [[(R1 + R2) * C1 / (R1 * R2 * (C1 + C2))]])
    np.testing.assert_allclose(m.D, [[-C1 / (R1 * (C1 + C2))]])
    np.testing.assert_allclose(m.F, [[C1 * C2 / (C1 + C2)]])


def test_two_springs_eq_104_and_standard_form_107_108():
    m_, B2, B1, K2, K1 = 3.0, 4.0, 10.0, 200.0, 100.0
    model = _m("two_springs")
    np.testing.assert_allclose(model.A, [[-B2 / m_, 0], [0, -K1 * K2 / (B1 * (K1 + K2))]])
    np.testing.assert_allclose(model.B, [[1 / m_], [0]])
    np.testing.assert_allclose(model.E, [[0], [K1 / (K1 + K2)]])
    np.testing.assert_allclose(model.C, [[0, 1 / B1]])
    std = model.standard_form()
    # eq. 107 prints K1^2 K2 / (B1 (K1 + K2)^2) with a plus sign; B' = B + A E gives minus.
    np.testing.assert_allclose(std.B, [[1 / m_], [-K1**2 * K2 / (B1 * (K1 + K2) ** 2)]])
    np.testing.assert_allclose(std.D, [[K1 / (B1 * (K1 + K2))]])   # eq. 108


def test_matrix_method_eq_127_derived():
    """Eq. 127 as printed has wrong signs and entries; derived from eqs. 117-120:
    v_R2 = (R2 v_C - R1 R2 i_L) / (R1 + R2), i_R1 = (v_C - v_R2) / R1."""
    C, R1, R2, L = 0.01, 10.0, 5.0, 0.2
    m = _m("matrix_method")
    S = R1 + R2
    np.testing.assert_allclose(m.A, [[-1 / (S * C), -R2 / (S * C)],
                                     [R2 / (S * L), -R1 * R2 / (S * L)]])
    np.testing.assert_allclose(m.B, [[1 / C], [0]])


def test_excess_storage_reported_when_not_combined():
    graph = Graph.load(GRAPHS / "mass_spring_damper.toml")
    tree = graph.normal_tree(combine=False)
    assert tree.excess == [["K1", "K2"]] and tree.order == 3
    combined = graph.normal_tree()
    assert combined.combined == {"K1+K2": ["K1", "K2"]} and combined.order == 2
    loose = graph.linearize(combine=False)
    for s in S_POINTS:   # same input-output behaviour, one uncontrollable state more
        np.testing.assert_allclose(model_response(loose, s)[:1],
                                   model_response(graph.linearize(), s)[:1], rtol=1e-10)


def test_dependent_storage_reported():
    tree = Graph.load(GRAPHS / "two_springs.toml").normal_tree()
    assert tree.dependent == ["K2"] and tree.states == ["v:m", "f:K1"]
    tree = Graph.load(GRAPHS / "lead_lag.toml").normal_tree()
    assert tree.dependent == ["C1"]


# ---------------------------------------------------------------------------------------------
# Nonlinear examples (section 6) linearized (section 7)


def test_car_drag():
    m, Fp, Fr, cd = 1200.0, 500.0, 100.0, 0.4
    model = Graph.load(GRAPHS / "car_drag.toml").linearize()
    v0 = math.sqrt((Fp - Fr) / cd)
    assert model.info["operating_point"]["x0"]["v:m"] == pytest.approx(v0, rel=1e-10)
    np.testing.assert_allclose(model.A, [[-2 * cd * v0 / m]], rtol=1e-9)
    # d v'/d Fr = -1/m (the handout prints +1/m: the road resistance opposes the motion)
    np.testing.assert_allclose(model.B, [[1 / m, -1 / m]], rtol=1e-12)


def test_pendulum_torque_instrument():
    J, B, mgl, T0 = 0.05, 0.02, 0.981, 0.4
    model = Graph.load(GRAPHS / "pendulum_torque.toml").linearize()
    op = model.info["operating_point"]["x0"]
    assert abs(op["v:J"]) < 1e-9 and op["f:K"] == pytest.approx(T0, rel=1e-9)
    k = mgl * math.cos(math.asin(T0 / mgl))      # eq. 149 at the equilibrium
    np.testing.assert_allclose(model.A, [[-B / J, -1 / J], [k, 0]], rtol=1e-8)


def test_tank_with_orifices():
    K1, K2, Inert, Qs = 1e-5, 2e-5, 1e6, 0.002
    c = (2e-5, 5e-10, 1e-15)
    model = Graph.load(GRAPHS / "tank_orifices.toml").linearize()
    P0 = (Qs / (K1 + K2)) ** 2                    # Qs = (K1 + K2) sqrt(P0) at equilibrium
    Q0 = K2 * math.sqrt(P0)
    Cp = c[0] + 2 * c[1] * P0 + 3 * c[2] * P0**2  # dV/dP
    op = model.info["operating_point"]["x0"]
    assert op["v:C"] == pytest.approx(P0, rel=1e-9) and op["f:I"] == pytest.approx(Q0, rel=1e-9)
    np.testing.assert_allclose(model.A, [[-K1 / (2 * math.sqrt(P0)) / Cp, -1 / Cp],
                                         [1 / Inert, -2 * Q0 / (K2**2 * Inert)]], rtol=1e-7)


def test_nonlinear_rate_jacobian_matches_the_linear_model():
    """A of the linearized graph equals central differences of f(x, u) (eqs. 183-184)."""
    from pinlin.graph import NonlinearGraph

    graph = Graph.load(GRAPHS / "tank_orifices.toml")
    model = graph.linearize()
    x0 = np.array(list(model.info["operating_point"]["x0"].values()))
    u0 = np.array([0.002])
    nl = NonlinearGraph(graph)
    J = np.zeros((2, 2))
    for k in range(2):
        h = 1e-6 * max(1.0, abs(x0[k]))
        e = np.zeros(2)
        e[k] = h
        J[:, k] = (nl.rate(x0 + e, u0) - nl.rate(x0 - e, u0)) / (2 * h)
    np.testing.assert_allclose(J, model.A, rtol=1e-5)


def test_python_api_nonlinear_element():
    g = Graph("tank", "fluid")
    g.add_branch("Qs", "through_source", "g", "1", input=1.0)
    g.add_branch("C", "A", "1", "g", 2.0)
    g.add_branch("R", "D", "1", "g", relation=lambda p: 0.5 * math.sqrt(abs(p))
                 * math.copysign(1.0, p))
    model = g.linearize(x0=[1.0])
    assert model.info["operating_point"]["x0"]["v:C"] == pytest.approx(4.0)
    np.testing.assert_allclose(model.A, [[-0.5 / (2 * 2.0) / 2.0]], rtol=1e-9)


# ---------------------------------------------------------------------------------------------
# Bad graphs


BAD = {
    "disconnected": ("[[branches]]\nname = 'C'\ntype = 'A'\nfrom = 'a'\nto = 'g'\nvalue = 1.0\n"
                     "[[branches]]\nname = 'R'\ntype = 'D'\nfrom = 'b'\nto = 'c'\nvalue = 1.0\n",
                     "not connected"),
    "source_loop": ("[[branches]]\nname = 'V1'\ntype = 'across_source'\nfrom = 'a'\nto = 'g'\n"
                    "[[branches]]\nname = 'V2'\ntype = 'across_source'\nfrom = 'a'\nto = 'g'\n",
                    "across-variable sources form a loop"),
    "through_cutset": ("[[branches]]\nname = 'I1'\ntype = 'through_source'\nfrom = 'g'\n"
                       "to = 'a'\n[[branches]]\nname = 'C'\ntype = 'A'\nfrom = 'b'\nto = 'g'\n"
                       "value = 1.0\n[[branches]]\nname = 'I2'\ntype = 'through_source'\n"
                       "from = 'a'\nto = 'b'\n", "through-variable sources form a cut-set"),
    "unknown_type": ("[[branches]]\nname = 'X'\ntype = 'Q'\nfrom = 'a'\nto = 'g'\n",
                     "unknown element type 'Q'"),
    "missing_value": ("[[branches]]\nname = 'C'\ntype = 'A'\nfrom = 'a'\nto = 'g'\n",
                      "needs a value > 0"),
    "negative_value": ("[[branches]]\nname = 'C'\ntype = 'A'\nfrom = 'a'\nto = 'g'\n"
                       "value = -1.0\n", "expected a finite number > 0"),
    "unknown_output": ("[[branches]]\nname = 'C'\ntype = 'A'\nfrom = 'a'\nto = 'g'\n"
                       "value = 1.0\n[outputs]\nvariables = ['v:R']\n", "no branch named 'R'"),
    "malformed": ("[[branches]\n", "malformed TOML"),
}


@pytest.mark.parametrize("case", sorted(BAD))
def test_bad_graphs(case, tmp_path, capfd):
    text, fragment = BAD[case]
    path = tmp_path / f"{case}.toml"
    path.write_text(text)
    with pytest.raises(GraphError, match=fragment):
        Graph.load(path).linearize()
    assert main(["graph", str(path)]) == 2
    err = capfd.readouterr().err
    assert err.count("\n") == 1 and fragment in err


def test_graph_command_prints_tree_and_matrices(capfd):
    assert main(["graph", str(GRAPHS / "lead_lag.toml"), "--standard-form"]) == 0
    out = capfd.readouterr().out
    assert "normal tree: Vs, C2" in out and "dependent energy storage: C1" in out
    assert "standard form" in out and "E =" not in out


@pytest.mark.parametrize("shunt", [1e-6, 1e-12, 1e-17])
def test_small_resistance_beside_a_large_one_keeps_its_digits(shunt):
    """Vs - R3 (1 ohm) - node b, with L (1 H) and a shunt R4 from b to ground: by hand
    (node b), v_b = R4 / (R3 + R4) (Vs - R3 f_L), so A = -R4/(1 + R4), B = R4/(1 + R4) and
    v:L = v:R4 (one node pair). With R3 in the normal tree, v_L = Vs - v_R3 cancelled: B was
    off by 2e-5 at R4 = 1e-12 and 0 at 1e-17. Resistances now enter the tree smallest first."""
    g = Graph("shunt")
    g.add_branch("Vs", "across_source", "a", "g")
    g.add_branch("R3", "D", "a", "b", 1.0)
    g.add_branch("L", "T", "b", "g", 1.0)
    g.add_branch("R4", "D", "b", "g", shunt)
    m = g.linearize(outputs=["f:L", "v:L", "v:R4"])
    exact = shunt / (1.0 + shunt)
    np.testing.assert_allclose(m.A, [[-exact]], rtol=4 * np.finfo(float).eps)
    np.testing.assert_allclose(m.B, [[exact]], rtol=4 * np.finfo(float).eps)
    np.testing.assert_array_equal(m.C[1], m.C[2])
    np.testing.assert_array_equal(m.D[1], m.D[2])


def test_small_capacitor_beside_a_large_one_gets_its_share_exactly():
    """Capacitors C1 = 9.24e-6 F and C5 = 1.584e-2 F in parallel (C5, the larger, the state;
    C1 dependent storage), fed by Vs through R4, with R3 and two inductors across them. By
    hand (KCL at their node, v = v:C1 = -v:C5): (C1 + C5) v' = f_L0 + f_L6 - v/R3 +
    (Vs - v)/R4, and f_C1 = C1 v' = C1/(C1 + C5) (...). Taken as the cutset's difference of
    large currents, the share lost ~1e-13 (180 ulps); from the state equation it is exact to
    rounding."""
    C1, C5, R3, R4 = 9.24e-06, 0.01584, 0.07192, 0.0008979
    g = Graph("share")
    for b in [("L0", "T", "n2", "n0", 0.002965), ("C1", "A", "n0", "n1", C1),
              ("Vs", "across_source", "n2", "n1"), ("R3", "D", "n0", "n1", R3),
              ("R4", "D", "n2", "n0", R4), ("C5", "A", "n1", "n0", C5),
              ("L6", "T", "n1", "n0", 50020.0)]:
        g.add_branch(*b)
    m = g.linearize(outputs=["f:C1"])
    assert m.state_names == ("f:L0", "v:C5", "f:L6")
    k = C1 / (C1 + C5)
    # a handful of roundings on either side (sums of C and 1/R, a solve, one product): 16 eps
    # leaves 8x the largest error measured (2 eps); the cutset's difference was 180 eps off.
    rtol = 16 * np.finfo(float).eps
    np.testing.assert_allclose(m.C[0], [k, k * (1 / R3 + 1 / R4), k], rtol=rtol)
    np.testing.assert_allclose(m.D[0], [k / R4], rtol=rtol)


@pytest.mark.parametrize("C0, C7", [(4.73792e-6, 713960.0), (1e-8, 1e8)])
def test_dependent_capacitor_is_the_small_one(C0, C7):
    """Three capacitors in a loop (C0 n0-n1, C7 n1-n2, C2 n2-n0), a through source across C7
    and a resistor across C2. In file order C7 (listed after C0 and C2) was the dependent one:
    its value relative to the tree's (1e16) was added to 1 and rounded the answer away (B
    off by 1.6e-5, then of the wrong sign). Reference by nodal analysis (ground n0, KCL at
    n1 and n2): v:C2 / F = C0 / (s (C0 C2 + C0 C7 + C2 C7) + (C0 + C7) / R), so the state
    v:C2 has B = C0 / (C0 C2 + C0 C7 + C2 C7)."""
    C2, R = 0.00298258, 6.102e-6
    g = Graph("tri_caps", "translational")
    for b in [("A0", "A", "n0", "n1", C0), ("A2", "A", "n2", "n0", C2),
              ("S5", "through_source", "n1", "n2"), ("A7", "A", "n1", "n2", C7),
              ("D10", "D", "n2", "n0", R)]:
        g.add_branch(*b)
    m = g.linearize(outputs=["v:A2"])
    assert "A0" in g.normal_tree().dependent
    den = C0 * C2 + C0 * C7 + C2 * C7
    k = m.state_names.index("v:A2")
    # a few roundings in forming and solving the state equation: 16 eps
    np.testing.assert_allclose(m.B[k, 0], C0 / den, rtol=16 * np.finfo(float).eps)
    for s in (1e3j, 1.0, 1e-3 + 1e2j):
        H = (m.C @ np.linalg.solve(s * np.eye(len(m.A)) - m.A, m.B) + m.D)[0, 0]
        # |dH| <= eps K with K / |H| = 2.6 here (helper analysis): 1e-12 leaves 1000x
        assert abs(H - C0 / (s * den + (C0 + C7) / R)) <= 1e-12 * abs(H), s


# ---------------------------------------------------------------------------------------------
# Random graphs against exact modified nodal analysis (rational arithmetic, real s)


def _solve_exact(M, rhs):
    """x with M x = rhs (lists of Fractions; columns of rhs as lists), Gauss-Jordan."""
    n = len(M)
    M = [row[:] + list(r) for row, r in zip(M, rhs, strict=True)]
    for i in range(n):
        p = next(r for r in range(i, n) if M[r][i] != 0)
        M[i], M[p] = M[p], M[i]
        for r in range(n):
            if r != i and M[r][i] != 0:
                f = M[r][i] / M[i][i]
                M[r] = [x - f * y for x, y in zip(M[r], M[i], strict=True)]
    return [[x / M[i][i] for x in M[i][n:]] for i in range(n)]


def _exact_transfer(branches, s, source):
    """Every branch variable per unit of ``source`` (the other sources zero) at real ``s``,
    exactly: modified nodal analysis in Fractions (admittances sC, 1/(sL), 1/R; ground the
    first node; an across source adds its current as an unknown and v_from - v_to = u)."""
    nodes = sorted({n for b in branches for n in b[2:4]})
    index = {n: i for i, n in enumerate(nodes[1:])}
    sources = [b for b in branches if b[1] == "across_source"]
    size = len(index) + len(sources)
    M = [[Fraction(0)] * size for _ in range(size)]
    rhs = [Fraction(0)] * size

    def add(row, col, value):
        if row in index and col in index:
            M[index[row]][index[col]] += value

    admittance = {}
    for name, kind, a, b, value in branches:
        if kind in ("A", "T", "D"):
            value = Fraction(value)   # the double's exact value: Fraction * float is a float
            y = s * value if kind == "A" else 1 / (s * value) if kind == "T" else 1 / value
            admittance[name] = y
            add(a, a, y), add(b, b, y), add(a, b, -y), add(b, a, -y)
        elif kind == "through_source" and name == source:   # 1 flows a -> b through it
            for node, sign in ((a, -1), (b, 1)):
                if node in index:
                    rhs[index[node]] += sign
    for k, (name, _, a, b, _) in enumerate(sources):
        col = len(index) + k
        for node, sign in ((a, 1), (b, -1)):
            if node in index:
                M[index[node]][col] += sign
                M[col][index[node]] += sign
        rhs[col] = Fraction(1 if name == source else 0)
    x = [row[0] for row in _solve_exact(M, [[r] for r in rhs])]
    pot = {n: (x[index[n]] if n in index else Fraction(0)) for n in nodes}
    out = {}
    for k, (name, kind, a, b, _) in enumerate(branches):
        v = pot[a] - pot[b]
        out[f"v:{name}"] = v
        out[f"f:{name}"] = (admittance[name] * v if name in admittance else
                            Fraction(1 if name == source else 0) if kind == "through_source"
                            else x[len(index) + sources.index(branches[k])])
    return out


def _random_graph(rng, lo, hi):
    """3-6 nodes joined by a random spanning chain and extra branches (A, T, D with values
    log-uniform in [lo, hi], 3 significant digits), one or two sources."""
    n = int(rng.integers(3, 7))
    nodes = [f"n{i}" for i in range(n)]
    pairs = [(nodes[i], nodes[int(rng.integers(0, i))]) for i in range(1, n)]
    pairs += [tuple(rng.choice(nodes, 2, replace=False)) for _ in range(int(rng.integers(1, 5)))]
    branches = []
    for k, (a, b) in enumerate(pairs):
        kind = str(rng.choice(["A", "T", "D"]))
        value = float(f"{10 ** rng.uniform(np.log10(lo), np.log10(hi)):.3g}")
        branches.append((f"{kind}{k}", kind, str(a), str(b), value))
    for k in range(int(rng.integers(1, 3))):
        a, b = rng.choice(nodes, 2, replace=False)
        kind = str(rng.choice(["across_source", "through_source"]))
        branches.append((f"S{k}", kind, str(a), str(b), None))
    return branches


def _model_transfer(m, s):
    """C (sI - A)^-1 (B + s E) + D + s F of the model's float matrices, exactly (Fractions)."""
    q = lambda a: [[Fraction(float(x)) for x in row] for row in np.atleast_2d(a)]  # noqa: E731
    n, p, k = len(m.A), len(m.C), m.B.shape[1]
    E = q(m.E) if m.E is not None else [[Fraction(0)] * k for _ in range(n)]
    F = q(m.F) if m.F is not None else [[Fraction(0)] * k for _ in range(p)]
    A, B, C, D = q(m.A), q(m.B), q(m.C), q(m.D)
    sIA = [[(s if i == j else 0) - A[i][j] for j in range(n)] for i in range(n)]
    X = _solve_exact(sIA, [[B[i][j] + s * E[i][j] for j in range(k)] for i in range(n)]) \
        if n else []
    return [[sum((C[r][i] * X[i][j] for i in range(n)), Fraction(0)) + D[r][j] + s * F[r][j]
             for j in range(k)] for r in range(p)]


@pytest.mark.parametrize("lo, hi", [(0.1, 10.0), (1e-6, 1e6)])
def test_random_graphs_against_exact_nodal_analysis(lo, hi):
    """The transfer function of every branch variable from every source, H(s) = C (sI - A)^-1
    (B + s E) + D + s F at real s > 0 (no pole there: passive networks), evaluated exactly
    from the model's float matrices, against exact rational nodal analysis. The error allowed
    is what rounding the model's entries can cause in H: |dH| <= eps K with K = |C R| |A|
    |R B'| + |C R| |B'| + |C| |R B'| + |D| + s |F| (R = (sI - A)^-1, B' = B + s E, absolute
    values entrywise), times 1000 (the entries carry a few roundings each). Graphs the
    library refuses (loops of across sources, cut-sets of through sources) are skipped."""
    rng = np.random.default_rng(7)
    checked = refused = 0
    worst = 0.0
    while checked < 40:
        branches = _random_graph(rng, lo, hi)
        g = Graph("random")
        for name, kind, a, b, value in branches:
            g.add_branch(name, kind, a, b, value)
        names = [f"{w}:{b[0]}" for b in branches for w in "vf"]
        try:
            m = g.linearize(outputs=names)
        except GraphError:
            refused += 1
            continue
        checked += 1
        n = len(m.A)
        for s in (0.37, 2.9):
            E = np.zeros_like(m.B) if m.E is None else m.E
            F = np.zeros_like(m.D) if m.F is None else m.F
            Bs = m.B + s * E
            R = np.linalg.inv(s * np.eye(n) - m.A) if n else np.zeros((0, 0))
            K = (abs(m.C @ R) @ abs(m.A) @ abs(R @ Bs) + abs(m.C @ R) @ abs(Bs)
                 + abs(m.C) @ abs(R @ Bs) + abs(m.D) + s * abs(F))
            H = _model_transfer(m, Fraction(s))
            for j, source in enumerate(m.input_names):
                exact = _exact_transfer(branches, Fraction(s), source)
                for i, name in enumerate(m.output_names):
                    err = abs(float(H[i][j] - exact[name]))
                    ratio = err / (np.finfo(float).eps * max(K[i, j], 1e-300))
                    worst = max(worst, ratio)
                    assert ratio <= 1e3, (branches, name, source, s, float(H[i][j]), exact[name])
    assert refused < checked          # the generator makes mostly valid graphs
    assert worst > 0.0                # the comparison ran


def test_a_kink_at_the_equilibrium_is_refused():
    """v for v > 0, 3 v below, at v = 0: the symmetric difference quotients averaged the two
    slopes into 2 at every step, a model of neither side (A = -2 instead of -1 or -3)."""
    g = Graph("kink")
    g.add_branch("Is", "through_source", "g", "1", input=0.0)
    g.add_branch("C", "A", "1", "g", 1.0)
    g.add_branch("Dd", "D", "1", "g", relation=lambda v: v if v > 0 else 3 * v)
    with pytest.raises(GraphError, match="a kink at v = 0.*slope is 1 on the right and 3 on "
                                         "the left"):
        g.linearize()
    # Smooth on both sides of the same point: accepted, the slope exact.
    g = Graph("smooth")
    g.add_branch("Is", "through_source", "g", "1", input=0.0)
    g.add_branch("C", "A", "1", "g", 1.0)
    g.add_branch("Dd", "D", "1", "g", relation=lambda v: 2.0 * v + v ** 3)
    assert g.linearize().A[0, 0] == pytest.approx(-2.0, rel=1e-9)


def test_nonlinear_equilibrium_far_from_zero():
    """The tank of validation/graphs/tank_orifices.toml fed 0.1 m^3/s: at equilibrium the two
    orifices (K1 + K2) sqrt(P) pass it, P = (0.1 / 3e-5)^2 = 1.1e7 Pa (110 bar), f_I = K2
    sqrt(P). The orifices' flows were solved from zero and hybr's first steps never reached
    them: 'the dissipative elements have no solution' at the exact equilibrium."""
    g = Graph.load(Path(__file__).resolve().parent.parent / "validation" / "graphs"
                   / "tank_orifices.toml")
    P = (0.1 / 3e-5) ** 2
    m = g.linearize(u0={"Qs": 0.1}, x0=[P, 2e-5 * P ** 0.5])
    x0 = m.info["operating_point"]["x0"]
    assert x0["v:C"] == pytest.approx(P, rel=1e-9)
    assert x0["f:I"] == pytest.approx(2e-5 * P ** 0.5, rel=1e-9)


def test_slope_near_the_edge_of_a_relations_domain():
    """pendulum_torque's spring, theta = arcsin(T / 0.981), held at T = 0.9809 (0.9999 of its
    range): the first stencil (1e-4) stepped past 0.981 and the point was refused as outside
    the domain. Reference: d theta / dT = 1 / (s sqrt(1 - (T/s)^2)), s = 0.981."""
    g = Graph.load(Path(__file__).resolve().parent.parent / "validation" / "graphs"
                   / "pendulum_torque.toml")
    m = g.linearize(u0={"Ts": 0.9809})
    s, T = 0.981, 0.9809
    assert m.info["incremental_values"]["K"] == pytest.approx(
        1.0 / (s * math.sqrt(1.0 - (T / s) ** 2)), rel=1e-7)


def test_zero_slope_is_named_as_such(tmp_path):
    """car_drag with the propulsion equal to the rolling resistance rests at v = 0, where
    the drag B v|v| has slope 0: it was called 'a kink or an infinite slope'."""
    g = Graph.load(Path(__file__).resolve().parent.parent / "validation" / "graphs"
                   / "car_drag.toml")
    with pytest.raises(GraphError, match="incremental conductance df/dv = 0 .* not positive"):
        g.linearize(u0={"Fp": 100, "Fr": 100})
    # a drag law B |v|^e sgn v with e = 1.3 (fluid and aerodynamic laws: 1.5 .. 2) too
    source = (Path(__file__).resolve().parent.parent / "validation" / "graphs"
              / "car_drag.toml").read_text()
    assert "exponent = 2.0" in source
    path = tmp_path / "car_drag.toml"
    path.write_text(source.replace("exponent = 2.0", "exponent = 1.3"))
    with pytest.raises(GraphError, match="incremental conductance df/dv = 0"):
        Graph.load(path).linearize(u0={"Fp": 100, "Fr": 100})

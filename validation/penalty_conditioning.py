"""Penalty formulation over alpha = 1e3 ... 1e16: plain float64 assembly against pinlin's.

For each mechanism and alpha: the largest relative error of the physical eigenvalues against
the independent-coordinate model, (a) from plain assembly (A = [[0, I], [-M_p^-1 K_p,
-M_p^-1 C_p]] with M_p = M + alpha G^T G solved by Cholesky), (b) from pinlin's penalty model
(block elimination in the nullspace/range split of G, pinlin.formulations.constrained), and the
largest spurious real part of a physical eigenvalue (the true penalty model is dissipative: its
physical eigenvalues have Re <= 0; a positive real part above rounding is a false instability).
The penalty error itself is c / alpha; an error above it is rounding.

Usage: python validation/penalty_conditioning.py
Writes validation/reports/penalty_conditioning.md.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

import pinlin
from pinlin.files import write_text_atomic
from pinlin.formulations.constrained import first_order
from pinlin.scene import bundled_scenes

REPORT = Path(__file__).resolve().parent / "reports" / "penalty_conditioning.md"
ALPHAS = [10.0 ** k for k in range(3, 17)]
SYSTEMS = ("four_bar", "slider_crank", "five_bar", "delta")


def physical(lam: np.ndarray, ref: np.ndarray) -> np.ndarray:
    """The eigenvalues of lam closest to each reference eigenvalue (greedy, without reuse)."""
    pool = list(lam)
    out = []
    for r in ref:
        k = int(np.argmin([abs(x - r) for x in pool]))
        out.append(pool.pop(k))
    return np.array(out)


def main() -> None:
    rows = []
    for name in SYSTEMS:
        scene = pinlin.Scene.load(bundled_scenes()[name])
        ref = np.linalg.eigvals(pinlin.linearize(scene).A)
        for alpha in ALPHAS:
            model = pinlin.linearize(scene, formulation="penalty", alpha=alpha)
            ours = physical(np.linalg.eigvals(model.A), ref)
            try:
                A_plain, _ = first_order(model.M, model.C_damp, model.K, model.Bu)
                plain = physical(np.linalg.eigvals(A_plain), ref)
                err_plain = float(np.max(np.abs(plain - ref) / np.abs(ref)))
                re_plain = float(plain.real.max())
            except pinlin.PinlinError:
                err_plain, re_plain = float("nan"), float("nan")
            err = float(np.max(np.abs(ours - ref) / np.abs(ref)))
            rows.append((name, alpha, err_plain, err, re_plain, float(ours.real.max())))
    lines = [
        "# Penalty formulation: conditioning over alpha",
        "",
        "Produced by `python validation/penalty_conditioning.py` (mu = 1, Omega = 10 rad/s). "
        "Errors: largest relative error of the physical eigenvalues against the independent-"
        "coordinate model; the penalty error itself is c / alpha. 'Re max': the largest real "
        "part among the physical eigenvalues (the penalty model is dissipative, so a positive "
        "value is a spurious instability). Plain: A from M + alpha G^T G by Cholesky. pinlin: "
        "block elimination in the nullspace/range split of G = Phi_q (the penalty terms live "
        "only in the constrained block as alpha S^2 with S the singular values of G, and every "
        "solve involves O(1) quantities), see `pinlin.formulations.constrained."
        "penalty_first_order`.",
        "",
        "| system | alpha | error, plain | error, pinlin | Re max, plain | Re max, pinlin |",
        "|---|---|---|---|---|---|",
    ]
    for name, alpha, ep, e, rp, r in rows:
        lines.append(f"| {name} | {alpha:.0e} | {ep:.1e} | {e:.1e} | {rp:+.1e} | {r:+.1e} |")
    REPORT.parent.mkdir(parents=True, exist_ok=True)
    write_text_atomic(REPORT, "\n".join(lines) + "\n")
    print("\n".join(lines))


if __name__ == "__main__":
    main()

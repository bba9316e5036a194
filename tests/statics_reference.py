"""References for the least-norm split of a standing robot's or mechanism's statics, from
Pinocchio's bodies directly (not from pinlin)."""

from __future__ import annotations

import numpy as np
import pinocchio as pin


def radius_of_gyration(model: pin.Model, q: np.ndarray) -> float:
    """sqrt(sum_i (tr I_i + 2 m_i |c_i - c|^2) / (2 m)) [m] at ``q``: each body's rotational
    inertia about its own centre of mass (its trace does not depend on the axes), moved to
    the common centre of mass c by the parallel-axis theorem (which adds 2 m_i |c_i - c|^2 to
    the trace), over twice the total mass."""
    data = model.createData()
    pin.forwardKinematics(model, data, q)
    masses, centres, traces = [], [], []
    for i in range(1, model.njoints):
        body = model.inertias[i]
        masses.append(body.mass)
        centres.append(data.oMi[i].act(body.lever))
        traces.append(np.trace(body.inertia))
    m = np.array(masses)
    c = np.array(centres)
    centre = m @ c / m.sum()
    return float(np.sqrt((sum(traces) + 2.0 * m @ ((c - centre) ** 2).sum(axis=1))
                         / (2.0 * m.sum())))


def weighted_orthogonality(family: np.ndarray, x: np.ndarray, weights: np.ndarray) -> float:
    """max |N^T W^2 x| / |W x|_max: zero (to rounding) exactly when x is the member of least
    |W x| in its family x + N c (N = ``family``, an orthonormal basis of the directions;
    W = diag(``weights``)): the minimizer's W x is orthogonal to W N."""
    wx = weights * x
    return float(np.abs(family.T @ (weights * wx)).max() / np.abs(wx).max())

"""A configuration-free upper bound on the diagonal of M(q), so that a batch of points can tell
cheaply where M may be singular to working precision.

:meth:`pinlin.System.mass_inverse` refuses M(q) when the condition of Ms = D^-1/2 M D^-1/2
(D = diag M) reaches :func:`pinlin.conditioning.refuse_condition` (0.1 / (n eps)); it first
tries the bound cond_2(Ms) <= tr(Ms) tr(Ms^-1) = n sum_i M_ii (M^-1)_ii (the eigenvalues of the
positive definite Ms are positive: the largest is below their sum tr(Ms) = n, and 1 / the
smallest is below tr(Ms^-1) = sum_i M_ii (M^-1)_ii). A batch has diag(M^-1) from
``computeABADerivatives`` but not M. With b_i >= M_ii(q) for every q (this module),

    cond_2(Ms) <= n sum_i M_ii (M^-1)_ii <= n sum_i b_i (M^-1)_ii,

so a point whose right-hand side stays below the limit is one that ``mass_inverse`` accepts
(its own first test passes), and only points where it reaches the limit need the exact check
(:func:`pinlin.batch.check` then runs ``mass_inverse`` there).

**The bound.** M_ii = S_i^T I^c_i S_i + armature_i, with I^c_i the composite spatial inertia
of the bodies b that joint i carries (its subtree) and S_i its unit motion axis. For a
translation (a prismatic joint; the linear coordinates of a free flyer or planar joint, in
their local frame) M_ii = armature_i + sum_b m_b exactly, whatever q. For a rotation about a
unit axis a through the joint's origin o (revolute and continuous joints; angular coordinates
of free-flyer, spherical and planar joints)

    M_ii = armature_i + sum_b [m_b |a x (c_b - o)|^2 + a^T I_b a]
        <= armature_i + sum_b [m_b r_b^2 + lambda_max(I_b)],

I_b the rotational inertia about b's centre of mass c_b, and r_b >= |c_b - o| for every q:
the triangle inequality along the chain from joint i to b, r_b = sum_j |t_j| + |c_b^local|
over the joints j below i on the path to b (t_j: j's fixed placement in its parent [m]),
plus |q_j| for a prismatic joint j on the path (its largest value over the points checked:
the bound then holds for those points). Rotations do not change lengths, so no angle enters.
A joint type not listed here (helical, universal, composite, mimic), or a floating or planar
joint below i on a path, makes b_i = inf for the coordinates above it: those points are always
checked exactly (correct, only slower).
"""

from __future__ import annotations

import weakref
from typing import NamedTuple

import numpy as np

_ROTATION = ("JointModelR",)  # RX, RY, RZ, RevoluteUnaligned, RUBX... (continuous)
_TRANSLATION = ("JointModelP",)  # PX, PY, PZ, PrismaticUnaligned (not Planar: listed below)


class _Bound(NamedTuple):
    """b_i = base_i + sum_b m_b (fixed_ib + sum_j paths_ibj qmax_j)^2 over bodies b."""

    base: np.ndarray        # (nv,) armature + mass or armature + sum lambda_max(I_b)
    mass: np.ndarray        # (nv, nb) m_b where b is carried by a rotation coordinate, else 0
    fixed: np.ndarray       # (nv, nb) the q-free part of r_b [m]
    paths: np.ndarray       # (nv, nb, np) 1 where prismatic joint p lies on the path
    prismatic_q: np.ndarray  # (np,) configuration index of each prismatic joint


#: Relative margin on b for the rounding of M's diagonal as ``crba`` sums it (n eps |M_ii|,
#: n <= ~100 bodies): where b_i equals M_ii in exact arithmetic (translations), the computed
#: M_ii may exceed it by that much.
ROUNDING = 1e-12

_CACHE: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()


def _kind(joint) -> str:
    name = joint.shortname()
    if name.startswith("JointModelPlanar"):
        return "planar"
    if name.startswith(_ROTATION):
        return "rotation"
    if name.startswith(_TRANSLATION):
        return "translation"
    if name == "JointModelFreeFlyer":
        return "free"
    if name.startswith("JointModelSpherical"):
        return "spherical"
    return "other"


def _build(model) -> _Bound:
    nv, nj = model.nv, model.njoints
    kinds = [_kind(model.joints[j]) for j in range(nj)]
    prismatic = [j for j in range(1, nj) if kinds[j] == "translation"]
    column = {j: c for c, j in enumerate(prismatic)}
    mass = np.zeros((nv, nj))
    fixed = np.zeros((nv, nj))
    paths = np.zeros((nv, nj, len(prismatic)))
    base = np.array(model.armature, dtype=float)
    for i in range(1, nj):
        joint = model.joints[i]
        lin, ang = _axes(kinds[i], joint.nv)
        subtree = list(model.subtrees[i])
        total = sum(model.inertias[b].mass for b in subtree)
        for k in lin:
            base[joint.idx_v + k] += total
        if not ang:
            continue
        reach = np.zeros(nj)
        through = np.zeros((nj, len(prismatic)))
        finite = np.ones(nj, dtype=bool)
        for b in subtree:  # parents come first in Pinocchio's joint order
            if b != i:
                p = model.parents[b]
                reach[b] = reach[p] + np.linalg.norm(model.jointPlacements[b].translation)
                through[b] = through[p]
                finite[b] = finite[p] and kinds[b] in ("rotation", "translation",
                                                       "spherical")
                if kinds[b] == "translation":
                    through[b, column[b]] = 1.0
        for b in subtree:
            inertia = model.inertias[b]
            r = reach[b] + np.linalg.norm(inertia.lever)
            lam = float(np.linalg.eigvalsh(inertia.inertia)[-1]) if inertia.mass or \
                np.any(inertia.inertia) else 0.0
            for k in ang:
                c = joint.idx_v + k
                if not finite[b]:
                    base[c] = np.inf
                base[c] += lam
                mass[c, b] = inertia.mass
                fixed[c, b] = r
                paths[c, b] = through[b]
    if "other" in kinds[1:]:
        for i in range(1, nj):
            if kinds[i] == "other":
                j = model.joints[i]
                base[j.idx_v:j.idx_v + j.nv] = np.inf
                for a in _ancestors(model, i):  # what carries an unknown joint
                    aj = model.joints[a]
                    base[aj.idx_v:aj.idx_v + aj.nv] = np.inf
    q_index = np.array([model.joints[j].idx_q for j in prismatic], dtype=int)
    return _Bound(base, mass, fixed, paths, q_index)


def _axes(kind: str, nv: int) -> tuple[tuple[int, ...], tuple[int, ...]]:
    """(translation coordinates, rotation coordinates) of a joint, local indices."""
    return {"rotation": ((), (0,)), "translation": ((0,), ()), "free": ((0, 1, 2), (3, 4, 5)),
            "spherical": ((), (0, 1, 2)), "planar": ((0, 1), (2,))}.get(
        kind, ((), tuple(range(nv))))


def _ancestors(model, i: int) -> list[int]:
    out, j = [], model.parents[i]
    while j > 0:
        out.append(j)
        j = model.parents[j]
    return out


def diagonal_bound(system, Q: np.ndarray) -> np.ndarray:
    """b (nv,) with b_i >= M_ii(q) for every configuration q of ``Q`` (N, nq) (module
    docstring) [kg or kg*m^2]; inf where no finite bound is derived."""
    plan = _CACHE.get(system)
    if plan is None:
        plan = _CACHE[system] = _build(system.model)
    r = plan.fixed
    if plan.prismatic_q.size and len(Q):
        qmax = np.abs(Q[:, plan.prismatic_q]).max(axis=0)
        r = r + plan.paths @ qmax
    return (plan.base + np.einsum("ib,ib->i", plan.mass, r * r)) * (1.0 + ROUNDING)


def suspect(bound: np.ndarray, minv_diag: np.ndarray, limit: float) -> np.ndarray:
    """Points (rows of ``minv_diag``, diag(M^-1) per point) where M may be singular to working
    precision: n sum_i b_i (M^-1)_ii >= ``limit`` (the refusal condition), or a diagonal of
    M^-1 that is not positive (NaN included)."""
    n = minv_diag.shape[1]
    with np.errstate(invalid="ignore", over="ignore"):
        estimate = n * (minv_diag @ bound)
    return ~((estimate < limit) & (minv_diag.min(axis=1, initial=np.inf) > 0.0))


def may_warn(bound: np.ndarray, minv_diag: np.ndarray, threshold: float) -> np.ndarray:
    """Points where the single call's condition estimate tr(M) tr(M^-1) / n may exceed
    ``threshold`` (its AccuracyWarning): sum_i b_i sum_i (M^-1)_ii / n bounds it from above
    (b_i >= M_ii), so no point that warns is missed; :func:`pinlin.batch.check` computes the
    estimate itself where this says it may."""
    n = minv_diag.shape[1]
    with np.errstate(invalid="ignore", over="ignore"):
        return bound.sum() * minv_diag.sum(axis=1) / max(n, 1) > threshold


__all__ = ["ROUNDING", "diagonal_bound", "may_warn", "suspect"]

"""Shared helpers. References here never call pinlin: they use pin.aba / pin.integrate only."""

from __future__ import annotations

import contextlib
import signal
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest

REPO = Path(__file__).resolve().parent.parent
URDF_DIR = REPO / "urdf"


def aba_jacobians(model: pin.Model, q0: np.ndarray, tau0: np.ndarray, S: np.ndarray,
                  extra_tau=None, h: float = 1e-6, h_u: float | None = None
                  ) -> tuple[np.ndarray, np.ndarray]:
    """Central finite differences of x' = [v; aba(q, v, tau0 + S u + extra_tau(q, v))] at
    (q0, v = 0, u = 0), perturbing q on the manifold with pin.integrate. Returns (A, B).

    ``h_u`` (default ``h``) is the input step: aba is linear in u, so a large one (1 N*m) has
    no truncation error and a rounding error of only ~eps |a| per unit input."""
    nv = model.nv
    data = model.createData()
    extra = extra_tau or (lambda q, v: 0.0)

    def f(dq, v, du):
        q = pin.integrate(model, q0, dq)
        return pin.aba(model, data, q, v, tau0 + S @ du + extra(q, v)).copy()

    z, zu = np.zeros(nv), np.zeros(S.shape[1])
    A = np.zeros((2 * nv, 2 * nv))
    A[:nv, nv:] = np.eye(nv)
    B = np.zeros((2 * nv, S.shape[1]))
    for j in range(nv):
        e = np.zeros(nv)
        e[j] = h
        A[nv:, j] = (f(e, z, zu) - f(-e, z, zu)) / (2 * h)
        A[nv:, nv + j] = (f(z, e, zu) - f(z, -e, zu)) / (2 * h)
    hu = h if h_u is None else h_u
    for j in range(S.shape[1]):
        e = np.zeros(S.shape[1])
        e[j] = hu
        B[nv:, j] = (f(z, z, e) - f(z, z, -e)) / (2 * hu)
    return A, B


def rel_err(a: np.ndarray, b: np.ndarray) -> float:
    """max |a - b| / max(1, max |b|)."""
    return float(np.abs(a - b).max() / max(1.0, np.abs(b).max()))


@pytest.fixture
def write_scene(tmp_path):
    """Write a scene TOML (and optional files) into a temporary folder; returns its path."""

    def _write(text: str, name: str = "scene.toml", **files: str) -> Path:
        for fname, content in files.items():
            (tmp_path / fname.replace("__", ".")).write_text(content)
        path = tmp_path / name
        path.write_text(text)
        return path

    return _write


@contextlib.contextmanager
def deadline(seconds: int):
    """Fail (TimeoutError) instead of hanging past ``seconds`` (SIGALRM; POSIX only)."""
    if not hasattr(signal, "SIGALRM"):
        yield
        return

    def expire(*_):
        raise TimeoutError(f"still running after {seconds} s")

    previous = signal.signal(signal.SIGALRM, expire)
    signal.alarm(seconds)
    try:
        yield
    finally:
        signal.alarm(0)
        signal.signal(signal.SIGALRM, previous)

"""The view a mode picture is drawn in: an orthographic projection on the plane in which the
mode's stick figure moves most (:func:`best_view`), used by :mod:`pinlin.mode_pictures` (the
plane of each panel) and :mod:`pinlin.html_report` (the starting view of the 3-D figure)."""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from .stick_figure import AXIS_LENGTH

if TYPE_CHECKING:
    from .stick_figure import ModeMotion


@dataclass(frozen=True)
class View:
    """An orthographic view: screen axes ``right`` and ``up`` and the ``normal`` towards the
    viewer (unit vectors, right x up = normal), with axis labels."""

    right: np.ndarray
    up: np.ndarray
    normal: np.ndarray

    def project(self, points: np.ndarray) -> np.ndarray:
        """Screen coordinates (..., 2) [m] of points (..., 3) [m]."""
        return np.stack([points @ self.right, points @ self.up], axis=-1)

    @property
    def labels(self) -> tuple[str, str]:
        """Axis labels: ``"x [m]"`` for a world axis, else the direction's components."""
        return _axis_label(self.right), _axis_label(self.up)


def _axis_label(u: np.ndarray) -> str:
    for k, name in enumerate("xyz"):
        if abs(u[k]) > 1 - 1e-9:
            return f"{'-' if u[k] < 0 else ''}{name} [m]"
    shown = np.round(u, 2) + 0.0  # no "-0.00"
    return f"({shown[0]:.2f}, {shown[1]:.2f}, {shown[2]:.2f}) [m]"


def best_view(motion: ModeMotion) -> View:
    """The plane of largest displacement: the two principal directions of the displacements of
    the figure's marks (points and axis tips) over the drawn phases; where the motion is along
    one line (or none), the plane through it that shows the rest figure's largest spread. The
    normal snaps to a world axis within 1e-6; ``up`` is world z projected into the plane where
    that is well defined, so that gravity points down the page."""
    rest = motion.rest
    length = AXIS_LENGTH * rest.size
    base = rest.marks(length)
    d = np.vstack([f.marks(length) - base for f in motion.figures] or [np.zeros((1, 3))])
    w, V = np.linalg.eigh(d.T @ d)          # ascending
    spread = rest.points - rest.points.mean(axis=0)
    if w[2] <= 1e-24 * max(rest.size, 1.0) ** 2 * len(d):
        normal = np.linalg.eigh(spread.T @ spread)[1][:, 0]        # the figure's own plane
    elif w[1] <= 1e-6 * w[2]:
        e1 = V[:, 2]
        P = np.eye(3) - np.outer(e1, e1)
        ws, Vs = np.linalg.eigh(P @ spread.T @ spread @ P)
        e2 = Vs[:, 2] if ws[2] > 1e-12 * max(rest.size, 1.0) ** 2 else _perpendicular(e1)
        normal = np.cross(e1, e2)
    else:
        normal = V[:, 0]
    normal = normal / np.linalg.norm(normal)
    k = int(np.argmax(np.abs(normal)))
    if abs(normal[k]) > 1 - 1e-6:
        normal = np.zeros(3)
        normal[k] = 1.0
    z = np.array([0.0, 0.0, 1.0])
    up = z - (z @ normal) * normal
    if np.linalg.norm(up) < 0.3:            # looking along z: y up, x right
        y = np.array([0.0, 1.0, 0.0])
        up = y - (y @ normal) * normal
    up /= np.linalg.norm(up)
    # Look from the side that keeps "right" towards +x, +y (a front view of x-z is from -y).
    right = np.cross(up, normal)
    if right[int(np.argmax(np.abs(right)))] < 0:
        normal = -normal
        right = -right
    return View(right, up, normal)


def _perpendicular(u: np.ndarray) -> np.ndarray:
    k = int(np.argmin(np.abs(u)))
    e = np.zeros(3)
    e[k] = 1.0
    v = e - (e @ u) * u
    return v / np.linalg.norm(v)


__all__ = ["View", "best_view"]

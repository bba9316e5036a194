"""Reading URDF files into Pinocchio models, with errors that name the file and the element.

urdfdom (inside Pinocchio) prints its parse errors straight to the C-level stderr and then raises
a vague ``ValueError``. This module checks the XML first with the standard library, captures what
urdfdom prints, and turns both into one-line :class:`~pinlin.exceptions.UrdfError` messages.
"""

from __future__ import annotations

import contextlib
import math
import os
import sys
import tempfile
import xml.etree.ElementTree as ET
from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pinocchio as pin

from .exceptions import UrdfError


@contextlib.contextmanager
def quiet_stderr() -> Iterator[list[str]]:
    """Capture what C/C++ code writes to file descriptor 2 while the block runs.

    Yields a list that receives the captured text (one string) when the block exits.
    """
    captured: list[str] = []
    try:
        fd = sys.stderr.fileno()
    except (AttributeError, OSError, ValueError):  # no real stderr (e.g. some test runners)
        yield captured
        return
    sys.stderr.flush()
    saved = os.dup(fd)
    with tempfile.TemporaryFile(mode="w+b") as tmp:
        os.dup2(tmp.fileno(), fd)
        try:
            yield captured
        finally:
            sys.stderr.flush()
            os.dup2(saved, fd)
            os.close(saved)
            tmp.seek(0)
            captured.append(tmp.read().decode(errors="replace"))


def _first_error_line(text: str) -> str:
    for line in text.splitlines():
        line = line.strip()
        if line.startswith("Error:"):
            return line[len("Error:"):].strip()
    return ""


def _check_inertials(path: Path, root: ET.Element) -> None:
    """Reject masses and inertia tensors that no physical body has."""
    for link in root.iter("link"):
        inertial = link.find("inertial")
        if inertial is None:
            continue
        name = link.get("name", "?")
        mass_el = inertial.find("mass")
        if mass_el is not None:
            try:
                mass = float(mass_el.get("value", "nan"))
            except ValueError:
                raise UrdfError(path, f"link '{name}': mass value is not a number") from None
            if not math.isfinite(mass) or mass < 0.0:
                raise UrdfError(path, f"link '{name}': mass must be a finite number >= 0 [kg], "
                                      f"got {mass_el.get('value')}")
        inertia_el = inertial.find("inertia")
        if inertia_el is None:
            continue
        keys = ("ixx", "ixy", "ixz", "iyy", "iyz", "izz")
        try:
            v = {k: float(inertia_el.get(k, "0")) for k in keys}
        except ValueError:
            raise UrdfError(path, f"link '{name}': inertia entries must be numbers") from None
        inertia = np.array([[v["ixx"], v["ixy"], v["ixz"]],
                            [v["ixy"], v["iyy"], v["iyz"]],
                            [v["ixz"], v["iyz"], v["izz"]]])
        if not np.all(np.isfinite(inertia)):
            raise UrdfError(path, f"link '{name}': inertia entries must be finite")
        eig = np.linalg.eigvalsh(inertia)
        scale = max(1.0, float(np.abs(eig).max()))
        if eig[0] < -1e-12 * scale:
            raise UrdfError(path, f"link '{name}': inertia tensor is not positive semi-definite "
                                  f"(principal moments {np.array2string(eig, precision=3)} kg*m^2)")
        # Principal moments of a real body satisfy the triangle inequality.
        if eig[2] > eig[0] + eig[1] + 1e-9 * scale:
            raise UrdfError(path, f"link '{name}': principal moments "
                                  f"{np.array2string(eig, precision=3)} kg*m^2 violate the "
                                  "triangle inequality I3 <= I1 + I2 (no physical body has them)")


def load_urdf(path: str | Path, *, free_flyer: bool) -> pin.Model:
    """Build a Pinocchio model from a URDF file.

    Args:
        path: URDF file.
        free_flyer: Add a free-flyer root joint named ``root_joint`` (floating base).

    Raises:
        UrdfError: the file is missing, is not well-formed XML, is not a URDF, or has a link with
            a negative mass or a non-physical inertia tensor.
    """
    path = Path(path)
    if not path.is_file():
        raise UrdfError(path, "file not found")
    try:
        root = ET.parse(path).getroot()
    except ET.ParseError as exc:
        raise UrdfError(path, f"malformed XML: {exc}") from None
    if root.tag != "robot":
        raise UrdfError(path, f"root element must be <robot>, got <{root.tag}>")
    _check_inertials(path, root)
    with quiet_stderr() as captured:
        try:
            if free_flyer:
                model = pin.buildModelFromUrdf(str(path), pin.JointModelFreeFlyer())
            else:
                model = pin.buildModelFromUrdf(str(path))
        except (ValueError, RuntimeError) as exc:
            failure: Exception | None = exc
        else:
            failure = None
    if failure is not None:
        detail = _first_error_line(captured[0] if captured else "") or str(failure).splitlines()[0]
        raise UrdfError(path, f"not a valid URDF model: {detail}")
    return model

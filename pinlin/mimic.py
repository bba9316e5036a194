"""URDF ``<mimic>`` couplings, q_mimic = multiplier q_joint + offset, read from the file
(pinlin builds the Pinocchio model with mimic joints as joints of their own): the constraint set
turns them into constraint rows (``effects.mimic``), the MuJoCo export into equality
constraints."""

from __future__ import annotations

import xml.etree.ElementTree as ET
from dataclasses import dataclass
from pathlib import Path

from .exceptions import UrdfError


@dataclass(frozen=True)
class MimicCoupling:
    """q_mimic = multiplier * q_joint + offset, from a URDF ``<mimic>`` tag."""

    mimic: str
    joint: str
    multiplier: float
    offset: float


def read_mimic_tags(urdf: Path) -> tuple[MimicCoupling, ...]:
    """The ``<mimic>`` couplings of a URDF file, in file order."""
    try:
        root = ET.parse(urdf).getroot()
    except ET.ParseError as exc:
        raise UrdfError(urdf, f"malformed XML: {exc}") from None
    out = []
    for joint in root.findall("joint"):  # not <transmission><joint>
        tag = joint.find("mimic")
        if tag is None:
            continue
        try:
            out.append(MimicCoupling(joint.get("name", ""), tag.get("joint", ""),
                                     float(tag.get("multiplier", 1.0)),
                                     float(tag.get("offset", 0.0))))
        except ValueError:
            raise UrdfError(urdf, f"joint '{joint.get('name')}': <mimic> multiplier and offset "
                                  "must be numbers") from None
    return tuple(out)

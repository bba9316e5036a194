"""Closures a URDF tree cannot express, as a scene lists them: ``[[loops]]`` between two frames
of the robot and ``[[contacts]]`` that hold a frame where it is in the world.

A loop joins two frames (``point``: their origins coincide, 3 rows; ``weld``: the frames
coincide, 6 rows). A contact is a loop whose second frame is the world, at the place the first
frame occupies at the scene's posture (the anchor, see :mod:`pinlin.constraints`): a ``point``
contact (a foot's tip, 3 rows) or a ``weld`` (a flat foot, 6 rows). Names are unique across
loops and contacts: they name the constraint rows (``<loop>.x``, ``contact:<contact>.x``) and
the contact forces.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from .exceptions import SceneError
from .fields import Source, check_keys, string, table

LOOP_TYPES = ("point", "weld")
CONTACT_TYPES = LOOP_TYPES
LOOP_KEYS = ("name", "type", "frame1", "frame2")
CONTACT_KEYS = ("name", "type", "frame")


@dataclass(frozen=True)
class Loop:
    """A loop closure between two frames of the URDF tree.

    Attributes:
        name: Loop name (used in constraint-force and note names).
        type: ``"point"``: the frame origins coincide (3 rows); ``"weld"``: the frames coincide
            (origins and orientations, 6 rows).
        frame1, frame2: URDF frame (link) names.
    """

    name: str
    type: str
    frame1: str
    frame2: str

    def __post_init__(self) -> None:   # a Loop built in Python is checked as the file's
        string(None, "loops.name", self.name)
        string(None, f"loops.{self.name}.type", self.type, LOOP_TYPES)
        for key in ("frame1", "frame2"):
            string(None, f"loops.{self.name}.{key}", getattr(self, key))
        if self.frame1 == self.frame2:
            raise SceneError(None, f"loops.{self.name}.frame2", "must differ from frame1")


@dataclass(frozen=True)
class Contact:
    """A frame held where it is in the world at the scene's posture (feet on the ground).

    Attributes:
        name: Contact name (constraint rows ``contact:<name>.x`` ..., and the key of
            ``OperatingPoint.contact_forces``).
        type: ``"point"``: the frame origin stays at its anchor (3 rows; a foot's tip);
            ``"weld"``: the whole frame stays (origin and orientation, 6 rows; a flat foot).
        frame: URDF frame (link) name; it must move with some joint (not be fixed to the
            world).
    """

    name: str
    type: str
    frame: str

    def __post_init__(self) -> None:   # a Contact built in Python is checked as the file's
        string(None, "contacts.name", self.name)
        string(None, f"contacts.{self.name}.type", self.type, CONTACT_TYPES)
        string(None, f"contacts.{self.name}.frame", self.frame)


def _entries(src: Source, key: str, x: Any) -> list[Any]:
    if not isinstance(x, list | tuple):
        raise SceneError(src, key, f"expected an array of tables ([[{key}]])")
    return list(x)


def parse_loops(src: Source, x: Any) -> tuple[Loop, ...]:
    """The ``[[loops]]`` array, checked: keys, frame names as strings, distinct frames,
    unique names, type ``point`` (default) or ``weld``."""
    loops: list[Loop] = []
    for i, entry in enumerate(_entries(src, "loops", x)):
        fld = f"loops[{i}]"
        spec = table(src, fld, entry)
        check_keys(src, fld, spec, LOOP_KEYS)
        for key in ("frame1", "frame2"):
            if key not in spec:
                raise SceneError(src, f"{fld}.{key}", "missing; expected a frame (link) name")
        name = string(src, f"{fld}.name", spec.get("name", f"loop{i}"))
        if any(lp.name == name for lp in loops):
            raise SceneError(src, f"{fld}.name", f"loop name '{name}' is used twice")
        f1 = string(src, f"{fld}.frame1", spec["frame1"])
        f2 = string(src, f"{fld}.frame2", spec["frame2"])
        if f1 == f2:
            raise SceneError(src, f"{fld}.frame2", "must differ from frame1")
        loops.append(Loop(name, string(src, f"{fld}.type", spec.get("type", "point"),
                                       LOOP_TYPES), f1, f2))
    return tuple(loops)


def parse_contacts(src: Source, x: Any, loops: tuple[Loop, ...] = ()) -> tuple[Contact, ...]:
    """The ``[[contacts]]`` array, checked: keys, the frame name, type ``point`` (default) or
    ``weld``, names unique among the contacts and the ``loops``. (That the frame exists and
    moves is checked against the robot when the system is built.)"""
    contacts: list[Contact] = []
    taken = {lp.name: f"a loop's (loops[{k}])" for k, lp in enumerate(loops)}
    for i, entry in enumerate(_entries(src, "contacts", x)):
        fld = f"contacts[{i}]"
        spec = table(src, fld, entry)
        check_keys(src, fld, spec, CONTACT_KEYS)
        if "frame" not in spec:
            raise SceneError(src, f"{fld}.frame", "missing; expected a frame (link) name")
        name = string(src, f"{fld}.name", spec.get("name", f"contact{i}"))
        if name in taken:
            raise SceneError(src, f"{fld}.name", f"name '{name}' is already {taken[name]} "
                                                 "name; loops and contacts need distinct names")
        taken[name] = f"contacts[{i}]'s"
        kind = string(src, f"{fld}.type", spec.get("type", "point"), CONTACT_TYPES)
        contacts.append(Contact(name, kind, string(src, f"{fld}.frame", spec["frame"])))
    return tuple(contacts)

"""URDF links whose inertia MuJoCo refuses on its own, merged into bodies as Pinocchio merges them.

MuJoCo checks every URDF link's inertial as it compiles, before it fuses static bodies (so
``fusestatic`` does not help): positive principal moments, the triangle inequality A + B >= C,
and mass and inertia above mjMINVAL (1e-15) on every moving body. Many URDFs keep a placeholder
link whose fixed children carry the real mass (anymal's ``base``: mass 1e-6 and an inertia with
zero eigenvalues, its 16.8 kg in the fixed child ``base_inertia``), or fixed sensor links with
unphysical inertias. Pinocchio merges every fixed child into its parent body, and those merged
bodies are physical.

MuJoCo's own URDF import is kept wherever it compiles (it checks pinlin's parsing of the file
independently). Only when MuJoCo refuses a link, and only for that link, its inertial is moved
in the imported :class:`mujoco.MjSpec` (kinematics, names, frames and sites stay MuJoCo's):

- a link welded by fixed joints to a moving link: its inertial joins that link's, which is
  Pinocchio's body (the link stays as a massless body, so frames and sites on it and its
  children are untouched);
- a moving link (a joint or the free base): the inertials of the links welded to it join its own,
  which is the body Pinocchio simulates;
- a link welded to the world: its inertial is dropped; it never moves (Pinocchio's universe).

Inertials are combined by the parallel-axis theorem in the parent body's frame:
m = sum m_i, c = sum m_i c_i / m, I = sum [R_i I_i R_i^T + m_i (|d_i|^2 E - d_i d_i^T)] with
d_i = c_i - c. This is repeated, one refused link at a time, until MuJoCo compiles the model or
refuses a moving link that nothing can be merged into; that refusal names the link, its mass,
its principal moments and what to change in the URDF.
"""

from __future__ import annotations

import re
from dataclasses import dataclass

import mujoco
import numpy as np

_ELEMENT = re.compile(r"Element name '(?P<name>[^']*)', id (?P<id>\d+)")
_INERTIA_ERRORS = ("inertia", "mass")


@dataclass(frozen=True)
class Merge:
    """One link's inertial moved into another body: ``link`` into ``into`` ("world": dropped),
    because MuJoCo refused the inertia of link ``refused`` (``link`` itself or its body)."""

    link: str
    into: str
    mass: float
    refused: str

    def describe(self) -> str:
        if self.into == "world":
            return f"{self.link} -> world (welded to it, never moves: {self.mass:.3g} kg dropped)"
        return f"{self.link} -> {self.into} ({self.mass:.3g} kg)"


class UnrepresentableBodyError(Exception):
    """A moving link MuJoCo refuses with nothing to merge it with (message: what to change)."""


def refused_link(message: str) -> str | None:
    """The name of the link a MuJoCo compile error refuses for its inertia, else None."""
    m = _ELEMENT.search(message)
    if m is None or not any(word in message for word in _INERTIA_ERRORS):
        return None
    return m["name"]


def _rotation(quat) -> np.ndarray:
    q = np.asarray(quat, dtype=float)
    R = np.zeros(9)
    mujoco.mju_quat2Mat(R, q / np.linalg.norm(q))
    return R.reshape(3, 3)


def inertial(body) -> tuple[float, np.ndarray, np.ndarray]:
    """(mass [kg], centre of mass [m], inertia about it [kg m^2]) of a spec body, in its frame."""
    if not body.explicitinertial:
        return 0.0, np.zeros(3), np.zeros((3, 3))
    full = np.asarray(body.fullinertia, dtype=float)
    if np.isnan(full[0]):
        F = np.diag(np.asarray(body.inertia, dtype=float))
    else:
        F = np.array([[full[0], full[3], full[4]],
                      [full[3], full[1], full[5]],
                      [full[4], full[5], full[2]]])
    R = _rotation(body.iquat)
    return float(body.mass), np.array(body.ipos, dtype=float), R @ F @ R.T


def combine(parts: list[tuple[float, np.ndarray, np.ndarray]]
            ) -> tuple[float, np.ndarray, np.ndarray]:
    """Inertials (mass, centre, inertia about the centre), all in one frame, as one (parallel-axis
    theorem); massless parts add their rotational inertia only."""
    m = sum(p[0] for p in parts)
    c = sum(p[0] * p[1] for p in parts) / m if m > 0 else np.zeros(3)
    inertia = np.zeros((3, 3))
    for mi, ci, Ii in parts:
        d = ci - c
        inertia += Ii + mi * (float(d @ d) * np.eye(3) - np.outer(d, d))
    return m, c, inertia


def _set(body, m: float, c: np.ndarray, inertia: np.ndarray) -> None:
    body.mass = m
    body.ipos = c
    body.iquat = [1.0, 0.0, 0.0, 0.0]
    body.inertia = [0.0, 0.0, 0.0]
    body.fullinertia = [inertia[0, 0], inertia[1, 1], inertia[2, 2],
                        inertia[0, 1], inertia[0, 2], inertia[1, 2]]
    body.explicitinertial = True


def _clear(body) -> None:
    body.mass = 0.0
    body.ipos = [0.0, 0.0, 0.0]
    body.iquat = [1.0, 0.0, 0.0, 0.0]
    body.inertia = [0.0, 0.0, 0.0]
    body.fullinertia = [float("nan"), 0.0, 0.0, 0.0, 0.0, 0.0]
    body.explicitinertial = False


def _moves(body) -> bool:
    while body is not None and body.name != "world":
        if len(body.joints):
            return True
        body = body.parent
    return False


def _welded(body) -> tuple[float, np.ndarray, np.ndarray]:
    """A body's inertial together with those of the links welded to it, in its frame."""
    parts = [inertial(body)]
    stack = [(child, np.eye(3), np.zeros(3)) for child in body.bodies]
    while stack:
        child, R0, p0 = stack.pop()
        if len(child.joints):
            continue
        R = R0 @ _rotation(child.quat)
        p = p0 + R0 @ np.asarray(child.pos, dtype=float)
        m, c, inertia = inertial(child)
        parts.append((m, p + R @ c, R @ inertia @ R.T))
        stack.extend((grandchild, R, p) for grandchild in child.bodies)
    return combine(parts)


def _alike(spec: mujoco.MjSpec, name: str) -> str:
    """"; N other moving links are alike: ..." for the other moving links whose mass or
    smallest principal moment (theirs and their welded links') is below mjMINVAL."""
    others = []
    for body in spec.bodies:
        if body.name in (name, "world") or not len(body.joints):
            continue
        m, _, inertia = _welded(body)
        if m < 1e-15 or np.linalg.eigvalsh(inertia)[0] < 1e-15:
            others.append(body.name)
    if not others:
        return ""
    shown = ", ".join(f"'{n}'" for n in others[:6]) + (", ..." if len(others) > 6 else "")
    return f"; {len(others)} other moving link{'s' * (len(others) > 1)} alike: {shown}"


def _describe_inertia(body) -> str:
    m, _, inertia = inertial(body)
    moments = np.linalg.eigvalsh(inertia)
    return (f"mass {m:.3g} kg, principal moments of inertia "
            f"({', '.join(f'{x:.3g}' for x in moments)}) kg*m^2")


def import_urdf(text: str, free_joint: str | None = None
                ) -> tuple[mujoco.MjSpec, tuple[Merge, ...]]:
    """MuJoCo's import of URDF ``text`` (with a free joint named ``free_joint`` on the root link
    if given) and the merges it needed to compile, none if MuJoCo accepts the file as it is.

    After a failed compile MuJoCo's spec keeps raising the error, so each attempt starts from
    a fresh import and replays the merges decided so far.

    Raises:
        ValueError: MuJoCo cannot parse the file, or refuses it for another reason than a
            link's inertia (MuJoCo's message).
        UnrepresentableBodyError: a refused link that nothing can be merged with.
    """
    links: list[str] = []
    reasons: dict[str, str] = {}   # MuJoCo's own words for each refused link
    while True:
        spec = mujoco.MjSpec.from_string(text)
        if free_joint is not None:
            spec.worldbody.first_body().add_freejoint(name=free_joint)
        done: set[str] = set()
        merges = [m for link in links for m in merge_one(spec, link, done, reasons.get(link))]
        try:
            spec.compile()
        except ValueError as exc:
            link = refused_link(str(exc))
            if link is None:
                raise
            if link in done:  # the merged body is refused too: say why
                spec = mujoco.MjSpec.from_string(text)
                if free_joint is not None:
                    spec.worldbody.first_body().add_freejoint(name=free_joint)
                for earlier in links:
                    merge_one(spec, earlier, set())
                raise UnrepresentableBodyError(
                    f"link '{link}' is still refused after merging what is welded to it "
                    f"({_describe_inertia(spec.body(link))}); give it a physical <inertial> "
                    "in the URDF (positive principal moments, each at most the sum of the "
                    "other two)") from None
            links.append(link)
            reasons[link] = str(exc).splitlines()[0].removeprefix("Error: ")
            continue
        spec = mujoco.MjSpec.from_string(text)  # a spec that never failed, for the caller
        if free_joint is not None:
            spec.worldbody.first_body().add_freejoint(name=free_joint)
        for link in links:
            merge_one(spec, link, set())
        return spec, tuple(merges)


def merge_one(spec: mujoco.MjSpec, name: str, done: set[str], reason: str | None = None
              ) -> list[Merge]:
    """Move inertials so that MuJoCo can accept link ``name``; the merges made (``name`` is
    added to ``done``). ``reason``: MuJoCo's message refusing it, quoted if nothing merges.

    Raises:
        UnrepresentableBodyError: ``name`` moves and has nothing to merge with.
    """
    body = spec.body(name)
    if body is None:
        raise UnrepresentableBodyError(f"MuJoCo refuses the inertia of '{name}', which is not a "
                                  "link of the URDF")
    joints = [j.name or "(free)" for j in body.joints]
    done.add(name)
    if not _moves(body):
        m = inertial(body)[0]
        _clear(body)
        return [Merge(name, "world", m, name)]
    if not joints:  # welded to a moving body: join the inertial of that body (Pinocchio's)
        m, c, inertia = inertial(body)
        R, p, owner = np.eye(3), np.zeros(3), body
        while not len(owner.joints):
            Ro = _rotation(owner.quat)
            R, p = Ro @ R, np.asarray(owner.pos, dtype=float) + Ro @ p
            owner = owner.parent
        _set(owner, *combine([inertial(owner), (m, p + R @ c, R @ inertia @ R.T)]))
        _clear(body)
        return [Merge(name, owner.name, m, name)]
    # A moving link: the links welded to it (its fixed subtree) join its inertial.
    merges: list[Merge] = []
    parts = [inertial(body)]
    stack = [(child, np.eye(3), np.zeros(3)) for child in body.bodies]
    while stack:
        child, R0, p0 = stack.pop()
        if len(child.joints):
            continue
        R = R0 @ _rotation(child.quat)  # the child's frame in the moving link's
        p = p0 + R0 @ np.asarray(child.pos, dtype=float)
        m, c, inertia = inertial(child)
        if m > 0 or np.any(inertia):
            parts.append((m, p + R @ c, R @ inertia @ R.T))
            merges.append(Merge(child.name, name, m, name))
            _clear(child)
        stack.extend((grandchild, R, p) for grandchild in child.bodies)
    if not merges:
        why = ("Pinocchio accepts a massless link: the links after it carry the mass"
               if inertial(body)[0] < 1e-15 else "Pinocchio accepts it: a point mass or a "
               "flat body is a limit case of a rigid body")
        raise UnrepresentableBodyError(
            f"link '{name}' needs a physical <inertial> in the URDF (the mass and inertia of "
            f"the part it stands for), or its joint '{joints[0]}' locked: it moves with "
            f"{_describe_inertia(body)} and nothing with mass is welded to it, while MuJoCo "
            "needs a mass and principal moments of inertia above 1e-15 (mjMINVAL) on every "
            f"moving body, each moment at most the sum of the other two ({why})"
            + _alike(spec, name) + (f" (MuJoCo: {reason})" if reason else ""))
    _set(body, *combine(parts))
    return merges

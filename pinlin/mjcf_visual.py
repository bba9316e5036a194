"""Visual-only geoms for a scene's MuJoCo model, so that MuJoCo's viewer shows it.

The URDF's own visuals are removed on import (their mesh paths do not resolve). In their place
each body gets a capsule from its joint origin to each child's joint origin (in the body's
frame; a body without joints uses its frame origin) and, if it has mass, a sphere at its centre
of mass whose volume grows with the mass. Sizes follow the extent of the model at its reference
configuration: capsule radius 1.5 % of the diagonal of the bounding box of the joint origins and
centres of mass, spheres from 1.5 to 3.5 capsule radii.

None of them changes the dynamics: contype = conaffinity = 0 (no contacts), mass = density = 0,
and the compiler infers no inertia from geoms (``inertiafromgeom="false"``, set on import), so
every body keeps its URDF inertial. They are in group :data:`VISUAL_GROUP` (MuJoCo's viewer
shows groups 0-2 by default; group 2 is the usual one for visuals).
"""

from __future__ import annotations

import mujoco
import numpy as np

from .mjcf_merge import inertial

#: Geom group of the visual geoms.
VISUAL_GROUP = 2
LINK_RGBA = (0.55, 0.62, 0.75, 1.0)
MASS_RGBA = (0.93, 0.55, 0.2, 1.0)
#: Capsule radius as a fraction of the bounding-box diagonal.
RADIUS_FRACTION = 0.015


def _rotation(quat) -> np.ndarray:
    q = np.asarray(quat, dtype=float)
    R = np.zeros(9)
    mujoco.mju_quat2Mat(R, q / np.linalg.norm(q))
    return R.reshape(3, 3)


def _origin(body) -> np.ndarray:
    """A body's joint origin in its own frame (its frame origin if it has no joint)."""
    joints = body.joints
    if joints and joints[0].type != mujoco.mjtJoint.mjJNT_FREE:
        return np.asarray(joints[0].pos, dtype=float)
    return np.zeros(3)


def _walk(spec: mujoco.MjSpec):
    """(body, rotation, position) of every body but the world at the reference configuration."""
    stack = [(child, np.eye(3), np.zeros(3)) for child in spec.worldbody.bodies]
    while stack:
        body, R0, p0 = stack.pop()
        R = R0 @ _rotation(body.quat)
        p = p0 + R0 @ np.asarray(body.pos, dtype=float)
        yield body, R, p
        stack.extend((child, R, p) for child in body.bodies)


def _visual(geom, rgba) -> None:
    geom.contype = 0
    geom.conaffinity = 0
    geom.group = VISUAL_GROUP
    geom.mass = 0.0
    geom.density = 0.0
    geom.rgba = rgba


def add_visual_geoms(spec: mujoco.MjSpec) -> int:
    """Add the visual geoms to ``spec`` (before it is compiled); the number added.

    Also turns off the compiler's ``discardvisual``, which would drop geoms without contacts.
    """
    spec.compiler.discardvisual = False
    bodies = list(_walk(spec))
    if not bodies:
        return 0
    points = [p + R @ _origin(b) for b, R, p in bodies]
    masses = [inertial(b)[0] for b, _, _ in bodies]
    points += [p + R @ inertial(b)[1] for (b, R, p), m in zip(bodies, masses, strict=True)
               if m > 0]
    points = np.array(points)
    diagonal = float(np.linalg.norm(points.max(axis=0) - points.min(axis=0)))
    radius = RADIUS_FRACTION * diagonal if diagonal > 0 else 0.01
    heaviest = max(masses)
    added = 0
    for (body, _, _), mass in zip(bodies, masses, strict=True):
        start = _origin(body)
        for child in body.bodies:
            end = np.asarray(child.pos, dtype=float) + _rotation(child.quat) @ _origin(child)
            if np.linalg.norm(end - start) < 0.5 * radius:
                continue  # a joint at (nearly) the same place: nothing to draw
            geom = body.add_geom()
            geom.type = mujoco.mjtGeom.mjGEOM_CAPSULE
            geom.fromto = np.concatenate([start, end])
            geom.size = [radius, 0.0, 0.0]
            _visual(geom, LINK_RGBA)
            added += 1
        if mass > 0:
            geom = body.add_geom()
            geom.type = mujoco.mjtGeom.mjGEOM_SPHERE
            geom.pos = inertial(body)[1]
            geom.size = [radius * (1.5 + 2.0 * (mass / heaviest) ** (1 / 3)),
                         0.0, 0.0]
            _visual(geom, MASS_RGBA)
            added += 1
    return added

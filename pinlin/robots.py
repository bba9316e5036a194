"""Kinematic and inertial models of the example-robot-data robots.

The loaders of ``example_robot_data`` also build visual and collision geometry, which costs
seconds per robot and is useless for linearization. For loaders that use the generic recipe
(URDF, optional free-flyer root, SRDF reference posture and rotor parameters) this module repeats
exactly that recipe with ``pin.buildModelFromUrdf`` and ``readParamsFromSrdf``; loaders that
change the model in their own ``__init__`` (e.g. ``talos_legs``, ``human``) are run as they are.
``tests/test_robots.py`` checks that both routes give the same model.

urdfdom prints some faults on stderr and goes on with a different robot (a zeroed inertia, a
dropped visual): every complaint it prints while a robot loads is a :class:`RobotLoadError`.
(The XML checks of :func:`pinlin.urdf_check.check_urdf` are not applied here: the physical checks
on inertia tensors refuse placeholder links that several example-robot-data robots carry, e.g.
tiago, pr2, anymal; Pinocchio's merged bodies of those robots are physical.)
"""

from __future__ import annotations

import contextlib
import functools
import io
from dataclasses import dataclass
from os.path import join
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
import pinocchio as pin

from .exceptions import PinlinError, RobotLoadError, SceneError, UnknownRobotError
from .urdf_io import build_model, complaint_summary, load_urdf, quiet_stderr, urdfdom_complaints

if TYPE_CHECKING:
    from .scene import Scene


@dataclass(frozen=True)
class RobotModel:
    """A robot as example-robot-data defines it.

    Attributes:
        name: Loader name, e.g. ``"ur5"``.
        model: Pinocchio model (free-flyer root joint named ``root_joint`` when floating).
        q_ref: Reference configuration (SRDF posture, else neutral), size ``model.nq``.
        free_flyer: Whether the loader gives the robot a floating base.
        urdf_path: The URDF the model was built from.
        srdf_path: The SRDF used for posture and armature, or None.
    """

    name: str
    model: pin.Model
    q_ref: np.ndarray
    free_flyer: bool
    urdf_path: str
    srdf_path: str | None


def _loaders() -> dict:
    from example_robot_data.robots_loader import ROBOTS

    return ROBOTS


def robot_names() -> list[str]:
    """All robot names example-robot-data declares (some may fail to load)."""
    return list(_loaders())


def _uses_generic_recipe(loader_cls) -> bool:
    from example_robot_data.robots_loader import RobotLoader

    custom = [
        c for c in loader_cls.__mro__ if "__init__" in c.__dict__ and c not in (RobotLoader, object)
    ]
    return not custom and bool(loader_cls.urdf_filename)


def _build_generic(name: str, loader_cls) -> RobotModel:
    from example_robot_data.robots_loader import getModelPath, readParamsFromSrdf

    rel = join(loader_cls.path, loader_cls.urdf_subpath, loader_cls.urdf_filename)
    model_path = getModelPath(rel)
    urdf_path = join(model_path, rel)
    model, failure, complaints = build_model(urdf_path, free_flyer=loader_cls.free_flyer)
    _raise_on_complaints(name, urdf_path, complaints)
    if failure is not None:
        raise failure
    srdf_path = None
    if loader_cls.srdf_filename:
        srdf_path = join(
            model_path, loader_cls.path, loader_cls.srdf_subpath, loader_cls.srdf_filename
        )
        q_ref = readParamsFromSrdf(
            model, srdf_path, False, loader_cls.has_rotor_parameters, loader_cls.ref_posture
        )
    else:
        q_ref = pin.neutral(model)
    return RobotModel(name, model, np.asarray(q_ref, float), loader_cls.free_flyer, urdf_path,
                      srdf_path)


def _raise_on_complaints(name: str, urdf_path: str, complaints: list[str]) -> None:
    """Turn urdfdom's complaints while loading robot ``name`` into a :class:`RobotLoadError`."""
    if complaints:
        raise RobotLoadError(name, f"urdfdom reports on {urdf_path}: "
                                   f"{complaint_summary(complaints)}")


def _build_with_loader(name: str, loader_cls) -> RobotModel:
    with quiet_stderr() as captured, contextlib.redirect_stdout(io.StringIO()):
        try:
            loader = loader_cls()
        except Exception as exc:  # reported below, after urdfdom's complaints if any
            failure: Exception | None = exc
        else:
            failure = None
    _raise_on_complaints(name, loader_cls.urdf_filename or "its model file",
                         urdfdom_complaints(captured[0] if captured else ""))
    if failure is not None:
        raise failure
    robot = loader.robot
    return RobotModel(name, robot.model, np.asarray(robot.q0, float), loader_cls.free_flyer,
                      loader.df_path, getattr(loader, "srdf_path", None))


@functools.cache
def _load_cached(name: str) -> RobotModel:
    loaders = _loaders()
    if name not in loaders:
        raise UnknownRobotError(name, loaders)
    loader_cls = loaders[name]
    try:
        if _uses_generic_recipe(loader_cls):
            return _build_generic(name, loader_cls)
        return _build_with_loader(name, loader_cls)
    except PinlinError:
        raise
    except Exception as exc:  # the loaders raise anything: ImportError, OSError, ValueError
        reason = str(exc).strip().splitlines()[0] if str(exc).strip() else type(exc).__name__
        raise RobotLoadError(name, reason) from exc


def load_robot(name: str) -> RobotModel:
    """Load robot ``name``; the returned model is a fresh copy the caller may modify.

    Raises:
        UnknownRobotError: ``name`` is not an example-robot-data robot.
        RobotLoadError: the robot's loader fails here (e.g. ``cassie``: no SDF support).
    """
    cached = _load_cached(name)
    return RobotModel(cached.name, pin.Model(cached.model), cached.q_ref.copy(), cached.free_flyer,
                      cached.urdf_path, cached.srdf_path)


def loadable_robots() -> dict[str, str | None]:
    """Try every robot; map its name to None when it loads, else to the reason it does not."""
    result: dict[str, str | None] = {}
    for name in robot_names():
        try:
            _load_cached(name)
            result[name] = None
        except RobotLoadError as exc:
            result[name] = exc.reason
    return result


def robot_model(scene: Scene) -> tuple[pin.Model, np.ndarray]:
    """The example-robot-data model of ``scene.robot`` and its reference configuration, with the
    base the scene asks for (a free flyer locked at the reference pose for ``base = "fixed"``,
    one added for ``"free"``)."""
    rm = load_robot(scene.robot)
    model, q_ref = rm.model, rm.q_ref
    if scene.base == "fixed" and rm.free_flyer:
        # Lock the free flyer at the reference pose: the rest of the model is untouched.
        model = pin.buildReducedModel(model, [1], q_ref)
        q_ref = q_ref[7:].copy()
    elif scene.base == "free" and not rm.free_flyer:
        from example_robot_data.robots_loader import ROBOTS, readParamsFromSrdf

        loader = ROBOTS[scene.robot]
        if not _uses_generic_recipe(loader):
            raise SceneError(scene.source, "base", f"robot '{scene.robot}' is built by a custom "
                                                   "loader; it cannot be given a floating base")
        model = load_urdf(Path(rm.urdf_path), free_flyer=True)
        q_ref = (readParamsFromSrdf(model, rm.srdf_path, False, loader.has_rotor_parameters,
                                    loader.ref_posture)
                 if rm.srdf_path is not None else pin.neutral(model))
    return model, np.asarray(q_ref, float)

"""pinlin: linear state-space models of multibody systems, checked against MuJoCo.

Typical use::

    import pinlin
    scene = pinlin.Scene.load("urdf/double_pendulum.toml")
    model = pinlin.linearize(scene)          # LinearModel: A, B, C, D, M, C_damp, K, Bu
    print(pinlin.modal(model))               # eigenvalues, wn, zeta, mode shapes
"""

from . import graph
from .conditioning import AccuracyWarning
from .exceptions import (
    ArgumentError,
    AssemblyError,
    EquilibriumError,
    ModelError,
    ModelFileError,
    PinlinError,
    ResourceError,
    RobotLoadError,
    SceneError,
    ShapeError,
    UnknownNameError,
    UnknownRobotError,
    UrdfError,
)
from .linear_model import LinearModel
from .linearization import linearize, operating_point
from .modal import ModalAnalysis, modal
from .operating_point import OperatingPoint
from .options import Analytic, Canonical, FiniteDifferences, Independent, Penalty
from .resources import set_memory_limit
from .scene import Effects, Scene, Spring
from .simulation import Simulation, simulate
from .system import System

__version__ = "0.1.0"

__all__ = [
    "AccuracyWarning",
    "Analytic",
    "ArgumentError",
    "AssemblyError",
    "Canonical",
    "Effects",
    "EquilibriumError",
    "FiniteDifferences",
    "Independent",
    "LinearModel",
    "ModalAnalysis",
    "ModelError",
    "ModelFileError",
    "OperatingPoint",
    "Penalty",
    "PinlinError",
    "ResourceError",
    "RobotLoadError",
    "Scene",
    "SceneError",
    "ShapeError",
    "Simulation",
    "Spring",
    "System",
    "UnknownNameError",
    "UnknownRobotError",
    "UrdfError",
    "__version__",
    "graph",
    "linearize",
    "modal",
    "operating_point",
    "set_memory_limit",
    "simulate",
]

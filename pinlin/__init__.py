"""pinlin: linear state-space models of multibody systems, checked against MuJoCo.

Typical use::

    import pinlin
    scene = pinlin.Scene.load("urdf/double_pendulum.toml")
    model = pinlin.linearize(scene)          # LinearModel: A, B, C, D, M, C_damp, K, Bu
    print(pinlin.modal(model))               # eigenvalues, wn, zeta, mode shapes
"""

from . import graph
from .conditioning import AccuracyWarning
from .contacts import ContactWarning
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
from .frequency import FrequencyResponse, bode, frequency_response
from .gain_files import read_gain, write_gain
from .html_report import write_html_report
from .linear_model import LinearModel
from .linearization import linearize, operating_point
from .modal import ModalAnalysis, modal
from .modal_coordinates import ModalCoordinates
from .modal_energy import ModalEnergy
from .mode_pictures import animate_modes, plot_modes
from .operating_point import OperatingPoint
from .options import Analytic, Canonical, FiniteDifferences, Independent, Penalty
from .resources import set_memory_limit
from .response import Response, response
from .scene import Effects, Scene, Spring
from .signals import Signal, harmonic, impulse, step
from .simulation import Simulation, simulate
from .stick_figure import ModeMotion, Skeleton, StickFigure, mode_motion
from .system import System
from .trajectory import TrajectoryModel, linearize_trajectory
from .trajectory_files import trajectory_columns
from .validity import Validity, validity

__version__ = "0.1.0"

__all__ = [
    "AccuracyWarning",
    "Analytic",
    "ArgumentError",
    "AssemblyError",
    "Canonical",
    "ContactWarning",
    "Effects",
    "EquilibriumError",
    "FiniteDifferences",
    "FrequencyResponse",
    "Independent",
    "LinearModel",
    "ModalAnalysis",
    "ModalCoordinates",
    "ModalEnergy",
    "ModeMotion",
    "ModelError",
    "ModelFileError",
    "OperatingPoint",
    "Penalty",
    "PinlinError",
    "ResourceError",
    "Response",
    "RobotLoadError",
    "Scene",
    "SceneError",
    "ShapeError",
    "Signal",
    "Simulation",
    "Skeleton",
    "Spring",
    "StickFigure",
    "System",
    "TrajectoryModel",
    "UnknownNameError",
    "UnknownRobotError",
    "UrdfError",
    "Validity",
    "__version__",
    "animate_modes",
    "bode",
    "frequency_response",
    "graph",
    "harmonic",
    "impulse",
    "linearize",
    "linearize_trajectory",
    "modal",
    "mode_motion",
    "operating_point",
    "plot_modes",
    "read_gain",
    "response",
    "set_memory_limit",
    "simulate",
    "step",
    "trajectory_columns",
    "validity",
    "write_gain",
    "write_html_report",
]

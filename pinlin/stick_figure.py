"""Stick figures of a scene and of its modes: the geometry that mode pictures and reports draw.

A :class:`Skeleton` is the drawing's topology, built once from a :class:`~pinlin.system.System`:

- a point per joint, at the joint origin ``data.oMi[j]`` (Pinocchio's forward kinematics on
  ``system.model``: the rotating frame for a spinning scene), plus the world origin where a
  joint hangs from it (not for a free-flyer base, which is not attached);
- a *tip* per joint: the BODY or OP_FRAME frame on that joint farthest from its origin
  (``data.oMf``; an end effector, a foot, a link's far end), where it lies off the origin;
- the frames of every loop of the scene (``frame1`` and ``frame2``), each joined to its joint;
- links: each joint to its parent (the world origin for a root joint), each tip and loop frame
  to its joint; closures: the two frames of each loop (a zero-length segment when closed).

A :class:`StickFigure` is that skeleton at one configuration q: the points [m] and their
rotations (``oMi`` / ``oMf``), for drawing body frames.

**A mode's motion** (:func:`mode_motion`). With phi the mode's shape in the model's coordinates
(:attr:`pinlin.ModalAnalysis.shapes`, largest entry exactly 1) and dq(phi) its tangent-space
deviation over the scene's nv coordinates (phi itself for an open chain or a floating base;
R phi for a mechanism's independent-coordinate model, R = ``model.info["R"]``), the figure at
phase theta [rad] and amplitude a [rad or m] is drawn at

    q(theta) = integrate(q0, a Re(e^{i theta} dq(phi)))            (open chains, free bases)

and, for a scene with constraints (loops, mimic couplings), at that configuration with its
dependent coordinates re-solved by :func:`pinlin.assembly.assemble`, the independent
coordinates z held (``model.info["independent"]``, else the partition at q0). integrate(q0,
a R phi) closes the loops only to first order (a gap O(a^2)); the assembled configuration
closes them to the assembly tolerance (1e-12 m) at every phase, and differs from it by O(a^2)
in the dependent coordinates only.

A real shape (an undamped mode, a real eigenvalue; a lightly damped one too, see
:data:`COMPLEX_TOL`) is drawn at theta = 0 and pi: at +a and -a. A complex shape (a damped or
gyroscopic mode whose coordinates move out of phase) at :data:`COMPLEX_PHASES` phases of the
cycle. The default amplitude makes the largest point
displacement :data:`READABLE` of the figure's size, at most :data:`MAX_EXCURSION` on the
largest coordinate (see :func:`readable_amplitude`).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import pinocchio as pin

from .exceptions import ArgumentError, AssemblyError, ModelError
from .fields import show
from .modal import ModalAnalysis

#: The default amplitude moves the figure's farthest-moving point by this fraction of its size.
READABLE = 0.15
#: ... and never moves the largest coordinate by more than this [rad or m].
MAX_EXCURSION = 0.5
#: A given amplitude is refused above this [rad or m]: far beyond any drawable excursion
#: (a few rad turns a joint round; a robot's figure is metres), and float64's range is kept.
MAX_AMPLITUDE = 1e3
#: Body-frame axes are drawn (and count as moving points) at this fraction of the figure size.
AXIS_LENGTH = 0.08
#: At most this many joint frames are drawn where a mode turns links about their own axes.
TRIADS = 4
#: Phases at which a complex mode is drawn by default (evenly spaced over a cycle).
COMPLEX_PHASES = 4
#: A shape is drawn as complex (at COMPLEX_PHASES phases) when max |Im| exceeds this fraction
#: of max |shape| (which is 1): its coordinates then move visibly out of phase. Below, the
#: figures at +-a (phases 0 and pi) show the motion, a lightly damped mode's included.
COMPLEX_TOL = 0.05
#: Halvings of a default amplitude tried when a mechanism cannot be assembled there.
ASSEMBLY_RETRIES = 4
#: A frame closer than this to its joint's origin (relative to the span of the joint origins)
#: is not drawn as a tip.
SAME_POINT = 1e-9


@dataclass(frozen=True, eq=False)
class StickFigure:
    """A skeleton drawn at one configuration.

    Attributes:
        q: The configuration (nq).
        points: Point positions in the world frame (P, 3) [m].
        rotations: Orientation of each point's frame in the world (P, 3, 3): ``oMi`` of a
            joint, ``oMf`` of a frame, the identity for the world origin.
        names: Joint or frame name of each point (``"universe"`` for the world origin,
            ``"anchor:<contact>"`` for where a contact holds its frame).
        kinds: ``"world"`` (the world origin, a contact's anchor), ``"joint"`` or ``"frame"``
            per point.
        links: Index pairs (L, 2) of the points each link joins.
        closures: Index pairs (C, 2) of the two frames of each loop, then of each contact's
            frame and its anchor, in scene order.
    """

    q: np.ndarray
    points: np.ndarray
    rotations: np.ndarray
    names: tuple[str, ...]
    kinds: tuple[str, ...]
    links: np.ndarray
    closures: np.ndarray

    def point(self, name: str) -> np.ndarray:
        """The position [m] of the point named ``name``."""
        try:
            return self.points[self.names.index(name)]
        except ValueError:
            raise ArgumentError("name", f"no point named {name!r} in the figure; expected one "
                                        f"of {', '.join(self.names)}") from None

    @property
    def gaps(self) -> np.ndarray:
        """Distance between the two points of each closure (C,) [m]: 0 when a loop is closed
        and a contact holds its frame at its anchor."""
        if not len(self.closures):
            return np.zeros(0)
        a, b = self.closures[:, 0], self.closures[:, 1]
        return np.linalg.norm(self.points[a] - self.points[b], axis=1)

    @property
    def size(self) -> float:
        """Diagonal of the points' bounding box [m] (at least 1e-3 m)."""
        span = self.points.max(axis=0) - self.points.min(axis=0)
        return max(float(np.linalg.norm(span)), 1e-3)

    def marks(self, length: float) -> np.ndarray:
        """The points and the tips of their frames' axes at ``length`` [m] ((4P, 3) [m]): what
        the default amplitude and the view plane measure the motion by."""
        tips = self.points[:, None, :] + length * np.swapaxes(self.rotations, 1, 2)
        return np.vstack([self.points, tips.reshape(-1, 3)])


def _frame_index(model: pin.Model, name: str) -> int:
    """Index of frame ``name`` in ``model`` (len(model.frames) if none), as
    :meth:`pinlin.system.System.frame_id` resolves it: a link and a joint may share a name
    (anymal_c, z1, so100), and the link's frame wins."""
    for kind in (pin.FrameType.BODY, pin.FrameType.OP_FRAME, pin.FrameType.FIXED_JOINT,
                 pin.FrameType.JOINT):
        if model.existFrame(name, kind):
            return model.getFrameId(name, kind)
    return len(model.frames)


class Skeleton:
    """The points and links of a system's stick figure (module docstring); build once, then
    draw at any configuration with :meth:`figure`. Holds one ``pin.Data``: one skeleton per
    thread."""

    def __init__(self, scene: object) -> None:
        """``scene``: a :class:`~pinlin.Scene`, its System, or a scene file / bundled scene /
        robot name."""
        system = _system(scene)
        self.system = system
        model: pin.Model = system.model
        self.model = model
        self._data = pin.Data(model)
        free = {j.id for j in system.joints.values() if j.kind.endswith("FreeFlyer")}
        # Points: (kind, joint id or frame id); joints first, in model order.
        entries: list[tuple[str, int]] = []
        names: list[str] = []
        index_of_joint: dict[int, int] = {}
        needs_world = any(model.parents[j] == 0 and j not in free
                          for j in range(1, model.njoints))
        if needs_world:
            entries.append(("world", 0))
            names.append("universe")
            index_of_joint[0] = 0
        for j in range(1, model.njoints):
            index_of_joint[j] = len(entries)
            entries.append(("joint", j))
            names.append(model.names[j])
        links = [(index_of_joint[model.parents[j]], index_of_joint[j])
                 for j in range(1, model.njoints) if model.parents[j] in index_of_joint
                 and j not in free]
        frames = self._tip_frames(system)
        loop_frames = []
        for loop in system.scene.loops:
            pair = []
            for fname in (loop.frame1, loop.frame2):
                fid = _frame_index(model, fname)
                if fid >= len(model.frames):
                    raise ModelError(f"scene '{system.scene.name}': loop frame '{fname}' is not "
                                     "a frame of the model")
                pair.append(fid)
                if fid not in frames:
                    frames.append(fid)
            loop_frames.append(pair)
        # Contacts: the frame, and its anchor in the world (drawn as the world origin is).
        self._anchors: list[pin.SE3] = []
        for contact in system.constraints.contacts:
            fid = _frame_index(model, contact.frame)
            if fid not in frames:
                frames.append(fid)
            self._anchors.append(contact.placement)
        index_of_frame: dict[int, int] = {}
        for fid in frames:
            parent = model.frames[fid].parentJoint
            if parent == 0 and 0 not in index_of_joint:
                index_of_joint[0] = len(entries)
                entries.append(("world", 0))
                names.append("universe")
            index_of_frame[fid] = len(entries)
            entries.append(("frame", fid))
            names.append(model.frames[fid].name)
            links.append((index_of_joint[parent], index_of_frame[fid]))
        anchored = []
        for k, contact in enumerate(system.constraints.contacts):
            anchored.append([index_of_frame[_frame_index(model, contact.frame)], len(entries)])
            entries.append(("anchor", k))
            names.append(f"anchor:{contact.name}")
        self.names = tuple(names)
        self.kinds = tuple("world" if kind == "anchor" else kind for kind, _ in entries)
        self._entries = entries
        self.links = np.array(links, dtype=int).reshape(-1, 2)
        self.closures = np.array([[index_of_frame[a], index_of_frame[b]]
                                  for a, b in loop_frames] + anchored, dtype=int).reshape(-1, 2)
        for arr in (self.links, self.closures):
            arr.flags.writeable = False

    def _tip_frames(self, system) -> list[int]:
        """Per joint, the BODY or OP_FRAME frame farthest from the joint origin at the
        reference configuration, where it lies off it (SAME_POINT of the figure's span)."""
        model, data = self.model, self._data
        pin.framesForwardKinematics(model, data, system.q_ref)
        origins = np.array([data.oMi[j].translation for j in range(model.njoints)])
        span = max(float(np.linalg.norm(origins.max(axis=0) - origins.min(axis=0))), 1e-3)
        best: dict[int, tuple[float, int]] = {}
        for fid, frame in enumerate(model.frames):
            if frame.parentJoint == 0 or frame.type not in (pin.FrameType.BODY,
                                                             pin.FrameType.OP_FRAME):
                continue
            offset = float(np.linalg.norm(data.oMf[fid].translation
                                          - data.oMi[frame.parentJoint].translation))
            if offset > SAME_POINT * span and offset > best.get(frame.parentJoint, (0.0, -1))[0]:
                best[frame.parentJoint] = (offset, fid)
        return [fid for _, fid in sorted(best.values(), key=lambda item: item[1])]

    def figure(self, q: np.ndarray) -> StickFigure:
        """The figure at configuration ``q`` (nq) from ``pin.framesForwardKinematics``."""
        q = np.asarray(q, dtype=float)
        if q.shape != (self.model.nq,):
            raise ArgumentError("q", f"expected nq = {self.model.nq} numbers, got shape "
                                     f"{q.shape}")
        model, data = self.model, self._data
        pin.framesForwardKinematics(model, data, q)
        points = np.zeros((len(self._entries), 3))
        rotations = np.zeros((len(self._entries), 3, 3))
        for k, (kind, ident) in enumerate(self._entries):
            placement = (pin.SE3.Identity() if kind == "world" else
                         self._anchors[ident] if kind == "anchor" else
                         data.oMi[ident] if kind == "joint" else data.oMf[ident])
            points[k] = placement.translation
            rotations[k] = placement.rotation
        for arr in (points, rotations):
            arr.flags.writeable = False
        q = q.copy()
        q.flags.writeable = False
        return StickFigure(q, points, rotations, self.names, self.kinds, self.links,
                           self.closures)


# --------------------------------------------------------------------------------------------
@dataclass(frozen=True, eq=False)
class ModeMotion:
    """A mode drawn as stick figures (module docstring).

    Attributes:
        index: Eigenvalue index of the mode in the analysis.
        number: Its row in the mode table (1 = first row).
        label: ``"mode K: f = ... Hz, zeta = ..."`` for titles.
        amplitude: a: the largest coordinate's excursion [rad or m].
        phases: Phases theta of the drawn figures [rad].
        deviations: a Re(e^{i theta} dq(phi)) per phase (N, nv), tangent space.
        configurations: The drawn configurations (N, nq).
        figures: The figure at each phase.
        rest: The figure at q0.
        complex: Whether the shape is drawn as complex (coordinates visibly out of phase,
            :data:`COMPLEX_TOL`).
        assembled: Whether the configurations were re-assembled (a scene with constraints).
    """

    index: int
    number: int
    label: str
    amplitude: float
    phases: np.ndarray
    deviations: np.ndarray
    configurations: np.ndarray
    figures: tuple[StickFigure, ...]
    rest: StickFigure
    complex: bool
    assembled: bool

    @property
    def gap(self) -> float:
        """Largest loop gap over the drawn figures [m] (0 without loops)."""
        return max((float(f.gaps.max(initial=0.0)) for f in self.figures), default=0.0)

    def displacements(self) -> np.ndarray:
        """Displacement of every point from the rest figure, per phase (N, P, 3) [m]."""
        return np.array([f.points - self.rest.points for f in self.figures])

    def turning(self, count: int = TRIADS) -> list[int]:
        """Points whose frames a picture should draw: where the points barely move (their
        largest displacement is below half that of the frames' axis tips at AXIS_LENGTH of
        the figure size: the mode turns links about their own axes), the ``count`` joints
        whose frames turn most (at least half the largest turn); else none."""
        if not self.figures:
            return []
        length = AXIS_LENGTH * self.rest.size
        base = self.rest.marks(length)
        marks = max(float(np.linalg.norm(f.marks(length) - base, axis=1).max())
                    for f in self.figures)
        points = float(np.linalg.norm(self.displacements(), axis=2).max())
        if marks <= 0.0 or points >= 0.5 * marks:
            return []
        angle = np.zeros(len(self.rest.names))
        for f in self.figures:
            relative = np.einsum("pji,pjk->pik", self.rest.rotations, f.rotations)
            cos = np.clip((np.trace(relative, axis1=1, axis2=2) - 1.0) / 2.0, -1.0, 1.0)
            angle = np.maximum(angle, np.arccos(cos))
        angle[[k for k, kind in enumerate(self.rest.kinds) if kind != "joint"]] = 0.0
        order = [int(k) for k in np.argsort(-angle, kind="stable")[:count]]
        return [k for k in order if angle[k] >= 0.5 * angle[order[0]] and angle[k] > 0.0]


def _system(scene: object):
    from .linearization import _system as resolve

    return resolve(scene)


def full_shape(system, modes: ModalAnalysis, index: int) -> np.ndarray:
    """dq(phi) (nv, complex): the mode's shape over the scene's nv coordinates.

    Raises:
        ModelError: the analysis is not of a model of this scene (other coordinates).
    """
    phi = modes.shapes[:, index]
    model = modes.model
    R = model.info.get("R")
    if R is not None:
        R = np.asarray(R, dtype=float)
        if R.shape == (system.nv, phi.size):
            return R @ phi
    elif tuple(modes.coordinate_names) == tuple(system.coordinate_names):
        return np.array(phi, dtype=complex)
    raise ModelError(f"model '{model.name}': its coordinates ({', '.join(modes.coordinate_names)})"
                     f" are not those of scene '{system.scene.name}' "
                     f"({', '.join(system.coordinate_names)}), and it carries no projection R: "
                     "draw a model linearized from this scene")


def _independent(system, model, q0: np.ndarray) -> np.ndarray | None:
    """Velocity indices of the coordinates held while assembling (None: no constraints)."""
    if not system.constraints:
        return None
    names = model.info.get("independent")
    if names and all(n in system.coordinate_names for n in names):
        return np.array(sorted(system.coordinate_names.index(n) for n in names), dtype=int)
    from .assembly import partition

    return partition(system, q0, check=False).independent


def _mode_index(modes: ModalAnalysis, index: object) -> int:
    if isinstance(index, bool) or not isinstance(index, int | np.integer):
        raise ArgumentError("index", f"expected an eigenvalue index (int), got {index!r:.40}")
    n = len(modes.eigenvalues)
    if not 0 <= index < n:
        raise ArgumentError("index", f"no eigenvalue {index}: expected 0 to {n - 1}")
    keep = modes.modes()
    return int(index) if index in keep else int(index) - 1  # a conjugate: its pair's first


def mode_label(modes: ModalAnalysis, index: int) -> str:
    """``"mode K: f = 1.23 Hz, zeta = 0.01 (oscillatory)"``: K the row in the mode table."""
    number = modes.modes().index(index) + 1
    kind = modes.kind(index)
    if modes.rigid[index]:
        return f"mode {number}: rigid"
    lam = modes.eigenvalues[index]
    if modes.oscillates(index):
        zeta = 0.0 if abs(lam.real) <= modes.rounding[index] else float(modes.zeta[index])
        return f"mode {number}: f = {modes.wn[index] / (2 * np.pi):.4g} Hz, zeta = {zeta:.3g}"
    return f"mode {number}: lambda = {lam.real:+.4g} 1/s ({kind})"


def readable_amplitude(skeleton: Skeleton, q0: np.ndarray, dq: np.ndarray) -> float:
    """The default amplitude a [rad or m] for shape ``dq`` (nv, complex, largest entry 1).

    The first-order displacement of the figure's marks (points and axis tips,
    :meth:`StickFigure.marks`) per unit a is taken by differences along Re dq and Im dq
    (step 1e-6), its largest norm over 36 phases is D [m per rad or m]; a = READABLE size / D,
    at most MAX_EXCURSION (also where nothing drawn moves).
    """
    rest = skeleton.figure(q0)
    size = rest.size
    length = AXIS_LENGTH * size
    base = rest.marks(length)
    h = 1e-6
    parts = []
    for part in (dq.real, dq.imag):
        moved = skeleton.figure(pin.integrate(skeleton.model, q0, h * part)).marks(length)
        parts.append((moved - base) / h)
    theta = np.linspace(0.0, 2 * np.pi, 36, endpoint=False)
    moves = np.cos(theta)[:, None, None] * parts[0] - np.sin(theta)[:, None, None] * parts[1]
    largest = float(np.linalg.norm(moves, axis=2).max(initial=0.0))
    if largest <= 1e-12 * size:
        return MAX_EXCURSION
    return min(MAX_EXCURSION, READABLE * size / largest)


def mode_motion(scene: object, modes: ModalAnalysis, index: int, *,
                amplitude: float | None = None, phases: Sequence[float] | None = None,
                skeleton: Skeleton | None = None) -> ModeMotion:
    """The stick figures of mode ``index`` of ``modes`` (module docstring).

    Args:
        scene: The :class:`~pinlin.Scene` (or System, or scene name) the model was made from.
        modes: ``pinlin.modal(model)`` of a model of that scene (any formulation).
        index: Eigenvalue index (as for :meth:`ModalAnalysis.kind`); a conjugate's index
            means its pair.
        amplitude: a, the largest coordinate's excursion [rad or m] (> 0); default
            :func:`readable_amplitude` (halved up to ASSEMBLY_RETRIES times where a mechanism
            cannot be assembled there).
        phases: Phases theta [rad] to draw; default 0 and pi for a real shape,
            COMPLEX_PHASES evenly spaced phases for a complex one.
        skeleton: A :class:`Skeleton` of the scene's system, to reuse.

    Raises:
        ArgumentError: a bad index, amplitude or phase.
        ModelError: the analysis is not of a model of this scene.
        AssemblyError: a mechanism cannot be assembled at the given amplitude.
    """
    system = _system(scene)
    if not isinstance(modes, ModalAnalysis):
        raise ArgumentError("modes", f"expected a pinlin ModalAnalysis, got "
                                     f"{type(modes).__name__}")
    model = modes.model
    if model.operating_point is None:
        raise ModelError(f"model '{model.name}' has no operating point to draw about")
    i = _mode_index(modes, index)
    dq = full_shape(system, modes, i)
    q0 = np.asarray(model.operating_point.q, dtype=float)
    skeleton = skeleton or Skeleton(system)
    is_complex = bool(np.abs(dq.imag).max(initial=0.0)
                      > COMPLEX_TOL * max(np.abs(dq).max(initial=0.0), 1e-300))
    if phases is None:
        theta = (np.arange(COMPLEX_PHASES) * 2 * np.pi / COMPLEX_PHASES if is_complex
                 else np.array([0.0, np.pi]))
    else:
        theta = np.asarray(phases, dtype=float).reshape(-1)
        if not theta.size or not np.all(np.isfinite(theta)):
            raise ArgumentError("phases", "expected one or more finite phases [rad]")
    independent = _independent(system, model, q0)
    if amplitude is not None:
        if isinstance(amplitude, bool) or not isinstance(amplitude, int | float | np.floating) \
                or not (np.isfinite(amplitude) and 0 < amplitude <= MAX_AMPLITUDE):
            raise ArgumentError("amplitude", f"expected an amplitude > 0 and <= "
                                             f"{MAX_AMPLITUDE:g} [rad or m], got "
                                             f"{show(amplitude)}")
        tries = [float(amplitude)]
    else:
        a = readable_amplitude(skeleton, q0, dq)
        tries = [a * 0.5 ** k for k in range(ASSEMBLY_RETRIES + 1)]
    for k, a in enumerate(tries):
        deviations = a * np.real(np.exp(1j * theta)[:, None] * dq[None, :])
        try:
            configurations = np.array([_configuration(system, q0, d, independent)
                                       for d in deviations])
            break
        except AssemblyError as exc:
            if k == len(tries) - 1:
                raise AssemblyError(
                    f"mode {modes.modes().index(i) + 1} of '{modes.model.name}': the loops or "
                    f"contacts cannot be closed at amplitude a = {a:.4g} [rad or m] along it; "
                    "choose a smaller amplitude", exc.residual, exc.names) from None
    figures = tuple(skeleton.figure(q) for q in configurations)
    for arr in (theta, deviations, configurations):
        arr.flags.writeable = False
    return ModeMotion(i, modes.modes().index(i) + 1, mode_label(modes, i), a, theta,
                      deviations, configurations, figures, skeleton.figure(q0), is_complex,
                      independent is not None)


def _configuration(system, q0: np.ndarray, dq: np.ndarray,
                   independent: np.ndarray | None) -> np.ndarray:
    q = pin.integrate(system.model, q0, dq)
    if independent is None:
        return q
    from .assembly import assemble

    return assemble(system, q, independent)


__all__ = ["ModeMotion", "Skeleton", "StickFigure", "full_shape", "mode_label", "mode_motion",
           "readable_amplitude"]

"""The multibody system a scene describes: a Pinocchio model holding exactly the scene's effects.

Pinocchio carries gravity (``model.gravity``) and armature (``model.armature``). Viscous damping
and joint springs are not part of ``pin.rnea``/``pin.aba`` (URDF ``<dynamics damping>`` is parsed
but ignored), so pinlin holds them as diagonal matrices and adds their forces and derivatives
itself. Everything the scene does not list is zeroed: a robot loaded with SRDF armature has none
unless the scene asks for ``armature``.

Conventions: the state is x = [dq; v] with dq = ``pin.difference(q0, q)`` (tangent space, size
nv). A floating base is Pinocchio's free-flyer joint ``root_joint``: configuration
[x, y, z, qx, qy, qz, qw] (position in the world [m], unit quaternion), velocity
[vx, vy, vz, wx, wy, wz] expressed in the base frame (LOCAL), in [m/s] and [rad/s].
"""

from __future__ import annotations

import copy
import functools
import threading
from pathlib import Path

import numpy as np
import pinocchio as pin

from .arrays import complement, read_only
from .conditioning import refuse_condition
from .coordinates import (  # noqa: F401  (SPHERICAL, OutputMap, one_dof_configuration: re-exported)
    FREE_FLYER,
    SPHERICAL,
    JointInfo,
    OutputMap,
    apply_armature,
    check_configuration_spec,
    check_model_names,
    damping_vector,
    input_indices,
    one_dof_configuration,
    output_map,
    slides_only,
    spring_vectors,
)
from .exceptions import SceneError, UnknownNameError
from .mass_diagnosis import checked_inverse
from .robots import load_robot, robot_model
from .scene import Scene
from .urdf_io import load_urdf


class System:
    """A scene turned into a Pinocchio model plus the effects Pinocchio does not carry.

    Build with :meth:`build`; a scene caches its system as ``scene.system``.

    Attributes:
        scene: The scene.
        model: Pinocchio model (gravity and armature as the scene says).
        data: Pinocchio data owned by this system (not thread-safe).
        q_ref: Reference configuration (SRDF posture or neutral), before the scene's q overrides.
        joints: Joint information by name, in model order (the universe excluded).
        coordinate_names: The nv velocity-coordinate names.
        damping: Viscous damping per velocity coordinate [N*m*s/rad or N*s/m] (zeros if none).
        stiffness: Spring stiffness per velocity coordinate [N*m/rad or N/m] (zeros if none).
        q_rest: Configuration at which every spring is relaxed (others: neutral).
        actuated: Velocity indices driven by the inputs, in input order.
        unactuated: The other velocity indices, ascending.
        actuated_columns: ``actuated`` as a slice when it is a contiguous ascending range
            (indexing with it is a view), else the index array.
        input_names: ``u:<coordinate>`` for each input [N*m or N].
        input_matrix: S (nv x nu, read-only): generalized force = S u.
        state_names: ``q:<coordinate>`` then ``v:<coordinate>``.
        outputs: Output map, or None when the output is the full state.
        base_joint: Name of the free-flyer joint, or None for a fixed base.
        constraints: The scene's loops, contacts (anchored at the scene's posture, see
            :meth:`anchored_at`) and mimic couplings
            (:class:`~pinlin.constraints.ConstraintSet`).
    """

    def __init__(self, scene: Scene, model: pin.Model, q_ref: np.ndarray) -> None:
        self.scene = scene
        self.model = model
        self.q_ref = q_ref
        self.joints: dict[str, JointInfo] = {}
        for jid in range(1, model.njoints):
            j = model.joints[jid]
            self.joints[model.names[jid]] = JointInfo(
                model.names[jid], jid, j.shortname(), j.idx_q, j.nq, j.idx_v, j.nv
            )
        self.coordinate_names = [n for j in self.joints.values() for n in j.coordinate_names()]
        check_model_names(self)
        self.base_joint = next((n for n, j in self.joints.items() if j.kind == FREE_FLYER and
                                model.parents[j.id] == 0), None)
        eff = scene.effects
        model.gravity.linear = np.array(eff.gravity if eff.gravity is not None else (0, 0, 0.0))
        apply_armature(self, eff.armature)
        self.damping = damping_vector(self, eff.damping)
        self.stiffness, self.q_rest = spring_vectors(self, eff.springs)
        check_configuration_spec(self)
        self.has_damping = bool(np.any(self.damping))
        self.has_springs = bool(np.any(self.stiffness))
        self.actuated = input_indices(self, scene.inputs)
        self.input_names = tuple(f"u:{self.coordinate_names[i]}" for i in self.actuated)
        self.state_names = tuple([f"q:{n}" for n in self.coordinate_names]
                                 + [f"v:{n}" for n in self.coordinate_names])
        nu = len(self.actuated)
        selection = np.zeros((model.nv, nu))
        selection[self.actuated, np.arange(nu)] = 1.0
        self.input_matrix = _known_finite(selection)
        self.unactuated = complement(model.nv, self.actuated)
        self.actuated_columns = _as_slice(self.actuated)
        self._workspaces = threading.local()
        self._main_thread = threading.get_ident()
        # createData() would hold a second copy while returning.
        self._main_data = pin.Data(model)
        self.rotation = eff.rotation
        self._build_kinematic_model()
        self.outputs = output_map(self)
        self.constraints = self._constraints()
        if scene.operating_point.independent and not self.constraints:
            # (a joint named there was never looked up: a misspelt name passed silently)
            raise SceneError(scene.source, "operating_point.independent",
                             "names the independent joints of loops, contacts or mimic "
                             "couplings, and this scene has none: its joint coordinates are "
                             "independent already; leave the key out")

    # ----------------------------------------------------------------------------------------
    @classmethod
    def build(cls, scene: Scene) -> System:
        """Load the scene's robot and apply its effects.

        Raises:
            UrdfError, UnknownRobotError, RobotLoadError: the robot cannot be loaded.
            SceneError: a field names a joint or frame the robot lacks, or a bad size.
            ResourceError: the model would need more memory than
                :func:`pinlin.resources.memory_limit` allows (checked from the URDF's sizes
                before Pinocchio parses it, and again on the model before any ``Data``).
        """
        from .resources import check_system_memory

        rotating = scene.effects.rotation is not None
        what = str(scene.urdf) if scene.robot is None else f"robot '{scene.robot}'"

        def check(nv: int, njoints: int) -> None:
            check_system_memory(nv, njoints, rotating=rotating, what=what)

        if scene.robot is not None:
            model, q_ref = robot_model(scene)
        else:
            assert scene.urdf is not None
            model = load_urdf(scene.urdf, free_flyer=scene.base == "free", check=check)
            q_ref = pin.neutral(model)
            model.armature = np.zeros(model.nv)
        check(model.nv, model.njoints)
        return cls(scene, model, q_ref)

    # ----------------------------------------------------------------------------------------
    @property
    def nq(self) -> int:
        return self.model.nq

    @property
    def nv(self) -> int:
        return self.model.nv

    def joint(self, name: str, field: str | None = None) -> JointInfo:
        """Joint ``name`` or an :class:`UnknownNameError` naming ``field`` (a
        :class:`SceneError` when ``name`` is not a string at all)."""
        if not isinstance(name, str):
            raise SceneError(self.scene.source, field,
                             f"expected a joint name (a string), got {type(name).__name__}")
        try:
            return self.joints[name]
        except KeyError:
            raise UnknownNameError(self.scene.source, field, name, "joint", list(self.joints)) \
                from None

    def frame_id(self, name: str, field: str | None = None) -> int:
        """Index of frame ``name`` in :attr:`kin_model`, or an :class:`UnknownNameError`
        naming ``field``."""
        if not name.startswith("__spin"):
            # A link and a joint may share a name (anymal_c, z1, so100): the link's frame wins.
            for kind in (pin.FrameType.BODY, pin.FrameType.OP_FRAME, pin.FrameType.FIXED_JOINT,
                         pin.FrameType.JOINT):
                if self.kin_model.existFrame(name, kind):
                    return self.kin_model.getFrameId(name, kind)
        known = [f.name for f in self.model.frames][1:]
        raise UnknownNameError(self.scene.source, field, name, "frame", known)

    @property
    def urdf_path(self) -> Path:
        """The URDF file the model comes from."""
        if self.scene.urdf is not None:
            return Path(self.scene.urdf)
        return Path(load_robot(self.scene.robot).urdf_path)

    # ----------------------------------------------------------------------------------------
    # Dynamics, with the steady rotation of the scene when it has one. A rotating scene is
    # computed on a model with one more joint at the root, a revolute joint about the rotation
    # axis whose velocity is held at the rate and whose acceleration is zero: rnea on that
    # model gives the centrifugal and Coriolis forces of the rotating frame exactly, and the
    # spin coordinate (the first) is dropped from every result.

    def _build_kinematic_model(self) -> None:
        """:attr:`kin_model` / :attr:`kin_data`: the model every dynamics call runs on."""
        if self.rotation is None:
            self.kin_model, self._main_kin_data = self.model, self._main_data
            self.kin_columns = slice(None)
            return
        g = np.asarray(self.scene.effects.gravity or (0.0, 0.0, 0.0))
        axis = np.asarray(self.rotation.axis)
        if np.linalg.norm(np.cross(g, axis)) > 1e-12 * max(1.0, np.linalg.norm(g)):
            raise SceneError(self.scene.source, "effects.rotation.axis",
                             "a steady rotation needs gravity along the rotation axis (or no "
                             f"gravity); gravity is {g.tolist()}, axis {axis.tolist()}")
        spin = pin.Model()
        jid = spin.addJoint(0, pin.JointModelRevoluteUnaligned(axis), pin.SE3.Identity(),
                            "__spin__")
        spin.appendBodyToJoint(jid, pin.Inertia.Zero(), pin.SE3.Identity())
        fid = spin.addFrame(pin.Frame("__spin_body__", jid, 0, pin.SE3.Identity(),
                                      pin.FrameType.BODY))
        kin = pin.appendModel(spin, self.model, fid, pin.SE3.Identity())
        kin.armature = np.concatenate([[0.0], self.model.armature])
        kin.gravity = self.model.gravity
        self.kin_model, self._main_kin_data = kin, pin.Data(kin)
        self.kin_columns = slice(1, None)

    # ----------------------------------------------------------------------------------------
    # Workspaces: Pinocchio's Data is scratch memory every algorithm writes into, so two
    # threads sharing one race (measured: 7 of 1000 A matrices silently wrong with 8 threads on
    # ur5). Each thread gets its own, made on its first call (a Data is 32 nv^3 bytes plus
    # O(nv^2); the main thread's is made with the system, inside the memory check).

    @property
    def data(self) -> pin.Data:
        """This thread's Pinocchio data for :attr:`model`."""
        if threading.get_ident() == self._main_thread:
            return self._main_data
        ws = self._workspaces
        if not hasattr(ws, "data"):
            ws.data = pin.Data(self.model)
            ws.kin_data = ws.data if self.rotation is None else pin.Data(self.kin_model)
        return ws.data

    @property
    def kin_data(self) -> pin.Data:
        """This thread's Pinocchio data for :attr:`kin_model`."""
        if threading.get_ident() == self._main_thread:
            return self._main_kin_data
        self.data  # noqa: B018  (makes this thread's workspaces)
        return self._workspaces.kin_data

    def kin_q(self, q: np.ndarray) -> np.ndarray:
        """Configuration of :attr:`kin_model` (spin angle 0 first when rotating)."""
        return q if self.rotation is None else np.concatenate([[0.0], q])

    def kin_v(self, v: np.ndarray, spin: bool = True) -> np.ndarray:
        """Velocity of :attr:`kin_model`: the relative velocity v, after the spin rate when
        rotating (``spin=False``: after zero) [rad/s, m/s]."""
        if self.rotation is None:
            return v
        return np.concatenate([[self.rotation.rate if spin else 0.0], v])

    def _kin_a(self, a: np.ndarray) -> np.ndarray:
        return a if self.rotation is None else np.concatenate([[0.0], a])

    def static_force(self, q: np.ndarray) -> np.ndarray:
        """Generalized force at rest: gravity (and centrifugal when rotating) [N*m or N]."""
        if self.rotation is None:
            return pin.computeGeneralizedGravity(self.model, self.data, q).copy()
        z = np.zeros(self.nv)
        return pin.rnea(self.kin_model, self.kin_data, self.kin_q(q), self.kin_v(z),
                        self._kin_a(z))[1:].copy()

    def static_scale(self, q: np.ndarray, static: np.ndarray,
                     spring: np.ndarray | None = None) -> float:
        """The size of the generalized forces in the statics at ``q`` [N*m or N]: the largest
        of gravity and, when rotating, the centrifugal force, each on its own, of the springs
        (``static``: :meth:`static_force` at q; ``spring``: :meth:`spring_torque` at q when
        the caller has it), and of :attr:`force_reference`. A residual of
        the statics is measured against it: the terms can cancel (a passive equilibrium) or
        vanish (a pendulum hanging straight down), but rounding scales with their size, and
        so does what counts as zero; nothing in it is absolute, so that a robot of
        millimetres and milligrams (forces of ~1e-9 N*m) keeps the verdict it has at metres
        and kilograms."""
        scale = max(self.force_reference, float(np.abs(static).max(initial=0.0)))
        if self.rotation is not None:
            gravity = pin.computeGeneralizedGravity(self.model, self.data, q)
            scale = max(scale, float(np.abs(gravity).max(initial=0.0)),
                        float(np.abs(static - gravity).max(initial=0.0)))
        if self.has_springs:
            if spring is None:
                spring = self.spring_torque(q)
            scale = max(scale, float(np.abs(spring).max(initial=0.0)))
        return scale

    def rnea(self, q: np.ndarray, v: np.ndarray, a: np.ndarray) -> np.ndarray:
        """Inverse dynamics M a + b(q, v) (rotating frame when rotating) [N*m or N]."""
        if self.rotation is None:
            return pin.rnea(self.model, self.data, q, v, a).copy()
        return pin.rnea(self.kin_model, self.kin_data, self.kin_q(q), self.kin_v(v),
                        self._kin_a(a))[1:].copy()

    def rnea_derivatives(self, q: np.ndarray, v: np.ndarray, a: np.ndarray,
                         with_v: bool = True
                         ) -> tuple[np.ndarray, np.ndarray | None, np.ndarray]:
        """(d tau/d q, d tau/d v, M) of :meth:`rnea`, fresh arrays (d tau/d v None unless
        ``with_v``)."""
        if self.rotation is None:
            dq, dv, M = pin.computeRNEADerivatives(self.model, self.data, q, v, a)
            return np.array(dq), (np.array(dv) if with_v else None), np.array(M)
        dq, dv, M = pin.computeRNEADerivatives(self.kin_model, self.kin_data, self.kin_q(q),
                                               self.kin_v(v), self._kin_a(a))
        return dq[1:, 1:].copy(), dv[1:, 1:].copy(), M[1:, 1:].copy()

    def mass_matrix(self, q: np.ndarray) -> np.ndarray:
        """M(q), symmetric, fresh array [kg, kg*m^2]."""
        M = pin.crba(self.kin_model, self.kin_data, self.kin_q(q))[self.kin_columns,
                                                                   self.kin_columns]
        return np.triu(M) + np.triu(M, 1).T

    @functools.cached_property
    def force_reference(self) -> float:
        """The generalized force this system's statics are sized by [N*m or N], whatever the
        configuration: over its joints, the most that gravity (and a steady rotation) can
        exert on each, m_i (g + w^2 rho_i) r_i for rotations and m_i (g + w^2 rho_i) for
        translations (m_i, r_i: mass and centre of mass of the joint's subtree and its
        distance from the joint at the neutral configuration; rho_i: that centre's distance
        from the rotation axis, plus r_i), and the springs' stiffness times one radian (or
        times the largest r_i, per metre). It scales with the robot (k s for lengths x s,
        masses x k), so a residual measured against it does too."""
        model = self.model
        data = pin.Data(model)   # its own: a cached value may be made in any thread
        pin.centerOfMass(model, data, pin.neutral(model), True)
        g = float(np.linalg.norm(model.gravity.linear))
        w2, axis = 0.0, np.zeros(3)
        if self.rotation is not None:
            w2 = float(self.rotation.rate) ** 2
            axis = np.asarray(self.rotation.axis, dtype=float)
            axis = axis / np.linalg.norm(axis)
        reference, reach = 0.0, 0.0
        for i in range(1, model.njoints):
            com = np.asarray(data.com[i])
            r = float(np.linalg.norm(com - data.oMi[i].translation))
            rho = float(np.linalg.norm(com - (com @ axis) * axis)) + r
            pull = float(data.mass[i]) * (g + w2 * rho)
            kind = model.joints[i].shortname()
            turns = not slides_only(kind)
            slides = slides_only(kind) or kind.startswith(("JointModelFreeFlyer",
                                                           "JointModelPlanar"))
            reference = max(reference, pull * r if turns else 0.0, pull if slides else 0.0)
            reach = max(reach, r)
        if self.has_springs:
            for joint in self.joints.values():
                k = self.stiffness[joint.idx_v:joint.idx_v + joint.nv]
                if k.size:
                    lever = reach if slides_only(joint.kind) else 1.0
                    reference = max(reference, float(np.abs(k).max()) * lever)
        return reference

    @functools.cached_property
    def effects_in_play(self) -> tuple[str, ...]:
        """Names of the scene's effects present (fixed for a system)."""
        return tuple(self.scene.effects.in_play())

    @functools.cached_property
    def state_output(self) -> tuple[np.ndarray, np.ndarray]:
        """(C, D) for y = x: the identity and zeros, read-only, built once."""
        n = 2 * self.nv
        return _known_finite(np.eye(n)), _known_finite(np.zeros((n, len(self.actuated))))

    @functools.cached_property
    def zero_velocity_terms(self) -> np.ndarray:
        """The nv x nv zero matrix (read-only): C of a model at rest without damping."""
        return _known_finite(np.zeros((self.nv, self.nv)))

    @functools.cached_property
    def kinematic_rows(self) -> np.ndarray:
        """[[0, I], [0, 0]] (2nv x 2nv, read-only): the state matrix's kinematic block row
        d(dq)/dt = v, the start of every A in independent coordinates."""
        n = self.nv
        A = np.zeros((2 * n, 2 * n))
        A[:n, n:] = np.eye(n)
        return read_only(A)

    @functools.cached_property
    def scene_configuration(self) -> np.ndarray:
        """q0 the scene asks for (read-only; :func:`pinlin.operating_point.configuration`
        hands out copies), built on first use."""
        from .operating_point import _configuration_from

        return read_only(_configuration_from(self, self.scene.operating_point.q))

    @functools.cached_property
    def _refuse_limit(self) -> float:
        """:func:`pinlin.conditioning.refuse_condition` of nv (fixed for a system)."""
        return refuse_condition(self.nv)

    def mass_inverse(self, q: np.ndarray, *, allow_ill_conditioned: bool = False
                     ) -> np.ndarray:
        """M(q)^-1 from ``pin.computeMinverse`` (one recursion, no factorization), symmetric.

        M is checked on the way (see :mod:`pinlin.conditioning`): n sum_i M_ii (M^-1)_ii (one
        ``crba`` for diag M) bounds the condition of M scaled to unit diagonal from above, and
        only where that bound reaches 0.1/(n eps) do the eigenvalues of the scaled M decide.

        Args:
            allow_ill_conditioned: Return M^-1 as computed (finite, but without a reliable
                digit) when M is singular to working precision, instead of refusing.

        Raises:
            ModelError: M is singular: a coordinate moves no inertia at all (M^-1 is not
                finite, whatever ``allow_ill_conditioned`` says), or M is singular to working
                precision (scaled condition >= 0.1/(n eps)) and ``allow_ill_conditioned`` is
                False. The message names the coordinate, or the motion and the bodies
                responsible, and offers the opt-in only where it would give a model.
        """
        if self.rotation is None:
            M = pin.crba(self.model, self.data, q)
            Minv = pin.computeMinverse(self.model, self.data, q)
        else:  # the spin coordinate is prescribed: invert the block of the other coordinates
            M = self.mass_matrix(q)
            Minv = np.linalg.inv(M) if np.all(np.isfinite(M)) else M
        return self.check_mass_inverse(q, M, Minv, allow_ill_conditioned=allow_ill_conditioned)

    def unchecked_mass_inverse(self, q: np.ndarray) -> np.ndarray | None:
        """M(q)^-1 from ``pin.computeMinverse`` before any check (None when rotating): the
        caller owes :meth:`check_mass_inverse` with the M that its RNEA derivatives give, which
        saves :meth:`mass_inverse`'s ``crba``. Until checked it may hold inf or NaN."""
        if self.rotation is not None:
            return None
        return pin.computeMinverse(self.model, self.data, q)

    def check_mass_inverse(self, q: np.ndarray, M: np.ndarray, Minv: np.ndarray, *,
                           allow_ill_conditioned: bool = False) -> np.ndarray:
        """:meth:`mass_inverse`'s checks of M(q) (only its upper triangle and diagonal are
        read) and of Minv = M(q)^-1 as computed; returns Minv. Raises as
        :meth:`mass_inverse` (:func:`pinlin.mass_diagnosis.checked_inverse`)."""
        return checked_inverse(self, q, M, Minv, allow_ill_conditioned)

    def applied_force(self, q: np.ndarray, v: np.ndarray, u: np.ndarray) -> np.ndarray:
        """S u + tau_spring(q) - D v: the generalized force of the inputs, springs and
        damping at (q, v, u) [N*m or N]."""
        tau = self.input_matrix @ u
        if self.has_springs:
            tau = tau + self.spring_torque(q)
        if self.has_damping:
            tau = tau - self.damping * v
        return tau

    def spring_torque(self, q: np.ndarray) -> np.ndarray:
        """Generalized spring force at configuration ``q`` [N*m or N]."""
        if not self.has_springs:
            return np.zeros(self.nv)
        return -self.stiffness * pin.difference(self.model, self.q_rest, q)

    def anchored_at(self, q: np.ndarray) -> System:
        """This system with its contacts anchored where configuration ``q`` (nq) puts their
        frames, instead of at the scene's posture; itself when the scene has no contacts.

        The copy shares the Pinocchio model, data and every other attribute (it is as
        thread-safe as this system); only :attr:`constraints` differs.
        """
        if not self.constraints.contacts:
            return self
        other = copy.copy(self)
        other.constraints = self.constraints.anchored_at(other, q)
        return other

    # ----------------------------------------------------------------------------------------
    def _constraints(self):
        from .constraints import ConstraintSet
        from .mimic import read_mimic_tags

        mimics = ()
        if self.scene.effects.mimic:
            mimics = read_mimic_tags(self.urdf_path)
            if not mimics:
                raise SceneError(self.scene.source, "effects.mimic",
                                 f"the URDF {self.urdf_path} has no <mimic> joints")
        return ConstraintSet(self, mimics)


def _known_finite(arr: np.ndarray) -> np.ndarray:
    """:func:`pinlin.model_checks.known_finite` (imported here: model_checks imports this
    module through model_files and operating_point)."""
    from .model_checks import known_finite

    return known_finite(arr)


def _as_slice(index: np.ndarray) -> slice | np.ndarray:
    """``index`` as an equivalent slice when it is a contiguous ascending range."""
    if index.size and np.array_equal(index, np.arange(index[0], index[0] + index.size)):
        return slice(int(index[0]), int(index[0]) + index.size)
    return index

"""The stacked linear models of a trajectory: :class:`TrajectoryModel` (computed by
:func:`pinlin.linearize_trajectory`, :mod:`pinlin.trajectory`).

Point k's model is ``model.at(k)``, a :class:`~pinlin.LinearModel`; the stacks are read-only
float64 arrays with the point first. Files: :mod:`pinlin.trajectory_files`; reuse of the
arrays by a later call: :mod:`pinlin.trajectory_buffers`.
"""

from __future__ import annotations

import math
import weakref
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from types import SimpleNamespace
from typing import Any

import numpy as np

from .arrays import real_array, restore_read_only
from .exceptions import ArgumentError, ModelError, ShapeError
from .fields import show
from .linear_model import LinearModel
from .model_checks import check_second_order, name_tuple
from .operating_point import OperatingPoint

#: Key of a model's record of where its arrays came from (:mod:`pinlin.trajectory_buffers`):
#: not pickled, not copied into models made from its fields.
ARENA = "_arena"
#: Arrays a later ``linearize_trajectory(..., out=model)`` may overwrite, by id (weak: an entry
#: leaves with its array). What is derived from them (``at(k)``, ``discretize``, a model made
#: with ``dataclasses.replace``) copies them instead of sharing, so that it does not change.
_REUSABLE: dict[int, weakref.ref] = {}


def register_reusable(arrays: Iterable[np.ndarray]) -> None:
    """Mark ``arrays`` as memory a later call may overwrite (:data:`_REUSABLE`)."""
    for arr in arrays:
        key = id(arr)
        _REUSABLE[key] = weakref.ref(arr, lambda _, key=key: _REUSABLE.pop(key, None))


def reusable_memory(arr: np.ndarray) -> bool:
    """Whether ``arr`` is, or is a view of, memory a later call may overwrite."""
    while isinstance(arr, np.ndarray):
        ref = _REUSABLE.get(id(arr))
        if ref is not None and ref() is arr:
            return True
        arr = arr.base
    return False


def _own(arr: np.ndarray | None) -> np.ndarray | None:
    """``arr`` itself, or a read-only copy where it lies in reusable memory."""
    if arr is None or not _REUSABLE or not reusable_memory(arr):
        return arr
    out = arr.copy()
    out.setflags(write=False)
    return out
_SECOND_ORDER = ("M", "C_damp", "K", "Bu")


@dataclass(frozen=True, eq=False)
class TrajectoryModel:
    """The linear models of N points of a trajectory, stacked along the first axis.

    Attributes:
        A, B, C, D: (N, n, n), (N, n, m), (N, p, n), (N, p, m). C and D are broadcast views of
            one matrix (no memory per point) when the outputs do not depend on the state.
        f0: (N, n): the drift at each point, x' = f0 + A x + B u (discrete: the state change
            over one step); zeros at an equilibrium.
        q: (N, nq) configurations; v: (N, nv) velocities [rad/s or m/s]; u: (N, m) inputs
            [N*m or N]; a: (N, nv) accelerations at the points [rad/s^2 or m/s^2].
        t: (N,) times [s], or None.
        y: (N, p) output values at the points (zeros when the output is the state, as for a
            single model).
        state_names, input_names, output_names: Signal names (n, m, p).
        name: Scene name.
        info: Metadata: formulation, derivatives, effects, base, points, path ("batch": Pinocchio's
            kernels per point, :mod:`pinlin.batch`; "per point": :func:`pinlin.linearize`); a
            schedule of rest points (:mod:`pinlin.rest_schedule`) adds ``at_rest`` (True),
            ``notes``, and where they apply ``non_equilibrium_points``,
            ``least_norm_points`` and ``operating_point_sensitivity``.
        dt: Sample time [s] of discrete models; 0 for continuous ones.
        lam: (N, m) constraint forces of a mechanism [N or N*m] (names in
            ``info["lam_names"]``; :mod:`pinlin.trajectory_loops`), else None. A mechanism's
            states are its independent coordinates z (``info["independent"]``), the same at
            every point; its ``q`` are the assembled configurations, ``v`` the velocities
            projected onto the constraint nullspace, ``a`` the accelerations of all nv
            coordinates.
        M, C_damp, K: (N, n/2, n/2) mass [kg, kg*m^2], velocity (damping and gyroscopic)
            and stiffness matrices of every point, Bu: (N, n/2, m) input matrix: the
            second-order model M dq'' + C_damp dq' + K dq = Bu du of :class:`LinearModel`,
            with ``linearize_trajectory(..., second_order=True)`` (open chains: n/2 = nv, Bu
            one matrix broadcast; a mechanism's schedule of rest points: its independent
            coordinates); else None.
    """

    A: np.ndarray
    B: np.ndarray
    C: np.ndarray
    D: np.ndarray
    f0: np.ndarray
    q: np.ndarray
    v: np.ndarray
    u: np.ndarray
    a: np.ndarray
    state_names: tuple[str, ...]
    input_names: tuple[str, ...]
    output_names: tuple[str, ...]
    t: np.ndarray | None = None
    y: np.ndarray | None = None
    name: str = ""
    info: Mapping[str, Any] = field(default_factory=dict)
    dt: float = 0.0
    lam: np.ndarray | None = None
    M: np.ndarray | None = None
    C_damp: np.ndarray | None = None
    K: np.ndarray | None = None
    Bu: np.ndarray | None = None

    def __post_init__(self) -> None:
        names = {}
        for key in ("state_names", "input_names", "output_names"):
            # as a LinearModel's: distinct, non-blank, no control characters (at(k) makes one)
            names[key] = name_tuple(key, getattr(self, key), str(self.name))
            object.__setattr__(self, key, names[key])
        n, m, p = (len(names[k]) for k in ("state_names", "input_names", "output_names"))
        N = np.shape(self.A)[0] if np.ndim(self.A) == 3 else -1
        nv = np.shape(self.v)[-1] if np.ndim(self.v) == 2 else -1
        half = n // 2  # second-order: the coordinates of the states (a mechanism's z)
        shapes = {"A": (N, n, n), "B": (N, n, m), "C": (N, p, n), "D": (N, p, m),
                  "f0": (N, n), "v": (N, nv), "u": (N, m), "a": (N, nv), "t": (N,),
                  "y": (N, p), "q": (N, np.shape(self.q)[-1] if np.ndim(self.q) == 2 else -1),
                  "lam": (N, np.shape(self.lam)[-1] if np.ndim(self.lam) == 2 else -1),
                  "M": (N, half, half), "C_damp": (N, half, half), "K": (N, half, half),
                  "Bu": (N, half, m)}
        given = [key for key in _SECOND_ORDER if getattr(self, key) is not None]
        if given and len(given) < len(_SECOND_ORDER):
            raise ArgumentError(given[0], "the second-order matrices M, C_damp, K, Bu come "
                                          "together: give all four or none")
        for key, shape in shapes.items():
            value = getattr(self, key)
            if value is None and key in ("t", "y", "lam", *_SECOND_ORDER):
                continue
            arr = _stack(key, value, shape)
            object.__setattr__(self, key, arr)
        _check_widths(self, n)
        if self.t is not None and np.any(np.diff(self.t) <= 0):
            raise ArgumentError("t", "times must increase strictly (one per point, as "
                                     "linearize_trajectory takes them)")
        if not isinstance(self.name, str):
            raise ArgumentError("name", f"expected a str, got {type(self.name).__name__}")
        dt = self.dt
        if isinstance(dt, bool) or not isinstance(dt, int | float | np.floating) \
                or not (math.isfinite(dt) and dt >= 0):
            raise ArgumentError("dt", f"expected a sample time >= 0 [s], got {dt!r}")
        object.__setattr__(self, "dt", float(dt))
        if not isinstance(self.info, Mapping):
            raise ArgumentError("info", f"expected a mapping, got {type(self.info).__name__}")
        object.__setattr__(self, "info", dict(self.info))
        _check_info(self)
        _check_rest_drift(self)
        _check_second_order_points(self)

    def __getstate__(self) -> dict[str, Any]:
        """Pickling: the fields, without the record of the arrays' origin
        (:mod:`pinlin.trajectory_buffers`: an unpickled model's arrays are new memory)."""
        return {k: v for k, v in self.__dict__.items() if k != ARENA}

    def __setstate__(self, state: dict[str, Any]) -> None:
        """Unpickling: the fields as pickled, the arrays read-only again (pickle hands numpy
        arrays back writeable)."""
        restore_read_only(self, state)

    @classmethod
    def trusted(cls, **fields: Any) -> TrajectoryModel:
        """A model from code that built every field consistent (read-only float64 arrays,
        tuples of distinct names): no checks."""
        fields.pop(ARENA, None)   # a model made from another's fields owns no arena
        obj = object.__new__(cls)
        obj.__dict__.update(fields)
        return obj

    # ----------------------------------------------------------------------------------------
    def __len__(self) -> int:
        return self.A.shape[0]

    def __repr__(self) -> str:
        kind = f"discrete dt = {self.dt:g} s" if self.dt else "continuous"
        return (f"TrajectoryModel({self.name!r}: {len(self)} points, {len(self.state_names)} "
                f"states, {len(self.input_names)} inputs, {len(self.output_names)} outputs, "
                f"{kind})")

    @property
    def is_discrete(self) -> bool:
        return self.dt > 0

    def at(self, k: int) -> LinearModel:
        """The model of point ``k`` (negative: from the end) as a :class:`LinearModel`: what
        :func:`pinlin.linearize` gives at (q[k], v[k], u[k]) (a schedule of rest points: at
        q[k], an equilibrium with f0 None, or a falling point opted in with its f0), to
        rounding, with the
        second-order matrices M, C_damp, K, Bu where the trajectory has them
        (``second_order=True``), else None. Its operating point carries q, v, u, a and y;
        its ``residual`` (M a0) is None.

        Raises:
            ArgumentError: ``k`` is not an integer in [-N, N).
        """
        N = len(self)
        if isinstance(k, bool) or not isinstance(k, int | np.integer):
            raise ArgumentError("k", f"expected a point index (an integer), got "
                                     f"{type(k).__name__}")
        if not -N <= k < N:
            raise ArgumentError("k", f"expected a point index in [0, {N}) (or from the end, "
                                     f"down to -{N}), got {k}")
        k = int(k) % N
        q, v, u, a = self.q[k], self.v[k], self.u[k], _own(self.a[k])
        rest = bool(self.info.get("at_rest"))  # a schedule of rest points (rest_schedule)
        moving = bool(_moving(self, slice(k, k + 1))[0])
        when = f" (t = {self.t[k]:.6g} s)" if self.t is not None else ""
        note = (f"point {k} of {N} of a schedule of rest points{when}: the inputs that hold q "
                "were solved; the residual is not kept in a batch" if rest else
                f"point {k} of {N} of a trajectory{when}: the state is given; the residual "
                "M a0 is not computed in a batch (a0 is operating_point.a)")
        info = {**self.info, "point": k}
        loop_info = info.pop("loops", None)
        if loop_info is not None:  # a mechanism: its point's diagnostics, as linearize's
            info["condition"] = {"constraint_jacobian": loop_info["condition"][k]}
            info["velocity_correction"] = loop_info["velocity_correction"][k]
            info["position_correction"] = loop_info["position_correction"][k]
        op = OperatingPoint.trusted(
            q=q, v=v, u=u, a=a, residual=None, equilibrium=not moving, tolerance=0.0,
            y=None if self.y is None else _own(self.y[k]),
            lam=None if self.lam is None else self.lam[k],
            lam_names=tuple(self.info.get("lam_names", ())) if self.lam is not None else (),
            notes=(note,))
        if self.t is not None:
            info["t"] = float(self.t[k])
        return LinearModel.assembled(
            A=_own(self.A[k]), B=_own(self.B[k]), C=_own(self.C[k]), D=self.D[k],
            state_names=self.state_names, input_names=self.input_names,
            output_names=self.output_names, E=None, F=None, operating_point=op, G=None,
            name=self.name, info=info, f0=_own(self.f0[k]) if moving else None, dt=self.dt,
            **{key: None if getattr(self, key) is None else _own(getattr(self, key)[k])
               for key in _SECOND_ORDER})

    def discretize(self, dt: float, method: str = "zoh") -> TrajectoryModel:
        """The discrete models over sample time ``dt`` [s], point by point, as
        :meth:`LinearModel.discretize` gives them (:mod:`pinlin.discretization`), vectorized:
        ``"zoh"`` by batched matrix exponentials, ``"euler"`` (semi-implicit: v, then dq with
        the new v) by batched products. C, D, the states and ``a`` are unchanged; the
        second-order matrices describe the continuous model and are left out (None), as
        :meth:`LinearModel.discretize` leaves them out.

        Raises:
            ArgumentError: ``dt`` not a positive finite number [s], an unknown method,
                models that are already discrete, or ``"euler"`` on models whose states are
                not [q:...; v:...] or whose inputs act on the positions.
            ModelError: ``dt`` so long that a discrete matrix overflows (naming the point),
                or that the zero-order hold keeps no correct digit.
        """
        from .discretization import (
            check_mechanical,
            check_step,
            refuse_overflow,
            stacked_euler,
            stacked_zoh,
            warn_if_inaccurate,
        )

        dt = check_step(dt, method)
        if self.dt:
            raise ArgumentError("model", f"trajectory model '{self.name}' is already discrete "
                                         f"(dt = {self.dt:g} s)")
        if method == "euler":
            check_mechanical(self.name, self.state_names, self.B)
        elif method == "zoh":   # before the exponentials: refuses a dt without a correct digit
            warn_if_inaccurate(self.name, dt, self.A)
        with np.errstate(over="ignore", invalid="ignore"):  # refused below, naming dt
            A_d, B_d, f_d = (stacked_zoh if method == "zoh" else stacked_euler)(
                self.A, self.B, self.f0, dt)
        refuse_overflow(self.name, dt, method, A_d, B_d, f_d)
        for arr in (A_d, B_d, f_d):
            arr.setflags(write=False)
        kept = {k: _own(v) if isinstance(v, np.ndarray) else v for k, v in self.__dict__.items()}
        return TrajectoryModel.trusted(**{
            **kept, "A": A_d, "B": B_d, "f0": f_d, "dt": dt,
            **dict.fromkeys(_SECOND_ORDER),
            "info": {**self.info, "discretization": {"method": method, "dt": dt}}})

    # ----------------------------------------------------------------------------------------
    def save(self, path: str | Path) -> Path:
        """Write the models as ``.npz`` or MATLAB ``.mat`` (atomically: a temporary file beside
        it, renamed into place). :meth:`load` reads it back; nothing in it is a pickle.

        Raises:
            ArgumentError: ``path`` is not a path.
            ModelFileError: another suffix, or the file cannot be written.
        """
        from .trajectory_files import save_trajectory_model

        return save_trajectory_model(self, path)

    @classmethod
    def load(cls, path: str | Path) -> TrajectoryModel:
        """Read models written by :meth:`save` (never unpickles anything).

        Raises:
            ArgumentError: ``path`` is not a path.
            ModelFileError: missing file, unknown suffix, or content that is not a trajectory
                model pinlin wrote (the message names the file and what is wrong).
        """
        from .trajectory_files import load_trajectory_model

        return load_trajectory_model(path, cls)


def _moving(model: TrajectoryModel, rows: slice = slice(None)) -> np.ndarray:
    """Which points (``rows``, default all) :meth:`TrajectoryModel.at` gives as moving (with
    their f0): a velocity or acceleration, or constraint forces outside a schedule of rest
    points (a falling point opted in)."""
    moving = model.v[rows].any(axis=1) | model.a[rows].any(axis=1)
    if model.lam is not None and not model.info.get("at_rest"):
        moving = np.ones_like(moving)
    return moving


def _check_rest_drift(model: TrajectoryModel) -> None:
    """Refuse a drift f0 at a point at rest: :meth:`TrajectoryModel.at` gives such a point as
    an equilibrium, without f0, so a drift there (a file edited by hand) would be dropped.

    Raises:
        ArgumentError: naming the first such point and its largest |f0|.
    """
    still = ~_moving(model)
    drifting = np.flatnonzero(still & model.f0.any(axis=1))
    if drifting.size:
        k = int(drifting[0])
        raise ArgumentError("f0", f"point {k} is at rest (v = 0, a = 0) but its drift f0 is "
                                  f"not zero (max |f0| = {np.abs(model.f0[k]).max():.3g}, "
                                  f"{drifting.size} such point(s)): a point at rest has no "
                                  "drift; give its velocity and acceleration, or f0 = 0")


def _check_second_order_points(model: TrajectoryModel) -> None:
    """:func:`pinlin.model_checks.check_second_order` at every point: M, C_damp, K and Bu
    describe the dynamics of A and B (:func:`pinlin.modal` reads them in place of A).

    Raises:
        ModelError: naming the point, the block and the residual.
    """
    if model.M is None or model.dt:
        return
    for k in range(len(model)):
        try:
            check_second_order(SimpleNamespace(
                name=model.name, dt=0.0, A=model.A[k], B=model.B[k], M=model.M[k],
                C_damp=model.C_damp[k], K=model.K[k], Bu=model.Bu[k]))
        except ModelError as exc:
            raise ModelError(f"point {k} of {len(model)}: {exc}") from None


def _check_widths(model: TrajectoryModel, n: int) -> None:
    """A configuration has at least one entry per velocity (nq >= nv), and the velocities
    cover the n/2 coordinates of the states [dq; v] (a mechanism's states are its
    independent coordinates, fewer than nv).

    Raises:
        ShapeError: naming the array and the widths.
    """
    nq, nv = model.q.shape[1], model.v.shape[1]
    if nv < n // 2:
        raise ShapeError(f"v and a must have at least n/2 = {n // 2} columns (the coordinates "
                         f"of the states), got {nv}")
    if nq < nv:
        raise ShapeError(f"q must have at least as many columns as v ({nv}), got {nq}")


def _check_info(model: TrajectoryModel) -> None:
    """The entries of ``info`` that :meth:`TrajectoryModel.at` reads: ``lam_names`` (one
    string per column of lam, given exactly when lam is), ``at_rest`` (a boolean) and a
    mechanism's ``loops`` (lists of N numbers: condition, velocity_correction,
    position_correction).

    Raises:
        ArgumentError: naming the entry and what it must be.
    """
    info, N = model.info, model.A.shape[0]
    names = info.get("lam_names", ())
    width = 0 if model.lam is None else model.lam.shape[1]
    if isinstance(names, str) or not isinstance(names, Sequence) or \
            not all(isinstance(x, str) for x in names) or len(names) != width:
        raise ArgumentError("info", f"info['lam_names'] must name each of the {width} columns "
                                    f"of lam (a list of strings), got {show(names)}")
    if not isinstance(info.get("at_rest", False), bool):
        raise ArgumentError("info", f"info['at_rest'] must be true or false, got "
                                    f"{show(info['at_rest'])}")
    loops = info.get("loops")
    if loops is None:
        return
    keys = ("condition", "velocity_correction", "position_correction")
    if not isinstance(loops, Mapping) or any(
            isinstance(loops.get(k), str) or not isinstance(loops.get(k), Sequence)
            or len(loops[k]) != N or not all(isinstance(x, int | float) and
                                             not isinstance(x, bool) for x in loops[k])
            for k in keys):
        raise ArgumentError("info", f"info['loops'] must hold {', '.join(keys)}: lists of "
                                    f"{N} numbers, one per point")


def _stack(key: str, value: Any, shape: tuple[int, ...]) -> np.ndarray:
    """``value`` as a read-only float64 array of ``shape`` (-1: free), finite."""
    if type(value) is np.ndarray and value.dtype == np.float64:
        arr = value   # shared when read-only (below), as the model's own arrays are
    else:
        arr = real_array(value, key, "an array of real numbers")
    want = tuple(arr.shape[i] if s == -1 and i < arr.ndim else s for i, s in enumerate(shape))
    if arr.shape != want or any(s < 0 for s in want):
        raise ShapeError(f"{key} must have shape {_shape_text(shape)}, got {arr.shape}")
    if not np.isfinite(arr).all():
        raise ModelError(f"{key} has NaN or inf; a trajectory model with NaN or inf is never "
                         "built")
    if arr is not value or arr.flags.writeable or reusable_memory(arr):  # owns its arrays
        arr = arr.copy()
        arr.setflags(write=False)
    return arr


def _shape_text(shape: tuple[int, ...]) -> str:
    return "(" + ", ".join("?" if s < 0 else str(s) for s in shape) + ")"


# --------------------------------------------------------------------------------------------
# linearize_trajectory


__all__ = ["TrajectoryModel"]

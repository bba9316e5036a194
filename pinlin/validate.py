"""``pinlin validate``: every linear model checked against MuJoCo, which shares none of its code.

For one system: (1) sanity at q0 — mass matrix, generalized gravity and total mass of the MuJoCo
scene against Pinocchio's (a mismatch stops with the worst joint named); (2) matrices — the
continuous A recovered exactly from MuJoCo's centered ``mjd_transitionFD`` against pinlin's A
(open chains; with loops MuJoCo's state is the dependent coordinates under soft equalities, a
different model, so only eigenvalues are compared); (3) eigenvalues — those of MuJoCo's continuous A
(recovered exactly from the one-step map, so free of the time-step bias that log(z)/dt carries:
O(dt^2) undamped, O(dt) damped; log(z)/dt is listed beside them) matched to pinlin's by linear
assignment; rigid (zero) modes compared in absolute terms; MuJoCo's extra soft-constraint modes
(2 per loop row) set aside.

Tolerances, written into every report:

- matrix: 1e-8 relative (max |A_mj - A| / max |A|). MuJoCo's centered differences at eps and
  2 eps = 3e-4, 6e-4 combined by Richardson leave O(eps^4) + u / eps, ~1e-12..1e-10 relative
  (plain centered differences bottom out near 1e-9 on these robots).
- eigenvalues, non-rigid: 1e-6 relative, or the first-order perturbation bound
  10 kappa_i |A_mj - A|_2 / |lam_i| where that is larger (kappa_i: the eigenvalue's condition
  number from pinlin's left and right vectors): a tiny or ill-conditioned eigenvalue cannot be
  resolved to 1e-6 from finite differences, and the report counts and marks those modes.
  dt = min(1e-3, 0.01 / max |lam|) for open chains keeps the
  listed log(z)/dt within about 1e-5 of the continuous eigenvalues.
- rigid and near-rigid modes: a zero eigenvalue of a Jordan block moves like the square root
  of a perturbation of A, with constants set by the whole model. pinlin perturbs the bottom
  block row of its own A by random matrices with entries of the measured difference |dA|
  (1e-8 max |A| for loops) and
  takes 10x the largest move of its zero eigenvalues as the absolute tolerance; eigenvalues
  below it are compared in absolute terms.
- loops: MuJoCo's equality constraints leak a fraction 1 - d (impedance d <= 0.9999) of the
  free acceleration: the physical eigenvalues are off by O(1e-4) at d = 0.9999. pinlin builds
  MuJoCo at d = 0.999 and d = 0.9999 (time constant 2 dt) and extrapolates each matched
  eigenvalue linearly to d = 1; both raw and extrapolated errors are reported. The step is
  set by the system's own time scale, dt = :data:`LOOP_PHASE` / max |lam| (at most
  :data:`LOOP_DT_MAX`): the soft constraints then stay 1 / (2 LOOP_PHASE) = 1000 times faster
  than the fastest mode at any size, and the MuJoCo problem is the same problem with time
  stretched (dynamic similarity), so its error does not grow with the system. A fixed
  dt = 1e-4 s failed the bundled four-bar made 4x larger (error 1.2e-6 against 1e-6) and
  256x larger (1.2e-4): the constraint springs, stiff as 1 / dt^2, amplify the rounding of
  the positions against ever slower modes.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from os import PathLike
from pathlib import Path

import numpy as np
from scipy.optimize import linear_sum_assignment

from .files import check_folder_target, check_ours, make_folder
from .validation_report import (  # noqa: F401  (re-exported: the report's old home)
    INDEX_MARKER,
    INDEX_NAME,
    PNG_MARKER,
    REPORT_MARKER,
    picture_name,
    write_report,
    write_summary,
)

MATRIX_TOL = 1e-8
#: Moving-state check: pinlin's Euler step against MuJoCo's (A_d entries are O(1); transition
#: differences at 3e-4 and 6e-4, Richardson-combined, leave O(eps^4) + eps_mach |x| / eps;
#: measured on the 31 systems it applies to: at most 9e-10, tiago_pro's light fingers).
MOVING_TOL = 1e-8
MOVING_SEED = 20261123
EIG_TOL = 1e-6
#: Open chains: MuJoCo's centered differences at eps and 2 eps, combined by Richardson
#: extrapolation (the O(eps^2) truncation cancels; what is left is O(eps^4) + u / eps).
EPS_OPEN = 3e-4
#: Loops: stiff soft constraints (time constant 2 dt) make larger steps inaccurate.
EPS_LOOP = 1e-6
#: Loops: MuJoCo's step times the fastest eigenvalue of pinlin's model, max |lam| dt [-]
#: (module docstring). Measured on the bundled four-bar's extrapolated eigenvalue error:
#: 4e-8 at 4.8e-4 (its old dt = 1e-4 s), 4e-6 at 1.4e-4 (rounding amplified by stiffer
#: constraints), 4e-7 at 1.4e-3 and 4.8e-3; the delta 1e-7 from 8e-4 to 8e-3.
LOOP_PHASE = 5e-4
#: Loops: the longest step [s], for a system whose modes are all (near) rigid.
LOOP_DT_MAX = 1e-2


@dataclass
class Validation:
    """Outcome for one system."""

    name: str
    status: str                      # "pass", "FAIL", "MuJoCo refuses", "pinlin refuses", ...
    reason: str = ""
    effects: list[str] = field(default_factory=list)
    nv: int = 0
    dt: float = float("nan")
    sanity: dict[str, float] = field(default_factory=dict)
    matrix_error: float | None = None
    eig_error: float = float("nan")
    eig_error_raw: float = float("nan")
    rigid_error: float = float("nan")
    rigid_tol: float = float("nan")
    table: list[tuple] = field(default_factory=list)
    set_aside: list[complex] = field(default_factory=list)
    pinlin_eigs: np.ndarray | None = None
    mujoco_eigs: np.ndarray | None = None
    log_eigs: np.ndarray | None = None
    eig_tols: np.ndarray | None = None
    conditioning_limited: int = 0
    #: URDF links merged into the bodies Pinocchio simulates ("link -> body (mass)"), because
    #: MuJoCo refused the inertia of the links in ``refused`` on their own.
    merged: list[str] = field(default_factory=list)
    refused: list[str] = field(default_factory=list)
    #: PNG of the MuJoCo scene at the operating point, or why there is none.
    picture: bytes | None = None
    picture_note: str = ""
    #: Moving-state check (fixed-base open chains without damping): max |A_d - A_d,MuJoCo| of
    #: pinlin's Euler-discretized model against MuJoCo's step at a seeded moving state, and
    #: max |B_d - B_d,MuJoCo| / max |B_d,MuJoCo|; None where it does not apply.
    moving_error: tuple[float, float] | None = None

    @property
    def passed(self) -> bool:
        return self.status == "pass"

    @property
    def failed(self) -> bool:
        return self.status == "FAIL"


def _map_matrix(ms, system, q) -> np.ndarray:
    """T with v_mujoco = T v_pinlin at q (free-joint linear part in the world frame)."""
    from .mjcf import _base_rotation

    T = np.eye(system.nv)
    if ms.free:
        T[:3, :3] = _base_rotation(system, q)
    return T


def sanity(ms, system, q: np.ndarray) -> dict[str, float]:
    """Relative mismatches of M, generalized gravity and total mass at q (v = 0).

    Raises:
        MujocoError: a mismatch above 1e-9 relative, naming the worst joint.
    """
    import mujoco
    import pinocchio as pin

    from .mjcf import MujocoError, set_state

    nv = system.nv
    set_state(ms, system, q, np.zeros(nv), np.zeros(nv))
    M_mj = np.zeros((nv, nv))
    mujoco.mj_fullM(ms.model, ms.data, M_mj)
    idx = ms.dof
    T = _map_matrix(ms, system, q)
    M_mj = T.T @ M_mj[np.ix_(idx, idx)] @ T
    g_mj = T.T @ ms.data.qfrc_bias[idx]  # gravity only at v = 0 (springs are passive forces)
    M = system.mass_matrix(q)
    g = system.static_force(q)
    moving = ms.model.body_weldid != 0   # bodies welded to the world do not move
    mass_mj = float(np.sum(ms.model.body_mass[moving]))
    mass = float(pin.computeTotalMass(system.model))
    out = {
        "mass matrix": float(np.abs(M_mj - M).max() / np.abs(M).max()),
        "gravity vector": float(np.abs(g_mj - g).max() / max(np.abs(g).max(), 1e-300))
        if np.any(g) else float(np.abs(g_mj).max()),
        "total mass": abs(mass_mj - mass) / mass,
    }
    for key, value in out.items():
        if value > 1e-9:
            if key == "total mass":
                where = f"MuJoCo {mass_mj:.9g} kg, Pinocchio {mass:.9g} kg"
            else:
                diff = np.abs(M_mj - M).max(axis=1) if key == "mass matrix" else np.abs(g_mj - g)
                where = f"worst at joint coordinate '{system.coordinate_names[int(diff.argmax())]}'"
            raise MujocoError(f"scene '{system.scene.name}': {key} of the MuJoCo scene differs "
                              f"from Pinocchio's by {value:.2e} (relative), {where}")
    return out


def _eigs_mujoco(ms, system, op, loops: bool) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(eigenvalues of MuJoCo's continuous A, log(z)/dt of its one-step map, the continuous A
    in MuJoCo coordinates)."""
    from .mjcf import recover_continuous, transition_matrix

    if loops:
        A_d = transition_matrix(ms, system, op, eps=EPS_LOOP, centered=True)
    else:
        A_2 = transition_matrix(ms, system, op, eps=2 * EPS_OPEN, centered=True)
        A_1 = transition_matrix(ms, system, op, eps=EPS_OPEN, centered=True)
        A_d = (4.0 * A_1 - A_2) / 3.0
    A_c = recover_continuous(ms, A_d)
    z = np.linalg.eigvals(A_d).astype(complex)
    with np.errstate(divide="ignore", invalid="ignore"):  # z = 0: a soft mode gone in a step
        return np.linalg.eigvals(A_c), np.log(z) / ms.dt, A_c


def _zero_sensitivity(A: np.ndarray, ref: np.ndarray, d_abs: float) -> float:
    """Largest move of the (near-)zero eigenvalues of A under random perturbations of its bottom
    block row with entries of size d_abs (three seeded draws); at least sqrt(d_abs |A|)."""
    scale = math.sqrt(d_abs * float(np.abs(A).max()))
    small = np.abs(ref) <= 10 * scale
    if not small.any():
        return scale
    rng = np.random.default_rng(0)
    worst = scale
    n = A.shape[0] // 2
    for _ in range(3):
        E = np.zeros_like(A)  # differences live in the bottom block row; the top is [0, I]
        E[n:] = d_abs * rng.uniform(-1.0, 1.0, (A.shape[0] - n, A.shape[1]))
        lam = np.linalg.eigvals(A + E)
        moved = lam[_match(ref, lam)]
        worst = max(worst, float(np.abs(moved[small] - ref[small]).max()))
    return worst


def _match(ref: np.ndarray, lam: np.ndarray) -> np.ndarray:
    """Indices into lam matched to each ref eigenvalue (rectangular linear assignment)."""
    cost = np.abs(ref[:, None] - lam[None, :])
    rows, cols = linear_sum_assignment(cost)
    out = np.empty(len(ref), dtype=int)
    out[rows] = cols
    return out


def _resolve(scene: object, name: str | None) -> tuple[object, str]:
    """(scene, report name) for a Scene, a System, or a scene file / URDF / bundled scene /
    robot name resolved as ``pinlin validate`` resolves it."""
    from .bench import check_scene
    from .exceptions import ArgumentError
    from .scene import Scene
    from .system import System

    if name is not None and not isinstance(name, str):
        raise ArgumentError("name", f"expected a report name (str), got {type(name).__name__}")
    if isinstance(scene, System):
        scene = scene.scene
    if isinstance(scene, Scene):
        return scene, name or scene.name
    if isinstance(scene, str | PathLike):
        text = str(Path(scene)) if isinstance(scene, PathLike) else scene
        if not isinstance(text, str) or not text:
            raise ArgumentError("scene", "expected a scene file, URDF, bundled scene or robot "
                                         "name")
        return check_scene(text)[0], name or report_name(text)
    raise ArgumentError("scene", "expected a pinlin.Scene, a pinlin.System, or a scene file, "
                                 "URDF, bundled scene or robot name (str or path), got "
                                 f"{type(scene).__name__}")


def validate(scene, name: str | None = None, *, picture: bool | None = None) -> Validation:
    """Compare one scene's linear model with MuJoCo.

    Args:
        scene: A :class:`~pinlin.Scene`, its :class:`~pinlin.system.System`, or a scene file,
            URDF, bundled scene or robot name (str or path), resolved as ``pinlin validate``
            resolves it: a floating-base robot named so falls freely at rest from a rotated
            base pose (:func:`pinlin.bench.check_scene`).
        name: Name of the report (default: the scene's name, or the file's stem).
        picture: Render the MuJoCo scene at the operating point into ``picture`` (PNG; see
            :mod:`pinlin.mjcf_picture`); default: for scenes with loops (the mechanisms).

    Returns:
        The outcome; a scene pinlin or MuJoCo refuses is a result with that status, not an
        exception.

    Raises:
        ArgumentError: ``scene`` or ``name`` of the wrong type.
        UnknownRobotError, SceneError, UrdfError, ...: a name or file that does not resolve
            to a scene.
    """
    from . import mjcf
    from .exceptions import PinlinError
    from .formulations.constrained import constrained_effects
    from .linearization import linearize
    from .modal import modal

    scene, name = _resolve(scene, name)
    if picture is not None and not isinstance(picture, bool):
        from .exceptions import ArgumentError

        raise ArgumentError("picture", f"expected True, False or None, got {picture!r}")
    try:
        system = scene.system
        model = linearize(scene)
    except PinlinError as exc:
        return Validation(name, "pinlin refuses", " ".join(str(exc).split()))
    effects = constrained_effects(system)
    res = Validation(name, "pass", effects=effects, nv=system.nv)
    modes = modal(model, method="general")
    ref = modes.eigenvalues
    res.pinlin_eigs = ref
    loops = bool(system.constraints)
    if loops:   # (the fastest mode, however slow: a floor of 1 would undo the scaling)
        fastest = float(np.abs(ref).max(initial=0.0))
        dt = LOOP_DT_MAX if not fastest * LOOP_DT_MAX > LOOP_PHASE else \
            max(LOOP_PHASE / fastest, mjcf.MIN_TIME_STEP)
    else:
        lam_max = float(np.abs(ref).max(initial=1.0))
        dt = min(1e-3, 0.01 / max(lam_max, 1e-9))
    res.dt = dt
    op = model.operating_point
    try:
        ms = mjcf.build(system, dt=dt)
        res.merged = [m.describe() for m in ms.merged]
        res.refused = list(dict.fromkeys(m.refused for m in ms.merged))
        res.sanity = sanity(ms, system, op.q)
        lam, lam_log, A_c = _eigs_mujoco(ms, system, op, loops)
        if not loops:
            A_mj = mjcf.to_pinlin_coordinates(ms, system, op, A_c)
            res.matrix_error = float(np.abs(A_mj - model.A).max() / np.abs(model.A).max())
        matched = lam[_match(ref, lam)]
        res.log_eigs = lam_log[_match(ref, lam_log)]
        raw = matched
        if loops:
            ms_soft = mjcf.build(system, dt=dt, impedance=0.999)
            lam_soft = _eigs_mujoco(ms_soft, system, op, loops)[0]
            soft = lam_soft[_match(ref, lam_soft)]
            d1, d2 = 0.999, mjcf.LOOP_IMPEDANCE
            matched = raw + (raw - soft) * (1 - d2) / (d2 - d1)
        res.mujoco_eigs = lam
        used = set(_match(ref, lam).tolist())
        res.set_aside = [lam[k] for k in range(len(lam)) if k not in used]
        if not loops and not ms.free and not system.has_damping:
            res.moving_error = _moving_state_check(ms, system, op)
    except mjcf.MujocoError as exc:
        status = "MuJoCo refuses" if "refuses" in str(exc) or "cannot import" in str(exc) \
            else ("not expressible" if "counterpart" in str(exc) else "FAIL")
        res.status, res.reason = status, " ".join(str(exc).split())
        return res
    if not len(ref):   # nothing moves (e.g. a welded body): every MuJoCo mode is a soft one
        # The constraints hold all nv velocities (redundant rows add none): 2 nv soft modes.
        expected = 2 * system.nv
        if len(res.set_aside) != expected:
            res.status, res.reason = "FAIL", (f"pinlin's model has no states; MuJoCo's has "
                                              f"{len(res.set_aside)} eigenvalues where the "
                                              f"{system.nv} velocities its constraints hold "
                                              f"give {expected}")
        return res
    # Zero eigenvalues (Jordan blocks) move like sqrt of a perturbation of A, with constants
    # set by the whole model: measure it on pinlin's own A perturbed at the size of the
    # measured difference. Below that floor eigenvalues are compared in absolute terms.
    a_max = float(np.abs(model.A).max())
    d_abs = (max(res.matrix_error, 1e-12) if res.matrix_error is not None else MATRIX_TOL) * a_max
    res.rigid_tol = 10 * _zero_sensitivity(model.A, ref, d_abs) + modes.rigid_tol
    rigid = modes.rigid | (np.abs(ref) <= res.rigid_tol)
    # First-order bound: |d lam_i| <= kappa_i |dA|_2 (kappa_i: eigenvalue condition number).
    # Where MuJoCo's own finite-difference error cannot resolve 1e-6, the bound is the tolerance.
    n = len(ref)
    dA2 = (float(np.linalg.norm(A_mj - model.A, 2)) if res.matrix_error is not None
           else MATRIX_TOL * a_max * n)
    kappa = np.minimum(np.nan_to_num(modes.condition, nan=1e30, posinf=1e30), 1e30)
    res.eig_tols = np.maximum(EIG_TOL, 10 * kappa * dA2 / np.maximum(np.abs(ref), 1e-30))
    rel = np.abs(matched - ref) / np.where(rigid, 1.0, np.abs(ref))
    rel_raw = np.abs(raw - ref) / np.where(rigid, 1.0, np.abs(ref))
    res.eig_error = float(rel[~rigid].max(initial=0.0))
    res.eig_error_raw = float(rel_raw[~rigid].max(initial=0.0))
    res.conditioning_limited = int(np.sum(~rigid & (res.eig_tols > EIG_TOL)))
    res.rigid_error = float(np.abs(matched[rigid] - ref[rigid]).max(initial=0.0))
    res.table = [(ref[i], matched[i], res.log_eigs[i], rel[i],
                  "rigid (abs.)" if rigid[i] and not modes.rigid[i] else modes.kind(i),
                  res.rigid_tol if rigid[i] else res.eig_tols[i]) for i in range(len(ref))]
    failures = []
    if res.matrix_error is not None and res.matrix_error > MATRIX_TOL:
        failures.append(f"matrix error {res.matrix_error:.1e} > {MATRIX_TOL:.0e}")
    if res.moving_error is not None and max(res.moving_error) > MOVING_TOL:
        failures.append(f"moving-state step error {max(res.moving_error):.1e} > "
                        f"{MOVING_TOL:.0e}")
    bad = ~rigid & (rel > res.eig_tols)
    if bad.any():
        k = int(np.argmax(np.where(bad, rel / res.eig_tols, 0.0)))
        failures.append(f"eigenvalue {ref[k]:.6g}: error {rel[k]:.1e} > tolerance "
                        f"{res.eig_tols[k]:.1e}")
    if res.rigid_error > res.rigid_tol:
        failures.append(f"rigid modes {res.rigid_error:.1e} > {res.rigid_tol:.1e}")
    if failures:
        res.status, res.reason = "FAIL", "; ".join(failures)
    if picture if picture is not None else bool(scene.loops):
        _render(res, ms, system, op)
    return res


def _render(res: Validation, ms, system, op) -> None:
    """The MuJoCo scene at the operating point as a PNG (``res.picture``), or why not."""
    from .mjcf import set_state
    from .mjcf_picture import NoRendererError, render_png

    set_state(ms, system, op.q, op.v, np.zeros(system.nv))
    try:
        res.picture = render_png(ms.spec.to_xml(), ms.data.qpos)
    except NoRendererError as exc:
        res.picture_note = (f"no OpenGL backend could render here ({exc}); set MUJOCO_GL to a "
                            "working backend (egl, osmesa or glfw) and run again")


def targets(all_systems: bool, names: list[str]) -> list[str]:
    if not all_systems:
        return names
    from .robots import loadable_robots
    from .scene import bundled_scenes

    robots = [n for n, reason in loadable_robots().items() if reason is None]
    return sorted(bundled_scenes()) + robots


def report_name(target: str) -> str:
    """The file name (without suffix) of a target's report: a scene or URDF file's stem, or
    the bundled scene or robot name."""
    path = Path(target)
    return path.stem if path.suffix in (".toml", ".urdf") else path.name


def run(names: Sequence[str], out_dir: str | Path = "validation/reports", progress: bool = True,
        command: str = "pinlin validate", summary: bool = True, *, strict: bool = True,
        merge: bool = True, announce: bool = True) -> list[Validation]:
    """Validate ``names`` (scene files, bundled scenes, robots), write reports; returns them.

    Everything that can be refused is refused before any work and before anything is
    written: an output folder that is a file, two targets with the same report name, an
    existing report or index that pinlin did not write and, with ``strict``, a target that
    names nothing (or a scene that does not build). Without ``strict`` (``--all``) such a
    target gets a "pinlin refuses" row instead. Reports are written atomically as each
    system is done; the index merges into an existing one (``merge``: the rows of systems not
    run are kept and the totals count every row). With ``announce``, one line on stdout says
    where the reports and the index were written and the index's totals.

    Raises:
        ArgumentError: ``names`` is not a list of names, or two give the same report name.
        UnknownRobotError, SceneError, UrdfError, ...: with ``strict``, a target that does
            not resolve to a scene.
        ModelFileError: the output folder cannot be used, or a file cannot be written.
    """
    from .bench import Progress, check_scene
    from .exceptions import ArgumentError, PinlinError

    if isinstance(names, str) or not all(isinstance(n, str) for n in names):
        raise ArgumentError("names", "expected a list of scene files, bundled scenes or "
                                     "robot names")
    names = list(dict.fromkeys(names))  # a system named twice is validated once
    folder = check_folder_target(out_dir, "out_dir")
    by_report: dict[str, str] = {}
    for target in names:
        key = report_name(target)
        if key in by_report:
            raise ArgumentError("names", f"'{by_report[key]}' and '{target}' would both write "
                                         f"the report {key}.md")
        if key in ("", ".", "..", "README"):
            raise ArgumentError("names", f"'{target}' gives no usable report name")
        by_report[key] = target
    for key in by_report:  # never replace a file pinlin did not write
        check_ours(folder / f"{key}.md", REPORT_MARKER)
        check_ours(folder / f"{key}.png", PNG_MARKER)
        check_ours(folder / picture_name(key), PNG_MARKER)
    if summary:
        check_ours(folder / INDEX_NAME, INDEX_MARKER)
    scenes: dict[str, object] = {}
    for target in names:
        try:
            scene = check_scene(target)[0]
            scene.system  # noqa: B018  built now: a scene that does not build is refused here
            scenes[target] = scene
        except PinlinError as exc:
            if strict:
                raise
            scenes[target] = exc
    make_folder(folder)
    bar = Progress(len(names), progress)
    results = []
    try:
        for target in names:
            name, scene = report_name(target), scenes[target]
            if isinstance(scene, PinlinError):
                res = Validation(name, "pinlin refuses", " ".join(str(scene).split()))
            else:
                try:
                    res = validate(scene, name=name)
                except PinlinError as exc:
                    res = Validation(name, "pinlin refuses", " ".join(str(exc).split()))
            results.append(res)
            write_report(res, folder)
            bar.step(f"{res.name}: {res.status}")
    finally:
        bar.close()
    where = f"{len(results)} report{'s' * (len(results) != 1)} written to {folder}"
    if summary:
        counts = write_summary(results, folder, command, merge=merge)
        where += (f"; index {folder / INDEX_NAME}: {sum(counts.values())} systems ("
                  + ", ".join(f"{k}: {v}" for k, v in counts.items()) + ")")
    if announce:
        print(where)
    return results


def _moving_state_check(ms, system, op) -> tuple[float, float]:
    """pinlin's Euler-discretized model at a seeded moving state (q0, random v in [-1, 1]
    rad/s, u0) against MuJoCo's own step there (:func:`pinlin.mjcf.euler_step_jacobians`)."""
    from . import mjcf
    from .linearization import linearize

    rng = np.random.default_rng(MOVING_SEED)
    v0 = rng.uniform(-1.0, 1.0, system.nv)
    model = linearize(system, q=op.q, v=v0, u=op.u, estimate_error=False)
    A_mj, B_mj = mjcf.euler_step_jacobians(ms, system, model.operating_point)
    disc = model.discretize(ms.dt, "euler")
    b_scale = max(float(np.abs(B_mj).max(initial=0.0)), np.finfo(float).tiny)
    return (float(np.abs(disc.A - A_mj).max()),
            float(np.abs(disc.B - B_mj).max(initial=0.0)) / b_scale)

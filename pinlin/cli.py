"""Command-line interface: ``pinlin linearize``, ``pinlin trajectory``, ``pinlin validate``,
``pinlin export-mjcf``, ``pinlin bench``, ``pinlin graph``, ``pinlin robots``.

Bad input never produces a traceback: the error goes to stderr as one line and the exit status
is 2. Warnings (:class:`pinlin.AccuracyWarning` and others) go to stderr as one
``warning: ...`` line each, without the Python source line; this applies inside :func:`main`
only, library users keep Python's usual warnings.
"""

from __future__ import annotations

import argparse
import os
import sys
import warnings
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from .exceptions import ArgumentError, ModelFileError, PinlinError

if TYPE_CHECKING:
    from .coordinates import JointInfo

EXIT_BAD_INPUT = 2
#: Width of printed matrices: wider ones are printed in labelled blocks of columns.
MATRIX_WIDTH = 100


class _Parser(argparse.ArgumentParser):
    """argparse with one-line errors (argparse prints the usage first by default)."""

    def error(self, message: str) -> None:  # type: ignore[override]
        message = " ".join(message.split())
        raise _UsageError(f"pinlin: error: {message} (see '{self.prog} --help')")


class _UsageError(Exception):
    pass


class _Done(Exception):  # noqa: N818  (not an error: the work is done)
    """Raised by an action that has printed everything (``--version``): exit status 0."""


class _VersionAction(argparse.Action):
    """``--version``: pinlin's version and those of the libraries it rests on."""

    def __init__(self, option_strings: Sequence[str], dest: str = argparse.SUPPRESS,
                 default: str = argparse.SUPPRESS, help: str | None = None) -> None:
        super().__init__(option_strings, dest, nargs=0, default=default, help=help)

    def __call__(self, parser: argparse.ArgumentParser, namespace: argparse.Namespace,
                 values: object, option_string: str | None = None) -> None:
        print(version_text())
        raise _Done


def version_text() -> str:
    """``pinlin X (pin Y, mujoco Z, numpy W, Python V)``: versions as imported."""
    import platform

    from . import __version__

    parts = []
    for label, module in (("pin", "pinocchio"), ("mujoco", "mujoco"), ("numpy", "numpy")):
        try:
            parts.append(f"{label} {__import__(module).__version__}")
        except Exception:  # noqa: BLE001  a missing or broken library is reported, not raised
            parts.append(f"{label} not importable")
    parts.append(f"Python {platform.python_version()}")
    return f"pinlin {__version__} ({', '.join(parts)})"


def _plural(count: int, word: str, plural: str | None = None) -> str:
    """"1 input", "2 inputs" (``plural`` for irregular words)."""
    return f"{count} {word if count == 1 else plural or word + 's'}"


def _show_warning(message: Warning | str, category: type[Warning], filename: str, lineno: int,
                  file: object = None, line: str | None = None) -> None:
    """``warnings.showwarning`` for the CLI: one ``warning: ...`` line on stderr (pinlin's own
    warnings bare, others with their category), no source line or file path."""
    text = " ".join(str(message).split())
    if not (category.__module__ or "").startswith("pinlin"):
        text = f"{category.__name__}: {text}"
    print(f"warning: {text}", file=sys.stderr)


def _check_out(path: Path) -> None:
    """Refuse an --out path before any work, so that a failure writes nothing: unknown
    format, a folder, a folder that does not exist or is a file, no permission."""
    from .files import check_file_target

    if path.suffix not in (".npz", ".mat", ".json"):
        raise ModelFileError(path, f"unknown model format '{path.suffix}'; expected .npz, .mat "
                                   "or .json")
    check_file_target(path)
    parent = path.parent if str(path.parent) else Path(".")
    if not os.access(parent, os.W_OK) or (path.exists() and not os.access(path, os.W_OK)):
        raise ModelFileError(path, "cannot write: permission denied")


def _file_name(option: str) -> Callable[[str], str]:
    """argparse ``type`` for an output option: an empty value is refused at once (it would
    otherwise be taken as "no file" and silently save nothing)."""

    def check(text: str) -> str:
        if not text.strip():
            raise ArgumentError(option, "needs a file name, got an empty string")
        return text

    return check


def _folder_name(value: str, option: str) -> str:
    if not value.strip():
        raise ArgumentError(option, "needs a folder name, got an empty string")
    return value


def _fmt(values: np.ndarray) -> str:
    return np.array2string(np.asarray(values), precision=6, suppress_small=True,
                           max_line_width=100)


def _number(x: float) -> str:
    """A matrix entry: 6 significant digits, exact zeros (also -0) as 0."""
    return "0" if x == 0 else f"{x:.6g}"


def _vector(values: np.ndarray) -> str:
    """[a b c] with 6 significant digits."""
    return "[" + " ".join(_number(float(x)) for x in values) + "]"


def format_matrix(key: str, matrix: np.ndarray, rows: Sequence[str], columns: Sequence[str],
                  width: int = MATRIX_WIDTH) -> str:
    """``key =`` and the matrix with its row and column names, in blocks of whole columns
    that fit in ``width`` characters; each block after the first of several names its
    columns (``A, columns 9-16 of 76 (v:...):``). Entries print with 6 significant digits;
    an exact zero as ``0`` and a nonzero entry below 1e-12 of the largest (rounding noise, for
    a matrix computed in float64) as ``~0``."""
    matrix = np.asarray(matrix)
    n_rows, n_cols = matrix.shape
    head = f"{key} = ({n_rows} x {n_cols})"
    if matrix.size == 0:
        return f"{head} empty"
    noise = 1e-12 * float(np.abs(matrix).max())
    cells = [[_number(float(x)) if not 0 < abs(x) < noise else "~0" for x in row]
             for row in matrix]
    label = max(len(r) for r in rows)
    widths = [max(len(columns[j]), *(len(cells[i][j]) for i in range(n_rows)))
              for j in range(n_cols)]
    blocks: list[tuple[int, int]] = []
    start, used = 0, label
    for j, w in enumerate(widths):
        if j > start and used + 2 + w > width:
            blocks.append((start, j))
            start, used = j, label
        used += 2 + w
    blocks.append((start, n_cols))
    lines = [head]
    for a, b in blocks:
        if len(blocks) > 1:
            lines.append(f"{key}, columns {a + 1}-{b} of {n_cols} ({columns[a]} .. "
                         f"{columns[b - 1]}):")
        lines.append(" " * label + "".join(f"  {columns[j]:>{widths[j]}}" for j in range(a, b)))
        for i in range(n_rows):
            lines.append(f"{rows[i]:<{label}}" + "".join(f"  {cells[i][j]:>{widths[j]}}"
                                                          for j in range(a, b)))
    return "\n".join(lines)


def _joint_value(j: JointInfo, values: np.ndarray) -> str:
    """A joint's configuration as a person reads it: angle, position and rpy, or the value."""
    import pinocchio as pin

    from .coordinates import FREE_FLYER, SPHERICAL

    if j.continuous:
        return f"{float(np.arctan2(values[1], values[0])):.6g} (angle)"
    if j.kind in (FREE_FLYER, SPHERICAL):
        quat = values[3:7] if j.kind == FREE_FLYER else values[:4]
        rpy = pin.rpy.matrixToRpy(pin.Quaternion(np.asarray(quat, float)).matrix())
        where = f"position {_vector(values[:3])} m, " if j.kind == FREE_FLYER else ""
        return f"{where}rpy {_vector(rpy)} rad"
    return _fmt(values) if j.nq > 1 else f"{values[0]:.6g}"


def _print_operating_point(model, system) -> None:
    op = model.operating_point
    print(f"scene '{model.name}': nq = {system.nq}, nv = {system.nv}, "
          f"{_plural(model.n_inputs, 'input')}, {_plural(model.n_outputs, 'output')}; "
          f"base {model.info['base']}")
    effects = model.info["effects"]
    print(f"effects in play: {', '.join(effects) if effects else 'none'}")
    extra = ""
    if "alpha" in model.info:
        extra = (f", alpha = {model.info['alpha']:g}, mu = {model.info['mu']:g}, "
                 f"Omega = {model.info['omega']:g} rad/s")
    elif "basis" in model.info:
        extra = f", {model.info['basis']} basis"
    steps = ""
    if "step" in model.info:
        steps = " (steps " + ", ".join(f"{k} {v:g}" for k, v in model.info["step"].items()) + ")"
    print(f"linear model: {model.info['formulation']} formulation, "
          f"{model.info['derivatives']} derivatives{steps}{extra}")
    if "error_estimate" in model.info:
        print(f"error estimate of A (relative, truncation + rounding): "
              f"{model.info['error_estimate']:.1e}")
    print("operating point:")
    for name, j in system.joints.items():
        print(f"  q[{name}] = {_joint_value(j, op.q[j.idx_q:j.idx_q + j.nq])}")
    for name, u in zip(model.input_names, op.u, strict=True):
        print(f"  {name} = {u:.6g}")
    if op.lam is not None:
        for name, lam in zip(op.lam_names, op.lam, strict=True):
            print(f"  lam[{name}] = {lam:.6g}")
    worst = float(np.abs(op.residual).max(initial=0.0)) if op.residual is not None else 0.0
    state = "equilibrium" if op.equilibrium else "NOT an equilibrium"
    print(f"  residual max |r| = {worst:.3e} (tolerance {op.tolerance:.1e}): {state}")
    for note in op.notes:
        print(f"  note: {note}")


def _cmd_linearize(args: argparse.Namespace) -> int:
    from .linear_model import LinearModel  # noqa: F401  (import cost paid before the work)
    from .linearization import linearize
    from .modal import modal
    from .scene import Scene

    out = Path(args.out) if args.out else None
    if out is not None:
        _check_out(out)
    scene = Scene.resolve(args.target)
    model = linearize(scene, formulation=args.formulation, derivatives=args.derivatives,
                      step=args.step,
                      allow_non_equilibrium=True if args.allow_non_equilibrium else None,
                      allow_ill_conditioned=args.allow_ill_conditioned,
                      basis=args.basis, alpha=args.alpha, mu=args.mu, omega=args.omega)
    _print_operating_point(model, scene.system)
    print()
    print(modal(model, method=args.method))
    if args.matrices:
        names = {"A": (model.state_names, model.state_names),
                 "B": (model.state_names, model.input_names),
                 "C": (model.output_names, model.state_names),
                 "D": (model.output_names, model.input_names)}
        for key, (rows, columns) in names.items():
            print(f"\n{format_matrix(key, getattr(model, key), rows, columns)}")
    if out is not None:
        model.save(out)
        print(f"\nmodel written to {out}")
    return 0


def _cmd_robots(args: argparse.Namespace) -> int:
    from .robots import load_robot, loadable_robots

    status = loadable_robots()
    ok = [n for n, reason in status.items() if reason is None]
    print(f"{len(ok)} of {_plural(len(status), 'example-robot-data robot')} "
          f"load{'s' if len(ok) == 1 else ''}:")
    for name in ok:
        rm = load_robot(name)
        base = "floating" if rm.free_flyer else "fixed"
        armature = "armature" if np.any(rm.model.armature) else ""
        print(f"  {name:28s} nq = {rm.model.nq:3d}  nv = {rm.model.nv:3d}  {base:8s} {armature}")
    failed = {n: r for n, r in status.items() if r is not None}
    if failed:
        print("do not load here:")
        for name, reason in failed.items():
            print(f"  {name:28s} {reason}")
    return 0


def _cmd_bench(args: argparse.Namespace) -> int:
    from .bench import MECHANISMS, ROBOTS, run

    _folder_name(args.out_dir, "--out-dir")
    systems = args.systems or list(ROBOTS + MECHANISMS)
    command = "pinlin bench" + "".join(f" {s}" for s in args.systems)
    if args.repeats != 5:
        command += f" --repeats {args.repeats}"
    run(systems, args.repeats, args.out_dir, not args.no_progress, command)
    return 0


def _cmd_validate(args: argparse.Namespace) -> int:
    from .validate import run, targets

    if not args.all and not args.targets:
        raise ArgumentError("SCENE_OR_ROBOT", "name scenes or robots, or give --all (see "
                                              "'pinlin validate --help')")
    if args.all and args.targets:
        raise ArgumentError("--all", "validates every bundled scene and robot; name systems "
                                     "or give --all, not both")
    _folder_name(args.out_dir, "--out-dir")
    names = targets(args.all, list(args.targets))
    command = "pinlin validate" + (" --all" if args.all else "") + "".join(
        f" {t}" for t in args.targets)
    # Named systems must all exist (else exit 2, nothing written) and merge into the index;
    # --all rebuilds the index and reports a system pinlin cannot build as a row.
    results = run(names, args.out_dir, not args.no_progress, command, strict=not args.all,
                  merge=not args.all)
    for r in results:
        print(f"{r.name:28s} {r.status:15s} {r.reason}")
    failed = [r.name for r in results if r.failed]
    print(f"{_plural(len(results), 'system')}: {sum(r.passed for r in results)} pass, "
          f"{len(failed)} fail"
          + (f" ({', '.join(failed)})" if failed else ""))
    return 1 if failed else 0


def _cmd_export_mjcf(args: argparse.Namespace) -> int:
    from .files import check_file_target, write_text_atomic
    from .mjcf import MujocoError, build, check_time_step
    from .scene import Scene

    dt = check_time_step(args.dt, "--dt")
    out = Path(args.output)
    if out.suffix != ".xml":
        raise ModelFileError(out, "expected an .xml file for MJCF")
    check_file_target(out)
    scene = Scene.resolve(args.target)
    inputs = {Path(p).resolve() for p in (scene.source, scene.system.urdf_path) if p}
    if out.resolve() in inputs:
        raise ModelFileError(out, "is an input of the scene (its scene file or URDF); choose "
                                  "another output name")
    ms = build(scene.system, dt=dt)
    try:
        xml = ms.spec.to_xml()
    except Exception as exc:  # noqa: BLE001  MuJoCo raises ValueError or RuntimeError
        raise MujocoError(f"MuJoCo cannot write MJCF for '{scene.name}': {exc}") from None
    write_text_atomic(out, xml)
    print(f"MJCF of '{scene.name}' written to {out} (nq = {ms.model.nq}, nv = {ms.model.nv}, "
          f"{_plural(ms.model.neq, 'equality', 'equalities')}, dt = {dt:g} s)")
    return 0


def _cmd_graph(args: argparse.Namespace) -> int:
    from .graph import Graph

    graph = Graph.load(args.file)
    tree = graph.normal_tree(combine=not args.no_combine)
    model = graph.linearize(combine=not args.no_combine, standard_form=args.standard_form)
    branches = _plural(len(graph.branches), "branch", "branches")
    print(f"graph '{graph.name}' ({graph.domain}): {branches}, inputs "
          f"{', '.join(model.input_names) or 'none'}")
    print(tree.describe())
    if "operating_point" in model.info:
        op = model.info["operating_point"]
        print("operating point: " + ", ".join(f"{k} = {v:.6g}" for k, v in
                                              {**op["x0"], **op["u0"]}.items()))
    if args.standard_form and graph.linearize(combine=not args.no_combine).E is not None:
        print("standard form: new state x' = x - E u (primed names), B' = B + A E, "
              "D' = D + C E (eqs. 90-93)")
    print(f"states: {', '.join(model.state_names)}")
    print(f"outputs: {', '.join(model.output_names)}")
    states, inputs, outputs = model.state_names, model.input_names, model.output_names
    shapes = {"A": (states, states), "B": (states, inputs), "E": (states, inputs),
              "C": (outputs, states), "D": (outputs, inputs), "F": (outputs, inputs)}
    for key, (rows, columns) in shapes.items():
        value = getattr(model, key)
        if value is not None:
            print(format_matrix(key, value, rows, columns))
    print(f"poles (eigenvalues of A) [1/s]: {format_poles(model.A)}")
    return 0


#: The trajectory command draws its progress bar once a run has taken this long [s].
PROGRESS_AFTER = 1.0


class _PointsBar:
    """``progress(done, total)`` for :func:`pinlin.linearize_trajectory`: a one-line bar on
    stderr, drawn once the run has taken :data:`PROGRESS_AFTER` seconds."""

    def __init__(self, enabled: bool) -> None:
        import time

        self.enabled, self.start, self.drawn = enabled, time.perf_counter(), False

    def __call__(self, done: int, total: int) -> None:
        import time

        if not self.enabled or (not self.drawn and
                                time.perf_counter() - self.start < PROGRESS_AFTER):
            return
        width = 30
        filled = int(width * done / total)
        sys.stderr.write(f"\r[{'#' * filled}{'.' * (width - filled)}] {done}/{total} points")
        sys.stderr.flush()
        self.drawn = True
        if done == total:
            sys.stderr.write("\n")
            self.enabled = False

    def close(self) -> None:
        """End a bar left part-drawn (a run stopped by an error)."""
        if self.enabled and self.drawn:
            sys.stderr.write("\n")
            sys.stderr.flush()
            self.enabled = False


def _dask_executor(address: str):
    """(client, executor) for the Dask scheduler at ``address``."""
    try:
        from distributed import Client
    except ImportError:
        raise ArgumentError("--dask", "needs Dask: pip install 'pinlin[dask]'") from None
    try:
        client = Client(address, timeout=10)
    except (OSError, TimeoutError, ValueError) as exc:
        raise ArgumentError("--dask", f"cannot reach a Dask scheduler at {address!r}: "
                                      f"{' '.join(str(exc).split()) or type(exc).__name__}") \
            from None
    return client, client.get_executor()


def _cmd_trajectory(args: argparse.Namespace) -> int:
    import time

    from .exceptions import ShapeError
    from .files import check_file_target
    from .scene import Scene
    from .trajectory import linearize_trajectory
    from .trajectory_files import MODEL_FORMATS, read_states

    out = Path(args.out)
    if out.suffix not in MODEL_FORMATS:
        raise ModelFileError(out, f"unknown trajectory model format '{out.suffix}'; expected "
                                  ".npz or .mat")
    check_file_target(out)
    parent = out.parent if str(out.parent) else Path(".")
    if not os.access(parent, os.W_OK) or (out.exists() and not os.access(out, os.W_OK)):
        raise ModelFileError(out, "cannot write: permission denied")
    if args.workers < 1:
        raise ArgumentError("--workers", f"expected a number of processes >= 1, got "
                                         f"{args.workers}")
    if args.dask is not None and args.workers != 1:
        raise ArgumentError("--dask", "runs on the cluster's workers; leave out --workers")
    if args.dt is not None and not (np.isfinite(args.dt) and args.dt > 0):
        raise ArgumentError("--dt", f"expected a sample time > 0 [s], got {args.dt:g}")
    if args.discretization is not None and args.dt is None:
        raise ArgumentError("--discretization", "applies with --dt (the sample time [s])")
    scene = Scene.resolve(args.target)
    q, v, u, t = read_states(args.states, scene.system)
    client = executor = None
    if args.dask is not None:
        client, executor = _dask_executor(args.dask)
    bar = _PointsBar(not args.no_progress)
    start = time.perf_counter()
    try:
        model = linearize_trajectory(scene, q, v, u, t, workers=args.workers,
                                     executor=executor, derivatives=args.derivatives,
                                     step=args.step, progress=bar)
    except ArgumentError as exc:
        bar.close()
        if exc.argument in ("q", "v", "u", "t"):
            raise ModelFileError(args.states, f"{exc.argument}: {exc.reason}") from None
        raise
    except ShapeError as exc:
        bar.close()
        raise ModelFileError(args.states, str(exc).replace("argument ", "")) from None
    except BaseException:
        bar.close()
        raise
    finally:
        if client is not None:
            client.close()
    elapsed = time.perf_counter() - start
    where = (f"Dask at {args.dask}" if args.dask else _plural(args.workers, "process",
                                                                "processes"))
    n_points = len(model)
    print(f"trajectory of '{model.name}': {_plural(n_points, 'point')}, "
          f"{_plural(len(model.state_names), 'state')}, "
          f"{_plural(len(model.input_names), 'input')}, "
          f"{_plural(len(model.output_names), 'output')}; {model.info['derivatives']} "
          f"derivatives ({model.info['path']}), {where}: {elapsed:.3g} s "
          f"({1e6 * elapsed / n_points:.3g} us per point)")
    if args.dt is not None:
        method = args.discretization or "zoh"
        model = model.discretize(args.dt, method)
        print(f"discretized: {method}, dt = {args.dt:g} s")
    model.save(out)
    print(f"models written to {out}")
    return 0


def format_poles(A: np.ndarray) -> str:
    """The eigenvalues of A, slowest first, a conjugate pair once as ``re +- im j``; "none"
    for a model without states."""
    if A.size == 0:
        return "none"
    lam = np.linalg.eigvals(A)
    lam = lam[np.lexsort((-lam.imag, lam.real, np.abs(lam)))]
    shown = []
    for x in lam:
        if x.imag < 0 and np.any(np.isclose(lam, x.conjugate(), rtol=1e-12, atol=0.0)):
            continue  # printed with its partner
        re = _number(float(x.real))
        shown.append(f"{re} +- {_number(float(x.imag))}j" if x.imag > 0 else re)
    return ", ".join(shown)


def build_parser() -> argparse.ArgumentParser:
    from .derivatives import BACKENDS
    from .formulations import BASES, FORMULATIONS, PENALTY_DEFAULTS
    from .modal import METHODS

    parser = _Parser(prog="pinlin", description="Linear models of multibody systems.")
    parser.add_argument("--version", action=_VersionAction,
                        help="print the versions of pinlin, pin, mujoco, numpy and exit")
    sub = parser.add_subparsers(dest="command", required=True, parser_class=_Parser)
    lin = sub.add_parser("linearize", help="linearize a scene and print its modes")
    lin.add_argument("target", metavar="SCENE_OR_ROBOT",
                     help="scene .toml, .urdf, bundled scene name or example-robot-data robot")
    lin.add_argument("--formulation", choices=FORMULATIONS, default="independent")
    lin.add_argument("--derivatives", choices=BACKENDS, default="analytic")
    lin.add_argument("--step", type=float, default=None,
                     help="finite-difference step for fd3/fd5, all variables [rad, m, rad/s, "
                          "m/s, N*m, N]; default: per variable, see the README")
    lin.add_argument("--basis", choices=BASES, default=None,
                     help="independent coordinates of a mechanism with loops")
    lin.add_argument("--alpha", type=float, default=None,
                     help=f"penalty factor (penalty, canonical; default "
                          f"{PENALTY_DEFAULTS['alpha']:g})")
    lin.add_argument("--mu", type=float, default=None,
                     help=f"penalty damping ratio (default {PENALTY_DEFAULTS['mu']:g})")
    lin.add_argument("--omega", type=float, default=None,
                     help=f"penalty natural frequency [rad/s] (default "
                          f"{PENALTY_DEFAULTS['omega']:g})")
    lin.add_argument("--method", choices=METHODS, default="auto", help="eigensolver")
    lin.add_argument("--allow-non-equilibrium", action="store_true",
                     help="linearize even if the inputs cannot hold q0 at rest")
    lin.add_argument("--allow-ill-conditioned", action="store_true",
                     help="linearize even if the mass matrix is singular to working precision "
                          "(scaled to unit diagonal, condition >= 0.1/(n eps)): a warning instead "
                          "of an error, but no reliable digit")
    lin.add_argument("--matrices", action="store_true",
                     help="print A, B, C, D with their row and column names")
    lin.add_argument("--out", metavar="FILE", type=_file_name("--out"),
                     help="save the model (.npz, .mat or .json)")
    lin.set_defaults(func=_cmd_linearize)
    ben = sub.add_parser("bench", help="measure accuracy against time (analytic, fd3, fd5, "
                                       "MuJoCo) and write validation/reports/accuracy_vs_time.md")
    ben.add_argument("systems", nargs="*", metavar="SYSTEM",
                     help="robots or bundled scenes (default: six robots and two mechanisms)")
    ben.add_argument("--repeats", type=int, default=5,
                     help="timing repeats per point (1 to 1000)")
    ben.add_argument("--out-dir", default="validation/reports",
                     help="folder for accuracy_vs_time.md and its plots")
    ben.add_argument("--no-progress", action="store_true", help="no progress bar")
    ben.set_defaults(func=_cmd_bench)
    val = sub.add_parser("validate", help="compare linear models with MuJoCo and write reports")
    val.add_argument("targets", nargs="*", metavar="SCENE_OR_ROBOT")
    val.add_argument("--all", action="store_true",
                     help="every bundled scene and every example-robot-data robot that loads")
    val.add_argument("--out-dir", default="validation/reports", help="folder for the reports")
    val.add_argument("--no-progress", action="store_true", help="no progress bar")
    val.set_defaults(func=_cmd_validate)
    exp = sub.add_parser("export-mjcf", help="write the scene as MJCF with only its effects")
    exp.add_argument("target", metavar="SCENE_OR_ROBOT")
    exp.add_argument("-o", "--output", required=True, metavar="FILE.xml",
                     type=_file_name("--output"))
    exp.add_argument("--dt", type=float, default=1e-3, help="time step [s] (default 1e-3)")
    exp.set_defaults(func=_cmd_export_mjcf)
    gra = sub.add_parser("graph", help="state equations of a linear graph (Rowell)")
    gra.add_argument("file", metavar="FILE.toml")
    gra.add_argument("--standard-form", action="store_true",
                     help="remove the input-derivative term E u' with the new state "
                          "x' = x - E u (state names get a prime; B' = B + A E, "
                          "D' = D + C E)")
    gra.add_argument("--no-combine", action="store_true",
                     help="keep A-type elements in series and T-type in parallel (report the "
                          "excess states instead of combining them)")
    gra.set_defaults(func=_cmd_graph)
    tra = sub.add_parser("trajectory", help="linear models at every state of a trajectory")
    tra.add_argument("target", metavar="SCENE_OR_ROBOT",
                     help="scene .toml, .urdf, bundled scene name or example-robot-data robot")
    tra.add_argument("states", metavar="TRAJECTORY",
                     help=".npz with arrays q (N, nq), v (N, nv), u (N, nu) [, t (N,)], or .csv "
                          "with a header naming the columns t, q:<joint>, v:<coordinate>, "
                          "u:<coordinate> (see the README)")
    tra.add_argument("--out", required=True, metavar="FILE", type=_file_name("--out"),
                     help="write the stacked models (.npz or .mat)")
    tra.add_argument("--workers", type=int, default=1,
                     help="processes on this machine (default 1)")
    tra.add_argument("--dask", metavar="ADDRESS", default=None,
                     help="run on a Dask cluster, e.g. tcp://scheduler:8786 (extra 'dask')")
    tra.add_argument("--derivatives", choices=BACKENDS, default="analytic")
    tra.add_argument("--step", type=float, default=None,
                     help="finite-difference step for fd3/fd5 [rad, m, rad/s, m/s, N*m, N]")
    tra.add_argument("--dt", type=float, default=None,
                     help="discretize the models with this sample time [s]")
    tra.add_argument("--discretization", choices=("zoh", "euler"), default=None,
                     help="with --dt: zero-order hold (default) or semi-implicit Euler")
    tra.add_argument("--no-progress", action="store_true", help="no progress bar")
    tra.set_defaults(func=_cmd_trajectory)
    for command in (lin, ben, val, exp, tra):
        command.add_argument("--memory-limit", metavar="SIZE", default=None,
                             help="refuse a model whose estimated memory exceeds SIZE: bytes, "
                                  "or with suffix K, M, G, T (powers of 1024), e.g. 8G "
                                  "(default: $PINLIN_MEMORY_LIMIT, else half the memory)")
    rob = sub.add_parser("robots", help="list the example-robot-data robots that load")
    rob.set_defaults(func=_cmd_robots)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of the ``pinlin`` console script; returns the exit status."""
    with warnings.catch_warnings():
        warnings.showwarning = _show_warning
        return _main(argv)


def _main(argv: Sequence[str] | None) -> int:
    try:
        args = build_parser().parse_args(argv)
        limit = getattr(args, "memory_limit", None)
        if limit is None:
            return int(args.func(args))
        from .resources import memory_limit_override

        with memory_limit_override(limit, argument="--memory-limit"):
            return int(args.func(args))
    except _Done:
        return 0
    except _UsageError as exc:
        print(str(exc), file=sys.stderr)
        return EXIT_BAD_INPUT
    except PinlinError as exc:
        message = " ".join(str(exc).split())
        print(f"pinlin: error: {message}", file=sys.stderr)
        return EXIT_BAD_INPUT
    except BrokenPipeError:  # output piped into head & co.: stop quietly
        sys.stderr.close()
        return 0


if __name__ == "__main__":
    sys.exit(main())

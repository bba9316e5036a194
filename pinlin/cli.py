"""Command-line interface: ``pinlin linearize``, ``pinlin trajectory``, ``pinlin validate``,
``pinlin export-mjcf``, ``pinlin bench``, ``pinlin graph``, ``pinlin robots``.

Bad input never produces a traceback: the error goes to stderr as one line and the exit status
is 2. Warnings (:class:`pinlin.AccuracyWarning` and others) go to stderr as one
``warning: ...`` line each, without the Python source line; this applies inside :func:`main`
only, library users keep Python's usual warnings.
"""

from __future__ import annotations

import argparse
import sys
import warnings
from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from .cli_format import (
    check_out,
    file_name,
    folder_name,
    format_matrix,
    format_poles,
    options_named,
    plural,
    print_operating_point,
    scene_of,
    strict_float,
)
from .cli_motion import add_commands
from .cli_pictures import add_commands as add_picture_commands
from .exceptions import ArgumentError, ModelFileError, PinlinError

if TYPE_CHECKING:
    pass

EXIT_BAD_INPUT = 2


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


def _show_warning(message: Warning | str, category: type[Warning], filename: str, lineno: int,
                  file: object = None, line: str | None = None) -> None:
    """``warnings.showwarning`` for the CLI: one ``warning: ...`` line on stderr (pinlin's own
    warnings bare, others with their category), no source line or file path."""
    text = " ".join(str(message).split())
    if not (category.__module__ or "").startswith("pinlin"):
        text = f"{category.__name__}: {text}"
    print(f"warning: {text}", file=sys.stderr)


def _cmd_linearize(args: argparse.Namespace) -> int:
    from .linear_model import LinearModel  # noqa: F401  (import cost paid before the work)
    from .linearization import linearize
    from .modal import modal

    out = Path(args.out) if args.out else None
    if out is not None:
        check_out(out, (".npz", ".mat", ".json"))
    scene = scene_of(args.target)
    with options_named({"alpha": "--alpha", "mu": "--mu", "omega": "--omega",
                        "basis": "--basis", "step": "--step",
                        "formulation": "--formulation", "derivatives": "--derivatives"}):
        model = linearize(scene, formulation=args.formulation, derivatives=args.derivatives,
                          step=args.step,
                          allow_non_equilibrium=True if args.allow_non_equilibrium else None,
                          allow_ill_conditioned=args.allow_ill_conditioned,
                          basis=args.basis, alpha=args.alpha, mu=args.mu, omega=args.omega)
    modes = modal(model, method=args.method)    # refuses before anything is printed
    if out is not None:     # the file first: a failed write prints one line, not the table
        model.save(out)
    print_operating_point(model, scene.system)
    print()
    print(modes)
    if args.matrices:
        names = {"A": (model.state_names, model.state_names),
                 "B": (model.state_names, model.input_names),
                 "C": (model.output_names, model.state_names),
                 "D": (model.output_names, model.input_names)}
        for key, (rows, columns) in names.items():
            print(f"\n{format_matrix(key, getattr(model, key), rows, columns)}")
    if out is not None:
        print(f"\nmodel written to {out}")
    return 0


def _cmd_robots(args: argparse.Namespace) -> int:
    from .robots import load_robot, loadable_robots

    status = loadable_robots()
    ok = [n for n, reason in status.items() if reason is None]
    print(f"{len(ok)} of {plural(len(status), 'example-robot-data robot')} "
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

    folder_name(args.out_dir, "--out-dir")
    systems = args.systems or list(ROBOTS + MECHANISMS)
    command = "pinlin bench" + "".join(f" {s}" for s in args.systems)
    if args.repeats != 5:
        command += f" --repeats {args.repeats}"
    with options_named({"name": "SYSTEM", "names": "SYSTEM", "target": "SYSTEM"}):
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
    folder_name(args.out_dir, "--out-dir")
    command = "pinlin validate" + (" --all" if args.all else "") + "".join(
        f" {t}" for t in args.targets)
    # Named systems must all exist (else exit 2, nothing written) and merge into the index;
    # --all rebuilds the index and reports a system pinlin cannot build as a row.
    with options_named({"names": "SCENE_OR_ROBOT", "name": "SCENE_OR_ROBOT",
                        "target": "SCENE_OR_ROBOT"}):
        names = targets(args.all, list(args.targets))
        results = run(names, args.out_dir, not args.no_progress, command,
                      strict=not args.all, merge=not args.all)
    for r in results:
        print(f"{r.name:28s} {r.status:15s} {r.reason}")
    failed = [r.name for r in results if r.failed]
    print(f"{plural(len(results), 'system')}: {sum(r.passed for r in results)} pass, "
          f"{len(failed)} fail"
          + (f" ({', '.join(failed)})" if failed else ""))
    return 1 if failed else 0


def _cmd_export_mjcf(args: argparse.Namespace) -> int:
    from .files import check_file_target, write_text_atomic
    from .linearization import linearize, operating_point
    from .mjcf import build, check_resolved, check_time_step
    from .mjcf_xml import to_xml

    dt = check_time_step(args.dt, "--dt")
    out = Path(args.output)
    if out.suffix.lower() != ".xml":
        raise ModelFileError(out, "expected an .xml file for MJCF")
    scene = scene_of(args.target)
    inputs = {Path(p).resolve() for p in (scene.source, scene.system.urdf_path) if p}
    if out.resolve() in inputs:
        raise ModelFileError(out, "is an input of the scene (its scene file or URDF); choose "
                                  "another output name")
    check_file_target(out)
    ms = build(scene.system, dt=dt)
    op = None   # the linear model's point (it checks dt); without one, no keyframe
    try:
        model = linearize(scene, allow_non_equilibrium=True)
    except PinlinError as exc:
        try:
            operating_point(scene, allow_non_equilibrium=True)
        except PinlinError:     # the model stands without it: say where to find out why
            key = "; no keyframe: pinlin linearize says why the operating point is refused"
        else:
            raise exc from None     # the point stands, its linear model does not
    else:
        op = model.operating_point
        key = ("; keyframe 'operating_point' holds q0, v0"
               + (" and the inputs u0 (ctrl of its motors)" if op.u.size else ""))
        check_resolved(model, dt, "--dt")
    xml = to_xml(ms, scene.system, *((op.q, op.v) if op is not None else ()),
                 u=op.u if op is not None else None)
    write_text_atomic(out, xml)
    print(f"MJCF of '{scene.name}' written to {out} (nq = {ms.model.nq}, nv = {ms.model.nv}, "
          f"{plural(ms.model.neq, 'equality', 'equalities')}, dt = {dt:g} s{key})")
    return 0


def _cmd_graph(args: argparse.Namespace) -> int:
    from .graph import Graph

    graph = Graph.load(args.file)
    tree = graph.normal_tree(combine=not args.no_combine)
    model = graph.linearize(combine=not args.no_combine, standard_form=args.standard_form)
    branches = plural(len(graph.branches), "branch", "branches")
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
    lin.add_argument("--step", type=strict_float, default=None,
                     help="finite-difference step for fd3/fd5, all variables [rad, m, rad/s, "
                          "m/s, N*m, N]; default: per variable, see the README")
    lin.add_argument("--basis", choices=BASES, default=None,
                     help="independent coordinates of a mechanism with loops")
    lin.add_argument("--alpha", type=strict_float, default=None,
                     help=f"penalty factor (penalty, canonical; default "
                          f"{PENALTY_DEFAULTS['alpha']:g})")
    lin.add_argument("--mu", type=strict_float, default=None,
                     help=f"penalty damping ratio (default {PENALTY_DEFAULTS['mu']:g})")
    lin.add_argument("--omega", type=strict_float, default=None,
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
    lin.add_argument("--out", metavar="FILE", type=file_name("--out"),
                     help="save the model (.npz, .mat or .json)")
    lin.set_defaults(func=_cmd_linearize)
    ben = sub.add_parser("bench", help="measure accuracy against time (analytic, fd3, fd5, "
                                       "MuJoCo) and write validation/reports/accuracy_vs_time.md")
    ben.add_argument("systems", nargs="*", metavar="SYSTEM",
                     help="robots or bundled scenes (default: six robots and two mechanisms)")
    ben.add_argument("--repeats", type=int, default=5,
                     help="timing repeats per point (1 to 1000)")
    ben.add_argument("--out-dir", default="validation/reports",
                     help="folder for accuracy_vs_time.md and its plots (default: "
                          "validation/reports under the current folder; pinlin's own "
                          "reports there are replaced)")
    ben.add_argument("--no-progress", action="store_true", help="no progress bar")
    ben.set_defaults(func=_cmd_bench)
    val = sub.add_parser("validate", help="compare linear models with MuJoCo and write reports")
    val.add_argument("targets", nargs="*", metavar="SCENE_OR_ROBOT")
    val.add_argument("--all", action="store_true",
                     help="every bundled scene and every example-robot-data robot that loads")
    val.add_argument("--out-dir", default="validation/reports",
                     help="folder for the reports (default: validation/reports under the "
                          "current folder; pinlin's own reports there are replaced, its index "
                          "keeps the rows of other systems)")
    val.add_argument("--no-progress", action="store_true", help="no progress bar")
    val.set_defaults(func=_cmd_validate)
    exp = sub.add_parser("export-mjcf", help="write the scene as MJCF with only its effects")
    exp.add_argument("target", metavar="SCENE_OR_ROBOT")
    exp.add_argument("-o", "--output", required=True, metavar="FILE.xml",
                     type=file_name("--output"))
    exp.add_argument("--dt", type=strict_float, default=1e-3, help="time step [s] (default 1e-3)")
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
    motion = add_commands(sub, BACKENDS)
    add_picture_commands(sub)  # modes, report (each with its own --memory-limit)
    for command in (lin, ben, val, exp, *motion):
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
        # Each run shows its warnings once each, whatever ran earlier in this process (a
        # fresh filter resets the "already shown" registries).
        warnings.simplefilter("default")
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
    except KeyboardInterrupt:  # Ctrl-C: one line, the shell's status for SIGINT
        print("pinlin: interrupted", file=sys.stderr)
        return 130


if __name__ == "__main__":
    sys.exit(main())

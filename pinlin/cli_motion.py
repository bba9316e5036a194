"""Command-line commands for motion: ``pinlin trajectory``, ``pinlin simulate``,
``pinlin response`` and ``pinlin validity`` (parsing and printing only; the work is in
:mod:`pinlin.trajectory`, :mod:`pinlin.simulation`, :mod:`pinlin.response` and
:mod:`pinlin.validity`)."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

from .cli_format import (
    check_out,
    file_name,
    folder_name,
    mode_rows,
    options_named,
    plural,
    scene_of,
    strict_float,
)
from .cli_histories import (
    assignments,
    check_history_out,
    check_plot,
    initial_state,
    number,
    times,
    write_results,
)
from .exceptions import ArgumentError, ModelFileError

#: The trajectory progress bar appears once a run has taken this long [s].
PROGRESS_AFTER = 1.0


class _PointsBar:
    """``progress(done, total)`` for :func:`pinlin.linearize_trajectory`: a one-line bar on
    stderr, drawn once the run has taken :data:`PROGRESS_AFTER` seconds. A mechanism of
    ``points`` points reports 2 ``points`` steps (assembled, then linearized): the bar names
    the pass."""

    def __init__(self, enabled: bool, points: int = 0) -> None:
        import time

        self.enabled, self.start, self.drawn = enabled, time.perf_counter(), False
        self.points = points

    def __call__(self, done: int, total: int) -> None:
        import time

        if not self.enabled or (not self.drawn and
                                time.perf_counter() - self.start < PROGRESS_AFTER):
            return
        width = 30
        filled = int(width * done / total)
        text = f"{done}/{total} points"
        if self.points and total == 2 * self.points:
            n = self.points
            text = (f"{done}/{n} points assembled" if done < n else
                    f"{done - n}/{n} points linearized (all assembled)")
        sys.stderr.write(f"\r[{'#' * filled}{'.' * (width - filled)}] {text}")
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
    except (MemoryError, Exception) as exc:  # noqa: BLE001  a service that speaks no Dask (an
        # ssh banner read as a frame length asked numpy for 2.8 EiB): what it is, in one line
        raise ArgumentError("--dask", f"no Dask scheduler answers at {address!r} (the service "
                                      f"there sent what Dask cannot read: "
                                      f"{type(exc).__name__}); give the scheduler's address, "
                                      "e.g. tcp://host:8786") from None
    return client, client.get_executor()


def _cmd_trajectory(args: argparse.Namespace) -> int:
    import time

    from .exceptions import ShapeError
    from .trajectory import linearize_trajectory
    from .trajectory_files import MODEL_FORMATS, csv_location, read_states

    out = Path(args.out)
    check_out(out, MODEL_FORMATS, "trajectory model")
    if args.workers < 1:
        raise ArgumentError("--workers", f"expected a number of processes >= 1, got "
                                         f"{args.workers}")
    if args.dask is not None and args.workers != 1:
        raise ArgumentError("--dask", "runs on the cluster's workers; leave out --workers")
    if args.dt is not None and not (np.isfinite(args.dt) and args.dt > 0):
        raise ArgumentError("--dt", f"expected a sample time > 0 [s], got {args.dt:g}")
    if args.discretization is not None and args.dt is None:
        raise ArgumentError("--discretization", "applies with --dt (the sample time [s])")
    if args.second_order and args.dt is not None:
        raise ArgumentError("--second-order", "M, C_damp, K, Bu describe the continuous "
                                              "models; a discretized model (--dt) has none: "
                                              "leave out one of the two")
    scene = scene_of(args.target)
    q, v, u, t = read_states(args.states, scene.system)
    client = executor = None
    if args.dask is not None:
        client, executor = _dask_executor(args.dask)
    bar = _PointsBar(not args.no_progress, len(q))
    start = time.perf_counter()
    try:
        model = linearize_trajectory(scene, q, v, u, t, workers=args.workers,
                                     executor=executor, derivatives=args.derivatives,
                                     step=args.step, progress=bar,
                                     second_order=args.second_order,
                                     allow_non_equilibrium=args.allow_non_equilibrium or None)
    except ArgumentError as exc:
        bar.close()
        if exc.argument in ("q", "v", "u", "t"):
            row = getattr(exc, "row", None)
            if row is not None and Path(args.states).suffix == ".csv":  # the file's own terms
                where = csv_location(args.states, scene.system, exc.argument, row,
                                     exc.columns)
                raise ModelFileError(args.states, f"{where}: point {row} {exc.detail}"
                                                  f"{exc.tail}") from None
            raise ModelFileError(args.states, f"{exc.argument}: {exc.reason}") from None
        flag = {"second_order": "--second-order", "step": "--step", "workers": "--workers",
                "allow_non_equilibrium": "--allow-non-equilibrium", "executor": "--dask",
                "derivatives": "--derivatives"}.get(exc.argument)
        if flag is not None:
            raise ArgumentError(flag, exc.reason) from None
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
    where = (f"Dask at {args.dask}" if args.dask else plural(args.workers, "process",
                                                                "processes"))
    n_points = len(model)
    kind = "schedule of rest points" if model.info.get("at_rest") else "trajectory"
    linearized = model
    if args.dt is not None:   # before any line is printed: a dt that overflows is refused
        method = args.discretization or "zoh"
        with options_named({"dt": "--dt", "method": "--discretization"}):
            model = model.discretize(args.dt, method)
    lines = [f"{kind} of '{model.name}': {plural(n_points, 'point')}, "
             f"{plural(len(model.state_names), 'state')}, "
             f"{plural(len(model.input_names), 'input')}, "
             f"{plural(len(model.output_names), 'output')}; {model.info['derivatives']} "
             f"derivatives ({model.info['path']}), {where}: {elapsed:.3g} s "
             f"({1e6 * elapsed / n_points:.3g} us per point)"]
    loops = model.info.get("loops") or {}
    moved = {key: float(np.max(loops[key], initial=0.0))
             for key in ("position_correction", "velocity_correction") if key in loops}
    if any(value > 0.0 for value in moved.values()):   # the states the models are about
        lines.append(
            "states moved onto the constraints (loops closed, velocities projected): largest "
            f"change |dq| = {moved.get('position_correction', 0.0):.3g}, |dv| = "
            f"{moved.get('velocity_correction', 0.0):.3g}; the models are about the moved "
            "states (in the file's q, v)")
    if linearized.M is not None:
        lines.append("second-order matrices M, C_damp, K, Bu stored at every point")
    if args.dt is not None:
        lines.append(f"discretized: {method}, dt = {args.dt:g} s" + _other_spacing(linearized.t,
                                                                                  args.dt))
    model.save(out)     # the file first: a failed write prints one line, not the summary
    lines.append(f"models written to {out}")
    print("\n".join(lines))
    return 0


def _other_spacing(t: np.ndarray | None, dt: float) -> str:
    """A remark when the states file's t is evenly spaced by other than ``dt`` [s] (a model
    stepped at dt along points sampled at another spacing, which a TV-LQR would misuse)."""
    if t is None or len(t) < 2:
        return ""
    steps = np.diff(t)
    if not np.allclose(steps, steps[0], rtol=1e-9, atol=0.0) or \
            abs(steps[0] - dt) <= 1e-9 * dt:
        return ""
    return (f" (the states file's t is spaced {steps[0]:g} s: each model steps {dt:g} s, not "
            "from one point to the next)")


def _gain(path: str | None, model) -> tuple[np.ndarray, object] | None:
    """--feedback FILE as the pair (K, model) that simulate and validity check against the
    model's states (None without the option)."""
    if path is None:
        return None
    from .gain_files import read_gain

    return read_gain(path, model), model


def _loop_line(path: str, model) -> str:
    return (f"closed loop: u = u0 - K x, K ({len(model.input_names)} inputs x "
            f"{len(model.state_names)} states) from {path}")


#: --allow-non-equilibrium of simulate, response and validity.
ALLOW_HELP = ("take the scene's point even if its inputs cannot hold q0 at rest (the motion "
              "then drifts from it: x' = f0 + A x + B u)")


def allowing(scene, allow: bool):
    """``scene`` with ``operating_point.allow_non_equilibrium`` set where ``allow``."""
    if not allow:
        return scene
    import dataclasses

    return dataclasses.replace(scene, operating_point=dataclasses.replace(
        scene.operating_point, allow_non_equilibrium=True))


def _cmd_simulate(args: argparse.Namespace) -> int:
    from .formulations.constrained import constrained_effects
    from .linearization import linearize
    from .simulation import simulate

    t = times(args)
    out, plot = check_history_out(args.out), check_plot(args.plot)
    scene = allowing(scene_of(args.target), args.allow_non_equilibrium)
    model = linearize(scene)
    x0 = initial_state(model, args.x0)
    gain = _gain(args.feedback, model)
    with options_named({"dx0": "--x0", "rtol": "--rtol", "atol": "--atol",
                         "method": "--method", "feedback": "--feedback"}):
        sim = simulate(scene, t, dx0=x0, rtol=args.rtol, atol=args.atol, method=args.method,
                       feedback=gain)
    n = len(sim.independent_names) // 2      # z: the linear model's states
    effects = constrained_effects(scene.system)
    lines = [f"simulated '{scene.name}' (nonlinear, the scene's effects: "
             f"{', '.join(effects) or 'none'}) over {t[-1]:g} s: "
             f"{sim.info.get('method')}, {plural(int(sim.info.get('nfev', 0)), 'evaluation')}"]
    if gain is not None:
        lines.append(_loop_line(args.feedback, model))
    if sim.drift is not None and sim.drift.size and np.any(sim.drift):
        lines.append(f"constraint drift: |Phi| <= {sim.drift[:, 0].max():.1e}, |Phi_q v| <= "
                     f"{sim.drift[:, 1].max():.1e}")
    if sim.energy is not None:
        lines.append(f"energy change: {np.abs(sim.energy - sim.energy[0]).max():.3e} J")
    final = ", ".join(f"{name} = {value:.6g}" for name, value
                      in zip(sim.independent_names[:n], sim.z[-1, :n], strict=True))
    lines.append(f"final deviation: "
                 f"{final or 'none (no states: the constraints hold everything)'}")
    columns = {name: sim.z[:, k] for k, name in enumerate(sim.independent_names)}
    columns.update({f"y:{name}": sim.y[:, k] for k, name in enumerate(sim.output_names)})
    if gain is not None:     # the inputs the loop applied
        columns.update({name: sim.u[:, k] for k, name in enumerate(sim.input_names)})
    lines += write_results(out, plot, sim.t, columns, f"{scene.name}: nonlinear simulation"
                            + (" in closed loop" if gain is not None else ""),
                            [(name, sim.t, sim.z[:, k], "-")
                             for k, name in enumerate(sim.independent_names[:n])])
    print("\n".join(lines))
    return 0


def _signals(args: argparse.Namespace, model):
    """--step, --impulse, --harmonic as one pinlin signal (None without any)."""
    from .signals import harmonic, impulse, step

    total = None
    for option, make in (("--step", step), ("--impulse", impulse)):
        given = assignments(getattr(args, option[2:]), model.input_names, option, "u:")
        if given:
            sig = make({k: number(v, option) for k, v in given.items()})
            total = sig if total is None else total + sig
    for item in args.harmonic or []:
        name, sep, rest = item.partition("=")
        amp, at, freq = rest.partition("@")
        if not sep or not at:
            raise ArgumentError("--harmonic", f"expected u:NAME=AMPLITUDE@W (W [rad/s]), got "
                                              f"{item!r}")
        key = next(iter(assignments([f"{name}={amp}"], model.input_names, "--harmonic",
                                     "u:")))
        sig = harmonic({key: number(amp, "--harmonic")}, number(freq, "--harmonic"))
        total = sig if total is None else total + sig
    return total


def _cmd_response(args: argparse.Namespace) -> int:
    from .linearization import linearize
    from .response import response

    t = times(args)
    if args.nonlinear and (args.step or args.impulse or args.harmonic):
        raise ArgumentError("--nonlinear", "compares free responses (--x0 only); inputs "
                                           "are not simulated nonlinearly from the CLI")
    out, plot = check_history_out(args.out), check_plot(args.plot)
    scene = allowing(scene_of(args.target), args.allow_non_equilibrium)
    model = linearize(scene)
    x0 = initial_state(model, args.x0)
    u = _signals(args, model)
    gain = _gain(args.feedback, model)
    open_loop = model
    if gain is not None:
        model = model.closed_loop(gain[0])
    with options_named({"x0": "--x0", "method": "--method",
                        "u": "--step/--impulse/--harmonic"}):
        res = response(model, t, x0=x0, u=u, method=args.method)
    n = len(model.state_names) // 2
    if n == 0:
        lines = [f"linear response of '{model.name}': the model has no states (its "
                 f"constraints hold every coordinate), nothing moves"]
    else:
        peak = np.abs(res.x[:, :n]).max(axis=0)
        worst = int(np.argmax(peak))
        lines = [f"linear response of '{model.name}' ({args.method}) over {t[-1]:g} s: "
                 f"largest excursion {peak[worst]:.6g} on {model.state_names[worst]}"]
    if gain is not None:
        lines.append(_loop_line(args.feedback, open_loop))
    curves = [(name, res.t, res.x[:, k], "-") for k, name in enumerate(model.state_names[:n])]
    columns = {name: res.x[:, k] for k, name in enumerate(model.state_names)}
    if args.nonlinear:
        from .simulation import simulate

        with options_named({"dx0": "--x0", "feedback": "--feedback"}):
            sim = simulate(scene, t, dx0=x0, feedback=gain)
        diff = np.abs(sim.z - res.x).max(initial=0.0)
        scale = max(float(np.abs(res.x).max(initial=0.0)), np.finfo(float).tiny)
        lines.append(f"nonlinear simulation from the same state: max |x_nl - x_lin| = "
                     f"{diff:.3e} ({diff / scale:.2e} of the largest linear value)")
        curves += [(f"{name} (nonlinear)", sim.t, sim.z[:, k], "--")
                   for k, name in enumerate(sim.independent_names[:n])]
        columns.update({f"nl:{name}": sim.z[:, k]
                        for k, name in enumerate(sim.independent_names)})
    lines += write_results(out, plot, res.t, columns, f"{model.name}: linear response"
                            + (" and nonlinear simulation" if args.nonlinear else ""), curves)
    print("\n".join(lines))
    return 0


def _cmd_validity(args: argparse.Namespace) -> int:
    from .files import check_file_target, check_folder_target, make_folder
    from .linearization import linearize
    from .modal import modal
    from .validity import validity
    from .validity_report import plot_paths

    folder = None
    if args.out_dir is not None:
        folder = check_folder_target(folder_name(args.out_dir, "--out-dir"), "--out-dir")
    scene = allowing(scene_of(args.target), args.allow_non_equilibrium)
    if folder is not None and folder.is_dir():    # a file there is refused before the run
        for path in plot_paths(folder, scene.name):
            check_file_target(path)
    model = linearize(scene) if args.feedback is not None or args.modes is not None else None
    gain = _gain(args.feedback, model)
    modes = None
    if args.modes is not None:    # rows of the mode table, numbered from 1 as printed
        modes = mode_rows(modal(model if gain is None else model.closed_loop(gain[0])),
                          args.modes, "--modes")
    with options_named({"amplitudes": "--amplitudes", "periods": "--periods",
                        "tolerance": "--tolerance", "modes": "--modes",
                        "direction": "--direction", "rtol": "--tolerance",
                        "atol": "--amplitudes", "feedback": "--feedback"}):
        result = validity(scene, amplitudes=args.amplitudes, periods=args.periods,
                          tolerance=args.tolerance, modes=modes, direction=args.direction,
                          feedback=gain)
    print(result.table())
    if folder is not None:
        make_folder(folder)
        paths = result.plot(folder)
        print("plots written to " + ", ".join(str(p) for p in paths))
    return 0


def add_commands(sub, backends: tuple[str, ...]) -> list[argparse.ArgumentParser]:
    """The motion subcommands; returns the ones that take --memory-limit."""
    scene_help = "scene .toml, .urdf, bundled scene name or example-robot-data robot"
    tra = sub.add_parser("trajectory", help="linear models at every state of a trajectory")
    tra.add_argument("target", metavar="SCENE_OR_ROBOT", help=scene_help)
    tra.add_argument("states", metavar="TRAJECTORY",
                     help=".npz with arrays q (N, nq), v (N, nv), u (N, nu) [, t (N,)], or .csv "
                          "with a header naming the columns t, q:<joint>, v:<coordinate>, "
                          "u:<coordinate> (see the README); q alone: a gain schedule of rest "
                          "points, the holding inputs solved at each")
    tra.add_argument("--out", required=True, metavar="FILE", type=file_name("--out"),
                     help="write the stacked models (.npz or .mat)")
    tra.add_argument("--workers", type=int, default=1,
                     help="processes on this machine (default 1)")
    tra.add_argument("--dask", metavar="ADDRESS", default=None,
                     help="run on a Dask cluster, e.g. tcp://scheduler:8786 (extra 'dask')")
    tra.add_argument("--derivatives", choices=backends, default="analytic")
    tra.add_argument("--step", type=strict_float, default=None,
                     help="finite-difference step for fd3/fd5 [rad, m, rad/s, m/s, N*m, N]")
    tra.add_argument("--dt", type=strict_float, default=None,
                     help="discretize the models with this sample time [s]")
    tra.add_argument("--discretization", choices=("zoh", "euler"), default=None,
                     help="with --dt: zero-order hold (default) or semi-implicit Euler")
    tra.add_argument("--second-order", action="store_true",
                     help="also store M, C_damp, K (and Bu) of every point (open chains, and "
                          "a mechanism's schedule of rest points)")
    tra.add_argument("--allow-non-equilibrium", action="store_true",
                     help="a schedule of rest points: keep points the inputs cannot hold "
                          "(models of the falling state)")
    tra.add_argument("--no-progress", action="store_true", help="no progress bar")
    tra.set_defaults(func=_cmd_trajectory)

    feedback_help = ("close the loop u = u0 - K x with the gain in GAIN: a .csv whose header "
                     "is input,<state>,... and whose lines are u:<name>,<gains> (the names "
                     "checked against the linear model's), or a bare .npy (inputs x states)")

    def timed(p: argparse.ArgumentParser) -> None:
        p.add_argument("target", metavar="SCENE_OR_ROBOT", help=scene_help)
        p.add_argument("--t-end", type=strict_float, required=True, metavar="T",
                       help="duration [s]")
        p.add_argument("--dt", type=strict_float, default=0.01,
                       help="output step [s] (default 0.01)")
        p.add_argument("--x0", nargs="+", action="extend", metavar="NAME=VALUE",
                       help="initial deviation, e.g. q:elbow=0.1 v:shoulder=0.5 [rad, m, "
                            "rad/s, m/s] (the linear model's state names)")
        p.add_argument("--out", metavar="FILE", type=file_name("--out"),
                       help="write the time histories (.csv or .npz)")
        p.add_argument("--plot", metavar="FILE.png", type=file_name("--plot"),
                       help="plot the position histories")
        p.add_argument("--feedback", metavar="GAIN", type=file_name("--feedback"),
                       help=feedback_help)

    sim = sub.add_parser("simulate", help="the scene's nonlinear dynamics about its operating "
                                          "point, with exactly its effects")
    timed(sim)
    sim.add_argument("--method", default=None, help="solve_ivp method (default: DOP853, or "
                                                    "Radau for stiff scenes)")
    sim.add_argument("--rtol", type=strict_float, default=1e-10, help="relative tolerance")
    sim.add_argument("--atol", type=strict_float, default=None,
                     help="absolute tolerance in the state's units (default 1e-12 per rad or "
                          "rad/s, 1e-12 L per m or m/s, L the robot's characteristic length)")
    sim.add_argument("--allow-non-equilibrium", action="store_true", help=ALLOW_HELP)
    sim.set_defaults(func=_cmd_simulate)
    res = sub.add_parser("response", help="the linear model's response (chapter 9.3) to an "
                                          "initial state and inputs")
    timed(res)
    res.add_argument("--step", nargs="+", action="extend", metavar="u:NAME=VALUE",
                     help="step inputs [N*m or N] from t = 0")
    res.add_argument("--impulse", nargs="+", action="extend", metavar="u:NAME=VALUE",
                     help="impulses at t = 0 [N*m*s or N*s]")
    res.add_argument("--harmonic", nargs="+", action="extend", metavar="u:NAME=AMP@W",
                     help="harmonic inputs AMP sin(W t) [N*m or N, rad/s]")
    res.add_argument("--method", choices=("modal", "exact"), default="modal",
                     help="modal superposition (default) or the matrix exponential")
    res.add_argument("--nonlinear", action="store_true",
                     help="also simulate the nonlinear dynamics from the same state and "
                          "report the difference")
    res.add_argument("--allow-non-equilibrium", action="store_true", help=ALLOW_HELP)
    res.set_defaults(func=_cmd_response)
    val = sub.add_parser("validity", help="how large a motion the linear model stays "
                                          "accurate for, per mode")
    val.add_argument("target", metavar="SCENE_OR_ROBOT", help=scene_help)
    val.add_argument("--amplitudes", nargs="+", action="extend", type=strict_float, default=None,
                     help="initial amplitudes [rad, or L for a length: the robot's "
                          "characteristic length, printed] (default: a sweep)")
    val.add_argument("--periods", type=strict_float, default=5,
                     help="horizon in periods (default 5)")
    val.add_argument("--tolerance", type=strict_float, default=0.01,
                     help="relative error that limits the radius (default 0.01)")
    val.add_argument("--modes", nargs="+", action="extend", type=int, default=None,
                     help="mode indices as in the mode table (default: every non-rigid one)")
    val.add_argument("--direction", default=None,
                     help="a coordinate name instead of the modes, e.g. elbow or v:elbow")
    val.add_argument("--out-dir", default=None, help="write the plots into this folder")
    val.add_argument("--feedback", metavar="GAIN", type=file_name("--feedback"),
                     help=feedback_help + "; the closed loop's modes are compared")
    val.add_argument("--allow-non-equilibrium", action="store_true", help=ALLOW_HELP)
    val.set_defaults(func=_cmd_validity)
    return [tra, sim, res, val]

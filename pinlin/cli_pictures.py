"""Command-line commands that draw modes: ``pinlin modes`` (the mode table, a PNG of the mode
shapes, an animated GIF) and ``pinlin report`` (one self-contained HTML file). Parsing and
printing only; the work is in :mod:`pinlin.mode_pictures` and :mod:`pinlin.html_report`."""

from __future__ import annotations

import argparse

from .cli_format import file_name, mode_rows, plural, scene_of, strict_float
from .exceptions import ArgumentError


def _linearize(args: argparse.Namespace):
    from .linearization import linearize
    from .modal import modal

    scene = scene_of(args.target)
    model = linearize(scene, allow_non_equilibrium=True if args.allow_non_equilibrium
                      else None)
    return scene, model, modal(model)


def _cmd_modes(args: argparse.Namespace) -> int:
    from .cli_format import print_operating_point
    from .files import all_or_nothing
    from .mode_pictures import animate_modes, check_target, default_modes, plot_modes
    from .stick_figure import MAX_AMPLITUDE

    png = check_target(args.plot, ".png", "--plot") if args.plot else None
    gif = check_target(args.gif, ".gif", "--gif") if args.gif else None
    if args.amplitude is not None and not (0 < args.amplitude <= MAX_AMPLITUDE):
        raise ArgumentError("--amplitude", f"expected an amplitude > 0 and <= "
                                           f"{MAX_AMPLITUDE:g} [rad or m], got "
                                           f"{args.amplitude:g}")
    if args.amplitude is not None and png is None and gif is None:
        raise ArgumentError("--amplitude", "sets the drawn amplitude: give --plot FILE.png or "
                                           "--gif FILE.gif as well")
    if args.mode is not None and png is None and gif is None:
        raise ArgumentError("--mode", "chooses the modes to draw: give --plot FILE.png or "
                                      "--gif FILE.gif as well")
    scene, model, modes = _linearize(args)
    indices = mode_rows(modes, args.mode, "--mode")
    if (png or gif) and indices is None and not default_modes(modes):
        raise ArgumentError("--plot" if png else "--gif",
                            f"model '{model.name}' has no mode to draw (no states)")
    written = []     # the files first: a failure prints one line, not the table before it
    with all_or_nothing():      # both files, or neither
        if png is not None:
            plot_modes(scene, modes, png, indices, amplitude=args.amplitude)
            written.append(f"mode picture written to {png}")
        if gif is not None:
            animate_modes(scene, modes, gif, indices, amplitude=args.amplitude)
            written.append(f"mode animation written to {gif}")
    print_operating_point(model, scene.system)
    print()
    print(modes)
    if written:
        print("\n" + "\n".join(written))
    return 0


def _cmd_report(args: argparse.Namespace) -> int:
    from .html_report import check_report_target, write_html_report

    out = check_report_target(args.output, "--output")
    if not 1 <= args.max_modes <= 500:
        raise ArgumentError("--max-modes", f"expected 1 to 500 modes to draw, got "
                                           f"{args.max_modes}")
    scene, model, modes = _linearize(args)
    write_html_report(scene, out, model=model, modes=modes, max_modes=args.max_modes,
                 include_response=not args.no_response, include_validity=args.validity)
    print(f"report of '{model.name}' ({plural(len(modes.modes()), 'mode')}) written to {out}; "
          "open it in a browser (it needs no network)")
    return 0


def add_commands(sub) -> list[argparse.ArgumentParser]:
    """Add ``modes`` and ``report`` to the subparsers ``sub``; returns them."""
    scene_help = "scene .toml, .urdf, bundled scene name or example-robot-data robot"
    mod = sub.add_parser("modes", help="print the mode table and draw the mode shapes (PNG, "
                                       "animated GIF)")
    mod.add_argument("target", metavar="SCENE_OR_ROBOT", help=scene_help)
    mod.add_argument("--plot", metavar="FILE.png", type=file_name("--plot"),
                     help="draw the modes as stick figures at q0 and displaced (one panel "
                          "per mode)")
    mod.add_argument("--gif", metavar="FILE.gif", type=file_name("--gif"),
                     help="animate the modes over one cycle")
    mod.add_argument("--mode", type=int, nargs="+", action="extend", metavar="K",
                     help="rows of the mode table to draw (1 = first row; default: the first "
                          "four that are not rigid)")
    mod.add_argument("--amplitude", type=strict_float, default=None,
                     help="excursion of each shape's largest coordinate [rad or m] (default: "
                          "a readable one per mode)")
    mod.add_argument("--allow-non-equilibrium", action="store_true",
                     help="linearize even if the inputs cannot hold q0 at rest")
    mod.set_defaults(func=_cmd_modes)
    rep = sub.add_parser("report", help="write one self-contained HTML report (operating "
                                        "point, modes, animated mode shapes)")
    rep.add_argument("target", metavar="SCENE_OR_ROBOT", help=scene_help)
    rep.add_argument("-o", "--output", required=True, metavar="FILE.html",
                     type=file_name("--output"))
    rep.add_argument("--max-modes", type=int, default=24,
                     help="modes that get an animated figure (default 24; the table lists "
                          "all)")
    rep.add_argument("--no-response", action="store_true",
                     help="leave out the free linear response plot")
    rep.add_argument("--validity", action="store_true",
                     help="add the validity plots of the first mode (simulates the nonlinear "
                          "dynamics: slow for large robots)")
    rep.add_argument("--allow-non-equilibrium", action="store_true",
                     help="linearize even if the inputs cannot hold q0 at rest")
    rep.set_defaults(func=_cmd_report)
    for command in (mod, rep):
        command.add_argument("--memory-limit", metavar="SIZE", default=None,
                             help="refuse a model whose estimated memory exceeds SIZE: bytes, "
                                  "or with suffix K, M, G, T (powers of 1024), e.g. 8G "
                                  "(default: $PINLIN_MEMORY_LIMIT, else half the memory)")
    return [mod, rep]

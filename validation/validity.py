"""How large a motion do the linear models stay accurate for? ``pinlin.validity`` per system.

For every system below, each non-rigid mode (and, for the UR5 arm, one joint direction) is
started at growing amplitudes in the nonlinear simulation and in the linear model, and the
relative error over 5 periods (2 time constants for real modes) is tabulated; the validity
radius is the largest amplitude with a relative error <= 1% (method: pinlin/validity.py).

Systems: the bundled scenes (pendulum hanging, inverted and with a wrong u0; double pendulum,
rotating double pendulum, four-bar, slider-crank, five-bar, delta, UR5 arm) and the solo12
quadruped with servo springs, floating in zero gravity (an equilibrium) and in free fall (not
one: v = 0 with gravity). Excluded: the 30+ DoF humanoids (dozens of modes at ~0.3 s per
simulation would take minutes; solo12 shows a floating base) and the graphs (linear already).

Usage: python validation/validity.py [NAME ...]     (default: all; about a minute)
Writes validation/reports/validity/<name>.md, <name>_histories.png, <name>_errors.png and
README.md (the index; rows of systems not run are kept).
"""

from __future__ import annotations

import dataclasses
import math
import platform
import sys
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np

import pinlin
from pinlin.files import make_folder, write_text_atomic
from pinlin.robots import load_robot
from pinlin.scene import bundled_scenes

OUT = Path(__file__).resolve().parent / "reports" / "validity"
INDEX = OUT / "README.md"
TOLERANCE, PERIODS = 0.01, 5.0
SOLO_MODES = 3   # lowest non-rigid modes of solo12 (12 in all; each costs ~4 s)


def _bundled(name: str) -> pinlin.Scene:
    return pinlin.Scene.load(bundled_scenes()[name])


def _wrong_u0() -> pinlin.Scene:
    """The hanging pendulum with u0 = 0.05 N*m given (the equilibrium needs 0)."""
    scene = _bundled("pendulum")
    point = dataclasses.replace(scene.operating_point, solve="none", u={"hinge": 0.05})
    return dataclasses.replace(scene, name="pendulum_wrong_u0", operating_point=point)


def _solo(gravity: list[float], name: str) -> pinlin.Scene:
    """solo12 floating, servo springs (5 N*m/rad) about its reference posture, state given
    (v = 0): an equilibrium without gravity, free fall with it."""
    robot = load_robot("solo12")
    model = robot.model
    springs = {model.names[j]: {"stiffness": 5.0,
                                "rest": float(robot.q_ref[model.joints[j].idx_q])}
               for j in range(1, model.njoints) if model.names[j] != "root_joint"}
    scene = pinlin.Scene.from_robot("solo12", effects={"gravity": gravity, "springs": springs},
                                    operating_point={"solve": "none"})
    return dataclasses.replace(scene, name=name)


#: name -> (scene factory, validity keyword arguments, what it shows)
SYSTEMS: dict[str, tuple[Callable[[], pinlin.Scene], dict, str]] = {
    "pendulum": (lambda: _bundled("pendulum"), {},
                 "hanging; hand estimate sqrt(8 tol / (pi periods)) from T = T0 (1 + a^2/16)"),
    "pendulum_inverted": (lambda: dataclasses.replace(_bundled("pendulum"),
                                                      name="pendulum_inverted"),
                          {"q": np.array([math.pi])},
                          "unstable equilibrium: horizon 2 time constants (growth e^2)"),
    "pendulum_wrong_u0": (_wrong_u0, {}, "not an equilibrium (u0 = 0.05 N*m): first order"),
    "double_pendulum": (lambda: _bundled("double_pendulum"), {}, "two modes, odd nonlinearity"),
    "rotating_double_pendulum": (lambda: _bundled("rotating_double_pendulum"), {},
                                 "steady rotation (centrifugal and Coriolis terms)"),
    "four_bar": (lambda: _bundled("four_bar"), {}, "loop; quadratic terms"),
    "slider_crank": (lambda: _bundled("slider_crank"), {}, "loop between two moving bodies"),
    "five_bar": (lambda: _bundled("five_bar"), {}, "loop, two DoF"),
    "delta": (lambda: _bundled("delta"), {}, "three loops"),
    "ur5_arm": (lambda: _bundled("ur5_arm"), {"modes": "all", "direction": "elbow_joint"},
                "servoed arm, damped modes, and a joint direction"),
    "solo12_zero_g": (lambda: _solo([0.0, 0.0, 0.0], "solo12_zero_g"), {"modes": "lowest"},
                      "floating base, servo springs, no gravity: an equilibrium"),
    "solo12_free_fall": (lambda: _solo([0.0, 0.0, -9.81], "solo12_free_fall"),
                         {"modes": "lowest"},
                         "floating base in free fall: not an equilibrium (f0 = g)"),
    "standing_box": (lambda: _bundled("standing_box"), {},
                     "floating base balanced on a point contact: an inverted spherical "
                     "pendulum (unstable tilts, a rigid spin)"),
    "solo12_standing": (lambda: _bundled("solo12_standing"), {"modes": "lowest"},
                        "standing on four point feet, held by its joint inputs"),
}


def _run(name: str) -> tuple[pinlin.Validity, str]:
    factory, options, what = SYSTEMS[name]
    scene, options = factory(), dict(options)
    if options.get("modes") in ("all", "lowest"):   # eigenvalue indices of the modes
        ma = pinlin.modal(pinlin.linearize(scene))
        modes = [i for i in ma.modes() if not ma.rigid[i]]
        options["modes"] = modes[:SOLO_MODES] if options["modes"] == "lowest" else modes
    result = pinlin.validity(scene, periods=PERIODS, tolerance=TOLERANCE, **options)
    return result, what


def _report(name: str, result: pinlin.Validity, what: str) -> str:
    lines = [f"# Validity of the linear model: {name}", "",
             f"{what}. Generated by `python validation/validity.py {name}` "
             f"({result.simulations} simulations, {result.seconds:.1f} s on "
             f"{platform.machine()}, pinlin {pinlin.__version__}).", "",
             "Relative error e = max over t and coordinates of |Dnl - Dlin| / max |Dlin|, for "
             "the positions and the velocities separately, the larger of the two (Dnl, Dlin: "
             "the deviations of the perturbed motions from the unperturbed ones; "
             + ("angles in rad and lengths in units of the robot's characteristic length "
                f"L = {result.length:.4g} m, as the amplitudes" if result.length is not None
                else "angles in rad") + "). The radius is "
             f"the largest amplitude (largest joint excursion at t = 0) with e <= "
             f"{100 * TOLERANCE:g}%; the order p is that of the error in the state's units, "
             "e ~ a^(p-1) (2: quadratic terms; 3: an odd nonlinearity; 1: not an "
             "equilibrium).", ""]
    if name == "pendulum":
        expected = math.sqrt(8 * TOLERANCE / (math.pi * PERIODS))
        lines += [f"Hand estimate: the period grows as T0 (1 + a^2/16), so after {PERIODS:g} "
                  f"periods the phase lags by 2 pi {PERIODS:g} a^2/16 = e: a = sqrt(8 tol / "
                  f"(pi {PERIODS:g})) = {expected:.5f} rad; measured {result.radius[0]:.5f} "
                  f"rad (ratio {result.radius[0] / expected:.4f}; the radius is found within "
                  "1.5% below the crossing).", ""]
    if name == "standing_box":
        lines += ["Cross-check: a tilt of the box about its held point obeys theta'' = lambda^2 "
                  "sin(theta), the inverted pendulum's equation in time scaled by lambda, and "
                  "both are followed for 2 time constants: the relative error is a function of "
                  "the amplitude alone, so the unstable tilts' radius must equal "
                  "[pendulum_inverted](pendulum_inverted.md)'s unstable one (0.0544 rad); the "
                  "decaying tilts' radius must equal its decaying one.", ""]
    lines += ["```", result.table(sweeps=True), "```", "",
              f"![histories]({name}_histories.png)", "", f"![errors]({name}_errors.png)", ""]
    return "\n".join(lines)


def _index_row(name: str, result: pinlin.Validity) -> str:
    point = "equilibrium" if result.equilibrium else f"not an equilibrium (max\\|f0\\| = " \
                                                     f"{result.drift:.3g})"
    k = int(np.argmin(result.radius))
    smallest = result.cases[k]
    sign = {"found": "", "above": ">= ", "below": "< "}[smallest.bound.value]
    orders = ", ".join("-" if not math.isfinite(p) else f"{p:.2f}" for p in result.slope)
    return (f"| [{name}]({name}.md) | {point} | {len(result.cases)} | {sign}{smallest.radius:.3g}"
            f" ({smallest.label}) | {orders} | {result.simulations} | {result.seconds:.1f} |")


def _write_index(rows: dict[str, str]) -> None:
    order = list(SYSTEMS) + sorted(set(rows) - set(SYSTEMS))
    lines = ["# Validity radius of the linear models", "",
             f"Produced by `python validation/validity.py`: for each mode, the largest motion "
             f"(largest joint excursion, in rad, and in units of the robot's characteristic "
             f"length L for a length) for which the linear model's relative error "
             f"stays within {100 * TOLERANCE:g}% over {PERIODS:g} periods (2 time constants "
             "for real modes; unstable ones until e^2 growth). Method and definitions: "
             "[pinlin/validity.py](../../../pinlin/validity.py).", "",
             "| system | point | cases | smallest radius [rad or L] | order per case | "
             "simulations | time [s] |", "|---|---|---|---|---|---|---|"]
    lines += [rows[n] for n in order if n in rows]
    write_text_atomic(INDEX, "\n".join(lines) + "\n")


def _read_index() -> dict[str, str]:
    if not INDEX.exists():
        return {}
    rows = {}
    for line in INDEX.read_text().splitlines():
        if line.startswith("| [") and "](" in line:
            rows[line[3:line.index("]")]] = line
    return rows


def main(names: list[str]) -> int:
    unknown = [n for n in names if n not in SYSTEMS]
    if unknown:
        print(f"unknown system(s) {', '.join(unknown)}; expected {', '.join(SYSTEMS)}",
              file=sys.stderr)
        return 2
    make_folder(OUT)
    rows = _read_index()
    start = time.perf_counter()
    for name in names or list(SYSTEMS):
        result, what = _run(name)
        result.plot(OUT, name)
        write_text_atomic(OUT / f"{name}.md", _report(name, result, what))
        rows[name] = _index_row(name, result)
        print(f"{name:<26} radius {np.array2string(result.radius, precision=3)} "
              f"orders {np.array2string(result.slope, precision=2)} "
              f"({result.seconds:.1f} s)", flush=True)
    _write_index(rows)
    print(f"total {time.perf_counter() - start:.1f} s; index {INDEX}")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))

"""The reports of ``pinlin validate``: one Markdown file per system with its eigenvalue plot (and,
for mechanisms, a picture of the MuJoCo scene), and the index ``README.md``, which merges into an
existing one. Every file is written atomically; a file pinlin did not write is never replaced
(each starts with a marker that :func:`pinlin.files.check_ours` looks for).
"""

from __future__ import annotations

import platform
import re
import warnings
from pathlib import Path

import numpy as np

from .files import PNG_METADATA, write_atomic, write_bytes_atomic, write_text_atomic

#: First line of every file pinlin writes into a report folder: an existing file there that
#: does not start so is the user's and is never replaced.
REPORT_MARKER = "# Validation of '"
INDEX_MARKER = "# Validation reports"
PNG_MARKER = b"\x89PNG"
INDEX_NAME = "README.md"
_INDEX_ROW = re.compile(r"^\| \[(?P<name>[^\]]+)\]\((?P=name)\.md\) \| (?P<status>[^|]*?) \|")


#: Modes drawn beside the eigenvalue plot, and the resolution of their picture [dpi].
MODE_PICTURE_COUNT = 3
MODE_PICTURE_DPI = 90


def picture_name(name: str) -> str:
    """File name of the rendered picture of a system's MuJoCo scene."""
    return f"{name}_mujoco.png"


def modes_picture_name(name: str) -> str:
    """File name of the mode-shape picture of a system's first modes."""
    return f"{name}_modes.png"


def _held(res) -> bool:
    """Whether MuJoCo's model holds loops or contacts by soft equalities."""
    return "loops" in res.effects or "contacts" in res.effects


def _worst_ratio(res) -> float:
    """max error / tolerance over the eigenvalue table (<= 1: every eigenvalue passes)."""
    return max((row[3] / row[5] for row in res.table if row[5] > 0), default=0.0)


def write_report(res, folder: Path, scene=None) -> None:
    """``<name>.md``, ``<name>.png`` (both eigenvalue sets in the complex plane),
    ``<name>_modes.png`` (stick figures of the first :data:`MODE_PICTURE_COUNT` modes,
    :mod:`pinlin.mode_pictures`) and, when the validation rendered one, ``<name>_mujoco.png``,
    each written atomically.

    Args:
        res: The :class:`~pinlin.validate.Validation`.
        folder: The report folder.
        scene: The scene validated; default: ``res.name`` resolved as ``pinlin validate``
            resolves a name (:func:`pinlin.bench.check_scene`). Without a scene (a name that
            does not resolve) the report has no mode picture and says why.

    Raises:
        ModelFileError: a file cannot be written (it is left as it was).
    """
    import mujoco
    import pinocchio as pin

    from .validate import EIG_TOL, EPS_LOOP, EPS_OPEN, MATRIX_TOL, MOVING_TOL

    lines = [f"# Validation of '{res.name}' against MuJoCo", "",
             f"Verdict: **{res.status}**" + (f" — {res.reason}" if res.reason else ""), ""]
    if res.pinlin_eigs is None:
        write_text_atomic(folder / f"{res.name}.md", "\n".join(lines) + "\n")
        return
    lines += [
        f"pin {pin.__version__}, MuJoCo {mujoco.__version__}, {platform.machine()}. "
        f"Reproduce: `pinlin validate {res.name}`.",
        "",
        f"- Effects in play: {', '.join(res.effects) or 'none'}; everything else is off in "
        "the MuJoCo scene (MuJoCo's own contacts between geoms, joint limits, friction loss, "
        "actuator clamps, equalities other than the scene's loops, contacts and mimic "
        "couplings).",
        "- MuJoCo model: " + (
            "MuJoCo's own import of the URDF." if not res.merged else
            "MuJoCo's own import of the URDF, except that MuJoCo refuses the inertia of "
            f"{_names(res.refused)} on its own (a placeholder whose fixed children carry the "
            "mass, or an unphysical inertia of a fixed part), so these links are merged into "
            "the bodies Pinocchio simulates (the world, for links welded to it), by the "
            "parallel-axis theorem (see "
            "pinlin/mjcf_merge.py): " + "; ".join(res.merged) + ".")
        + " Visual-only geoms (no mass, no contacts) do not change M or g.",
        f"- nv = {res.nv}; MuJoCo Euler, dt = {res.dt:.3g} s; "
        + ("centered transition differences with eps = "
           f"{EPS_LOOP:g}; loop and contact equalities with time constant 2 dt, impedance "
           "0.9999 and 0.999 "
           "(extrapolated to 1)" if _held(res) else
           f"centered transition differences at eps = {EPS_OPEN:g} and {2 * EPS_OPEN:g}, "
           "Richardson-combined") + ".",
        "- Sanity at q0 (relative): " + ", ".join(f"{k} {v:.1e}" for k, v in res.sanity.items()),
        "- Matrix error max |A_mj - A| / max |A|: "
        + (f"{res.matrix_error:.2e} (tolerance {MATRIX_TOL:.0e})" if res.matrix_error is not None
           else "not compared (loops or contacts: MuJoCo's state is the dependent "
                "coordinates)"),
        "- Moving state (v random in [-1, 1], seed fixed): pinlin's Euler step against "
        "MuJoCo's, max |A_d - A_d,mj| "
        + (f"{res.moving_error[0]:.2e}, B_d relative {res.moving_error[1]:.2e} (tolerance "
           f"{MOVING_TOL:.0e})" if res.moving_error is not None else
           "not compared (a floating base, loops or damping: MuJoCo integrates damping "
           "implicitly)"),
        f"- Largest relative eigenvalue error, non-rigid: {res.eig_error:.2e} (tolerance "
        f"{EIG_TOL:.0e}, or the eigenvalue's condition bound where that is larger; largest "
        f"error / its tolerance over the table: {_worst_ratio(res):.2f})"
        + (f"; raw at d = 0.9999, before extrapolation to d = 1: "
                             f"{res.eig_error_raw:.2e}" if _held(res)
                             or res.eig_error_raw != res.eig_error else ""),
        f"- Rigid and near-rigid modes (|lam| <= {res.rigid_tol:.1e}): largest |lam_mj - lam| "
        f"{res.rigid_error:.1e} (tolerance {res.rigid_tol:.1e})",
        f"- Set aside: {len(res.set_aside)} MuJoCo soft-constraint eigenvalues"
        + (f" (|lam| from {min(abs(x) for x in res.set_aside):.3g} to "
           f"{max(abs(x) for x in res.set_aside):.3g} 1/s)" if res.set_aside else ""),
        "",
        f"- Eigenvalues whose tolerance is set by their condition number (MuJoCo's difference "
        f"error times kappa exceeds 1e-6): {res.conditioning_limited}",
        "",
        "| # | pinlin eigenvalue [1/s] | MuJoCo, continuous A | error (rel.; abs. for rigid) "
        "| tolerance | MuJoCo log(z)/dt (for reference) | kind |",
        "|---|---|---|---|---|---|---|",
    ]
    if not len(res.pinlin_eigs):
        lines[-8:] = [f"- pinlin's model has no states (everything is held): MuJoCo's "
                       f"{len(res.set_aside)} eigenvalues are all soft-constraint modes "
                       "(2 per constraint row)."]
    for k, (a, b, c, e, kind, tol) in enumerate(res.table, start=1):
        lines.append(f"| {k} | {a.real:+.9g} {a.imag:+.9g}j | {b.real:+.9g} {b.imag:+.9g}j | "
                     f"{e:.1e} | {tol:.1e} | {c.real:+.7g} {c.imag:+.7g}j | {kind} |")
    modes_png, why = _mode_picture(res, scene)
    if modes_png is not None and _ours_or_absent(folder / modes_picture_name(res.name)):
        write_bytes_atomic(folder / modes_picture_name(res.name), modes_png)
        how = (f" `pinlin modes {res.name} --plot modes.png` draws the first four."
               if why == "command" else why)
        lines += ["", f"![eigenvalues]({res.name}.png) "
                      f"![first modes]({modes_picture_name(res.name)})", "",
                  "The second picture shows the first modes as stick figures (joint origins "
                  "and frames from Pinocchio's forward kinematics; grey at q0, coloured at q0 "
                  "displaced along the mode; see pinlin/stick_figure.py), each in its plane of "
                  f"largest displacement.{how}", ""]
    else:
        if modes_png is not None:
            why = (f"{modes_picture_name(res.name)} exists and was not written by pinlin; it "
                   "is left alone")
        lines += ["", f"![eigenvalues]({res.name}.png)", "", f"No mode picture: {why}.", ""]
    if res.picture is not None:
        write_bytes_atomic(folder / picture_name(res.name), res.picture)
        lines += ["The MuJoCo scene at the operating point (MuJoCo's offscreen renderer; "
                  "capsules join the joint origins, spheres sit at the centres of mass, sized "
                  "by mass):", "", f"![MuJoCo scene]({picture_name(res.name)})", ""]
    elif res.picture_note:
        lines += [f"No picture of the MuJoCo scene: {res.picture_note}", ""]
    _plot(res, folder / f"{res.name}.png")
    write_text_atomic(folder / f"{res.name}.md", "\n".join(lines) + "\n")


def _ours_or_absent(path: Path) -> bool:
    from .exceptions import ModelFileError
    from .files import check_ours

    try:
        check_ours(path, PNG_MARKER)
    except ModelFileError:
        return False
    return True


def _mode_picture(res, scene) -> tuple[bytes | None, str]:
    """(PNG of the first modes, how to reproduce it) or (None, why not): how is "command"
    where ``pinlin modes NAME`` draws the same scene, else a sentence."""
    from .exceptions import PinlinError
    from .linearization import linearize
    from .modal import modal
    from .mode_pictures import default_modes, picture

    how = ""
    if scene is None:
        from .bench import check_scene

        try:
            scene, kind = check_scene(res.name)
        except PinlinError:
            return None, (f"the report name '{res.name}' is no bundled scene or robot name, "
                          "and the validation did not pass its scene on")
        how = (" The model drawn is the validated one: the free fall at rest from a rotated "
               "base pose." if kind == "floating base" else "command")
    try:
        with warnings.catch_warnings():  # the validation has reported them already
            warnings.simplefilter("ignore")
            modes = modal(linearize(scene))
        chosen = default_modes(modes, MODE_PICTURE_COUNT)
        if not chosen:
            return None, "the model has no mode to draw"
        return picture(scene, modes, chosen, dpi=MODE_PICTURE_DPI, palette=True), how
    except PinlinError as exc:
        return None, " ".join(str(exc).split()).rstrip(".")


def _names(links: list[str]) -> str:
    quoted = [f"'{n}'" for n in links]
    return ("link " + quoted[0] if len(quoted) == 1 else
            "links " + ", ".join(quoted[:-1]) + " and " + quoted[-1])


def _plot(res, path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(5.5, 4.5))
    ours = np.asarray(res.pinlin_eigs)
    mj = np.array([row[1] for row in res.table])
    ax.plot(ours.real, ours.imag, "o", mfc="none", ms=9, label="pinlin")
    ax.plot(mj.real, mj.imag, "x", ms=7, label="MuJoCo (matched)")
    ax.set_xlabel("Re [1/s]")
    ax.set_ylabel("Im [1/s]")
    ax.set_title(f"{res.name}: {res.status}")
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize=8)
    fig.tight_layout()
    try:
        write_atomic(path, lambda fh: fig.savefig(fh, format="png", dpi=70,
                                                  metadata=PNG_METADATA))
    finally:
        plt.close(fig)


def index_row(r) -> str:
    """The index line of one validation."""
    mat = f"{r.matrix_error:.1e}" if r.matrix_error is not None else "-"
    eig = f"{r.eig_error:.1e}" if np.isfinite(r.eig_error) else "-"
    rig = f"{r.rigid_error:.1e}" if np.isfinite(r.rigid_error) else "-"
    note = r.reason or (f"MuJoCo refuses the inertia of {_names(r.refused)} alone; merged: "
                        + ", ".join(m.split(" (")[0] for m in r.merged) if r.merged else "")
    if len(note) > 160:
        note = note[:157] + "..."
    note = note.replace("|", "\\|")
    return f"| [{r.name}]({r.name}.md) | {r.status} | {mat} | {eig} | {rig} | {note} |"


def index_rows(path: Path) -> dict[str, str]:
    """Rows of an existing index, by system name, in file order (empty if there is none)."""
    try:
        text = path.read_text(encoding="utf-8", errors="replace")
    except OSError:
        return {}
    rows = {}
    for line in text.splitlines():
        m = _INDEX_ROW.match(line)
        if m:
            rows[m["name"]] = line
    return rows


def totals(rows: dict[str, str]) -> dict[str, int]:
    """Count of each verdict among index rows, by verdict (sorted)."""
    statuses = [m["status"] for m in (_INDEX_ROW.match(line) for line in rows.values()) if m]
    return {s: statuses.count(s) for s in sorted(set(statuses))}


def write_summary(results: list, folder: Path, command: str, merge: bool = True) -> dict[str, int]:
    """The index ``README.md``: one row per system, written atomically; returns the totals.

    With ``merge``, the rows of an existing index for systems not in ``results`` are kept
    (in place; new systems are appended) and the totals count every row, so that validating
    one system does not drop the others from the index.
    """
    path = folder / INDEX_NAME
    rows = index_rows(path) if merge else {}
    done = {r.name for r in results}
    kept = [name for name in rows if name not in done]
    for r in results:
        rows[r.name] = index_row(r)
    note = (f" Rows of {len(kept)} other systems are kept from earlier runs."
            if kept else "")
    lines = [INDEX_MARKER, "",
             f"Produced by `{command}`.{note} One line per system: pinlin's linear model "
             "against MuJoCo (see [pinlin/validate.py](../../pinlin/validate.py) for the method "
             "and tolerances). Other reports here: [accuracy_vs_time.md](accuracy_vs_time.md), "
             "[bench_linearize.md](bench_linearize.md).", "",
             "| system | verdict | matrix error | eigenvalue error | rigid | note |",
             "|---|---|---|---|---|---|", *rows.values()]
    counts = totals(rows)
    lines += ["", "Totals: " + ", ".join(f"{k}: {v}" for k, v in counts.items())
              + f" ({len(rows)} systems)", ""]
    write_text_atomic(path, "\n".join(lines))
    return counts

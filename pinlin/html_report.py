"""``pinlin report``: one self-contained HTML file per scene, to open from disk in any browser.

Contents: the operating point (q0 per joint, u0 per input, the effects and notes of the model),
the mode table (one row per mode, as :meth:`pinlin.ModalAnalysis.table`), the eigenvalue map
(inline SVG), an animated 3-D stick figure per mode with a mode selector and an amplitude
slider (:mod:`pinlin.html_report_assets`), the free linear response from the first drawn mode
(:func:`pinlin.response`, a PNG) and, on request, the validity plots of that mode
(:func:`pinlin.validity`, which simulates the nonlinear dynamics: seconds to minutes).

Nothing is fetched: the data are a JSON block, the script and the style sheet are inline, the
plots are ``data:`` URIs, and a Content-Security-Policy (``default-src 'none'``) forbids the
page any network access. Each stick-figure frame is a configuration computed here
(:func:`pinlin.stick_figure.mode_motion`: :data:`PHASES` phases of a cycle at each of
:data:`AMPLITUDE_FACTORS` times the readable amplitude), so the browser interpolates nothing
and a mechanism's loops stay closed in every frame; an amplitude at which a mechanism cannot be
assembled is left out of its slider.
"""

from __future__ import annotations

import base64
import html
import io
import json
import math
from pathlib import Path

import numpy as np

from .exceptions import ArgumentError, AssemblyError, ModelFileError
from .fields import show
from .figure_view import best_view
from .files import as_path, check_file_target, write_text_atomic
from .html_report_assets import SCRIPT, STYLE
from .linear_model import LinearModel
from .modal import ModalAnalysis
from .stick_figure import AXIS_LENGTH, Skeleton, mode_motion, readable_amplitude

#: Phases per cycle stored for each mode and amplitude.
PHASES = 24
#: Amplitudes offered by the slider, as multiples of the readable amplitude.
AMPLITUDE_FACTORS = (0.25, 0.5, 1.0, 1.5, 2.0)
#: Modes drawn by default (the table lists every mode).
MAX_MODES = 24
#: First line of the file (the report's marker).
MARKER = "<!DOCTYPE html>"
_CSP = ("default-src 'none'; img-src data:; style-src 'unsafe-inline'; "
        "script-src 'unsafe-inline'")


def _e(text: object) -> str:
    return html.escape(str(text), quote=True)


def _row_cells(modes: ModalAnalysis, i: int) -> list[str]:
    """The cells of mode ``i``'s table row, formatted as :meth:`ModalAnalysis.table`."""
    lam = modes.eigenvalues[i]
    if modes.rigid[i]:
        return ["0 (rigid)", "0", "0", "-"]
    noise = abs(lam.real) <= modes.rounding[i]
    re = "0" if noise else f"{lam.real:+.6g}"
    ev = f"{re} &plusmn; {abs(lam.imag):.6g}j" if modes.oscillates(i) else re
    zeta = "0" if noise else f"{modes.zeta[i]:.4g}"
    return [ev, f"{modes.wn[i]:.6g}", f"{modes.wn[i] / (2 * np.pi):.6g}", zeta]


def mode_table(modes: ModalAnalysis, drawn: set[int]) -> str:
    """``<table id="mode-table">`` with one body row per mode (``data-mode`` = its number)."""
    head = ("<tr><th>#</th><th>eigenvalue [1/s]</th><th>&omega;n [rad/s]</th><th>f [Hz]</th>"
            "<th>&zeta;</th><th class='text'>kind</th><th class='text'>dominant coordinates"
            "</th></tr>")
    rows = []
    for n, i in enumerate(modes.modes(), start=1):
        cells = "".join(f"<td>{c}</td>" for c in _row_cells(modes, i))
        cls = "" if n in drawn else " class='undrawn'"
        rows.append(f"<tr data-mode='{n}'{cls}><td>{n}</td>{cells}"
                    f"<td class='text'>{_e(modes.kind(i))}</td>"
                    f"<td class='text'>{_e(', '.join(modes.dominant(i)))}</td></tr>")
    return (f"<table id='mode-table'><thead>{head}</thead><tbody>{''.join(rows)}</tbody>"
            "</table>")


def eigenvalue_map(modes: ModalAnalysis, width: int = 420, height: int = 300) -> str:
    """The eigenvalues in the complex plane as inline SVG; each circle carries its mode's
    number (``data-mode``) so the page can highlight the selected mode."""
    lam = modes.eigenvalues
    number = {}
    for n, i in enumerate(modes.modes(), start=1):
        number[i] = n
    for i in range(len(lam)):
        number.setdefault(i, number.get(i - 1, 0))
    re = np.append(lam.real, 0.0)
    im = np.append(lam.imag, 0.0)
    pad = 40

    def span(v: np.ndarray) -> tuple[float, float]:
        lo, hi = float(v.min()), float(v.max())
        extra = max(0.08 * (hi - lo), 1e-9 + 0.05 * max(abs(lo), abs(hi)), 1e-6)
        return lo - extra, hi + extra

    (x0, x1), (y0, y1) = span(re), span(im)

    def sx(x: float) -> float:
        return pad + (x - x0) / (x1 - x0) * (width - 2 * pad)

    def sy(y: float) -> float:
        return height - pad - (y - y0) / (y1 - y0) * (height - 2 * pad)

    parts = [f"<svg class='eig' width='{width}' "
             f"height='{height}' viewBox='0 0 {width} {height}'>",
             f"<rect x='0' y='0' width='{width}' height='{height}' fill='#fff' stroke='#ccc'/>",
             f"<line x1='{sx(0):.1f}' y1='{pad - 10}' x2='{sx(0):.1f}' y2='{height - pad + 10}' "
             "stroke='#999'/>",
             f"<line x1='{pad - 10}' y1='{sy(0):.1f}' x2='{width - pad + 10}' y2='{sy(0):.1f}' "
             "stroke='#999'/>",
             f"<text x='{width - pad}' y='{height - 8}' text-anchor='end'>Re &#955; [1/s] "
             f"({x0:.3g} to {x1:.3g})</text>",
             f"<text x='8' y='14'>Im &#955; [1/s] ({y0:.3g} to {y1:.3g})</text>"]
    for i, x in enumerate(lam):
        parts.append(f"<circle data-mode='{number[i]}' cx='{sx(x.real):.1f}' "
                     f"cy='{sy(x.imag):.1f}' r='5'><title>mode {number[i]}: "
                     f"{x.real:+.5g} {x.imag:+.5g}j</title></circle>")
    parts.append("</svg>")
    return "".join(parts)


def operating_point_html(model, system) -> str:
    """The operating point as tables: q0 per joint, u0 per input; the effects and notes."""
    from .cli_format import _joint_value

    op = model.operating_point
    rows = "".join(f"<tr><td class='text'>{_e(name)}</td><td class='text'>"
                   f"{_e(_joint_value(j, op.q[j.idx_q:j.idx_q + j.nq]))}</td></tr>"
                   for name, j in system.joints.items())
    rows += "".join(f"<tr><td class='text'>{_e(name)}</td><td class='text'>{u:.6g}</td></tr>"
                    for name, u in zip(model.input_names, op.u, strict=True))
    if np.any(op.v):
        rows += f"<tr><td class='text'>v0</td><td class='text'>{_e(np.round(op.v, 6))}</td></tr>"
    info = model.info
    effects = ", ".join(info.get("effects", [])) or "none"
    lines = [f"formulation: {info.get('formulation', '?')}, derivatives "
             f"{info.get('derivatives', '?')}; effects in play: {effects}; base "
             f"{info.get('base', '?')}; "
             + ("an equilibrium" if op.equilibrium else "NOT an equilibrium")]
    lines += [f"note: {n}" for n in info.get("notes", [])]
    notes = "".join(f"<p class='note'>{_e(t)}</p>" for t in lines)
    return (f"{notes}<table id='operating-point'><thead><tr><th class='text'>joint or input"
            f"</th><th class='text'>value [rad, m; N*m, N]</th></tr></thead><tbody>{rows}"
            "</tbody></table>")


def _png(fig) -> str:
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=80)
    return "data:image/png;base64," + base64.b64encode(buf.getvalue()).decode("ascii")


#: The response plot ends before e^(rho T) reaches 1e8 for the fastest growth rate rho.
GROWTH_LIMIT = math.log(1e8)


def response_plot(model, modes: ModalAnalysis, index: int, amplitude: float) -> str:
    """``data:`` PNG of the free linear response from mode ``index``'s shape (positions a
    Re(r_q), velocities a Re(lambda r_q)): 5 periods, or 5 time constants of a real mode."""
    from matplotlib.figure import Figure

    from .response import response

    n = model.n_states // 2
    r = modes.right_vectors[:, index]
    r = r / r[int(np.argmax(np.abs(r[:n])))]
    x0 = amplitude * np.real(r)
    lam = modes.eigenvalues[index]
    if modes.oscillates(index):
        T = 5 * 2 * np.pi / abs(lam.imag)
    elif abs(lam.real) > modes.rigid_tol:
        T = 5 / abs(lam.real)
    else:
        T = 5.0
    # Rounding excites every other mode at ~eps of the shape's size: stop before the fastest
    # growing one (rate rho) lifts it past 1e-8 of it, e^(rho T) <= 1e8, so the plot shows the
    # chosen mode and not the others' growth from noise.
    rho = float(modes.eigenvalues.real.max(initial=0.0))
    capped = rho * T > GROWTH_LIMIT
    if capped:
        T = GROWTH_LIMIT / rho
    t = np.linspace(0.0, T, 400)
    res = response(model, t, x0=x0, modes=modes)
    fig = Figure(figsize=(7.0, 3.2))
    ax = fig.subplots()
    for k, name in enumerate(model.state_names[:n][:12]):
        ax.plot(t, res.x[:, k], lw=1.2, label=name)
    ax.set_xlabel("t [s]")
    ax.set_ylabel("deviation [rad or m]")
    ax.set_title(f"free linear response from mode {modes.modes().index(index) + 1}'s shape "
                 f"(a = {amplitude:.3g})" + (f"; ends at {T:.3g} s (growth {rho:.3g} 1/s)"
                                             if capped else ""),
                 fontsize=9)
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize=7, ncol=2)
    fig.tight_layout()
    return _png(fig)


def validity_plots(scene, index: int) -> list[str]:
    """``data:`` PNGs of :func:`pinlin.validity` for mode ``index`` (simulations)."""
    import tempfile

    from .validity import validity

    result = validity(scene, modes=[index])
    with tempfile.TemporaryDirectory() as folder:
        paths = result.plot(folder, "validity")
        return ["data:image/png;base64," + base64.b64encode(Path(p).read_bytes()).decode("ascii")
                for p in paths]


def _with_triads(fig, triads: list[int], length: float) -> np.ndarray:
    """The figure's points, then the tips of the x, y, z axes of the frames of ``triads``
    (``length`` [m] from their points): (P + 3 T, 3) [m]."""
    tips = [fig.points[k] + length * fig.rotations[k][:, axis] for k in triads
            for axis in range(3)]
    return np.vstack([fig.points, *tips]) if tips else fig.points


def _mode_data(system, modes: ModalAnalysis, i: int, skeleton: Skeleton, digits: int) -> dict:
    from .mode_pictures import unit_of

    q0 = np.asarray(modes.model.operating_point.q, dtype=float)
    from .stick_figure import full_shape

    base = readable_amplitude(skeleton, q0, full_shape(system, modes, i))
    phases = np.arange(PHASES) * 2 * np.pi / PHASES
    motions, factors = [], []
    for factor in AMPLITUDE_FACTORS:
        try:
            motions.append(mode_motion(system, modes, i, amplitude=factor * base,
                                       phases=phases, skeleton=skeleton))
        except AssemblyError:
            continue
        factors.append(factor)
    if not motions:
        return {}
    motion = motions[factors.index(1.0)] if 1.0 in factors else motions[0]
    view = best_view(motion)
    triads = motion.turning()
    length = AXIS_LENGTH * motion.rest.size
    levels = [[np.round(_with_triads(f, triads, length).ravel(), digits).tolist()
               for f in m.figures] for m in motions]
    amplitudes = [m.amplitude for m in motions]
    name, unit = unit_of(system, modes, motion)
    return {"number": motion.number, "label": motion.label, "unit": unit,
            "coordinate": name, "amplitudes": amplitudes, "factors": factors,
            "rigid": bool(modes.rigid[i]),
            "unit_level": factors.index(1.0) if 1.0 in factors else 0, "triads": triads,
            "view": [view.right.tolist(), view.up.tolist(), view.normal.tolist()],
            "frames": levels}


def report_html(scene, *, model=None, modes: ModalAnalysis | None = None,
                max_modes: int = MAX_MODES, include_response: bool = True,
                include_validity: bool = False) -> str:
    """The report of ``scene`` as one HTML document (module docstring).

    Args:
        scene: A :class:`~pinlin.Scene`, System, or scene file / bundled scene / robot name.
        model: Its linear model (default ``pinlin.linearize(scene)``).
        modes: ``pinlin.modal(model)`` (computed when not given).
        max_modes: How many modes get a stick figure (1 to 500; the first of
            :meth:`ModalAnalysis.modes` that are not constraint modes); the table lists all.
        include_response: Embed the free linear response from the first drawn mode.
        include_validity: Embed :func:`pinlin.validity`'s plots for the first drawn non-rigid
            mode (nonlinear simulations: slow for large robots).
    """
    from .linearization import _system, linearize
    from .modal import modal

    if isinstance(max_modes, bool) or not isinstance(max_modes, int) or not 1 <= max_modes <= 500:
        raise ArgumentError("max_modes", f"expected 1 to 500 modes to draw, got {max_modes!r}")
    system = _system(scene)
    if model is None:
        model = linearize(system)
    elif not isinstance(model, LinearModel) or model.operating_point is None or \
            np.shape(model.operating_point.q) != (system.nq,):
        raise ArgumentError("model", f"expected a linear model of scene '{system.scene.name}' "
                                     f"(an operating point with nq = {system.nq} coordinates), "
                                     f"got {show(model)}")
    modes = modal(model) if modes is None else modes
    skeleton = Skeleton(system)
    rest = skeleton.figure(np.asarray(model.operating_point.q, dtype=float))
    digits = max(3, 5 - math.floor(math.log10(rest.size)))
    moving = [i for i in modes.modes() if modes.kind(i) not in ("rigid", "constraint")]
    rigid = [i for i in modes.modes() if modes.kind(i) == "rigid"]
    chosen = (moving + rigid)[:max_modes]
    chosen.sort(key=modes.modes().index)
    entries = [d for d in (_mode_data(system, modes, i, skeleton, digits) for i in chosen) if d]
    data = {"name": model.name, "rest": np.round(rest.points.ravel(), digits).tolist(),
            "links": rest.links.tolist(), "closures": rest.closures.tolist(),
            "kinds": list(rest.kinds), "names": list(rest.names), "modes": entries,
            "start": next((k for k, d in enumerate(entries) if not d["rigid"]), 0)}
    drawn = {d["number"] for d in entries}
    options = "".join(f"<option value='{k}'>{_e(d['label'])}</option>"
                      for k, d in enumerate(entries))
    plots = []
    first = next((i for i in chosen if modes.kind(i) not in ("rigid", "constraint")), None)
    if include_response and first is not None:
        amp = next(d["amplitudes"][d["unit_level"]] for d in entries
                   if d["number"] == modes.modes().index(first) + 1)
        plots.append(("Free linear response", [response_plot(model, modes, first, amp)]))
    if include_validity and first is not None:
        plots.append(("Validity of the linear model (nonlinear simulation against linear)",
                      validity_plots(system, first)))
    plot_html = "".join(f"<h2>{_e(head)}</h2>" + "".join(
        f"<p><img class='plot' alt='{_e(head)}' src='{src}'></p>" for src in srcs)
        for head, srcs in plots)
    if include_validity and first is None:   # asked for, and nothing to check: say so
        plot_html += ("<h2>Validity of the linear model</h2><p class='note'>Not computed: "
                      "the model has no mode that is neither rigid nor a constraint mode "
                      "among those drawn, so no motion to compare with a nonlinear "
                      "simulation.</p>")
    undrawn = len(modes.modes()) - len(entries)
    note = (f"<p class='note'>{undrawn} mode(s) of the table are not drawn (rigid or "
            f"constraint modes beyond the first {max_modes}, or not assemblable).</p>"
            if undrawn else "")
    # No "<" in the script element at all: "</script" would close it and "<!--" open a
    # comment that swallows the page (HTML's script data states); JSON reads \u003c as "<".
    payload = json.dumps(data, separators=(",", ":")).replace("<", "\\u003c")
    title = f"pinlin report: {model.name}"
    count = len(modes.modes())
    return f"""{MARKER}
<html lang="en"><head><meta charset="utf-8">
<meta http-equiv="Content-Security-Policy" content="{_CSP}">
<meta name="viewport" content="width=device-width, initial-scale=1">
<link rel="icon" href="data:,">
<title>{_e(title)}</title><style>{STYLE}</style></head>
<body>
<h1>{_e(title)}</h1>
<p class="note">nq = {system.nq}, nv = {system.nv}; {count} mode{'s' * (count != 1)}
({len(modes.eigenvalues)} eigenvalues, {_e(modes.method)} eigensolver). Written by pinlin;
opens from disk, without a network.</p>
<h2>Operating point</h2>
{operating_point_html(model, system)}
<h2>Mode shapes</h2>
<div class="controls">
<label>Mode <select id="mode">{options}</select></label>
<label>Amplitude <input type="range" id="amplitude" min="0" max="0" step="1" value="0"></label>
<span id="amplitude-value"></span>
<button id="play" type="button">Pause</button>
<button id="reset-view" type="button">Reset view</button>
</div>
<div class="viewer">
<canvas id="figure" width="560" height="460"></canvas>
<div style="max-width: 440px">{eigenvalue_map(modes)}
<p class="note">Grey: q0. Blue: q0 displaced along the mode (phase shown at the top).
Drag the figure (or use the arrow keys) to turn it; click an eigenvalue or a table row to
select its mode.</p></div>
</div>
{note}
<h2>Mode table</h2>
{mode_table(modes, drawn)}
{plot_html}
<script type="application/json" id="pinlin-data">{payload}</script>
<script>{SCRIPT}</script>
</body></html>
"""


def check_report_target(path: object, argument: str = "path") -> Path:
    """``path`` as a Path that can be written and ends in .html (or .htm).

    Raises:
        ArgumentError: not a path.
        ModelFileError: another suffix, a folder, or a folder that does not exist.
    """
    path = as_path(path, argument)
    if path.is_dir():
        raise ModelFileError(path, "is a folder; expected an .html file name")
    if path.suffix.lower() not in (".html", ".htm"):
        raise ModelFileError(path, f"expected an .html file for the report, got "
                                   f"'{path.suffix or 'no suffix'}'")
    return check_file_target(path)


def write_html_report(scene, path: str | Path, **options) -> Path:
    """Write :func:`report_html` (``options`` are its keywords) to ``path`` (``.html``)
    atomically; returns the path.

    Raises:
        ModelFileError: ``path`` does not end in .html (or .htm) or cannot be written
            (checked before any work).
    """
    path = check_report_target(path)
    write_text_atomic(path, report_html(scene, **options))
    return path


__all__ = ["MAX_MODES", "check_report_target", "eigenvalue_map", "mode_table", "report_html",
           "write_html_report"]

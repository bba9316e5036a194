"""Stick figures and mode pictures (pinlin.stick_figure, pinlin.mode_pictures, `pinlin modes`).

The references never come from the code under test: drawn coordinates are compared with
Pinocchio's own ``oMi`` / ``oMf`` from a fresh ``pin.Data``, displaced figures with
``pin.integrate(q0, a Re(e^{i theta} shape))`` built here from the modal analysis, and loop
closure with the distance of the loop frames computed by Pinocchio at the drawn configuration.
"""

from __future__ import annotations

import io
import tomllib

import numpy as np
import pinocchio as pin
import pytest
from conftest import URDF_DIR

import pinlin
from pinlin.cli import main
from pinlin.figure_view import best_view
from pinlin.mode_pictures import animate_modes, default_modes, picture, plot_modes
from pinlin.stick_figure import ModeMotion, Skeleton, mode_motion, readable_amplitude


def _analysis(name: str, **options):
    scene = pinlin.Scene.resolve(name) if not options else pinlin.Scene.from_robot(name,
                                                                                   **options)
    model = pinlin.linearize(scene)
    return scene, model, pinlin.modal(model)


def _placements(model: pin.Model, q: np.ndarray) -> pin.Data:
    data = pin.Data(model)
    pin.forwardKinematics(model, data, q)
    pin.updateFramePlacements(model, data)
    return data


def _check_figure(fig, model: pin.Model, q: np.ndarray) -> None:
    """Every drawn point and its rotation against Pinocchio's placements at q."""
    data = _placements(model, q)
    for k, (name, kind) in enumerate(zip(fig.names, fig.kinds, strict=True)):
        if kind == "world":
            ref = pin.SE3.Identity()
        elif kind == "joint":
            ref = data.oMi[model.getJointId(name)]
        else:
            ref = data.oMf[model.getFrameId(name)]
        np.testing.assert_allclose(fig.points[k], ref.translation, rtol=0, atol=1e-12)
        np.testing.assert_allclose(fig.rotations[k], ref.rotation, rtol=0, atol=1e-12)


@pytest.mark.parametrize("name", ["ur5_arm", "four_bar", "delta", "rotating_double_pendulum"])
def test_figure_at_q0_matches_pinocchio_placements(name):
    scene, model, _ = _analysis(name)
    system = scene.system
    q0 = model.operating_point.q
    fig = Skeleton(system).figure(q0)
    _check_figure(fig, system.model, q0)
    # Every joint is drawn, joined to its parent joint (the world origin for a root joint).
    pm = system.model
    links = {tuple(sorted(pair)) for pair in fig.links.tolist()}
    for j in range(1, pm.njoints):
        parent = fig.names.index(pm.names[pm.parents[j]]) if pm.parents[j] else \
            fig.names.index("universe")
        assert tuple(sorted((parent, fig.names.index(pm.names[j])))) in links
    # The loop frames are drawn and each loop is a closure.
    for loop, (a, b) in zip(scene.loops, fig.closures, strict=True):
        assert (fig.names[a], fig.names[b]) == (loop.frame1, loop.frame2)


def test_figure_at_a_random_configuration_matches_pinocchio():
    scene = pinlin.Scene.from_robot("solo12")
    system = scene.system
    model = system.model
    lo = np.where(np.isfinite(model.lowerPositionLimit), model.lowerPositionLimit, -1.0)
    hi = np.where(np.isfinite(model.upperPositionLimit), model.upperPositionLimit, 1.0)
    q = pin.randomConfiguration(model, np.maximum(lo, -2.0), np.minimum(hi, 2.0))
    fig = Skeleton(system).figure(q)
    _check_figure(fig, model, q)
    # A free flyer is not tied to the world origin: no world point, feet drawn as tips.
    assert "universe" not in fig.names
    assert {"FL_FOOT", "FR_FOOT", "HL_FOOT", "HR_FOOT"} <= set(fig.names)


@pytest.mark.parametrize("name", ["double_pendulum", "ur5_arm"])
def test_displaced_figure_is_integrate_of_the_shape(name):
    scene, model, modes = _analysis(name)
    pm = scene.system.model
    q0 = model.operating_point.q
    for i in modes.modes():
        motion = mode_motion(scene, modes, i)
        phi = modes.shapes[:, i]
        assert 0 < motion.amplitude <= 0.5
        for theta, q, fig in zip(motion.phases, motion.configurations, motion.figures,
                                 strict=True):
            expected = pin.integrate(pm, q0, motion.amplitude * np.real(np.exp(1j * theta) * phi))
            np.testing.assert_allclose(q, expected, rtol=0, atol=1e-14)
            _check_figure(fig, pm, expected)
        # The shape's largest entry is 1, so the largest coordinate moves by a at phase 0.
        assert np.abs(motion.deviations[0]).max() == pytest.approx(motion.amplitude, rel=1e-12)
        assert not motion.assembled


def test_damped_mode_is_drawn_at_several_phases():
    urdf = pinlin.Scene.resolve("double_pendulum").system.urdf_path
    # Damping on one joint only makes the shapes complex (the joints move out of phase).
    damped = pinlin.Scene.from_urdf(urdf, effects={"gravity": [0.0, 0.0, -9.81],
                                                   "damping": {"shoulder": 2.0}})
    model = pinlin.linearize(damped)
    modes = pinlin.modal(model)
    motion = mode_motion(damped, modes, modes.modes()[0])
    assert motion.complex and len(motion.figures) == 4
    phi = modes.shapes[:, motion.index]
    for theta, q in zip(motion.phases, motion.configurations, strict=True):
        expected = pin.integrate(damped.system.model, model.operating_point.q,
                                 motion.amplitude * np.real(np.exp(1j * theta) * phi))
        np.testing.assert_allclose(q, expected, rtol=0, atol=1e-14)


def test_floating_base_moves_with_its_mode():
    scene = pinlin.Scene.from_robot("solo12", operating_point={"allow_non_equilibrium": True})
    model = pinlin.linearize(scene)
    modes = pinlin.modal(model)
    pm = scene.system.model
    q0 = model.operating_point.q
    base = "root_joint"
    moved = 0.0
    for i in modes.modes():
        motion = mode_motion(scene, modes, i)
        phi = modes.shapes[:, i]
        for theta, fig in zip(motion.phases, motion.figures, strict=True):
            q = pin.integrate(pm, q0, motion.amplitude * np.real(np.exp(1j * theta) * phi))
            np.testing.assert_allclose(fig.q, q, rtol=0, atol=1e-14)
            _check_figure(fig, pm, q)
            moved = max(moved, float(np.linalg.norm(fig.point(base) - motion.rest.point(base))))
    assert moved > 0.01  # the base itself moves (the rigid modes translate it)


@pytest.mark.parametrize("name", ["four_bar", "slider_crank", "five_bar", "delta"])
def test_mechanism_figure_stays_closed_at_every_phase(name):
    scene, model, modes = _analysis(name)
    system = scene.system
    pm = system.model
    q0 = model.operating_point.q
    R = np.asarray(model.info["R"])
    z = [system.coordinate_names.index(n) for n in model.info["independent"]]
    phases = np.linspace(0.0, 2 * np.pi, 16, endpoint=False)
    for i in modes.modes():
        motion = mode_motion(scene, modes, i, phases=phases)
        assert motion.assembled
        phi = R @ modes.shapes[:, i]
        first_order_gap = 0.0
        for theta, q, fig in zip(phases, motion.configurations, motion.figures, strict=True):
            dq = motion.amplitude * np.real(np.exp(1j * theta) * phi)
            naive = pin.integrate(pm, q0, dq)
            # The independent coordinates are those of integrate(q0, a R phi), held.
            np.testing.assert_allclose(pin.difference(pm, q0, q)[z], dq[z], rtol=0, atol=1e-12)
            data = _placements(pm, q)
            naive_data = _placements(pm, naive)
            for loop in scene.loops:
                f1, f2 = pm.getFrameId(loop.frame1), pm.getFrameId(loop.frame2)
                gap = np.linalg.norm(data.oMf[f1].translation - data.oMf[f2].translation)
                assert gap <= 1e-9
                first_order_gap = max(first_order_gap, np.linalg.norm(
                    naive_data.oMf[f1].translation - naive_data.oMf[f2].translation))
            assert fig.gaps.max() <= 1e-9
            _check_figure(fig, pm, q)
        # Without the assembly the loop would open by O(a^2): the test can tell.
        assert first_order_gap > 1e-5
        assert motion.gap <= 1e-9


def test_penalty_model_is_drawn_closed_too():
    scene = pinlin.Scene.resolve("four_bar")
    model = pinlin.linearize(scene, formulation="penalty")
    modes = pinlin.modal(model)
    i = next(k for k in modes.modes() if modes.kind(k) not in ("constraint", "rigid"))
    motion = mode_motion(scene, modes, i, phases=np.linspace(0, 2 * np.pi, 8, endpoint=False))
    assert motion.assembled and motion.gap <= 1e-9


def test_frames_are_drawn_where_a_mode_turns_links_in_place():
    scene, model, modes = _analysis("ur5_arm")
    pm = scene.system.model
    q0 = model.operating_point.q
    skeleton = Skeleton(scene)
    # The last wrist joint turns the flange about its own axis: no joint origin moves.
    turn = np.zeros(pm.nv, dtype=complex)
    turn[-1] = 1.0
    assert readable_amplitude(skeleton, q0, turn) == pytest.approx(0.5)  # the cap
    phases = np.array([0.0, np.pi])
    qs = np.array([pin.integrate(pm, q0, 0.5 * np.cos(t) * turn.real) for t in phases])
    motion = ModeMotion(0, 1, "turn", 0.5, phases, 0.5 * np.outer(np.cos(phases), turn.real),
                        qs, tuple(skeleton.figure(q) for q in qs), skeleton.figure(q0),
                        False, False)
    assert [motion.rest.names[k] for k in motion.turning()] == ["wrist_3_joint"]
    scene2, _, modes2 = _analysis("double_pendulum")
    assert mode_motion(scene2, modes2, modes2.modes()[0]).turning() == []


def test_view_is_the_plane_of_motion():
    scene, model, modes = _analysis("double_pendulum")
    for i in modes.modes():
        view = best_view(mode_motion(scene, modes, i))
        assert view.labels == ("x [m]", "z [m]")  # the pendulum swings in the x-z plane
        np.testing.assert_allclose(np.cross(view.right, view.up), view.normal, atol=1e-15)


def test_pictures_are_png_and_gif(tmp_path):
    from PIL import Image

    scene, model, modes = _analysis("five_bar")
    png = plot_modes(scene, modes, tmp_path / "modes.png")
    assert png.read_bytes().startswith(b"\x89PNG")
    gif = animate_modes(scene, modes, tmp_path / "modes.gif", modes.modes()[0], frames=6)
    with Image.open(gif) as im:
        assert im.format == "GIF" and im.n_frames == 6
    small = picture(scene, modes, default_modes(modes, 1), dpi=40, palette=True)
    with Image.open(io.BytesIO(small)) as im:
        assert im.mode == "P"


def test_bad_arguments():
    scene, model, modes = _analysis("double_pendulum")
    with pytest.raises(pinlin.ArgumentError, match="no eigenvalue 9"):
        mode_motion(scene, modes, 9)
    with pytest.raises(pinlin.ArgumentError, match="amplitude > 0"):
        mode_motion(scene, modes, 0, amplitude=-1.0)
    with pytest.raises(pinlin.ModelError, match="are not those of scene 'ur5_arm'"):
        mode_motion("ur5_arm", modes, 0)
    with pytest.raises(pinlin.ModelFileError, match="expected a .png file"):
        plot_modes(scene, modes, "modes.jpg")
    for indices in (1.0, [0, "1"], True):
        with pytest.raises(pinlin.ArgumentError, match="indices"):
            picture(scene, modes, indices)
    for dpi in (0, 1e6, float("nan"), "90"):
        with pytest.raises(pinlin.ArgumentError, match="dpi"):
            picture(scene, modes, dpi=dpi)
    with pytest.raises(pinlin.ArgumentError, match="modes"):
        picture(scene, model)


# --------------------------------------------------------------------------------------------
# pinlin modes


def test_cli_modes_writes_the_picture(tmp_path, capsys):
    out = tmp_path / "modes.png"
    assert main(["modes", "double_pendulum", "--plot", str(out), "--mode", "2"]) == 0
    printed = capsys.readouterr().out
    assert "Modes of 'double_pendulum'" in printed and f"mode picture written to {out}" in printed
    assert out.read_bytes().startswith(b"\x89PNG")


@pytest.mark.parametrize("args, message", [
    (["--plot", "{tmp}/m.png", "--mode", "3"],
     "argument '--mode': no mode 3: the mode table of 'double_pendulum' has rows 1 to 2"),
    (["--plot", "{tmp}/m.png", "--mode", "0"], "argument '--mode': no mode 0"),
    (["--plot", "{tmp}/m.jpg"], "m.jpg: expected a .png file for the mode picture, got '.jpg'"),
    (["--gif", "{tmp}/m.png"], "m.png: expected a .gif file for the mode animation"),
    (["--mode", "1"], "argument '--mode': chooses the modes to draw: give --plot"),
    (["--plot", "{tmp}/m.png", "--amplitude", "-0.1"], "expected an amplitude > 0"),
    (["--plot", "{tmp}/m.png", "--amplitude", "1e300"], "expected an amplitude > 0 and <= 1000"),
    (["--plot", "{tmp}/m.png", "--mode", "1", "1"], "argument '--mode': names a mode twice"),
    (["--plot", "{tmp}"], "is a folder; expected a .png file name"),
    (["--plot", "{tmp}/no/such/m.png"], "does not exist"),
    (["--plot", "{tmp}/m.png", "--mode", "x"], "invalid int value"),
])
def test_cli_modes_bad_options_one_line_exit_2(tmp_path, capsys, args, message):
    argv = ["modes", "double_pendulum", *(a.replace("{tmp}", str(tmp_path)) for a in args)]
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and message in err and "Traceback" not in err
    assert not list(tmp_path.iterdir())  # nothing written


@pytest.mark.parametrize("name", ["standing_box", "solo12_standing"])
def test_standing_figure_keeps_its_feet_on_their_anchors(name):
    """Contacts are drawn: each contact frame (Pinocchio's oMf at the drawn configuration) and
    its anchor (the frame's oMf at q0, a world mark) coincide at every phase of every drawn
    mode, to the assembly's 1e-9, while the rest of the figure moves; the default modes draw
    each +-sigma pair of an unstable tilt once."""
    scene, model, modes = _analysis(name)
    pm = scene.system.model
    q0 = model.operating_point.q
    at_q0 = _placements(pm, q0)
    chosen = default_modes(modes)
    lam = modes.eigenvalues[chosen]
    assert len(set(np.round(np.abs(lam), 9))) == len(chosen)  # no mirrored duplicate
    for i in chosen:
        motion = mode_motion(scene, modes, i)
        for q, fig in zip(motion.configurations, motion.figures, strict=True):
            data = _placements(pm, q)
            moved = 0.0
            for contact in scene.system.constraints.contacts:
                fid = pm.getFrameId(contact.frame)
                anchor = fig.point(f"anchor:{contact.name}")
                np.testing.assert_allclose(anchor, at_q0.oMf[fid].translation, rtol=0,
                                           atol=1e-12)
                np.testing.assert_allclose(fig.point(contact.frame), data.oMf[fid].translation,
                                           rtol=0, atol=1e-12)
                assert np.linalg.norm(data.oMf[fid].translation - anchor) <= 1e-9
            for j in range(1, pm.njoints):
                moved = max(moved, np.linalg.norm(data.oMi[j].translation
                                                  - at_q0.oMi[j].translation))
            assert moved > 1e-3
            assert fig.gaps.max() <= 1e-9


def test_amplitude_beyond_what_closes_names_the_amplitude():
    scene, model, modes = _analysis("solo12_standing")
    with pytest.raises(pinlin.AssemblyError, match="at amplitude a = 20 .*smaller amplitude"):
        mode_motion(scene, modes, default_modes(modes)[0], amplitude=20.0)
    with pytest.raises(pinlin.ArgumentError, match="<= 1000"):
        mode_motion(scene, modes, default_modes(modes)[0], amplitude=1e300)


# --------------------------------------------------------------------------------------------
# Validation reports


def test_validation_report_shows_the_first_modes(tmp_path):
    from pinlin.validate import run

    run(["double_pendulum"], tmp_path, progress=False, announce=False)
    text = (tmp_path / "double_pendulum.md").read_text(encoding="utf-8")
    assert ("![eigenvalues](double_pendulum.png) "
            "![first modes](double_pendulum_modes.png)") in text
    assert (tmp_path / "double_pendulum_modes.png").read_bytes().startswith(b"\x89PNG")


def test_validation_report_without_a_scene_says_why(tmp_path):
    from pinlin.validate import validate
    from pinlin.validation_report import write_report

    res = validate(pinlin.Scene.resolve("pendulum"), name="renamed_pendulum")
    write_report(res, tmp_path)
    text = (tmp_path / "renamed_pendulum.md").read_text(encoding="utf-8")
    assert "No mode picture: the report name 'renamed_pendulum' is no bundled scene" in text
    assert not (tmp_path / "renamed_pendulum_modes.png").exists()
    write_report(res, tmp_path, scene=pinlin.Scene.resolve("pendulum"))
    assert (tmp_path / "renamed_pendulum_modes.png").exists()


def test_contact_on_a_name_a_link_and_a_joint_share():
    """so100's 'gripper' names both a link and a joint (Pinocchio then refuses a lookup by
    name alone): the figure takes the link's frame, as the scene's contact does."""
    scene = pinlin.Scene.from_dict({"name": "so100_tip", "robot": "so100",
                                    "effects": {"gravity": [0.0, 0.0, 0.0]},
                                    "contacts": [{"name": "tip", "frame": "gripper"}]})
    pm = scene.system.model
    fig = Skeleton(scene).figure(scene.system.q_ref)
    link = pm.getFrameId("gripper", pin.FrameType.BODY)
    np.testing.assert_allclose(fig.point("anchor:tip"),
                               _placements(pm, scene.system.q_ref).oMf[link].translation,
                               rtol=0, atol=1e-12)


def test_one_mode_named_twice_is_refused(tmp_path):
    """The CLI refused a mode named twice; the Python API drew it twice (also an index and
    its conjugate's)."""
    scene = pinlin.Scene.resolve("double_pendulum")
    modes = pinlin.modal(pinlin.linearize(scene))
    first = modes.modes()[0]
    for indices in ([first, first], [first, first + 1]):
        with pytest.raises(pinlin.ArgumentError, match="name the same mode"):
            plot_modes(scene, modes, tmp_path / "m.png", indices)
    assert not (tmp_path / "m.png").exists()


def test_a_sliding_mode_is_titled_in_metres():
    """The slider-crank in its slider's coordinate: its one mode moves the slider (metres),
    and the picture's title gives the amplitude in m. The slider is Pinocchio's
    ``JointModelPX``, which the title's test for a prismatic joint (the word "Prismatic" in
    the kind) missed: it said rad."""
    from pinlin.mode_pictures import title

    data = tomllib.loads((URDF_DIR / "slider_crank.toml").read_text())
    data["urdf"] = str(URDF_DIR / data["urdf"])
    data["operating_point"]["independent"] = ["slider"]
    scene = pinlin.Scene.from_dict(data)
    modes = pinlin.modal(pinlin.linearize(scene))
    assert modes.coordinate_names == ("slider",)
    motion = mode_motion(scene, modes, modes.modes()[0])
    assert title(scene.system, modes, motion).endswith(" m on slider")

"""The MuJoCo scene beyond the dynamics: links merged where MuJoCo refuses a URDF link's inertia
alone, visual-only geoms that change nothing, pictures of the mechanisms, ``validate`` taking
names and paths, and reports that merge into existing ones (validation index and bench)."""

from __future__ import annotations

import re
import shutil
import struct

import mujoco
import numpy as np
import pytest
from conftest import REPO, URDF_DIR

import pinlin
from pinlin import mjcf
from pinlin.bench import check_scene
from pinlin.cli import main
from pinlin.exceptions import ArgumentError, UnknownRobotError
from pinlin.mjcf_merge import combine
from pinlin.mjcf_visual import VISUAL_GROUP
from pinlin.validate import run, sanity, validate

ROW = re.compile(r"^\| \[(?P<name>[^\]]+)\]\((?P=name)\.md\) \| (?P<status>[^|]*?) \|")


def test_parallel_axis_theorem_by_hand():
    """Two 1 kg point masses at x = +-1 m and a 2 kg sphere-like part at the origin with
    I = 0.1 E: m = 4 kg, c = 0, I = diag(0.1, 2.1, 2.1) (each point mass adds m x^2 about y
    and z). Off-centre: a 1 kg point at (1, 2, 0) alone about its own centre is zero; with a
    1 kg point at the origin, c = (0.5, 1, 0) and I = sum m (|d|^2 E - d d^T)."""
    point = (1.0, np.zeros(3), np.zeros((3, 3)))
    m, c, inertia = combine([(1.0, np.array([1.0, 0, 0]), np.zeros((3, 3))),
                             (1.0, np.array([-1.0, 0, 0]), np.zeros((3, 3))),
                             (2.0, np.zeros(3), 0.1 * np.eye(3))])
    assert m == 4.0 and np.all(c == 0.0)
    np.testing.assert_allclose(inertia, np.diag([0.1, 2.1, 2.1]), rtol=0, atol=1e-15)
    m, c, inertia = combine([point, (1.0, np.array([1.0, 2.0, 0.0]), np.zeros((3, 3)))])
    d = np.array([0.5, 1.0, 0.0])
    expected = 2 * (d @ d * np.eye(3) - np.outer(d, d))
    np.testing.assert_allclose(c, d, rtol=0, atol=1e-15)
    np.testing.assert_allclose(inertia, expected, rtol=0, atol=1e-15)


def test_refused_robot_passes_with_merged_links_named(tmp_path):
    """anymal's placeholder 'base' (1e-6 kg, an inertia with zero eigenvalues) used to make
    MuJoCo refuse the robot; merged with its fixed children as Pinocchio merges them, the
    robot passes, and its report and index row name the merged links. A robot MuJoCo accepts
    as it is keeps MuJoCo's own import (nothing merged)."""
    results = run(["anymal", "ur5"], tmp_path, progress=False, announce=False)
    anymal, ur5 = results
    assert anymal.passed, anymal.reason
    assert any(m.startswith("base_inertia -> base") for m in anymal.merged)
    assert anymal.sanity["total mass"] <= 1e-9 and anymal.sanity["mass matrix"] <= 1e-9
    assert ur5.passed and ur5.merged == []
    assert mjcf.build(pinlin.Scene.from_robot("ur5").system).merged == ()
    report = (tmp_path / "anymal.md").read_text()
    assert "base_inertia -> base" in report and "parallel-axis theorem" in report
    index = (tmp_path / "README.md").read_text()
    row = next(line for line in index.splitlines() if line.startswith("| [anymal]"))
    assert "| pass |" in row and "base_inertia -> base" in row


def test_unrepresentable_body_says_what_to_change():
    """human's spherical joints are chains of revolute joints through massless links: MuJoCo
    cannot represent a moving massless body, and the refusal says which link and what to do."""
    res = validate("human")
    assert res.status == "MuJoCo refuses"
    for words in ("link 'left_upperleg_virtual' needs a physical <inertial>",
                  "joint 'left_hip_Z' locked", "mass 0 kg", "mjMINVAL"):
        assert words in res.reason


def test_a_refusal_quotes_mujocos_own_reason(tmp_path):
    """A 1 mg pendulum bob of moments (5e-15, 8e-12, 8e-12) kg*m^2 meets mjMINVAL, yet MuJoCo
    refuses it ('positive eigenvalues': its own eigen-decomposition of so small a tensor); the
    refusal quoted only pinlin's explanation, which the moments contradict. MuJoCo's words
    now come with it."""
    urdf = (URDF_DIR / "pendulum.urdf").read_text()
    inertia = '<inertia ixx="0.001" ixy="0" ixz="0" iyy="0.001" iyz="0" izz="0.001"/>'
    assert inertia in urdf and '<mass value="1.0"/>' in urdf
    tiny = tmp_path / "tiny.urdf"
    tiny.write_text(urdf.replace('<mass value="1.0"/>', '<mass value="1e-06"/>').replace(
        inertia, '<inertia ixx="5e-15" ixy="0" ixz="0" iyy="8.33e-12" iyz="0" izz="8.33e-12"/>'))
    spec = mujoco.MjSpec.from_string(tiny.read_text())
    with pytest.raises(ValueError) as own:
        spec.compile()
    res = validate(str(tiny))
    assert res.status == "MuJoCo refuses"
    words = str(own.value).splitlines()[0].removeprefix("Error: ")
    assert f"(MuJoCo: {words})" in res.reason, res.reason


@pytest.mark.parametrize("target", ["solo12", "four_bar"])
def test_visual_geoms_change_neither_mass_matrix_nor_gravity(target):
    """A floating robot (rotated base) and a mechanism: MuJoCo's M, bias forces and body
    inertials are bitwise the same with and without the visual geoms, which have no contacts
    and no mass; the sanity check against Pinocchio passes with them."""
    scene, _ = check_scene(target)
    system = scene.system
    op = pinlin.linearize(scene).operating_point
    shown, bare = mjcf.build(system), mjcf.build(system, visual=False)
    assert bare.model.ngeom == 0 and shown.model.ngeom > system.model.nbodies // 2
    m = shown.model
    assert np.all(m.geom_contype == 0) and np.all(m.geom_conaffinity == 0)
    assert np.all(m.geom_group == VISUAL_GROUP)
    out = []
    for ms in (shown, bare):
        mjcf.set_state(ms, system, op.q, np.zeros(system.nv), np.zeros(system.nv))
        M = np.zeros((ms.model.nv, ms.model.nv))
        mujoco.mj_fullM(ms.model, ms.data, M)
        out.append((M, ms.data.qfrc_bias.copy(), ms.model.body_mass.copy(),
                    ms.model.body_inertia.copy(), ms.model.body_ipos.copy()))
    for a, b in zip(*out, strict=True):
        assert np.array_equal(a, b)
    assert max(sanity(shown, system, op.q).values()) <= 1e-9


def _png_size(data: bytes) -> tuple[int, int]:
    assert data.startswith(b"\x89PNG\r\n\x1a\n") and data[12:16] == b"IHDR"
    return struct.unpack(">II", data[16:24])


def test_mechanism_report_has_a_picture_or_says_why_not(tmp_path):
    """four_bar's report shows the MuJoCo scene (320 x 240 PNG) at the operating point, or, on
    a machine without an OpenGL backend, says that none rendered and how to choose one."""
    res = run(["four_bar"], tmp_path, progress=False, announce=False)[0]
    assert res.passed, res.reason
    report = (tmp_path / "four_bar.md").read_text()
    picture = tmp_path / "four_bar_mujoco.png"
    if res.picture is None:
        assert "MUJOCO_GL" in res.picture_note and "No picture of the MuJoCo scene" in report
        assert not picture.exists()
    else:
        assert _png_size(picture.read_bytes()) == (320, 240)
        assert "![MuJoCo scene](four_bar_mujoco.png)" in report
    plain = run(["double_pendulum"], tmp_path, progress=False, announce=False)[0]
    assert plain.picture is None and not (tmp_path / "double_pendulum_mujoco.png").exists()


def test_png_encoder_round_trips():
    import matplotlib.image

    from pinlin.mjcf_picture import encode_png

    rgb = np.random.default_rng(1).integers(0, 256, (5, 7, 3), dtype=np.uint8)
    data = encode_png(rgb)
    assert _png_size(data) == (7, 5)
    import io

    back = matplotlib.image.imread(io.BytesIO(data), format="png")
    assert np.array_equal(np.round(back[..., :3] * 255).astype(np.uint8), rgb)


def test_validate_takes_names_paths_and_systems():
    """Like pinlin.linearize: a bundled scene or robot name, a scene file as str or Path, a
    Scene or its System; anything else is an ArgumentError, an unknown name the usual error."""
    by_name = validate("pendulum")
    assert by_name.passed and by_name.name == "pendulum", by_name.reason
    for target in (URDF_DIR / "pendulum.toml", str(URDF_DIR / "pendulum.toml")):
        res = validate(target)
        assert res.passed and res.name == "pendulum"
    scene = pinlin.Scene.load(URDF_DIR / "pendulum.toml")
    assert validate(scene.system, name="p2").name == "p2"
    assert validate("ur5").passed
    with pytest.raises(ArgumentError, match="scene"):
        validate(3)
    with pytest.raises(ArgumentError, match="name"):
        validate("pendulum", name=5)
    with pytest.raises(UnknownRobotError):
        validate("robocop")


def _rows(text: str) -> dict[str, str]:
    return {m["name"]: line for line in text.splitlines() if (m := ROW.match(line))}


def test_validate_one_system_into_the_committed_reports_keeps_every_other_row(tmp_path, capfd):
    """pinlin validate z1 --out-dir <copy of validation/reports>: the z1 row is replaced (here
    a stale FAIL planted in the copy), every other row is kept byte for byte, the totals count
    every row again, and the command says where it wrote."""
    out = tmp_path / "reports"
    shutil.copytree(REPO / "validation" / "reports", out)
    index = out / "README.md"
    before = _rows(index.read_text())
    assert "z1" in before and len(before) > 60
    index.write_text(index.read_text().replace(before["z1"], "| [z1](z1.md) | FAIL | - | - | - "
                                                             "| planted |"))
    capfd.readouterr()
    assert main(["validate", "z1", "--out-dir", str(out), "--no-progress"]) == 0
    stdout = capfd.readouterr().out
    assert str(out) in stdout and str(index) in stdout
    text = index.read_text()
    after = _rows(text)
    assert list(after) == list(before)
    assert after["z1"].startswith("| [z1](z1.md) | pass |")
    assert {k: v for k, v in after.items() if k != "z1"} == \
        {k: v for k, v in before.items() if k != "z1"}
    statuses = [ROW.match(line)["status"] for line in after.values()]
    totals = ", ".join(f"{s}: {statuses.count(s)}" for s in sorted(set(statuses)))
    assert f"Totals: {totals} ({len(after)} systems)" in text


def test_bench_one_system_into_an_existing_report_keeps_the_others(tmp_path):
    """pinlin bench ur5 into a copy of the committed accuracy_vs_time.md: the ur5 headline row
    and sweep are new, every other system's row and sweep section is kept as it was, the
    humanoid's targets too, and the header says which rows come from an earlier run."""
    from pinlin.bench import read_report

    out = tmp_path / "reports"
    out.mkdir()
    shutil.copy(REPO / "validation" / "reports" / "accuracy_vs_time.md", out)
    shutil.copytree(REPO / "validation" / "reports" / "accuracy_vs_time",
                    out / "accuracy_vs_time")
    rows, targets, sweeps = read_report(out / "accuracy_vs_time.md")
    assert "ur5" in rows and len(rows) >= 3 and targets
    assert main(["bench", "ur5", "--repeats", "1", "--out-dir", str(out), "--no-progress"]) == 0
    rows2, targets2, sweeps2 = read_report(out / "accuracy_vs_time.md")
    assert list(rows2) == list(rows) and targets2 == targets
    for name in rows:
        if name != "ur5":
            assert rows2[name] == rows[name] and sweeps2[name] == sweeps[name]
    text = (out / "accuracy_vs_time.md").read_text()
    assert "Produced by `pinlin bench ur5 --repeats 1`" in text
    kept = [n for n in rows if n != "ur5"]
    assert f"Rows of {', '.join(kept)} are kept from an earlier run" in text


@pytest.mark.parametrize("name", ["solo12_standing", "talos_standing", "g1_standing",
                                  "four_bar"])
def test_exported_mjcf_starts_at_the_operating_point(name, tmp_path, capsys):
    """export-mjcf writes a keyframe 'operating_point' with pinlin's q0, and the bodies, their
    inertias and the sites at full precision: reset to it, MuJoCo's loops and held feet are
    closed to rounding of the URDF's O(1) lengths (1e-12; MuJoCo's own 6-digit writing left
    ~5e-7 m, 5e-9 m with only the sites rewritten), its qpos is pinlin's and the file's
    bodies are those pinlin validates (the same compiled numbers)."""
    out = tmp_path / f"{name}.{'XML' if name == 'four_bar' else 'xml'}"   # as .png, .html
    assert main(["export-mjcf", name, "-o", str(out)]) == 0
    assert "keyframe 'operating_point'" in capsys.readouterr().out
    m = mujoco.MjModel.from_xml_path(str(out))
    d = mujoco.MjData(m)
    mujoco.mj_resetDataKeyframe(m, d, mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_KEY,
                                                           "operating_point"))
    mujoco.mj_forward(m, d)
    assert d.nefc > 0 and np.abs(d.efc_pos[:d.nefc]).max() <= 1e-12
    scene = pinlin.Scene.resolve(name)
    ms = mjcf.build(scene.system)
    mjcf.set_state(ms, scene.system, pinlin.operating_point(scene).q,
                   np.zeros(scene.system.nv), np.zeros(scene.system.nv))
    np.testing.assert_array_equal(d.qpos, ms.data.qpos)
    for key in ("body_pos", "body_quat", "body_ipos", "body_iquat", "body_mass",
                "body_inertia"):
        np.testing.assert_array_equal(getattr(m, key), getattr(ms.model, key))
    q0 = pinlin.operating_point(scene).q
    for _ in range(2):       # the key goes into the text only: twice works, the spec keeps none
        assert '<key name="operating_point"' in mjcf.to_xml(ms, scene.system, q0)
    assert "<key" not in ms.spec.to_xml()


def test_exported_effects_and_options_keep_every_digit(tmp_path, capsys):
    """MuJoCo writes numbers with %g (6 digits): the time step, gravity and the joints'
    stiffness, spring reference, damping and armature were rounded in the file (2.123456789
    -> 2.12346) while validate compared the exact in-memory model. The file's compiled model
    now equals the one pinlin builds, bit for bit."""
    scene_file = tmp_path / "digits.toml"
    scene_file.write_text(
        f'name = "digits"\nurdf = "{URDF_DIR / "double_pendulum.urdf"}"\n'
        '[effects]\ngravity = [0.0, 0.0, -9.80665123]\n'
        'armature = { elbow = 0.0123456789 }\ndamping = { elbow = 0.123456789 }\n'
        'springs = { shoulder = { stiffness = 2.123456789, rest = 0.123456789 } }\n'
        '[inputs]\nactuated = "all"\n')
    out = tmp_path / "digits.xml"
    assert main(["export-mjcf", str(scene_file), "-o", str(out), "--dt",
                 "0.0012345678901"]) == 0
    capsys.readouterr()
    m = mujoco.MjModel.from_xml_path(str(out))
    ms = mjcf.build(pinlin.Scene.load(scene_file).system, dt=0.0012345678901)
    assert m.opt.timestep == 0.0012345678901
    np.testing.assert_array_equal(m.opt.gravity, [0.0, 0.0, -9.80665123])
    for key in ("jnt_stiffness", "qpos_spring", "dof_damping", "dof_armature"):
        np.testing.assert_array_equal(getattr(m, key), getattr(ms.model, key))
    assert m.jnt_stiffness[0] == 2.123456789 and m.dof_damping[1] == 0.123456789


def test_time_step_must_resolve_the_fastest_mode(tmp_path, capsys):
    """MuJoCo's (semi-implicit) Euler step integrates an oscillation of frequency w stably only
    for dt w < 2: checked here on MuJoCo itself (the double pendulum's fastest mode, |lambda|
    = 7.04 1/s: bounded at 0.9 x 2/|lambda|, blown up at 1.1 x), and export-mjcf refuses a dt
    beyond it (--dt 1e300 wrote a file whose first step gave qpos = -inf)."""
    scene = pinlin.Scene.resolve("double_pendulum")
    fastest = float(np.abs(np.linalg.eigvals(pinlin.linearize(scene).A)).max())
    limit = 2.0 / fastest
    peaks = []
    for factor in (0.9, 1.1):
        ms = mjcf.build(scene.system, dt=factor * limit)
        mujoco.mj_resetData(ms.model, ms.data)
        ms.data.qpos[:] = [1e-3, -1e-3]
        peak = 0.0
        for _ in range(500):
            mujoco.mj_step(ms.model, ms.data)
            peak = max(peak, float(np.abs(ms.data.qpos).max()))
        peaks.append(peak)
    assert peaks[0] < 1e-2 and peaks[1] > 1.0
    out = tmp_path / "dp.xml"
    for dt in (1.1 * limit, 1e300):
        assert main(["export-mjcf", "double_pendulum", "-o", str(out), "--dt", repr(dt)]) == 2
        err = capsys.readouterr().err
        assert f"use dt < {limit:.3g} s" in err and not out.exists()
    assert main(["export-mjcf", "double_pendulum", "-o", str(out), "--dt",
                 repr(0.9 * limit)]) == 0
    out.unlink()
    for dt in ("1e-300", "9e-10"):   # stable, but 1e9 steps and more per simulated second
        assert main(["export-mjcf", "double_pendulum", "-o", str(out), "--dt", dt]) == 2
        err = capsys.readouterr().err
        assert "argument '--dt'" in err and "of at least 1e-09 s" in err
        assert not out.exists()


@pytest.mark.parametrize("name", ["ur5_arm", "four_bar", "solo12_standing"])
def test_exported_inputs_hold_the_operating_point_in_mujoco(name, tmp_path, capsys):
    """Each input becomes a motor whose keyframe ctrl is u0: reset to the key, MuJoCo's own
    dynamics hold the posture. For the open chain MuJoCo's acceleration there is rounding
    (pinlin's u0 against MuJoCo's gravity and springs: ~eps |tau| |M^-1| ~ 1e-12); with loops
    or held feet, MuJoCo's soft equalities let it settle by ~1e-6 rad in 0.1 s, against
    1e-2 rad or more with the motors off (the file held no inputs before)."""
    out = tmp_path / f"{name}.xml"
    assert main(["export-mjcf", name, "-o", str(out)]) == 0
    assert "the inputs u0 (ctrl of its motors)" in capsys.readouterr().out
    m = mujoco.MjModel.from_xml_path(str(out))
    system = pinlin.Scene.resolve(name).system
    assert m.nu == len(system.input_names)
    assert [mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_ACTUATOR, i)
            for i in range(m.nu)] == list(system.input_names)
    drifts = []
    for motors in (True, False):
        d = mujoco.MjData(m)
        mujoco.mj_resetDataKeyframe(m, d, 0)
        if not motors:
            d.ctrl[:] = 0.0
        mujoco.mj_forward(m, d)
        if motors and name == "ur5_arm":
            assert np.abs(d.qacc).max() < 1e-10
        q0 = d.qpos.copy()
        for _ in range(round(0.1 / m.opt.timestep)):
            mujoco.mj_step(m, d)
        drifts.append(float(np.abs(d.qpos - q0).max()))
    assert drifts[0] < 1e-4 and drifts[1] > 1e-2, drifts


_TWO_LINKS = """<robot name="{name}">
  <link name="base"/>
  <link name="{l1}"><inertial><origin xyz="0 0 -0.5"/><mass value="1"/>
    <inertia ixx="0.02" ixy="0.001" ixz="0" iyy="0.025" iyz="0" izz="0.03"/></inertial></link>
  <link name="l2"><inertial><origin xyz="0 0 -0.5"/><mass value="1"/>
    <inertia ixx="0.01" ixy="0" ixz="0" iyy="0.01" iyz="0" izz="0.01"/></inertial></link>
  <joint name="{j1}" type="revolute"><parent link="base"/><child link="{l1}"/>
    <axis xyz="0 1 0"/><limit lower="-0.1" upper="0.1" effort="1" velocity="10"/></joint>
  <joint name="j2" type="continuous"><parent link="{l1}"/><child link="l2"/>
    <origin xyz="0 0 -1"/><axis xyz="0 1 0"/></joint>
</robot>
"""


def test_spring_on_a_continuous_joint_holds_at_the_keyframe(tmp_path):
    """A spring of rest 3.0 rad on a continuous joint held at 3.5 rad: the keyframe wrote the
    angle as atan2 (-2.78) beside springref 3.0, so MuJoCo's unwrapped hinge spring pushed
    with +28.9 N*m instead of -2.5 and the robot fell from its key. Now the key's angle lies
    on the spring's branch: the spring force is pinlin's and the key is an equilibrium."""
    (tmp_path / "dyn.urdf").write_text(_TWO_LINKS.format(name="dyn", l1="l1", j1="j1"))
    (tmp_path / "s.toml").write_text(
        'name = "spring_wrap"\nurdf = "dyn.urdf"\n[effects]\n'
        'springs = { j2 = { stiffness = 5.0, rest = 3.0 } }\n[operating_point]\n'
        'q = { j1 = 0.0, j2 = 3.5 }\n[inputs]\nactuated = ["j2"]\n')
    out = tmp_path / "s.xml"
    assert main(["export-mjcf", str(tmp_path / "s.toml"), "-o", str(out)]) == 0
    m = mujoco.MjModel.from_xml_path(str(out))
    d = mujoco.MjData(m)
    mujoco.mj_resetDataKeyframe(m, d, 0)
    mujoco.mj_forward(m, d)
    assert d.qfrc_spring[1] == pytest.approx(-5.0 * 0.5, rel=1e-12)
    assert np.abs(d.qacc).max() < 1e-9


def test_names_xml_escapes_keep_full_precision(tmp_path):
    """A joint 'j&1' is written 'j&amp;1': the full-precision pass looked for 'j&1' and left
    MuJoCo's 6 digits (stiffness 10.1235 for 10.123456789)."""
    (tmp_path / "amp.urdf").write_text(_TWO_LINKS.format(name="amp", l1="l&amp;1",
                                                          j1="j&amp;1"))
    (tmp_path / "a.toml").write_text(
        'name = "amp"\nurdf = "amp.urdf"\n[effects]\n'
        'springs = { "j&1" = { stiffness = 10.123456789, rest = 0.0123456789 } }\n')
    out = tmp_path / "a.xml"
    assert main(["export-mjcf", str(tmp_path / "a.toml"), "-o", str(out)]) == 0
    text = out.read_text()
    assert 'name="j&amp;1"' in text and 'stiffness="10.123456789"' in text
    m = mujoco.MjModel.from_xml_path(str(out))
    assert m.jnt_stiffness[0] == 10.123456789


PLANAR = """<?xml version="1.0"?>
<robot name="planar_bot">
  <link name="world_link"/>
  <link name="body"><inertial><origin xyz="0.1 0.05 0"/><mass value="2.0"/>
    <inertia ixx="0.02" ixy="0" ixz="0" iyy="0.03" iyz="0" izz="0.04"/></inertial></link>
  <joint name="slide" type="planar"><parent link="world_link"/><child link="body"/>
    <axis xyz="0 0 1"/></joint>
</robot>"""


def test_a_planar_joint_is_refused_as_planar(tmp_path, capfd):
    """MuJoCo imports a URDF planar joint as slides and a hinge of its own names: the
    refusal said the joint 'slide_TX' was locked in a reduced model, which the scene is not."""
    urdf = tmp_path / "planar.urdf"
    urdf.write_text(PLANAR)
    scene = pinlin.Scene.from_urdf(urdf, name="planar_bot", base="fixed",
                                   operating_point={"solve": "inputs"})
    assert pinlin.linearize(scene).A.shape == (6, 6)
    with pytest.raises(mjcf.MujocoError, match="joint 'slide' is planar.*no MuJoCo counterpart"):
        mjcf.build(scene.system)
    assert main(["export-mjcf", str(urdf), "-o", str(tmp_path / "p.xml")]) == 2
    err = capfd.readouterr().err
    assert "joint 'slide' is planar" in err and "locked" not in err

"""Bad model files, bad output paths and failed writes.

Every case asserts the exception class and the key words of its message; from the CLI, exit
status 2, exactly one stderr line starting "pinlin: error: " and no file written or changed.
Writes that fail for real (a file-size limit, a folder that is a file) leave an existing file
byte-identical and no temporary file behind. Everything runs on real files in tmp_path.
"""

from __future__ import annotations

import dataclasses
import io
import json
import os
import resource
import signal
import stat
import struct
import subprocess
import sys
import warnings
import zipfile
import zlib
from pathlib import Path

import numpy as np
import pytest
import scipy.io
from conftest import REPO, URDF_DIR

import pinlin
from pinlin import ArgumentError, LinearModel, ModelError, ModelFileError
from pinlin.cli import main
from pinlin.files import atomic_path, write_atomic, write_text_atomic
from pinlin.mat_check import MatStructureError, check_mat_elements

FORMATS = (".npz", ".mat", ".json")
GRAPHS = REPO / "validation" / "graphs"


# ---------------------------------------------------------------------------------- helpers
def cli(capfd, *argv: str) -> tuple[int, str, str]:
    code = main([str(a) for a in argv])
    out, err = capfd.readouterr()
    return code, out, err


def assert_refused(code: int, err: str, *words: str) -> None:
    """Exit 2, exactly one stderr line starting 'pinlin: error: ', the key words in it."""
    assert code == 2, err
    assert err.count("\n") == 1 and err.startswith("pinlin: error: "), err
    assert "Traceback" not in err
    for w in words:
        assert w in err, (w, err)


def snapshot(folder: Path) -> dict[str, bytes | None]:
    """Every path under folder with its bytes (None for folders)."""
    return {str(p.relative_to(folder)): (p.read_bytes() if p.is_file() else None)
            for p in sorted(folder.rglob("*"))}


def no_temporaries(folder: Path) -> None:
    stray = [p.name for p in folder.rglob("*") if ".tmp" in p.name]
    assert not stray, stray


def tiny() -> LinearModel:
    """x' = -x + u, y = x."""
    return LinearModel(A=[[-1.0]], B=[[1.0]], C=[[1.0]], D=[[0.0]], state_names=["x"],
                       input_names=["u"], output_names=["y"], name="tiny")


def fields_of(model: LinearModel) -> dict:
    return {f.name: getattr(model, f.name) for f in dataclasses.fields(model)}


_CHILD_ENV: dict[str, str] = {}


@pytest.fixture(scope="module", autouse=True)
def _matplotlib_cache_of_its_own(tmp_path_factory):
    """A matplotlib config folder for the limited children, its font cache built first without
    a limit: a child that had to build it (a fresh machine, or a cache another run left
    corrupt) would fail to write it beyond the limit, print matplotlib's complaints beside
    pinlin's one line, and leave the user's own cache truncated at the limit (matplotlib
    writes it in place)."""
    folder = tmp_path_factory.mktemp("mplconfig")
    env = {**os.environ, "MPLCONFIGDIR": str(folder)}
    subprocess.run([sys.executable, "-c", "import matplotlib.font_manager"], env=env,
                   check=True, timeout=600, capture_output=True)
    _CHILD_ENV.update(env)
    yield
    _CHILD_ENV.clear()


def _limit_files(limit: int):
    def limit_files() -> None:
        signal.signal(signal.SIGXFSZ, signal.SIG_IGN)
        resource.setrlimit(resource.RLIMIT_FSIZE, (limit, limit))

    return limit_files


def run_limited(argv: list[str], limit: int, cwd: Path) -> subprocess.CompletedProcess:
    """``pinlin argv`` in a child process whose files may not grow beyond ``limit`` bytes;
    SIGXFSZ is ignored so that write() fails with EFBIG instead of killing the child."""
    code = "import sys; from pinlin.cli import main; sys.exit(main(sys.argv[1:]))"
    return run_python_limited(code, limit, cwd, argv)


def run_python_limited(source: str, limit: int, cwd: Path, argv: list[str] = ()
                       ) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-c", source, *argv], capture_output=True,
                          text=True, preexec_fn=_limit_files(limit), cwd=cwd, timeout=600,
                          check=False, env=_CHILD_ENV or None)


@pytest.fixture(scope="module")
def pendulum() -> LinearModel:
    return pinlin.linearize(URDF_DIR / "pendulum.toml")


@pytest.fixture(scope="module")
def models() -> dict[str, LinearModel]:
    from pinlin.graph import Graph

    return {
        "open_chain": pinlin.linearize(URDF_DIR / "ur5_arm.toml"),
        "reduced": pinlin.linearize(URDF_DIR / "four_bar.toml"),
        "penalty": pinlin.linearize(URDF_DIR / "four_bar.toml", formulation="penalty"),
        "canonical": pinlin.linearize(URDF_DIR / "four_bar.toml", formulation="canonical"),
        "graph_with_E_F": Graph.load(GRAPHS / "lead_lag.toml").linearize(),
        "no_inputs_or_outputs": LinearModel(
            A=-np.eye(2), B=np.zeros((2, 0)), C=np.zeros((0, 2)), D=np.zeros((0, 0)),
            state_names=["q:ω", "v: ω (a space)"], input_names=[], output_names=[], name="bare",
            info={"nested": {"t": (1, 2)}, "estimate": 1e-300}),
    }


# ------------------------------------------------------------------ 1. the model itself
@pytest.mark.parametrize("key", ["A", "B", "C", "D"])
@pytest.mark.parametrize("bad", [np.nan, np.inf, -np.inf])
def test_non_finite_first_order_matrix_is_refused(key, bad):
    kw = {"A": [[-1.0]], "B": [[1.0]], "C": [[1.0]], "D": [[0.0]]}
    kw[key] = [[bad]]
    with pytest.raises(ModelError, match=rf"model 'tiny': matrix {key} has 1 non-finite"):
        LinearModel(**kw, state_names=["x"], input_names=["u"], output_names=["y"],
                    name="tiny")


@pytest.mark.parametrize("key", ["E", "F", "M", "C_damp", "K", "Bu", "G"])
def test_non_finite_optional_matrix_is_refused(models, key):
    source = models["graph_with_E_F"] if key in "EF" else models["penalty"]
    fields = fields_of(source)
    bad = np.array(fields[key], dtype=float)
    bad.flat[-1] = np.nan
    fields[key] = bad
    with pytest.raises(ModelError, match=rf"model '{source.name}': matrix {key} has 1 non"):
        LinearModel(**fields)


def test_trusted_constructor_refuses_nan_and_repeated_names(models):
    """LinearModel.assembled skips the shape checks, not these two."""
    fields = fields_of(models["open_chain"])
    K = np.array(fields["K"])
    K[2, 3] = np.inf
    K.flags.writeable = False
    with pytest.raises(ModelError, match=r"matrix K has 1 non-finite.*K\[2, 3\] = inf"):
        LinearModel.assembled(**{**fields, "K": K})
    outputs = fields["output_names"]
    with pytest.raises(ModelError, match=rf"output_names are not distinct: '{outputs[0]}'"):
        LinearModel.assembled(**{**fields, "output_names": (outputs[0], *outputs[1:-1],
                                                            outputs[0])})
    assert LinearModel.assembled(**fields).A is fields["A"]  # the good model still passes


def test_finite_entries_whose_sum_overflows_are_accepted_without_warning():
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        m = LinearModel(A=np.full((2, 2), 1e308), B=np.zeros((2, 0)), C=np.zeros((0, 2)),
                        D=np.zeros((0, 0)), state_names=["a", "b"], input_names=[],
                        output_names=[])
    assert m.A[0, 0] == 1e308


def test_repeated_names_are_refused_by_the_constructor():
    with pytest.raises(ModelError, match=r"output_names are not distinct: 'y' \(2 times\)"):
        LinearModel(A=[[0.0]], B=[[1.0]], C=[[1.0], [2.0]], D=[[0.0], [0.0]],
                    state_names=["x"], input_names=["u"], output_names=["y", "y"])


def test_repeated_scene_outputs_never_reach_a_file(write_scene, capfd, tmp_path):
    """Outputs 'hinge' and 'q:hinge' both ask for q:hinge: refused (by the scene or the
    model), and --out is never written."""
    path = write_scene('urdf = "robot.urdf"\n[effects]\ngravity = [0.0, 0.0, -9.81]\n'
                       '[outputs]\njoints = ["hinge", "q:hinge"]\n',
                       robot__urdf=(URDF_DIR / "pendulum.urdf").read_text())
    with pytest.raises((pinlin.SceneError, ModelError), match="q:hinge"):
        pinlin.linearize(path)
    out = tmp_path / "m.npz"
    code, _, err = cli(capfd, "linearize", path, "--out", out)
    assert_refused(code, err, "q:hinge")
    assert not out.exists()


@pytest.mark.parametrize("kwargs, cls, words", [
    ({"state_names": "x"}, ArgumentError, "argument 'state_names': expected a sequence"),
    ({"input_names": None}, ArgumentError, "argument 'input_names': expected a sequence"),
    ({"output_names": [7]}, ArgumentError, "expected names as strings, got int"),
    ({"output_names": (["y"],)}, ArgumentError, "expected names as strings, got list"),
    ({"state_names": [" "]}, ArgumentError, "the name at position 0 is empty or blank"),
    ({"input_names": [""]}, ArgumentError, "the name at position 0 is empty or blank"),
    ({"A": [[1j]]}, ArgumentError, "argument 'A': expected a matrix of real numbers, got complex"),
    ({"B": [["one"]]}, ArgumentError, "argument 'B': expected a matrix of real numbers"),
    ({"C": None}, ArgumentError, "argument 'C': expected a matrix, got None"),
    ({"info": [1, 2]}, ArgumentError, "argument 'info': expected a mapping"),
    ({"name": 7}, ArgumentError, "argument 'name': expected a str"),
])
def test_wrong_types_in_the_constructor(kwargs, cls, words):
    base = {"A": [[-1.0]], "B": [[1.0]], "C": [[1.0]], "D": [[0.0]], "state_names": ["x"],
            "input_names": ["u"], "output_names": ["y"]}
    with pytest.raises(cls) as info:
        LinearModel(**{**base, **kwargs})
    assert words in str(info.value)


# -------------------------------------------------------------------- round trips
@pytest.mark.parametrize("suffix", FORMATS)
@pytest.mark.parametrize("kind", ["open_chain", "reduced", "penalty", "canonical",
                                  "graph_with_E_F", "no_inputs_or_outputs"])
def test_what_saves_loads_back(models, kind, suffix, tmp_path):
    model = models[kind]
    back = LinearModel.load(model.save(tmp_path / f"m{suffix}"))
    for key in ("A", "B", "C", "D", "E", "F", "M", "C_damp", "K", "Bu", "G"):
        ours, theirs = getattr(model, key), getattr(back, key)
        assert (ours is None) == (theirs is None), key
        if ours is not None:
            assert theirs.shape == ours.shape and np.array_equal(theirs, ours), key
    for key in ("state_names", "input_names", "output_names", "name"):
        assert getattr(back, key) == getattr(model, key), key
    assert json.dumps(back.info, sort_keys=True) == json.dumps(
        json.loads(json.dumps(pinlin.linear_model._jsonable(model.info))), sort_keys=True)
    if model.operating_point is not None:
        np.testing.assert_array_equal(back.operating_point.q, model.operating_point.q)
    if kind in ("penalty", "canonical"):
        assert back.G.shape[0] > 0 and back.info["formulation"] == kind
    no_temporaries(tmp_path)


# ------------------------------------------------------------ 2. LinearModel.load
def _npz(path: Path, **members) -> Path:
    with path.open("wb") as fh:
        np.savez(fh, **members)
    return path


def _npy_header(shape: tuple[int, ...]) -> bytes:
    buf = io.BytesIO()
    np.lib.format.write_array_header_1_0(buf, {"descr": "<f8", "fortran_order": False,
                                               "shape": shape})
    return buf.getvalue()


def _npz_member(path: Path, name: str, data: bytes) -> None:
    with zipfile.ZipFile(path, "w") as z:
        z.writestr(name, data)


def _npz_twice(path: Path, members: dict) -> None:
    """The members pinlin writes, then a second A.npy (zip allows repeated names)."""
    _npz(path, **members)
    buf = io.BytesIO()
    np.save(buf, np.full((2, 2), 7.0))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", UserWarning)     # zipfile: "Duplicate name"
        with zipfile.ZipFile(path, "a") as z:
            z.writestr("A.npy", buf.getvalue())


def _valid_members(model: LinearModel) -> dict:
    buf = io.BytesIO(model._serialized(Path("x.npz"), ".npz"))
    with np.load(buf) as z:
        return {k: z[k] for k in z.files}


BAD_FILES = {
    "json_list": ("m.json", lambda p, m: p.write_text("[1, 2, 3]"),
                  "expected a JSON object with A, B, C, D and the names, got a list"),
    "json_scalar": ("m.json", lambda p, m: p.write_text("3.5"), "got a number"),
    "json_null": ("m.json", lambda p, m: p.write_text("null"), "got null"),
    "json_syntax": ("m.json", lambda p, m: p.write_text('{"A": [[1.0]'), "not valid JSON"),
    "json_deep": ("m.json", lambda p, m: p.write_text("[" * 200_000 + "]" * 200_000),
                  "nested too deeply"),
    "json_not_utf8": ("m.json", lambda p, m: p.write_bytes(b"\xff\xfe{}"), "not UTF-8 text"),
    "json_huge_integer": ("m.json", lambda p, m: p.write_text(
        _edit_json(m, lambda d: d["A"][0].__setitem__(0, 10 ** 400))),
        "matrix A has 1 non-finite entry"),
    "json_nan": ("m.json", lambda p, m: p.write_text(
        _edit_json(m, lambda d: d["B"][1].__setitem__(0, float("nan")))),
        "matrix B has 1 non-finite entry"),
    "json_names_as_string": ("m.json", lambda p, m: p.write_text(
        _edit_json(m, lambda d: d.__setitem__("state_names", "qv"))),
        "'state_names' must be a list of strings"),
    "json_repeated_names": ("m.json", lambda p, m: p.write_text(
        _edit_json(m, lambda d: d.__setitem__("state_names", ["q", "q"]))),
        "state_names are not distinct"),
    "json_matrix_not_a_list": ("m.json", lambda p, m: p.write_text(
        _edit_json(m, lambda d: d.__setitem__("A", "eye"))), "'A' must be a matrix"),
    "json_ragged": ("m.json", lambda p, m: p.write_text(
        _edit_json(m, lambda d: d.__setitem__("A", [[1.0, 2.0], [3.0]]))),
        "'A' is not a matrix of numbers"),
    "json_bad_operating_point": ("m.json", lambda p, m: p.write_text(
        _edit_json(m, lambda d: d["operating_point"].__setitem__("q", "zero"))),
        "field 'operating_point' is malformed"),
    "json_missing_names": ("m.json", lambda p, m: p.write_text(
        _edit_json(m, lambda d: d.pop("input_names"))), "missing 'input_names'"),
    # hand edits that json / np.array would have read silently
    "json_key_twice": ("m.json", lambda p, m: p.write_text(
        _edit_json(m, lambda d: None).rstrip()[:-1] + ', "A": [[7.0, 0.0], [0.0, 7.0]]}'),
        "key 'A' appears twice"),
    "json_text_entry": ("m.json", lambda p, m: p.write_text(
        _edit_json(m, lambda d: d["A"][0].__setitem__(0, "1"))), "'A' must hold numbers, got text"),
    "json_boolean_entry": ("m.json", lambda p, m: p.write_text(
        _edit_json(m, lambda d: d["A"][0].__setitem__(0, True))), "got booleans"),
    "json_unknown_key": ("m.json", lambda p, m: p.write_text(
        _edit_json(m, lambda d: d.__setitem__("a", [[1.0]]))), "unknown key 'a'"),
    "json_equilibrium_text": ("m.json", lambda p, m: p.write_text(
        _edit_json(m, lambda d: d["operating_point"].__setitem__("equilibrium", "no"))),
        "'equilibrium' must be true or false"),
    "json_op_nan": ("m.json", lambda p, m: p.write_text(
        _edit_json(m, lambda d: d["operating_point"].__setitem__("q", [float("nan")]))),
        "'q' has NaN or inf entries"),
    "json_op_negative_tolerance": ("m.json", lambda p, m: p.write_text(
        _edit_json(m, lambda d: d["operating_point"].__setitem__("tolerance", -1.0))),
        "'tolerance' must be a number >= 0"),
    "json_op_without_q": ("m.json", lambda p, m: p.write_text(
        _edit_json(m, lambda d: d["operating_point"].pop("q"))), "missing 'q'"),
    # (a saved model whose lam lost its names loaded, and saving it again failed inside zip)
    "json_op_lam_without_names": ("m.json", lambda p, m: p.write_text(
        _edit_json(m, lambda d: d["operating_point"].update(lam=[1.0, 2.0], lam_names=[]))),
        "'lam_names' must name each of the 2 entries of 'lam', got 0 names"),
    "json_op_short_a": ("m.json", lambda p, m: p.write_text(
        _edit_json(m, lambda d: d["operating_point"].update(a=[0.0, 0.0, 0.0]))),
        "'a' must have as many entries as 'v'"),
    "npz_member_twice": ("m.npz", lambda p, m: _npz_twice(p, _valid_members(m)),
                         "member 'A' appears twice"),
    "npz_unknown_member": ("m.npz", lambda p, m: _npz(p, **{**_valid_members(m),
                                                           "extra": np.eye(2)}),
                           "unknown key 'extra'"),
    "npz_truncated": ("m.npz", lambda p, m: p.write_bytes(
        m._serialized(p, ".npz")[:300]), "not an .npz archive"),
    "npz_random_bytes": ("m.npz", lambda p, m: p.write_bytes(
        np.random.default_rng(0).bytes(4096)), "not an .npz archive"),
    "npz_empty": ("m.npz", lambda p, m: p.write_bytes(b""), "not an .npz archive"),
    "npz_plain_npy": ("m.npz", lambda p, m: np.save(p.open("wb"), np.eye(2)),
                      "not an .npz archive"),
    "npz_foreign_zip": ("m.npz", lambda p, m: zipfile.ZipFile(p, "w").close(),
                        "missing 'meta'"),
    "npz_wrong_shape": ("m.npz", lambda p, m: _npz(p, **{**_valid_members(m),
                                                        "A": np.eye(3)}),
                        "A must be 2x2 to match the names given, got 3x3"),
    "npz_text_matrix": ("m.npz", lambda p, m: _npz(p, **{**_valid_members(m),
                                                        "A": np.array([["a", "b"]] * 2)}),
                        "'A' must be a real matrix"),
    "npz_names_2d": ("m.npz", lambda p, m: _npz(p, **{**_valid_members(m),
                                                     "input_names": np.array([["u"]])}),
                     "'input_names' must be a list of strings"),
    "npz_header_claims_terabytes": ("m.npz", lambda p, m: _npz_member(
        p, "A.npy", _npy_header((400_000, 400_000)) + bytes(16)),
        "member 'A': its header declares shape (400000, 400000)"),
    "npz_meta_not_json": ("m.npz", lambda p, m: _npz(p, **{**_valid_members(m),
                                                          "meta": np.array("{oops")}),
                          "'meta' is not valid JSON"),
    "mat_missing_fields": ("m.mat", lambda p, m: __import__("scipy.io").io.savemat(
        p, {"A": np.eye(2)}), "missing 'meta'"),
    "mat_random_bytes": ("m.mat", lambda p, m: p.write_bytes(b"MATLAB" + bytes(500)),
                         "not a MATLAB .mat file pinlin can read"),
    "mat_names_not_cells": ("m.mat", lambda p, m: __import__("scipy.io").io.savemat(
        p, {**m._arrays(), "state_names": np.eye(2), "input_names": np.eye(1),
            "output_names": np.eye(1), "meta": "{}"}), "must be a cell array of strings"),
}


def _edit_json(model: LinearModel, edit) -> str:
    doc = json.loads(model._serialized(Path("x.json"), ".json"))
    edit(doc)
    return json.dumps(doc)


@pytest.mark.parametrize("case", sorted(BAD_FILES))
def test_bad_model_file_is_a_model_file_error(case, pendulum, tmp_path, capfd):
    name, make, words = BAD_FILES[case]
    path = tmp_path / name
    make(path, pendulum)
    with pytest.raises(ModelFileError) as info:
        LinearModel.load(path)
    message = str(info.value)
    assert message.startswith(f"{path}: ") and words in message, message
    assert "\n" not in message


def test_object_arrays_are_never_unpickled(tmp_path):
    """An .npz holding a pickled object whose unpickling would run code: refused, not run."""
    marker = tmp_path / "pwned"

    class Evil:
        def __reduce__(self):
            return (Path.touch, (marker,))

    path = tmp_path / "evil.npz"
    arr = np.empty(1, dtype=object)
    arr[0] = Evil()
    with path.open("wb") as fh:
        np.savez(fh, A=arr, B=np.eye(1), C=np.eye(1), D=np.eye(1), state_names=np.array(["x"]),
                 input_names=np.array(["u"]), output_names=np.array(["y"]),
                 meta=np.array("{}"))
    with pytest.raises(ModelFileError, match="member 'A': holds Python objects"):
        LinearModel.load(path)
    assert not marker.exists()


@pytest.mark.parametrize("make, words", [
    (lambda p: p.mkdir(), "is a folder, expected a model file"),
    (lambda p: None, "file not found"),
    (lambda p: os.mkfifo(p), "not a regular file"),   # would block a reader forever
])
def test_model_path_that_is_not_a_file(make, words, tmp_path):
    path = tmp_path / "m.json"
    make(path)
    with pytest.raises(ModelFileError, match=words):
        LinearModel.load(path)


@pytest.mark.parametrize("name, words", [
    ("m.txt", "unknown model format ('.txt'); expected .npz, .mat or .json"),
    ("model", "unknown model format (no suffix)"),
])
def test_unknown_suffix(name, words, tmp_path, pendulum):
    for call in (lambda: LinearModel.load(tmp_path / name),
                 lambda: pendulum.save(tmp_path / name)):
        with pytest.raises(ModelFileError) as info:
            call()
        assert words in str(info.value)
    assert not (tmp_path / name).exists()


@pytest.mark.parametrize("call", ["load", "save"])
@pytest.mark.parametrize("path, words", [
    (123, "expected a file path (str or os.PathLike), got int"),
    (None, "got NoneType"),
    (b"m.npz", "got bytes"),
    ("", "expected a file name, got an empty string"),
    ("m\0.npz", "contains a NUL character"),
])
def test_wrong_typed_paths(call, path, words, pendulum):
    with pytest.raises(ArgumentError) as info:
        LinearModel.load(path) if call == "load" else pendulum.save(path)
    assert "argument 'path'" in str(info.value) and words in str(info.value)


@pytest.mark.parametrize("argv", [
    ["linearize", "pendulum", "--out", "{long}.npz"],
    ["simulate", "pendulum", "--t-end", "0.01", "--out", "{long}.csv"],
    ["report", "pendulum", "-o", "{long}.html"],
    ["export-mjcf", "pendulum", "-o", "{long}.xml"],
    ["trajectory", "pendulum", "{long}.npz", "--out", "m.npz"],
])
def test_file_names_too_long_for_the_file_system(argv, capfd, tmp_path, monkeypatch, pendulum):
    """A name of 300 bytes: the OS refuses it (ENAMETOOLONG) inside the first check that
    touches it; pinlin names it in one line, exit 2, before any work, and the API raises a
    ModelFileError."""
    monkeypatch.chdir(tmp_path)
    long = "x" * 300
    code, _, err = cli(capfd, *[a.format(long=long) for a in argv])
    assert code == 2 and err.count("\n") == 1, err
    assert "file name too long" in err and "has 30" in err
    assert list(tmp_path.iterdir()) == []
    for call in (lambda: pendulum.save(f"{long}.npz"), lambda: LinearModel.load(f"{long}.npz")):
        with pytest.raises(ModelFileError, match="file name too long"):
            call()


# ------------------------------------------------------------------ 3. atomic writes
@pytest.mark.parametrize("suffix", FORMATS)
def test_file_size_limit_leaves_the_old_model_intact(suffix, tmp_path, pendulum):
    """`ulimit -f`: the write fails half-way; the old file is byte-identical, nothing else
    appears, and the CLI says so in one line with exit 2."""
    out = tmp_path / f"model{suffix}"
    pendulum.save(out)
    before = snapshot(tmp_path)
    res = run_limited(["linearize", str(URDF_DIR / "double_pendulum.toml"), "--out", str(out)],
                      limit=200, cwd=tmp_path)
    assert res.returncode == 2, res.stderr
    assert res.stderr.count("\n") == 1 and res.stderr.startswith("pinlin: error: ")
    assert f"{out}: cannot write: File too large" in res.stderr
    assert snapshot(tmp_path) == before
    assert LinearModel.load(out).name == "pendulum"


def test_file_size_limit_leaves_the_old_mjcf_intact(tmp_path):
    out = tmp_path / "scene.xml"
    out.write_text("<!-- Written by pinlin export-mjcf from scene 'x' -->\n<mujoco/>\n")
    before = snapshot(tmp_path)
    res = run_limited(["export-mjcf", "double_pendulum", "-o", str(out)], limit=100,
                      cwd=tmp_path)
    assert res.returncode == 2 and res.stderr.count("\n") == 1, res.stderr
    assert "cannot write: File too large" in res.stderr
    assert snapshot(tmp_path) == before


def test_file_size_limit_leaves_old_validation_reports_intact(tmp_path):
    reports = tmp_path / "reports"
    reports.mkdir()
    (reports / "README.md").write_text("# Validation reports\n\nold index\n")
    (reports / "double_pendulum.md").write_text("# Validation of 'double_pendulum'\nold\n")
    before = snapshot(tmp_path)
    res = run_limited(["validate", "double_pendulum", "--out-dir", str(reports),
                       "--no-progress"], limit=100, cwd=tmp_path)
    assert res.returncode == 2, res.stderr
    assert res.stderr.count("\n") == 1 and "cannot write: File too large" in res.stderr
    assert snapshot(tmp_path) == before


def test_file_size_limit_leaves_the_old_bench_report_intact(tmp_path):
    """The bench's report and plots (the measurement itself is not needed to write them)."""
    out = tmp_path / "reports"
    (out / "accuracy_vs_time").mkdir(parents=True)
    (out / "accuracy_vs_time.md").write_text("# What accuracy costs in time\nold\n")
    (out / "accuracy_vs_time" / "sys.png").write_bytes(b"\x89PNG old, tEXtSoftware\x00pinlin")
    before = snapshot(tmp_path)
    source = (
        "from pathlib import Path\n"
        "from pinlin.bench import STEPS, Curve, SystemResult, plot, report\n"
        "r = SystemResult('sys', 1, 'scene', 1e-4, 1e-12)\n"
        "n = len(STEPS)\n"
        "r.curves['fd3'] = Curve('fd3', list(STEPS), [1e-8] * n, [1e-4] * n)\n"
        "import sys\n"
        f"out = Path({str(out)!r})\n"
        "for step in (lambda: plot([r], out), lambda: report([r], out, 'x')):\n"
        "    try:\n"
        "        step()\n"
        "    except Exception as exc:\n"
        "        print(type(exc).__name__, exc)\n")
    res = run_python_limited(source, limit=100, cwd=tmp_path)
    assert res.stdout.count("ModelFileError") == 2 and res.stdout.count("File too large") == 2, \
        res.stdout + res.stderr
    assert snapshot(tmp_path) == before


def test_exception_while_serializing_leaves_no_trace(tmp_path):
    """A writer that fails half-way (here: after writing some bytes)."""
    target = tmp_path / "report.md"
    target.write_text("old")

    def writer(fh):
        fh.write(b"new and partial")
        raise RuntimeError("serializer broke")

    with pytest.raises(RuntimeError, match="serializer broke"):
        write_atomic(target, writer)
    assert target.read_text() == "old"
    no_temporaries(tmp_path)


def test_unserializable_info_is_a_model_file_error_and_writes_nothing(tmp_path):
    out = tmp_path / "m.json"
    out.write_text('{\n "state_names": []}')  # an earlier model file: replaceable
    model = dataclasses.replace(tiny(), info={"callback": object()})
    for suffix in FORMATS:
        with pytest.raises(ModelFileError, match="cannot save: the model's info"):
            model.save(out.with_suffix(suffix))
    assert out.read_text() == '{\n "state_names": []}'
    assert sorted(os.listdir(tmp_path)) == ["m.json"]


def test_atomic_write_keeps_mode_and_follows_a_symlink(tmp_path):
    real = tmp_path / "real.md"
    real.write_text("old")
    real.chmod(0o640)
    link = tmp_path / "link.md"
    link.symlink_to(real)
    write_text_atomic(link, "new")
    assert link.is_symlink() and real.read_text() == "new"
    assert (real.stat().st_mode & 0o777) == 0o640
    with pytest.raises(ModelFileError, match="it is a folder"), atomic_path(tmp_path):
        pass
    no_temporaries(tmp_path)


def test_out_inside_a_file_writes_nothing(capfd, tmp_path):
    """Replaces test_bad_input.py::test_unwritable_out_writes_nothing, which cannot fail as
    root: here the folder of --out is a regular file, which stops root too."""
    blocker = tmp_path / "notes.txt"
    blocker.write_text("mine")
    before = snapshot(tmp_path)
    code, _, err = cli(capfd, "linearize", "pendulum", "--out", blocker / "m.npz")
    assert_refused(code, err, "'", "notes.txt' is a file, not a folder")
    code, _, err = cli(capfd, "export-mjcf", "double_pendulum", "-o", blocker / "m.xml")
    assert_refused(code, err, "notes.txt' is a file, not a folder")
    with pytest.raises(ModelFileError, match="is a file, not a folder"):
        tiny().save(blocker / "m.npz")
    assert snapshot(tmp_path) == before


# ----------------------------------------------------------------------------- 4. CLI
@pytest.mark.parametrize("dt", ["0", "-1", "nan", "inf", "1e999"])
def test_export_mjcf_refuses_a_bad_time_step(dt, capfd, tmp_path):
    out = tmp_path / "scene.xml"
    code, _, err = cli(capfd, "export-mjcf", "double_pendulum", "-o", out, "--dt", dt)
    assert_refused(code, err, "argument '--dt'", "finite time step of at least 1e-09 s")
    assert not out.exists()


@pytest.mark.parametrize("kwargs, words", [
    ({"dt": 0.0}, "argument 'dt'"), ({"dt": float("nan")}, "argument 'dt'"),
    ({"dt": -1e-3}, "argument 'dt'"), ({"dt": "1e-3"}, "expected a number, got str"),
    ({"impedance": 1.0}, "argument 'impedance': must be strictly between 0 and 1"),
])
def test_mjcf_build_checks_its_arguments(kwargs, words):
    from pinlin import mjcf

    system = pinlin.Scene.load(URDF_DIR / "double_pendulum.toml").system
    with pytest.raises(ArgumentError) as info:
        mjcf.build(system, **kwargs)
    assert words in str(info.value)


def test_validate_unknown_robot_writes_nothing(capfd, tmp_path):
    out = tmp_path / "reports"
    code, _, err = cli(capfd, "validate", "robocop", "--out-dir", out, "--no-progress")
    assert_refused(code, err, "'robocop' is not a scene file, a URDF, a bundled scene")
    assert not out.exists()
    code, _, err = cli(capfd, "validate", "double_pendulum", tmp_path / "nowhere.urdf",
                       "--out-dir", out, "--no-progress")
    assert_refused(code, err, "nowhere.urdf")
    assert not out.exists()


@pytest.mark.parametrize("command", ["validate", "bench"])
def test_out_dir_that_is_a_file(command, capfd, tmp_path):
    blocker = tmp_path / "reports"
    blocker.write_text("mine")
    before = snapshot(tmp_path)
    for out_dir in (blocker, blocker / "sub"):
        code, _, err = cli(capfd, command, "double_pendulum", "--out-dir", out_dir,
                           "--no-progress")
        assert_refused(code, err, str(out_dir), "is a file")
    code, _, err = cli(capfd, command, "double_pendulum", "--out-dir", "", "--no-progress")
    assert_refused(code, err, "argument '--out-dir': needs a folder name")
    assert snapshot(tmp_path) == before


def test_validate_never_replaces_a_file_it_did_not_write(capfd, tmp_path):
    """--out-dir . in a project: its README.md is the user's, not a validation index."""
    (tmp_path / "README.md").write_text("# My project\n")
    (tmp_path / "double_pendulum.md").write_text("my notes\n")
    before = snapshot(tmp_path)
    code, _, err = cli(capfd, "validate", "double_pendulum", "--out-dir", tmp_path,
                       "--no-progress")
    assert_refused(code, err, "was not written by pinlin", "double_pendulum.md")
    (tmp_path / "double_pendulum.md").unlink()
    del before["double_pendulum.md"]
    code, _, err = cli(capfd, "validate", "double_pendulum", "--out-dir", tmp_path,
                       "--no-progress")
    assert_refused(code, err, "README.md", "was not written by pinlin")
    assert snapshot(tmp_path) == before


def test_bench_never_replaces_a_report_it_did_not_write(capfd, tmp_path):
    (tmp_path / "accuracy_vs_time.md").write_text("my timings\n")
    before = snapshot(tmp_path)
    code, _, err = cli(capfd, "bench", "double_pendulum", "--out-dir", tmp_path,
                       "--repeats", "1", "--no-progress")
    assert_refused(code, err, "accuracy_vs_time.md", "was not written by pinlin")
    assert snapshot(tmp_path) == before


def test_validate_merges_into_an_existing_index(capfd, tmp_path):
    (tmp_path / "README.md").write_text(
        "# Validation reports\n\n| system | verdict | matrix error | eigenvalue error | rigid "
        "| note |\n|---|---|---|---|---|---|\n"
        "| [ur5](ur5.md) | pass | 1.0e-12 | 1.0e-12 | 0.0e+00 |  |\n")
    code, out, _ = cli(capfd, "validate", "double_pendulum", "--out-dir", tmp_path,
                       "--no-progress")
    assert code == 0, out
    index = (tmp_path / "README.md").read_text()
    assert "| [ur5](ur5.md) | pass |" in index
    assert "| [double_pendulum](double_pendulum.md) | pass |" in index
    assert "Totals: pass: 2" in index
    no_temporaries(tmp_path)


@pytest.mark.parametrize("argv, words", [
    (["linearize", "pendulum", "--out", ""], "argument '--out': needs a file name"),
    (["linearize", "pendulum", "--out", "  "], "argument '--out': needs a file name"),
    (["export-mjcf", "double_pendulum", "-o", ""], "argument '--output': needs a file name"),
    (["bench", "double_pendulum", "--repeats", "100000000000000000000", "--no-progress"],
     "--repeats must be >= 1 and <= 1000"),
    (["bench", "double_pendulum", "--repeats", "-3", "--no-progress"],
     "--repeats must be >= 1 and <= 1000"),
    (["bench", "robocop", "--no-progress"], "'robocop' is not"),
    (["validate", "--all", "ur5"], "argument '--all'"),
    (["validate"], "name scenes or robots, or give --all"),
    (["validate", "a/four_bar.toml", "b/four_bar.toml"], "would both write the report"),
])
def test_bad_output_arguments(argv, words, capfd, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    code, _, err = cli(capfd, *argv)
    assert_refused(code, err, words)
    assert os.listdir(tmp_path) == []


@pytest.mark.parametrize("target", ["folder.xml", "folder.npz"])
def test_output_onto_a_folder(target, capfd, tmp_path):
    (tmp_path / target).mkdir()
    before = snapshot(tmp_path)
    argv = (["export-mjcf", "double_pendulum", "-o"] if target.endswith(".xml")
            else ["linearize", "pendulum", "--out"])
    code, _, err = cli(capfd, *argv, tmp_path / target)
    assert_refused(code, err, "it is a folder, expected a file name")
    assert snapshot(tmp_path) == before


def test_export_mjcf_never_overwrites_the_scenes_own_urdf(write_scene, capfd, tmp_path):
    """A URDF named .xml is a valid scene input and a valid -o target: not the same file."""
    scene = write_scene('urdf = "robot.xml"\n[effects]\ngravity = [0.0, 0.0, -9.81]\n',
                        robot__xml=(URDF_DIR / "double_pendulum.urdf").read_text())
    before = snapshot(tmp_path)
    code, _, err = cli(capfd, "export-mjcf", scene, "-o", tmp_path / "robot.xml")
    assert_refused(code, err, "robot.xml: is an input of the scene")
    assert snapshot(tmp_path) == before


def test_report_names_stay_inside_the_output_folder():
    from pinlin.bench import report_label
    from pinlin.validate import report_name

    for f in (report_name, report_label):
        assert f("../../etc/x.urdf") == "x" and f("/abs/path/scene.toml") == "scene"
        assert f("ur5") == "ur5"


@pytest.mark.parametrize("args", [
    ("report", "double_pendulum", "-o", "{out}.html"),
    ("export-mjcf", "double_pendulum", "-o", "{out}.xml"),
    ("modes", "double_pendulum", "--plot", "{out}.png"),
    ("modes", "double_pendulum", "--gif", "{out}.gif"),
    ("linearize", "double_pendulum", "--out", "{out}.npz"),
    ("linearize", "double_pendulum", "--out", "{out}.json"),
], ids=["report", "mjcf", "png", "gif", "npz", "json"])
@pytest.mark.parametrize("how", ["file", "link", "dangling_link"])
def test_outputs_never_replace_a_file_of_another_kind(args, how, capfd, tmp_path):
    """A user's notes at an output name, or a link there to some other file, are refused
    before any work and left untouched; an earlier result of the same kind is replaced. A
    link to a file that does not exist (notes.txt to be) was written through: pinlin created
    the link's target, whatever its name."""
    notes = tmp_path / "notes.txt"
    argv = [a.format(out=tmp_path / "out") for a in args]
    target = Path(argv[-1])
    if how == "file":
        target.write_text("my notes\n")
    else:
        target.symlink_to(notes)
    if how != "dangling_link":
        notes.write_text("my notes\n")
    before = snapshot(tmp_path)
    code, _, err = cli(capfd, *argv)
    assert_refused(code, err, target.name, "pinlin does not create a file through a link"
                   if how == "dangling_link" else "pinlin does not replace it")
    assert snapshot(tmp_path) == before
    target.unlink()
    for _ in range(2):       # written, then its own earlier result replaced
        code, _, err = cli(capfd, *argv)
        assert code == 0, err
    no_temporaries(tmp_path)


@pytest.mark.parametrize("suffix, content", [
    (".json", b'{"my": "settings"}\n'),
    (".npz", None),          # a user's own archive: a zip, but none of pinlin's arrays
    (".npz", "names"),       # one that shares a name with pinlin's, and holds more
    (".mat", b"MATLAB 5.0 MAT-file, a user's own data" + bytes(100)),
    # MATLAB's v7.3 (HDF5) header: scipy raises NotImplementedError on it
    (".mat", b"MATLAB 7.3 MAT-file, HDF5 schema 1.00 .".ljust(124, b" ") + b"\x00\x02IM"
     + b"\x89HDF\r\n\x1a\n" + bytes(64)),
    (".mat", b"MATLAB 5.0 MAT-file"),         # truncated: IndexError inside scipy
    (".mat", "corrupt"),                      # compressed v5 with a damaged body: zlib.error
    # a pinlin model loaded in MATLAB, the user's results added, the workspace saved back
    (".mat", "names"),
], ids=["json", "npz", "npz_sharing_names", "mat", "mat_v73", "mat_truncated",
        "mat_corrupt", "mat_sharing_names"])
def test_data_files_of_the_same_format_but_not_pinlins_are_kept(suffix, content, capfd,
                                                                tmp_path):
    """Every JSON object starts with '{' and every .npz is a zip: for the data formats pinlin
    also looks for its own names (a model's state_names, a history's columns)."""
    target = tmp_path / f"mine{suffix}"
    if content is None:
        np.savez(target, x=np.ones(3))
    elif content == "corrupt":
        import scipy.io

        scipy.io.savemat(target, {"x": np.arange(1000.0)}, do_compression=True)
        raw = bytearray(target.read_bytes())
        raw[200:260] = bytes(60)
        target.write_bytes(bytes(raw))
    elif content == "names" and suffix == ".npz":
        np.savez(target, state_names=np.array(["x"]), A=np.ones((1, 1)), meta=np.array("{}"),
                 important=np.ones(3))
    elif content == "names":
        pinlin.linearize("double_pendulum").save(target)
        import scipy.io

        workspace = scipy.io.loadmat(target)
        workspace = {k: v for k, v in workspace.items() if not k.startswith("__")}
        scipy.io.savemat(target, {**workspace, "K_lqr": np.ones((2, 4))})
    else:
        target.write_bytes(content)
    before = snapshot(tmp_path)
    code, _, err = cli(capfd, "linearize", "double_pendulum", "--out", target)
    assert_refused(code, err, target.name, "pinlin does not replace it")
    assert snapshot(tmp_path) == before


def test_export_keeps_a_hand_written_mjcf(capfd, tmp_path):
    """pinlin's MJCF begins with its own comment: a user's MJCF at the output name stays."""
    mine = tmp_path / "robot.xml"
    mine.write_text('<mujoco model="mine"><worldbody/></mujoco>\n')
    before = snapshot(tmp_path)
    code, _, err = cli(capfd, "export-mjcf", "double_pendulum", "-o", mine)
    assert_refused(code, err, "robot.xml", "pinlin does not replace it")
    assert snapshot(tmp_path) == before


def _user_png(path: Path) -> None:
    """A PNG of the user's own, made by matplotlib as pinlin's are (but not by pinlin)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig = plt.figure()
    fig.savefig(path, format="png")
    plt.close(fig)


@pytest.mark.parametrize("kind", ["png", "gif", "html", "csv", "fifo"])
def test_files_of_the_same_format_or_no_file_at_all_are_kept(kind, capfd, tmp_path):
    """A user's matplotlib plot, GIF, HTML page or lab CSV (header 't,voltage') at an output
    name is kept (pinlin's own carry its marker or named signals), and so is a named pipe."""
    pendulum = URDF_DIR / "pendulum.toml"
    target = tmp_path / f"mine.{'csv' if kind == 'fifo' else kind}"
    if kind == "png":
        _user_png(target)
        argv = ["modes", pendulum, "--plot", target]
    elif kind == "gif":
        target.write_bytes(b"GIF89a" + bytes(40))
        argv = ["modes", pendulum, "--gif", target]
    elif kind == "html":
        target.write_text("<!DOCTYPE html>\n<title>my notes</title>\n")
        argv = ["report", pendulum, "-o", target, "--no-response"]
    elif kind == "csv":
        target.write_text("t,voltage\n0,1.5\n")
        argv = ["simulate", pendulum, "--t-end", "0.05", "--out", target]
    else:
        os.mkfifo(target)
        argv = ["simulate", pendulum, "--t-end", "0.05", "--out", target]
    before = snapshot(tmp_path) if kind != "fifo" else None
    code, _, err = cli(capfd, *argv)
    assert_refused(code, err, target.name, "pinlin does not replace it")
    if before is not None:
        assert snapshot(tmp_path) == before
    else:
        assert stat.S_ISFIFO(os.stat(target).st_mode)


def test_a_history_and_a_model_never_replace_each_other(capfd, tmp_path, pendulum):
    """Both are pinlin's .npz files, of different kinds: a simulation's --out over a saved
    model destroyed the model (and a model over a history the history)."""
    model_file, history_file = tmp_path / "model.npz", tmp_path / "history.npz"
    pendulum.save(model_file)
    assert main(["simulate", "pendulum", "--t-end", "0.1", "--out", str(history_file)]) == 0
    before = model_file.read_bytes(), history_file.read_bytes()
    capfd.readouterr()
    assert main(["simulate", "pendulum", "--t-end", "0.1", "--out", str(model_file)]) == 2
    # named for what it is (it said "not a .npz file of the kind pinlin writes")
    assert "model.npz: exists and holds a saved model (linear or trajectory), not a time " \
           "history" in capfd.readouterr().err
    with pytest.raises(pinlin.ModelFileError, match="holds a saved time history, not a model"):
        pendulum.save(history_file)
    assert (model_file.read_bytes(), history_file.read_bytes()) == before
    pendulum.save(model_file)      # each kind still replaces its own
    assert main(["simulate", "pendulum", "--t-end", "0.1", "--out", str(history_file)]) == 0


def _mat_variants(raw: bytes) -> dict[str, bytes]:
    """Corruptions of a pinlin .mat file that crashed scipy's compiled reader (segfault):
    a name's UTF-8 data element retyped 16 -> 24, and a name cell's class flipped from char
    (4) to sparse (5)."""
    tag = b"\x10\x00\x00\x00\x07\x00\x00\x00u:elbow"   # miUTF8, 7 bytes, "u:elbow"
    flags = b"\x06\x00\x00\x00\x08\x00\x00\x00\x04\x00\x00\x00"   # miUINT32, 8: class char
    assert tag in raw and flags in raw
    at = raw.index(flags)
    variants = {"unknown_type": raw.replace(tag, b"\x18" + tag[1:]),
                "char_as_sparse": raw[:at + 8] + b"\x05" + raw[at + 9:]}
    # scipy reads any minor version of level 5: one flipped bit there skipped the check
    for key in list(variants):
        variants[f"{key}_minor_version"] = variants[key][:124] + b"\x01" + variants[key][125:]
    return variants


@pytest.mark.parametrize("variant", ["unknown_type", "char_as_sparse",
                                     "unknown_type_minor_version",
                                     "char_as_sparse_minor_version"])
def test_a_mat_file_scipy_would_crash_on_is_refused(variant, tmp_path):
    """Checked before scipy reads it (pinlin.mat_check): one line naming the file and the
    byte, for a single model and a trajectory model alike."""
    scene = pinlin.Scene.load(URDF_DIR / "double_pendulum.toml")
    good = tmp_path / "m.mat"
    pinlin.linearize(scene).save(good)
    bad = tmp_path / "bad.mat"
    bad.write_bytes(_mat_variants(good.read_bytes())[variant])
    with pytest.raises(ModelFileError, match=r"bad\.mat.*at byte \d+"):
        LinearModel.load(bad)
    q = np.tile(pinlin.linearize(scene).operating_point.q, (3, 1))
    traj = tmp_path / "t.mat"
    pinlin.linearize_trajectory(scene, q, np.zeros((3, 2)), np.zeros((3, 2))).save(traj)
    bad.write_bytes(_mat_variants(traj.read_bytes())[variant])
    with pytest.raises(ModelFileError, match=r"bad\.mat.*at byte \d+"):
        pinlin.TrajectoryModel.load(bad)


def test_single_bit_flips_of_a_mat_file_never_crash(tmp_path):
    """400 random single-bit flips of a four-bar's .mat, its header included: each is
    refused with a ModelFileError or loads (MAT files carry no checksum: a flipped digit of a
    matrix loads as that digit); none may take the process down (scipy's reader did on about
    1 in 300)."""
    scene = pinlin.Scene.load(URDF_DIR / "four_bar.toml")
    good = tmp_path / "m.mat"
    pinlin.linearize(scene).save(good)
    raw = good.read_bytes()
    rng = np.random.default_rng(7)
    bad = tmp_path / "bad.mat"
    outcomes = {"refused": 0, "loaded": 0}
    for _ in range(400):
        flipped = bytearray(raw)
        at = int(rng.integers(100, len(raw)))   # the header's last 28 bytes, and the rest
        flipped[at] ^= 1 << int(rng.integers(8))
        bad.write_bytes(bytes(flipped))
        try:
            LinearModel.load(bad)
            outcomes["loaded"] += 1
        except ModelFileError:
            outcomes["refused"] += 1
    assert outcomes["refused"] > 100 and outcomes["loaded"] > 10, outcomes


def _npy(arr: np.ndarray) -> bytes:
    buf = io.BytesIO()
    np.lib.format.write_array(buf, arr)
    return buf.getvalue()


def test_an_archive_member_without_the_npy_suffix_is_refused(capfd, tmp_path):
    """np.load hands such a member back as raw bytes (an AttributeError traceback before):
    refused by name in a model file and in a states file alike."""
    model_file = tmp_path / "m.npz"
    LinearModel.save(tiny(), model_file)
    members = dict(np.load(model_file))
    bare = tmp_path / "bare.npz"
    with zipfile.ZipFile(bare, "w") as z:
        for key, arr in members.items():
            z.writestr(key if key == "meta" else f"{key}.npy", _npy(arr))
    with pytest.raises(ModelFileError, match=r"bare\.npz.*member 'meta' is not an array"):
        LinearModel.load(bare)
    states = tmp_path / "states.npz"
    with zipfile.ZipFile(states, "w") as z:
        z.writestr("q", b"xx")
        for key in ("v", "u"):
            z.writestr(f"{key}.npy", _npy(np.zeros((3, 2))))
    code, _, err = cli(capfd, "trajectory", "double_pendulum", states, "--out",
                       tmp_path / "out.npz")
    assert_refused(code, err, "states.npz", "member 'q' is not an array")
    assert not (tmp_path / "out.npz").exists()


@pytest.mark.parametrize("row, words", [
    ("0,0." + "0" * 200_000 + "1,0,0,0,0,0", "field larger than field limit"),
    ('0,"0\n",0,0,0,0,0', "2 values, the header names 7"),  # a quoted cell that runs on
], ids=["huge_cell", "quoted_line_break"])
def test_states_csv_lines_that_are_not_one_record_are_refused(row, words, capfd, tmp_path):
    """Each line is one record: a cell beyond the csv module's field limit (a csv.Error
    traceback before) and a quoted cell running on to the next line (zip's ValueError) are
    refused in one line naming the file and the line. A space after a closing quote in the
    header ("t" ,"q:shoulder") is read as before."""
    states = tmp_path / "states.csv"
    states.write_text("t,q:shoulder,q:elbow,v:shoulder,v:elbow,u:shoulder,u:elbow\n"
                      f"{row}\n1,0,0,0,0,0,0\n")
    code, _, err = cli(capfd, "trajectory", "double_pendulum", states, "--out",
                       tmp_path / "out.npz")
    assert_refused(code, err, "states.csv", "line 2", words)
    assert not (tmp_path / "out.npz").exists()
    states.write_text('"t" ,"q:shoulder","q:elbow","v:shoulder","v:elbow","u:shoulder",'
                      '"u:elbow"\n0,0,0,0,0,0,0\n1,0,0,0,0,0,0\n')
    code, _, err = cli(capfd, "trajectory", "double_pendulum", states, "--out",
                       tmp_path / "out.npz")
    assert code == 0, err


@pytest.mark.parametrize("edit, words", [
    ({"q": [0.0] * 7}, None),                       # wider than v: any nq >= nv loads
    ({"q": []}, "operating_point.q has 0 entries"),
    ({"q": [0.0] * 3, "v": [0.0] * 3, "a": [0.0] * 3, "residual": [0.0] * 3}, None),
    ({"v": [0.0] * 3, "a": [0.0] * 3, "residual": [0.0] * 3}, "operating_point.q has 2"),
    ({"v": [0.0], "a": [0.0], "residual": [0.0]}, "operating_point.v has 1 entries"),
    ({"u": [0.0] * 5}, "operating_point.u has 5 entries, expected 2"),
    ({"y": [0.0] * 9}, "operating_point.y has 9 entries, expected 3"),
    ("empty", "operating_point"),
], ids=["q_wider", "q_empty", "v_wider", "q_narrower_than_v", "v_narrow", "u", "y",
        "empty_table"])
def test_an_operating_point_that_does_not_fit_the_model_is_refused(edit, words, tmp_path):
    """Checked against the model's sizes when the file loads (before, every variant loaded
    and failed later, at use, without naming the file; an empty table read as no point)."""
    scene = pinlin.Scene.load(URDF_DIR / "double_pendulum.toml")
    path = tmp_path / "m.json"
    pinlin.linearize(scene).save(path)
    doc = json.loads(path.read_text())
    if edit == "empty":
        doc["operating_point"] = {}
    else:
        doc["operating_point"].update(edit)
    path.write_text(json.dumps(doc))
    if words is None:
        LinearModel.load(path)
        return
    with pytest.raises(ModelFileError, match=f"m\\.json.*{words}"):
        LinearModel.load(path)


def test_f0_of_another_shape_is_refused(tmp_path):
    """f0 is n numbers, as a row or a column; a 2 x 2 block of them is not (it was
    flattened)."""
    scene = pinlin.Scene.load(URDF_DIR / "double_pendulum.toml")
    path = tmp_path / "m.json"
    pinlin.linearize(scene, v=[0.5, -0.2]).save(path)
    doc = json.loads(path.read_text())
    f0 = np.array(doc["f0"], dtype=float).reshape(-1)
    for good in (f0.reshape(1, 4), f0.reshape(4, 1)):
        doc["f0"] = good.tolist()
        path.write_text(json.dumps(doc))
        np.testing.assert_array_equal(LinearModel.load(path).f0, f0)
    doc["f0"] = f0.reshape(2, 2).tolist()
    path.write_text(json.dumps(doc))
    with pytest.raises(ModelFileError, match="f0"):
        LinearModel.load(path)


def _edit_trajectory_file(src: Path, dst: Path, arrays=None, meta=None, info=None) -> None:
    members = dict(np.load(src))
    members.update(arrays or {})
    doc = json.loads(str(members["meta"]))
    doc.update(meta or {})
    doc["info"].update(info or {})
    members["meta"] = np.array(json.dumps(doc))
    np.savez(dst, **members)


@pytest.mark.parametrize("edit, words", [
    ({"arrays": {"q": np.zeros((5, 1))}}, "q must have at least as many columns as v"),
    ({"arrays": {"v": np.zeros((5, 1)), "a": np.zeros((5, 1))}}, "at least n/2 = 2 columns"),
    ({"arrays": {"output_names": np.array(["a\nb", "c", "d"])}}, "control characters"),
    ({"arrays": {"output_names": np.array(["  ", "c", "d"])}}, "empty or blank"),
    ({"arrays": {"lam": np.zeros((5, 3))}}, r"lam_names'\] must name each of the 3"),
    ({"info": {"lam_names": "abc"}}, r"lam_names'\] must name each of the 0"),
    ({"info": {"at_rest": "yes"}}, r"at_rest'\] must be true or false"),
    ({"info": {"loops": 5}}, r"loops'\] must hold"),
    ({"info": {"loops": {"condition": [1.0]}}}, r"loops'\] must hold"),
    ({"meta": {"version": 99}}, "format version 99"),
    ({"meta": {"foo": 1}}, "unknown metadata key 'foo'"),
    ({"arrays": {"t": np.linspace(0, 1, 5).reshape(5, 1)}}, r"'t' must be a list of times"),
], ids=["q_narrow", "v_narrow", "name_newline", "name_blank", "lam_unnamed",
        "lam_names_text", "at_rest", "loops_number", "loops_short", "version", "meta_key",
        "t_column"])
def test_a_trajectory_file_that_does_not_fit_is_refused_when_it_loads(edit, words, tmp_path):
    """Widths, names and the info that at(k) reads are checked when the file loads, naming
    it (before: each loaded, and failed at use, in at(k) or later, with a traceback or a
    message about another argument; a future format version was read as version 1)."""
    scene = pinlin.Scene.load(URDF_DIR / "double_pendulum.toml")
    rng = np.random.default_rng(2)
    q, v, u = rng.normal(size=(5, 2)), rng.normal(size=(5, 2)), rng.normal(size=(5, 2))
    good = tmp_path / "t.npz"
    pinlin.linearize_trajectory(scene, q, v, u, t=np.linspace(0, 1, 5)).save(good)
    bad = tmp_path / "bad.npz"
    _edit_trajectory_file(good, bad, **edit)
    with pytest.raises(ModelFileError, match=f"bad\\.npz.*{words}"):
        pinlin.TrajectoryModel.load(bad)


def test_a_mechanism_trajectory_file_keeps_its_loops_and_forces(tmp_path):
    """The checks admit what pinlin writes: a four-bar's lam, lam_names and loops."""
    scene = pinlin.Scene.load(URDF_DIR / "four_bar.toml")
    q = np.tile(pinlin.linearize(scene).operating_point.q, (4, 1))
    traj = pinlin.linearize_trajectory(scene, q, np.zeros((4, 3)), np.zeros((4, 1)))
    assert traj.lam is not None and "loops" in traj.info
    for suffix in (".npz", ".mat"):
        again = pinlin.TrajectoryModel.load(traj.save(tmp_path / f"t{suffix}"))
        np.testing.assert_array_equal(again.lam, traj.lam)
        assert again.at(2).operating_point.lam_names == traj.at(2).operating_point.lam_names


def _elements(raw: bytes):
    pos, out = 128, []
    while pos < len(raw):
        mtype, size = struct.unpack_from("<II", raw, pos)
        out.append((mtype, raw[pos + 8:pos + 8 + size]))
        pos += 8 + size + (0 if mtype == 15 else -size % 8)
    return out


def test_a_compressed_element_holding_two_arrays_is_refused():
    """A compressed element must hold one array: a second (here with a sparse class, which
    crashed scipy's reader) would reach scipy unchecked."""
    buf = io.BytesIO()
    scipy.io.savemat(buf, {"a": np.ones((2, 2)), "b": np.arange(3.0)}, do_compression=True)
    raw = buf.getvalue()
    inner = [zlib.decompress(data) for mtype, data in _elements(raw)]
    assert len(inner) == 2
    second = bytearray(inner[1])
    assert second[16] == 6           # class double -> sparse (5): scipy's reader crashed on it
    second[16] = 5
    packed = zlib.compress(inner[0] + bytes(second))
    bad = raw[:128] + struct.pack("<II", 15, len(packed)) + packed
    with pytest.raises(MatStructureError, match="byte 128"):
        check_mat_elements(bad)


def test_a_numeric_array_shorter_than_its_dimensions_is_refused():
    """Dimensions 4 x 1 over 3 doubles: refused, not handed to scipy."""
    buf = io.BytesIO()
    scipy.io.savemat(buf, {"x": np.arange(3.0)}, oned_as="column")
    raw = buf.getvalue()
    dims = struct.pack("<IIii", 5, 8, 3, 1)
    assert raw.count(dims) == 1
    check_mat_elements(raw)
    bad = raw.replace(dims, struct.pack("<IIii", 5, 8, 4, 1))  # 4 x 1 declared, 3 doubles held
    with pytest.raises(MatStructureError, match="does not hold its 4 entries"):
        check_mat_elements(bad)


def test_an_operating_point_whose_a_does_not_match_v_is_refused():
    """a changed alone (not with v): its size is checked against v's."""
    model = pinlin.linearize(pinlin.Scene.load(URDF_DIR / "double_pendulum.toml"))
    op = dataclasses.replace(model.operating_point, a=np.zeros(3))
    with pytest.raises(pinlin.ShapeError, match="operating_point.a has 3 entries, expected v's 2"):
        dataclasses.replace(model, operating_point=op)


def test_a_real_png_of_the_users_is_refused_for_what_it_lacks(tmp_path):
    """A PNG the user made begins as every PNG does: the refusal said it 'does not start with
    "PNG"', which it does; it lacks pinlin's mark."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from pinlin.files import check_ours
    from pinlin.validation_report import PNG_MARKER

    mine = tmp_path / "mine.png"
    fig = plt.figure(figsize=(1, 1))
    fig.savefig(mine)
    plt.close(fig)
    with pytest.raises(pinlin.ModelFileError, match="lacks the mark pinlin leaves"):
        check_ours(mine, PNG_MARKER)
    text = tmp_path / "notes.png"
    text.write_text("my notes\n")
    with pytest.raises(pinlin.ModelFileError, match="does not start with"):
        check_ours(text, PNG_MARKER)

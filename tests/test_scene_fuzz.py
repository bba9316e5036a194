"""Property test: junk in any scene field gives a finite model or a PinlinError, nothing else.

Three small bundled scenes (pendulum, double pendulum, four-bar) are taken in their dict form
and in their TOML text; hypothesis (derandomized, like tests/test_properties.py) replaces one to
three fields with junk -- wrong types, huge/tiny/NaN/inf floats, integers of hundreds of digits,
strings with line breaks, nested lists, unknown keys, unknown joint names -- or rewrites the
TOML's numbers. For every draw, ``pinlin.linearize`` and ``pinlin.modal`` either give finite
matrices and eigenvalues or raise a :class:`pinlin.PinlinError`; any other exception, or a
numpy RuntimeWarning (overflow, invalid value) on the way, fails the test.
"""

from __future__ import annotations

import copy
import re
import tomllib
import warnings
from typing import Any

import numpy as np
from conftest import URDF_DIR
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import pinlin
from pinlin.conditioning import AccuracyWarning
from pinlin.scene import COEFFICIENT_LIMIT, POSITION_LIMIT, RATE_LIMIT, Scene

SETTINGS = settings(max_examples=250, deadline=None, derandomize=True,
                    suppress_health_check=[HealthCheck.function_scoped_fixture,
                                           HealthCheck.too_slow])
SCENES = ("pendulum", "double_pendulum", "four_bar")


def _base(name: str) -> dict[str, Any]:
    """The bundled scene's dict form with an absolute URDF path."""
    data = tomllib.loads((URDF_DIR / f"{name}.toml").read_text())
    data["urdf"] = str(URDF_DIR / data["urdf"])
    return data


BASES = {name: _base(name) for name in SCENES}
JOINTS = {"pendulum": ["hinge"], "double_pendulum": ["shoulder", "elbow"],
          "four_bar": ["crank", "coupler", "rocker"]}

# Leaves: every kind of value a hostile user might put anywhere.
numbers_junk = st.one_of(
    st.floats(allow_nan=True, allow_infinity=True),
    st.sampled_from([0.0, -0.0, 5e-324, 1e-300, 1e6, 1e12, 1.1e12, 1e154, 1e200, 1e300,
                     -1e308, float("inf"), float("nan")]),
    st.integers(-10**6, 10**6),
    st.integers(min_value=10**300, max_value=10**500),
    st.integers(min_value=-10**500, max_value=-10**300),
)
names_junk = st.one_of(
    st.sampled_from(["hinge", "shoulder", "elbow", "crank", "rocker", "coupler", "tip",
                     "coupler_tip", "rocker_tip", "all", "q:hinge", "v:elbow", "x:crank",
                     "nope", "", " ", "a\nb", "q:", "__spin__", "universe", "inputs",
                     "positions", "point", "weld", "free", "fixed"]),
    st.text(max_size=8),
)
leaves = st.one_of(numbers_junk, names_junk, st.booleans(), st.none())
junk = st.recursive(
    leaves,
    lambda children: st.one_of(st.lists(children, max_size=4),
                               st.dictionaries(names_junk, children, max_size=3)),
    max_leaves=8,
)


def _paths(name: str) -> list[tuple]:
    """Field paths (tuples of keys / indices) a draw may overwrite."""
    joints = JOINTS[name] + ["nope"]
    paths: list[tuple] = [("name",), ("urdf",), ("robot",), ("base",), ("effects",),
                          ("operating_point",), ("inputs",), ("outputs",), ("loops",),
                          ("bogus",), ("effects", "gravity"), ("effects", "gravity", 2),
                          ("effects", "mimic"), ("effects", "rotation"),
                          ("effects", "rotation", "rate"), ("effects", "rotation", "axis"),
                          ("effects", "armature"), ("effects", "damping"),
                          ("effects", "springs"), ("effects", "bogus"),
                          ("operating_point", "q"), ("operating_point", "independent"),
                          ("operating_point", "solve"), ("operating_point", "u"),
                          ("operating_point", "allow_non_equilibrium"),
                          ("operating_point", "bogus"), ("inputs", "actuated"),
                          ("outputs", "frames"), ("outputs", "joints"), ("outputs", "bogus")]
    for j in joints:
        paths += [("effects", "armature", j), ("effects", "damping", j),
                  ("effects", "springs", j), ("effects", "springs", j, "stiffness"),
                  ("effects", "springs", j, "rest"), ("operating_point", "q", j),
                  ("operating_point", "u", j)]
    if name == "four_bar":
        paths += [("loops", 0, k) for k in ("name", "type", "frame1", "frame2", "bogus")]
    return paths


def _set(data: dict, path: tuple, value: Any) -> None:
    """Overwrite ``data`` at ``path``, creating tables on the way; a step into something that is
    not a table or list replaces it by a table."""
    node: Any = data
    for key in path[:-1]:
        if isinstance(node, list):
            if not node:
                node.append({})
            key = min(key, len(node) - 1) if isinstance(key, int) else 0
        elif isinstance(key, int):
            key = str(key)
        child = node[key] if (isinstance(node, list) or key in node) else None
        if not isinstance(child, dict | list):
            child = {}
            node[key] = child
        node = child
    last = path[-1]
    if isinstance(node, list):
        if isinstance(last, int) and last < len(node):
            node[last] = value
        else:
            node.append(value)
    else:
        node[str(last)] = value


@st.composite
def junk_scenes(draw) -> tuple[str, dict]:
    name = draw(st.sampled_from(SCENES))
    data = copy.deepcopy(BASES[name])
    paths = _paths(name)
    for _ in range(draw(st.integers(1, 3))):
        _set(data, draw(st.sampled_from(paths)), draw(junk))
    return name, data


def _check(make_scene, **options: str) -> None:
    """Build, linearize (with ``options``) and analyse; only a PinlinError may stop it, and a
    model must be finite."""
    with warnings.catch_warnings():
        warnings.simplefilter("error", RuntimeWarning)
        warnings.simplefilter("ignore", AccuracyWarning)
        try:
            scene = make_scene()
            model = pinlin.linearize(scene, **options)
        except pinlin.PinlinError as exc:
            assert "\n" not in str(exc), str(exc)
            return
        for key in ("A", "B", "C", "D"):
            assert np.all(np.isfinite(getattr(model, key))), key
        try:
            modes = pinlin.modal(model)
        except pinlin.PinlinError as exc:
            assert "\n" not in str(exc), str(exc)
            return
        assert np.all(np.isfinite(modes.eigenvalues))
        assert np.all(np.isfinite(modes.wn))
        str(modes)  # the table prints


@SETTINGS
@given(junk_scenes())
def test_junk_in_scene_fields_gives_a_finite_model_or_a_pinlin_error(drawn):
    _name, data = drawn
    _check(lambda: Scene.from_dict(data))


NUMBER = re.compile(r"(?<![\w.])-?\d+(\.\d+)?([eE][+-]?\d+)?(?![\w.])")
number_text = st.one_of(
    st.sampled_from(["nan", "inf", "-inf", "1e308", "-1e308", "1e-320", "0", "-0.0", "1e13",
                     "1e7", "999_999_999_999_999", "[]", "[[1.0]]", '"1.0"', "true", "{}",
                     "1979-05-27"]),
    st.integers(1, 600).map(lambda n: "9" * n),
    st.floats(allow_nan=False, allow_infinity=False).map(repr),
)


@SETTINGS
@given(name=st.sampled_from(SCENES), data=st.data())
def test_junk_numbers_in_scene_files_give_a_finite_model_or_a_pinlin_error(name, data,
                                                                          tmp_path_factory):
    text = (URDF_DIR / f"{name}.toml").read_text()
    matches = list(NUMBER.finditer(text))
    chosen = data.draw(st.sets(st.integers(0, len(matches) - 1), min_size=1, max_size=3))
    pieces, end = [], 0
    for k, m in enumerate(matches):
        if k in chosen:
            pieces += [text[end:m.start()], data.draw(number_text)]
            end = m.end()
    pieces.append(text[end:])
    folder = tmp_path_factory.mktemp("fuzz")
    path = folder / "scene.toml"
    path.write_text("".join(pieces).replace(f'"{name}.urdf"',
                                            repr(str(URDF_DIR / f"{name}.urdf"))))
    _check(lambda: Scene.load(path))


# Values inside the accepted ranges, extremes included: the scene is accepted, so the model
# must come out finite (or an equilibrium / assembly error say why there is none).
coefficients = st.one_of(st.sampled_from([0.0, 5e-324, 1e-300, 1e-12, 3.0, COEFFICIENT_LIMIT]),
                         st.floats(0.0, COEFFICIENT_LIMIT))
positions = st.one_of(st.sampled_from([0.0, 1e-300, 3.14159, POSITION_LIMIT, -POSITION_LIMIT]),
                      st.floats(-POSITION_LIMIT, POSITION_LIMIT))
signed = st.one_of(coefficients, coefficients.map(lambda x: -x))


@st.composite
def in_range_scenes(draw) -> dict:
    name = draw(st.sampled_from(SCENES))
    data = copy.deepcopy(BASES[name])
    joints = JOINTS[name]
    eff = data.setdefault("effects", {})
    op = data.setdefault("operating_point", {})
    for _ in range(draw(st.integers(1, 4))):
        what = draw(st.sampled_from(["gravity", "damping", "armature", "spring", "rotation", "q",
                                     "solve", "allow", "actuated", "outputs"]))
        j = draw(st.sampled_from(joints))
        if what == "gravity":
            eff["gravity"] = draw(st.lists(signed, min_size=3, max_size=3))
        elif what in ("damping", "armature"):
            eff.setdefault(what, {})[j] = draw(coefficients)
        elif what == "spring":
            eff.setdefault("springs", {})[j] = {"stiffness": draw(coefficients),
                                                "rest": draw(positions)}
        elif what == "rotation":
            eff["rotation"] = {"axis": draw(st.sampled_from([[0, 0, 1], [0, 1e-300, 0],
                                                             [1e300, 0, 0]])),
                               "rate": draw(st.floats(-RATE_LIMIT, RATE_LIMIT))}
        elif what == "q":
            op.setdefault("q", {})[j] = draw(positions)
        elif what == "solve":
            op["solve"] = draw(st.sampled_from(["inputs", "positions"]))
        elif what == "allow":
            op["allow_non_equilibrium"] = draw(st.booleans())
        elif what == "actuated":
            data.setdefault("inputs", {})["actuated"] = draw(st.lists(st.sampled_from(joints),
                                                                      unique=True))
        else:
            data["outputs"] = {"joints": draw(st.lists(st.sampled_from(joints), unique=True,
                                                       min_size=1))}
    if op.get("solve") == "positions" and draw(st.booleans()):
        op["u"] = {draw(st.sampled_from(joints)): draw(signed)}
    if op.get("solve") != "positions":
        op.pop("u", None)
    return data


@settings(SETTINGS, max_examples=150)
@given(in_range_scenes(), st.sampled_from(["analytic", "fd3", "fd5"]),
       st.sampled_from(["independent", "penalty", "canonical"]))
def test_extreme_values_inside_the_ranges_give_finite_models(data, derivatives, formulation):
    _check(lambda: Scene.from_dict(data), derivatives=derivatives, formulation=formulation)

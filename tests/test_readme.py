"""Every fenced code block of README.md runs as written.

What each fence language means here:

- ```python: executed with ``exec`` (tracebacks point at README.md's own line numbers) in a
  temporary working directory that holds copies of the repository's ``urdf/`` and
  ``validation/`` folders. Paths such as ``urdf/ur5_arm.toml`` or
  ``validation/graphs/two_springs.toml`` therefore resolve as they do from the repository root,
  while whatever a block writes (``ur5.npz``, ``validation/reports/...``) lands in the temporary
  folder and never in the checkout.
- ```toml: a scene file is written into that copy of ``urdf/`` (so ``urdf = "four_bar.urdf"``
  resolves beside the bundled URDFs), read with ``pinlin.Scene.load``, linearized with
  ``pinlin.linearize`` and analysed with ``pinlin.modal``. A linear graph (a file with
  ``[[branches]]``) is read with ``pinlin.graph.Graph.load(...).linearize()``.
- ```bash: every line is a command; ``&&`` chains are split. Each ``pinlin ...`` command runs
  in-process through ``pinlin.cli.main`` with its arguments (same working directory as the
  Python blocks) and must exit with status 0. ``pip install ...`` and ``python -m pytest`` are
  not run here: installing is what set up this test run, and ``.ci/run`` runs the README's
  install-and-test command itself (``test_ci_runs_the_readme_test_command`` checks that it is
  the same command). Any other command fails the test, so a new kind of command in the README
  needs a runner here.
- ```text: synopses (``[--option ...]``, ``SCENE_OR_ROBOT`` placeholders) and long-running
  commands (``pinlin validate --all``); never run. Any other fence language is an error.
"""

from __future__ import annotations

import math
import re
import shlex
import shutil
import tomllib
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pytest

import pinlin
from pinlin.cli import main
from pinlin.graph import Graph

REPO = Path(__file__).resolve().parent.parent
README = REPO / "README.md"
LANGUAGES = ("python", "toml", "bash", "text")
# Folders of the repository that README blocks name by relative path; copied, not linked, so
# that reports written by `pinlin validate` never touch the committed ones.
COPIED = ("urdf", "validation")
INSTALL_AND_RUN = "pip install . && pinlin linearize double_pendulum"
INSTALL_AND_TEST = 'pip install ".[test]" && python -m pytest'


@dataclass(frozen=True)
class Block:
    language: str
    line: int  # README line number of the block's first line of code
    code: str

    @property
    def id(self) -> str:
        return f"L{self.line}-{self.language or 'none'}"


def readme_blocks() -> list[Block]:
    """The fenced code blocks of README.md, in order."""
    blocks: list[Block] = []
    fence: tuple[str, int] | None = None
    body: list[str] = []
    for number, line in enumerate(README.read_text(encoding="utf-8").splitlines(), start=1):
        if fence is None:
            m = re.match(r"^\s*```(.*)$", line)
            if m:
                fence, body = (m.group(1).strip(), number + 1), []
        elif line.strip() == "```":
            blocks.append(Block(fence[0], fence[1], "\n".join(body) + "\n"))
            fence = None
        else:
            body.append(line)
    assert fence is None, f"README.md: the block opened on line {fence[1] - 1} is never closed"
    return blocks


BLOCKS = readme_blocks()


def blocks_of(language: str) -> list:
    return [pytest.param(b, id=b.id) for b in BLOCKS if b.language == language]


@pytest.fixture
def workdir(tmp_path, monkeypatch):
    """A working directory that reads like the repository root and takes what blocks write."""
    for name in COPIED:
        shutil.copytree(REPO / name, tmp_path / name,
                        ignore=shutil.ignore_patterns("__pycache__", "*.pyc"))
    monkeypatch.chdir(tmp_path)
    monkeypatch.setenv("MPLBACKEND", "Agg")
    return tmp_path


# --- the README's shape -----------------------------------------------------------------------

def test_every_block_has_a_known_language():
    assert BLOCKS
    for b in BLOCKS:
        assert b.language in LANGUAGES, (
            f"README.md line {b.line - 1}: fence '```{b.language}' is not one of {LANGUAGES} "
            f"(use ```text for a block that is deliberately not run)")


def test_the_first_two_blocks_are_install_and_run_then_install_and_test():
    readme = README.read_text(encoding="utf-8")
    first, second = BLOCKS[0], BLOCKS[1]
    assert (first.language, first.code.strip()) == ("bash", INSTALL_AND_RUN)
    assert (second.language, second.code.strip()) == ("bash", INSTALL_AND_TEST)
    # Only the title comes before them.
    before = readme[:readme.index("```")].strip()
    assert before.startswith("# ") and "\n" not in before


def test_ci_runs_the_readme_test_command():
    commands = [line.strip() for line in (REPO / ".ci" / "run").read_text().splitlines()
                if line.strip() and not line.lstrip().startswith("#")]
    assert commands[-1] == BLOCKS[1].code.strip()


def test_the_mutation_figures_are_the_script_and_its_committed_report():
    """The README says how many bugs validation/mutation.py plants (the script's list) and
    quotes the last full run's score from the committed report (both had stayed at an older
    run's 91 of 91 through two later runs)."""
    readme = " ".join(README.read_text(encoding="utf-8").split())
    report = (REPO / "validation" / "reports" / "mutation.md").read_text(encoding="utf-8")
    score = re.search(r"\*\*Score: (\d+) of (\d+) planted bugs caught\.\*\*", report)
    assert score, "validation/reports/mutation.md: no score line"
    caught, planted = score.groups()
    assert f"The last full run: **{caught} of {planted} caught**" in readme
    script = (REPO / "validation" / "mutation.py").read_text(encoding="utf-8")
    listed = script[script.index("MUTATIONS: dict"):script.index("\n}\n")]
    count = len(re.findall(r"^    ['\"]\w+['\"]: \($", listed, flags=re.M))
    assert count > 100 and f"plants {count} plausible bugs" in readme


# --- Python -----------------------------------------------------------------------------------

@pytest.mark.parametrize("block", blocks_of("python"))
def test_python_block_runs(block, workdir, capsys):
    # Leading newlines: a traceback's line number is the README's.
    source = "\n" * (block.line - 1) + block.code
    exec(compile(source, str(README), "exec"), {"__name__": "__main__"})  # noqa: S102
    capsys.readouterr()


# --- TOML -------------------------------------------------------------------------------------

def _assert_finite(model) -> None:
    for name in ("A", "B", "C", "D"):
        assert np.all(np.isfinite(getattr(model, name))), name


@pytest.mark.parametrize("block", blocks_of("toml"))
def test_toml_block_loads_and_linearizes(block, workdir):
    data = tomllib.loads(block.code)  # a syntax error names the README block via the test id
    path = workdir / "urdf" / f"readme_{block.line}.toml"
    path.write_text(block.code, encoding="utf-8")
    if "branches" in data:
        model = Graph.load(path).linearize()
        _assert_finite(model)
        shipped = workdir / "validation" / "graphs" / f"{data['name']}.toml"
        if shipped.exists():  # the README shows a shipped graph: the same state equations
            ref = Graph.load(shipped).linearize()
            assert model.state_names == ref.state_names
            np.testing.assert_array_equal(model.A, ref.A)
            np.testing.assert_array_equal(model.B, ref.B)
    else:
        scene = pinlin.Scene.load(path)
        model = pinlin.linearize(scene)
        _assert_finite(model)
        modes = pinlin.modal(model)
        assert str(modes)
        assert not any(math.isnan(w) for w in np.asarray(modes.wn))


# --- shell ------------------------------------------------------------------------------------

def _commands(code: str) -> list[list[str]]:
    """The commands of a bash block: one per line (backslash continuations joined), comments
    dropped, `&&` chains split. Other shell syntax is refused: the runner below is no shell."""
    commands: list[list[str]] = []
    for line in code.replace("\\\n", " ").splitlines():
        words = shlex.split(line, comments=True)
        if not words:
            continue
        assert not any(w in ("|", "||", ";", ">", "<", "&") for w in words), (
            f"'{line}': only plain commands and && chains can be run here")
        assert not any(w.startswith("[") or w.isupper() for w in words), (
            f"'{line}' looks like a synopsis (an [option] or a PLACEHOLDER): fence it as ```text")
        command: list[str] = []
        for w in [*words, "&&"]:
            if w == "&&":
                assert command, f"'{line}': empty command in an && chain"
                commands.append(command)
                command = []
            else:
                command.append(w)
    return commands


def _not_run(argv: list[str]) -> bool:
    """`pip install ...` and `python -m pytest`: see the module docstring."""
    return argv[:2] == ["pip", "install"] or argv[:3] == ["python", "-m", "pytest"]


@pytest.mark.parametrize("block", blocks_of("bash"))
def test_bash_block_runs(block, workdir, capsys):
    commands = _commands(block.code)
    assert commands, f"README.md line {block.line}: an empty bash block"
    for argv in commands:
        if _not_run(argv):
            continue
        assert argv[0] == "pinlin", (
            f"README.md block at line {block.line}: '{shlex.join(argv)}' has no runner in "
            f"tests/test_readme.py")
        code = main(argv[1:])
        out, err = capsys.readouterr()
        assert code == 0, f"'{shlex.join(argv)}' exited with {code}:\n{out}\n{err}"

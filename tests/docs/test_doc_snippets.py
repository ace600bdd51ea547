"""Every code snippet of README.md and docs/*.md runs (issue 30, item 4m).

The ```python blocks of each page are extracted and executed in order, in one fresh namespace
per page (a later block may continue an earlier one, as a reader would type them), and the
```bash blocks' ``casmbd …`` commands run as ``python -m casmbd …`` in a subprocess.  So the
documentation cannot drift from the code: a renamed function, a changed signature or a snippet
that stopped making sense fails here, naming the page and the line of the block.

Where they run: a fresh temporary directory that holds a symbolic link to every top-level
entry of the repository (``examples/``, ``ocp/``, ``tests/``, ``docs/`` …), so the snippets'
relative paths resolve as from the repository root while the files they write (``sweep_dir``,
``swing.npz``, ``out/…``) land in the temporary directory, never in the checkout.  The
compiled-code cache is the user's (``~/.cache/casmbd``), as for the tutorial's own test.

What is not run, and why (:data:`SKIPPED`): installation commands (``pip install``), the whole
test suite (``python -m pytest``), fragments that are not programs (a ``...`` body, a command
synopsis) and blocks that another part of the documentation work is changing (named with the
reason).  Long runs are capped in the snippets themselves (short horizons, few steps) so the
module runs in about a minute.
"""

from __future__ import annotations

import os
import pathlib
import re
import shlex
import subprocess
import sys
import warnings

import pytest

ROOT = pathlib.Path(__file__).resolve().parents[2]
PAGES = ["README.md", *sorted(str(p.relative_to(ROOT)) for p in (ROOT / "docs").glob("*.md"))]

#: blocks not run: page -> {a text fragment of the block: why}
SKIPPED: dict[str, dict[str, str]] = {
    "docs/extending.md": {
        "def equations(self, ctx): ...":
            "a pattern with an elided body ('...'): its runnable form is "
            "examples/custom_joint.py (run by tests/model/test_custom_kind.py)",
        'register_verb("mass_properties", _run,':
            "the registration of examples/custom_verb.py, quoted (run by "
            "tests/architecture/test_custom_registries.py)",
        'ContactModel("soft", force="my_penalty_force")':
            "a pattern (a force kind of the reader's own); its runnable form is "
            "tests/model/test_contact_models.py",
    },
}
#: shell commands not run: a prefix -> why
SKIPPED_COMMANDS = {
    "pip install": "installs the package (the test runs the checkout itself)",
    "python -m pytest": "the whole test suite",
}

_FENCE = re.compile(r"^(?P<indent>[ \t]*)```(?P<lang>[A-Za-z0-9_+-]*)\s*$")


def blocks(page: str, language: str) -> list[tuple[int, str]]:
    """The fenced blocks of ``language`` on ``page``: (line number of the fence, code),
    dedented by the fence's indentation (blocks inside list items)."""
    found, current, indent, start, lang = [], None, "", 0, ""
    for number, line in enumerate((ROOT / page).read_text().splitlines(), start=1):
        fence = _FENCE.match(line)
        if current is None:
            if fence and fence.group("lang"):
                current, indent, start = [], fence.group("indent"), number
                lang = fence.group("lang")
            continue
        if fence and not fence.group("lang"):
            if lang == language:
                found.append((start, "\n".join(current) + "\n"))
            current = None
            continue
        current.append(line[len(indent):] if line.startswith(indent) else line.lstrip())
    return found


def skipped(page: str, code: str) -> str | None:
    """Why the block ``code`` of ``page`` is not run, or None."""
    for fragment, why in SKIPPED.get(page, {}).items():
        if fragment in code:
            return why
    return None


def commands(page: str) -> list[tuple[int, str]]:
    """The ``casmbd …`` commands of the ```bash blocks of ``page`` (comments dropped, ``&&``
    chains split, installation and test-suite commands left out)."""
    found = []
    for start, code in blocks(page, "bash"):
        for offset, line in enumerate(code.replace("\\\n", " ").splitlines(), start=1):
            for part in line.split("&&"):
                part = part.split(" #")[0].strip()
                if part.startswith("casmbd ") and not any(
                        part.startswith(p) for p in SKIPPED_COMMANDS):
                    found.append((start + offset, part))
    return found


@pytest.fixture
def sandbox(tmp_path, monkeypatch) -> pathlib.Path:
    """A working directory that sees the repository's top-level entries (links) and keeps
    whatever the snippets write."""
    for entry in ROOT.iterdir():
        if entry.name.startswith(".") or entry.name in ("out", "__pycache__"):
            continue
        (tmp_path / entry.name).symlink_to(entry, target_is_directory=entry.is_dir())
    monkeypatch.chdir(tmp_path)
    monkeypatch.setenv("MPLBACKEND", "Agg")
    return tmp_path


def page_commands(page: str) -> list[list[str]]:
    """The ``$ casmbd …`` command lines written out in the text of ``page`` (continuation
    lines joined), as argument lists."""
    text = (ROOT / page).read_text().replace("\\\n", " ")
    return [shlex.split(line[2:]) for line in text.splitlines() if line.startswith("$ casmbd")]


def _prepare(page: str, code: str) -> None:
    """Run the page's own ``$ casmbd … --out FILE`` commands whose FILE the block reads (the
    tutorial's Python continues from the result its command line saved), in-process."""
    import contextlib
    import io

    from casmbd import cli

    for argv in page_commands(page):
        if "--out" in argv:
            path = argv[argv.index("--out") + 1]
            if f'"{path}"' in code and not pathlib.Path(path).exists():
                pathlib.Path(path).parent.mkdir(parents=True, exist_ok=True)
                with contextlib.redirect_stdout(io.StringIO()):
                    assert cli.main(argv[1:]) == 0, argv


def _run_page(page: str, sandbox: pathlib.Path) -> dict:
    """Execute the Python blocks of ``page`` in one namespace; returns the namespace."""
    namespace: dict = {"__name__": "__main__"}
    for start, code in blocks(page, "python"):
        if skipped(page, code):
            continue
        _prepare(page, code)
        try:
            exec(compile(code, f"{page}:{start}", "exec"), namespace)
        except Exception as exc:
            raise AssertionError(f"{page}, the block at line {start}: "
                                 f"{type(exc).__name__}: {exc}") from exc
    return namespace


PYTHON_PAGES = [p for p in PAGES if blocks(p, "python")]


@pytest.fixture
def registries():
    """The kind registries as they were before the test: docs/extending.md and
    docs/dynamics.md register a joint, a body and a formulation of their own, which must not
    leak into the tests that walk every registered kind."""
    from casmbd.analysis.formulations.base import FORMULATIONS
    from casmbd.analysis.integrators.kinds import INTEGRATORS
    from casmbd.model.registry import BODY_KINDS, FORCE_KINDS, JOINT_KINDS

    saved = [(reg, {k: (dict(v) if isinstance(v, dict) else v) for k, v in reg.items()})
             for reg in (INTEGRATORS, BODY_KINDS, FORCE_KINDS, JOINT_KINDS, FORMULATIONS)]
    yield
    for reg, copy in saved:
        reg.clear()
        reg.update(copy)


def _readme_ocp_is_meaningful(ns: dict) -> None:
    """The README's swing-up: solved, at the reference optimum (hand-written CasADi, degree-3
    collocation, N = 50: 59.03, ocp/double_pendulum_swingup.toml), and the optimal controls
    reproduce the optimal trajectory (measured 4.4e-7; the former snippet, elbow free at the
    start and one control unbounded, "succeeded" at 1.4e-42 with replay_error 8.55)."""
    sol = ns["sol"]
    assert sol.success
    assert sol.objective == pytest.approx(59.03, rel=1e-3)           # measured 59.026
    assert sol.stats["replay_error"] < 1e-4
    assert "replay_warning" not in sol.stats


#: what a page's namespace must hold after its blocks ran (beyond running without error)
CHECKS = {"README.md": _readme_ocp_is_meaningful}


@pytest.mark.parametrize("page", PYTHON_PAGES)
def test_python_snippets_run(page, sandbox, registries):
    with warnings.catch_warnings():
        warnings.simplefilter("error", RuntimeWarning)  # a snippet that warns is a defect
        namespace = _run_page(page, sandbox)
    if page in CHECKS:
        CHECKS[page](namespace)


def test_every_block_is_found():
    """The extraction sees the blocks a reader sees: every ```python fence of the pages is
    one block (none swallowed by an unclosed fence), and the skips name blocks that exist."""
    for page in PAGES:
        text = (ROOT / page).read_text()
        assert len(blocks(page, "python")) == len(re.findall(r"^[ \t]*```python\s*$", text,
                                                             flags=re.M)), page
    for page, fragments in SKIPPED.items():
        codes = [code for _, code in blocks(page, "python")]
        for fragment in fragments:
            assert any(fragment in code for code in codes), (page, fragment)
    assert sum(len(blocks(p, "python")) for p in PAGES) >= 15


def test_a_replay_far_from_the_optimum_warns(sandbox):
    """The README's former OCP snippet (elbow free at the start, the elbow's motor unbounded)
    rides a passive chaotic swing: its replay ends 8.55 from the optimal states, over 1 % of
    their scale (24.3): a RuntimeWarning and ``stats["replay_warning"]``."""
    from math import pi

    import casmbd
    from casmbd.ocp import Ocp

    mech = casmbd.load_scene("ocp/double_pendulum_swingup.toml")
    ocp = Ocp(mech, horizon=2.0, intervals=50)
    ocp.control_bounds("tau1", -50, 50)
    ocp.initial(shoulder=-pi / 2, shoulder_dot=0).final(shoulder=pi / 2, shoulder_dot=0)
    ocp.minimize("effort")
    sol = ocp.solve()
    with pytest.warns(RuntimeWarning, match="replay_error .* exceeds 0.01 × the state scale"):
        sol.replay()
    scale = max(1.0, abs(sol.q).max(), abs(sol.v).max())
    assert sol.stats["replay_error"] > 0.01 * scale                  # measured 8.55 / 24.3
    assert "replay_warning" in sol.stats


COMMANDS = [(p, line, cmd) for p in PAGES for line, cmd in commands(p)]


@pytest.mark.parametrize("page,line,command", COMMANDS,
                         ids=[f"{p}:{n}" for p, n, _ in COMMANDS])
def test_shell_commands_run(page, line, command, sandbox):
    argv = shlex.split(command)
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    done = subprocess.run([sys.executable, "-m", "casmbd", *argv[1:]], cwd=sandbox, env=env,
                          capture_output=True, text=True, timeout=600)
    assert done.returncode == 0, (page, line, command, done.stderr[-2000:])
    if "--json" in argv:
        import json

        json.loads(done.stdout)  # exactly one JSON object on stdout

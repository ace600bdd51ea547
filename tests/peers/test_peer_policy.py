"""The peer policy of tests/peer_policy.py: under ``CASMBD_REQUIRE_PEERS`` (set by .ci/run) a
skipped cross-check fails; without it, it skips.

Each case runs pytest in a subprocess on small test files written here, with a conftest that
imports the policy's hooks as tests/conftest.py does; the counts of the summary line are
compared: a skip of a test of a ``peers`` folder, of a test marked ``peer`` elsewhere, of a
``skipif`` on a peer test, and of a whole ``peers`` module (module-level ``importorskip``) each
fails, with the variable's name and the skip's reason in the report; an unmarked test elsewhere
still skips, an ``xfail`` is left alone, and ``CASMBD_HIDE_PEERS`` hides an installed module.
"""

from __future__ import annotations

import os
import re
import subprocess
import sys
from pathlib import Path

import pytest

TESTS = Path(__file__).resolve().parent.parent
ABSENT = "casmbd_no_such_peer"

FILES = {
    "conftest.py": f"import sys\nsys.path.insert(0, {str(TESTS)!r})\n"
                   "from peer_policy import (pytest_collection_modifyitems, pytest_configure,\n"
                   "    pytest_make_collect_report, pytest_runtest_makereport)\n",
    "peers/test_inside.py": "import pytest\n\n"
                            "def test_needs_a_peer():\n"
                            f"    pytest.importorskip({ABSENT!r})\n\n"
                            "def test_runs():\n    assert True\n\n"
                            "@pytest.mark.skipif(True, reason='no peer here')\n"
                            "def test_skipif():\n    pass\n",
    "peers/test_whole_module.py": f"import pytest\npytest.importorskip({ABSENT!r})\n\n"
                                  "def test_never_collected():\n    pass\n",
    "other/test_marked.py": "import pytest\n\n"
                            "@pytest.mark.peer('pinocchio')\n"
                            "def test_marked():\n"
                            f"    pytest.importorskip({ABSENT!r})\n\n"
                            "def test_unmarked():\n    pytest.skip('not a cross-check')\n\n"
                            "@pytest.mark.peer('pinocchio')\n"
                            "@pytest.mark.xfail(reason='known', strict=True)\n"
                            "def test_xfail():\n    assert False\n",
    "other/test_hidden.py": "import pytest\n\n"
                            "def test_installed():\n    pytest.importorskip('casmbd_fake_peer')\n",
    "casmbd_fake_peer.py": "",  # importable: the conftest's folder is on sys.path
}


@pytest.fixture(scope="module")
def project(tmp_path_factory) -> Path:
    root = tmp_path_factory.mktemp("peer_policy")
    for name, text in FILES.items():
        (root / name).parent.mkdir(parents=True, exist_ok=True)
        (root / name).write_text(text)
    return root


def _run(project: Path, **env: str) -> tuple[dict[str, int], str]:
    environment = {k: v for k, v in os.environ.items()
                   if k not in ("CASMBD_REQUIRE_PEERS", "CASMBD_HIDE_PEERS")}
    environment.update(env)
    out = subprocess.run([sys.executable, "-m", "pytest", "-q", "-rA", "-p", "no:cacheprovider",
                          str(project)], cwd=project, env=environment, capture_output=True,
                         text=True, timeout=120)
    last = out.stdout.strip().splitlines()[-1]
    counts = {word: int(n) for n, word in re.findall(r"(\d+) (\w+)", last)}
    return counts, out.stdout


def test_without_the_variable_a_missing_peer_skips(project):
    counts, text = _run(project)
    # skipped: test_needs_a_peer, test_skipif, the whole module, test_marked, test_unmarked
    assert counts == {"passed": 2, "skipped": 5, "xfailed": 1}, text


def test_in_ci_a_skipped_peer_test_fails(project):
    counts, text = _run(project, CASMBD_REQUIRE_PEERS="1", CASMBD_HIDE_PEERS="casmbd_fake_peer")
    # failed: test_needs_a_peer, the module's stand-in, test_marked; error: test_skipif (setup);
    # skipped: test_unmarked and test_installed (its module hidden; not a peer test)
    assert counts == {"failed": 3, "passed": 1, "skipped": 2, "xfailed": 1, "error": 1}, text
    assert "FAILED peers/test_whole_module.py::peer module skipped" in text
    assert "FAILED other/test_marked.py::test_marked" in text
    assert "ERROR peers/test_inside.py::test_skipif" in text
    assert "SKIPPED [1] other/test_marked.py" in text  # the unmarked one still skips
    assert "could not import 'casmbd_fake_peer'" in text  # hidden, though importable
    # once per report in the ERRORS/FAILURES sections; the short summary may repeat it in full
    # or cut it, depending on the terminal's width (COLUMNS), so it is not counted
    reports = text.split("short test summary info")[0]
    assert reports.count("skipped while CASMBD_REQUIRE_PEERS is set") == 4, text
    assert f"could not import '{ABSENT}'" in text and "no peer here" in text

"""The peer cross-checks' policy: in CI a skipped cross-check is a failure (issue 34, item 6).

A *peer test* compares casmbd with another program (Pinocchio, MuJoCo, Exudyn, the robots of
example-robot-data): every test of ``tests/peers/`` and every test marked
``@pytest.mark.peer("pinocchio", ...)`` (the names of the peers it needs; documentation only)
elsewhere.  Without a peer installed such a test skips, with the reason.  With the
environment variable ``CASMBD_REQUIRE_PEERS`` set to anything but ``""`` or ``"0"`` (``.ci/run``
sets it after installing the ``[peers]`` extra) a skip of a peer test is turned into a
failure naming the test and the skip's reason, so CI cannot report a cross-check it did not
run as passed:

* a skip inside a test, or from a ``skipif`` mark (setup): the test's report becomes a
  failure (an error for a skip in setup);
* a module of ``tests/peers/`` skipped as a whole while it is collected (a module-level
  ``pytest.importorskip``): one failing test ``<module>::peer module skipped`` stands for it.

An expected failure (``xfail``) is not a skip and is left alone.

``CASMBD_HIDE_PEERS=pinocchio,mujoco`` makes the named modules unimportable for the run
(``sys.modules[name] = None``, so ``pytest.importorskip`` skips): the way to see, on a machine
that has the peers, what the suite does without them (``tests/peers/test_peer_policy.py``).

The root ``conftest.py`` imports the hooks of this module (``from peer_policy import …``).
"""

from __future__ import annotations

import os
import sys
from pathlib import Path

import pytest

#: The variable that turns a skipped peer test into a failure.
REQUIRE = "CASMBD_REQUIRE_PEERS"
#: The variable that hides peer modules (comma-separated module names).
HIDE = "CASMBD_HIDE_PEERS"
#: The folder whose every test is a peer test.
PEER_FOLDER = "peers"


def required() -> bool:
    """Whether a skipped peer test fails (``CASMBD_REQUIRE_PEERS`` set, not ``""``/``"0"``)."""
    return os.environ.get(REQUIRE, "").strip() not in ("", "0")


def _in_peer_folder(path: Path) -> bool:
    return Path(path).parent.name == PEER_FOLDER


def _reason(longrepr) -> str:
    """The reason of a skip report (``longrepr`` is ``(file, line, "Skipped: …")``)."""
    if isinstance(longrepr, tuple) and len(longrepr) == 3:
        return str(longrepr[2]).removeprefix("Skipped: ")
    return str(longrepr)


def _message(what: str, reason: str) -> str:
    return (f"{what} skipped while {REQUIRE} is set (a skipped cross-check counts as a "
            f"failure; install the peers: pip install '.[peers]'): {reason}")


def pytest_configure(config) -> None:
    config.addinivalue_line(
        "markers", "peer(*modules): a cross-check against a peer program (the modules it "
        f"needs); its skip fails when {REQUIRE} is set (tests/README.md)")
    for name in os.environ.get(HIDE, "").split(","):
        if name.strip():
            sys.modules[name.strip()] = None  # an import of it raises ImportError


def pytest_collection_modifyitems(config, items) -> None:
    """Every test of ``tests/peers/`` is a peer test."""
    for item in items:
        if _in_peer_folder(item.path) and item.get_closest_marker("peer") is None:
            item.add_marker(pytest.mark.peer())


class PeerModuleSkipped(pytest.Item):
    """Stands for a module of ``tests/peers/`` that skipped as a whole while collected."""

    def __init__(self, *, reason: str, **kwargs):
        super().__init__(**kwargs)
        self.reason = reason

    def runtest(self) -> None:
        raise PeerSkippedError(_message(f"module {self.path.name}", self.reason))

    def repr_failure(self, excinfo, style=None):
        if isinstance(excinfo.value, PeerSkippedError):
            return str(excinfo.value)
        return super().repr_failure(excinfo, style)

    def reportinfo(self):
        return self.path, None, f"{self.path.name}: peer module skipped"


class PeerSkippedError(Exception):
    """A peer test or module skipped while ``CASMBD_REQUIRE_PEERS`` is set."""


@pytest.hookimpl(hookwrapper=True)
def pytest_make_collect_report(collector):
    outcome = yield
    report = outcome.get_result()
    if (report.outcome != "skipped" or not required() or not isinstance(collector, pytest.Module)
            or not _in_peer_folder(collector.path)):
        return
    item = PeerModuleSkipped.from_parent(collector, name="peer module skipped",
                                         reason=_reason(report.longrepr))
    outcome.force_result(pytest.CollectReport(report.nodeid, "passed", None, [item],
                                              sections=report.sections))


@pytest.hookimpl(hookwrapper=True)
def pytest_runtest_makereport(item, call):
    outcome = yield
    report = outcome.get_result()
    if (report.skipped and not hasattr(report, "wasxfail") and required()
            and item.get_closest_marker("peer") is not None):
        report.outcome = "failed"
        report.longrepr = _message(f"peer test {item.nodeid}", _reason(report.longrepr))

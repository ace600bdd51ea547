"""``casmbd bench --quick`` (issue 9): the suite's correctness checks, run through the CLI.

Every check compares an error against an independent reference with a stated bound
(benchmarks/__main__.py, QUICK); timings are printed, never asserted.  Peers that are not
installed are skipped, never failed, and counted as skipped, never as passed — except in CI,
where ``CASMBD_REQUIRE_PEERS`` is set and a skipped peer check fails the test
(tests/peer_policy.py).  Every bound is at most 30× the error measured in the same run
(issue 18).
"""

from __future__ import annotations

import json

import peer_policy

from casmbd import cli

#: a bound more than 30× the error it guards lets a regression of more than an order of
#: magnitude pass (issue 18: the four-bar's was 4 100×)
MAX_RATIO = 30.0


def test_bench_quick_passes_every_check(capsys):
    assert cli.main(["bench", "--quick", "--json"]) == 0
    data = json.loads(capsys.readouterr().out.strip().splitlines()[-1])
    assert data["passed"] is True
    checks = {c["check"]: c for c in data["checks"]}
    assert len(checks) >= 10
    for c in checks.values():
        assert c["status"] in ("ok", "skipped"), c
        if c["status"] == "ok":
            assert c["error"] <= c["bound"], c
            if c["error"] == 0.0:  # an exact (integer) quantity: an exact bound
                assert c["bound"] == 0.0, c
            else:
                assert c["bound"] / c["error"] <= MAX_RATIO, c
        else:  # a skip is no pass: no error measured, the reason given
            assert c["error"] is None and c["message"] == "not installed", c
    # the casmbd checks never skip; in CI (CASMBD_REQUIRE_PEERS) the peer checks neither
    assert all(c["status"] == "ok" for name, c in checks.items() if not name.startswith("peer"))
    if peer_policy.required():
        assert data["skipped"] == 0, [c for c in checks.values() if c["status"] == "skipped"]
    assert data["ok"] == sum(c["status"] == "ok" for c in checks.values())
    assert data["skipped"] == sum(c["status"] == "skipped" for c in checks.values())
    assert data["failed"] == 0 and data["ok"] + data["skipped"] == len(checks)


def test_bench_quick_counts_a_skip_as_a_skip(monkeypatch, capsys):
    """A skipped check (a peer not installed) is reported and counted as skipped, never as
    passed; it does not change the exit status."""
    import benchmarks.__main__ as suite

    monkeypatch.setattr(suite, "QUICK", (("fine", "0.1 ≤ 1", 1.0, lambda: (0.1, 0.0)),
                                         ("absent", "peer", 1.0, lambda: None)))
    assert suite.quick(as_json=True) == 0
    data = json.loads(capsys.readouterr().out)
    assert (data["passed"], data["ok"], data["skipped"], data["failed"]) == (True, 1, 1, 0)
    assert [c["status"] for c in data["checks"]] == ["ok", "skipped"]
    assert suite.quick(as_json=False) == 0
    lines = capsys.readouterr().out.splitlines()
    assert lines[1].startswith("skipped absent")
    assert lines[-1] == "1 of 2 checks passed, 1 skipped, 0 failed"


def test_bench_quick_fails_when_a_bound_is_broken(monkeypatch, capsys):
    """A check whose error exceeds its bound makes the suite (and the verb) fail."""
    import benchmarks.__main__ as suite

    monkeypatch.setattr(suite, "QUICK", (("broken", "always 1 > 0.5", 0.5,
                                          lambda: (1.0, 0.0)),))
    assert suite.quick(as_json=True) == 1
    data = json.loads(capsys.readouterr().out)
    assert (data["passed"], data["ok"], data["skipped"], data["failed"]) == (False, 0, 0, 1)

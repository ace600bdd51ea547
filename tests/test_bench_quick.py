"""``casmbd bench --quick`` (issue 9): the suite's correctness checks, run through the CLI.

Every check compares an error against an independent reference with a stated bound
(benchmarks/__main__.py, QUICK); timings are printed, never asserted.  Peers that are not
installed are skipped, never failed.
"""

from __future__ import annotations

import json

from casmbd import cli


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
    # the casmbd checks never skip
    assert all(c["status"] == "ok" for name, c in checks.items() if not name.startswith("peer"))


def test_bench_quick_fails_when_a_bound_is_broken(monkeypatch, capsys):
    """A check whose error exceeds its bound makes the suite (and the verb) fail."""
    import benchmarks.__main__ as suite

    monkeypatch.setattr(suite, "QUICK", (("broken", "always 1 > 0.5", 0.5,
                                          lambda: (1.0, 0.0)),))
    assert suite.quick(as_json=True) == 1
    assert json.loads(capsys.readouterr().out)["passed"] is False

"""The default ``dynamics="auto"`` of an optimal-control problem (issue 22 item 4,
casmbd/ocp/dynamics.py ``choose_dynamics``) and the Radau transcription with explicit
dynamics, whose last collocation state is the next mesh node (casmbd/ocp/transcription.py):
the choice and its reason per mechanism, the same NLP optimum as the implicit form with q̈ as
variables, and the sizes of both NLPs counted by hand."""

from __future__ import annotations

import json
import pathlib
import re

import numpy as np
import pytest

from casmbd.errors import AnalysisError
from casmbd.io.ocp_table import load_ocp
from casmbd.ocp.dynamics import AUTO_EXPLICIT_INSTRUCTIONS
from casmbd.ocp.transcription import Transcription

OCP = pathlib.Path(__file__).resolve().parents[2] / "ocp"


@pytest.fixture(autouse=True)
def _cache(tmp_path_factory, monkeypatch):
    monkeypatch.setenv("CASMBD_CACHE_DIR", str(tmp_path_factory.getbasetemp() / "cache_dyn"))


@pytest.mark.parametrize(("name", "explicit", "reason"), [
    ("cart_pole", True, r"auto: explicit, no constraint equations .*: \d+ <= 1000"),
    ("double_pendulum_min_time", True, r"auto: explicit"),
    ("slider_crank_cycle", False, r"auto: implicit, the mechanism has 2 constraint"),
    ("ur5_min_time", False, r"auto: implicit, large equations of motion .*: \d+ > 1000"),
])
def test_auto_dynamics_choice_and_reason(name, explicit, reason):
    """``dynamics="auto"`` (the default, also of a scene without the key) substitutes q̈ for
    the small trees and keeps q̈ as variables for a closed loop and for the UR5, whose
    equations of motion exceed :data:`AUTO_EXPLICIT_INSTRUCTIONS`; an explicit choice wins
    and is reported as given."""
    ocp = load_ocp(OCP / f"{name}.toml")
    assert ocp.dynamics == "auto" and AUTO_EXPLICIT_INSTRUCTIONS == 1000
    tr = Transcription(ocp)
    assert tr.explicit is explicit
    assert tr.dynamics_choice.startswith("auto:")
    assert re.search(reason, tr.dynamics_choice), tr.dynamics_choice
    ocp.dynamics = "implicit"
    given = Transcription(ocp)
    assert not given.explicit and given.dynamics_choice == "given"


@pytest.mark.parametrize(("name", "transcription"), [("cart_pole", "radau"),
                                                     ("crane_transfer", "radau"),
                                                     ("cart_pole", "legendre")])
def test_auto_and_implicit_reach_the_same_optimum(name, transcription):
    """The explicit NLP chosen by ``"auto"`` (q̈ substituted; on Radau points the last
    collocation state is the next mesh node, and path constraints are not repeated there) and
    the implicit one (q̈ as variables, continuity rows) are the same discrete problem: the same
    optimum to 1e-6 relative (measured ≤ 1e-13) and the same controls to 1e-6 (measured
    ≤ 1e-10; the crane's hinge angle path constraint included). Sizes counted by hand:
    nq·d·M acceleration variables and rows fewer and, on Radau points, 2 nq·M state variables
    and continuity rows fewer, and the crane's path constraint (independent of the control)
    not repeated at the M mesh nodes that end an element."""
    sols = {}
    for dynamics in ("auto", "implicit"):
        ocp = load_ocp(OCP / f"{name}.toml")
        ocp.compile, ocp.intervals, ocp.degree = False, 12, 3
        ocp.transcription, ocp.dynamics = transcription, dynamics
        sols[dynamics] = ocp.solve()
    auto, imp = sols["auto"], sols["implicit"]
    assert auto.stats["dynamics"] == "explicit" and imp.stats["dynamics"] == "implicit"
    assert auto.stats["dynamics_choice"].startswith("auto: explicit")
    assert imp.stats["dynamics_choice"] == "given"
    assert abs(auto.objective - imp.objective) <= 1e-6 * abs(imp.objective)
    np.testing.assert_allclose(auto.u, imp.u, rtol=0, atol=1e-6)
    np.testing.assert_allclose(auto.q, imp.q, rtol=0, atol=1e-6)
    nq, d, m = 2, 3, 12
    shared = 2 * nq * m if transcription == "radau" else 0
    assert imp.stats["variables"] - auto.stats["variables"] == nq * d * m + shared
    repeated = m if (name == "crane_transfer" and shared) else 0  # one path row per node
    assert imp.stats["constraints"] - auto.stats["constraints"] == nq * d * m + shared \
        + repeated
    assert auto.to_json()["stats"]["dynamics_choice"] == auto.stats["dynamics_choice"]


def test_explicit_dynamics_refused_for_a_closed_loop_and_unknown_names():
    """A closed loop refuses ``"explicit"`` naming its constraint equations (also for
    multiple shooting); an unknown name lists the accepted ones."""
    loop = load_ocp(OCP / "slider_crank_cycle.toml")
    loop.compile, loop.intervals, loop.dynamics = False, 4, "explicit"
    with pytest.raises(AnalysisError, match=r"explicit.*has 2"):
        Transcription(loop)
    with pytest.raises(AnalysisError, match=r"dynamics must be one of auto, implicit, "
                                            r"explicit.*'ode'"):
        type(loop)(loop.system, dynamics="ode")


def test_cli_reports_the_dynamics_and_why(capsys):
    """``casmbd ocp`` prints the dynamics used and the reason of the choice; ``--json`` has
    both in its stats (the cart-pole: explicit, small equations of motion)."""
    from casmbd import cli

    scene = str(OCP / "cart_pole.toml")
    assert cli.main(["ocp", scene, "--intervals", "6", "--no-replay"]) == 0
    text = capsys.readouterr().out
    assert re.search(r"dynamics explicit \(auto: explicit, no constraint equations", text), text
    assert cli.main(["ocp", scene, "--intervals", "6", "--no-replay", "--json"]) == 0
    stats = json.loads(capsys.readouterr().out)["stats"]
    assert stats["dynamics"] == "explicit" and stats["dynamics_choice"].startswith("auto:")


def test_multiple_shooting_reports_explicit_dynamics():
    """Multiple shooting integrates q̈ = f(q, q̇, u, t) whatever ``dynamics`` says: reported
    as explicit, with that reason; the RK4 optimum of the cart-pole equals collocation's to
    the discretisation error (1e-4 relative at N = 12; measured 4.1e-6)."""
    ocp = load_ocp(OCP / "cart_pole.toml")
    ocp.compile, ocp.intervals = False, 12
    colloc = ocp.solve()
    ocp.transcription, ocp.integrator, ocp.steps = "multiple_shooting", "rk4", 4
    sol = ocp.solve()
    assert sol.stats["dynamics"] == "explicit"
    assert sol.stats["dynamics_choice"].startswith("multiple shooting integrates")
    assert abs(sol.objective - colloc.objective) < 1e-4 * colloc.objective

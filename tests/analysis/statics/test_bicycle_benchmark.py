"""The Whipple bicycle of Meijaard, Papadopoulos, Ruina & Schwab (Proc. R. Soc. A 463 (2007)
1955–1982) from examples/bicycle.toml, linearized about straight upright rolling by
``linearize --steady-motion``: the eigenvalues against the paper's Table 2 (b, c) at 0–10 m/s,
the weave and capsize speeds against Table 2 (a), both to 1e-10, and an independent check
against the paper's printed matrices M, C1, K0, K2 (eq. 5.4 of the paper: the eigenvalues of
M s² + v C1 s + g K0 + v² K2)."""

from pathlib import Path

import numpy as np
import pytest

from casmbd.analysis.statics.steady_motion import SteadyMotion, parameter_root, root_locus
from casmbd.errors import AnalysisError
from casmbd.io.scene import load_scene

SCENE = Path(__file__).resolve().parents[3] / "examples" / "bicycle.toml"
TOL = 1e-10

#: Table 2 (b, c) of the paper: v -> eigenvalues (capsize, the weave pair, castering; at v = 0
#: the two pairs of real eigenvalues)
TABLE2 = {
    0: [3.13164324790656, -3.13164324790656, 5.53094371765393, -5.53094371765393],
    1: [-3.13423125066578, 3.52696170990070 + 0.80774027519930j,
        3.52696170990070 - 0.80774027519930j, -7.11008014637442],
    2: [-3.07158645641514, 2.68234517512745 + 1.68066296590675j,
        2.68234517512745 - 1.68066296590675j, -8.67387984831735],
    3: [-2.63366137253667, 1.70675605663975 + 2.31582447384325j,
        1.70675605663975 - 2.31582447384325j, -10.35101467245920],
    4: [-1.42944427361326, 0.41325331521125 + 3.07910818603206j,
        0.41325331521125 - 3.07910818603206j, -12.15861426576450],
    5: [-0.32286642900409, -0.77534188219585 + 4.46486771378823j,
        -0.77534188219585 - 4.46486771378823j, -14.07838969279820],
    6: [-0.00406690076970, -1.52644486584142 + 5.87673060598709j,
        -1.52644486584142 - 5.87673060598709j, -16.08537123098030],
    7: [0.10268170574766, -2.13875644258362 + 7.19525913329805j,
        -2.13875644258362 - 7.19525913329805j, -18.15788466125262],
    8: [0.14327879765713, -2.69348683581097 + 8.46037971396931j,
        -2.69348683581097 - 8.46037971396931j, -20.27940894394569],
    9: [0.15790184030917, -3.21675402252485 + 9.69377351531791j,
        -3.21675402252485 - 9.69377351531791j, -22.43788559040858],
    10: [0.16105338653172, -3.72016840437287 + 10.90681139476287j,
         -3.72016840437287 - 10.90681139476287j, -24.62459635017404],
}
#: Table 2 (a): the speed at which the weave pair leaves the real axis (there the double
#: eigenvalue 3.78290405129320), the weave and capsize speeds
BIFURCATION_SPEED, BIFURCATION_EIGENVALUE = 0.68428307889246, 3.78290405129320
WEAVE_SPEED = 4.29238253634111
CAPSIZE_SPEED = 6.02426201538837

#: eq. (5.4) of the paper: the benchmark's matrices as printed (to 1e-14)
M = np.array([[80.81722, 2.31941332208709], [2.31941332208709, 0.29784188199686]])
C1 = np.array([[0.0, 33.86641391492494], [-0.85035641456978, 1.68540397397560]])
K0 = np.array([[-80.95, -2.59951685249872], [-2.59951685249872, -0.80329488458618]])
K2 = np.array([[0.0, 76.59734589573222], [0.0, 2.65431523794604]])


def _paper_eigenvalues(v: float, g: float = 9.81) -> np.ndarray:
    a = np.block([[np.zeros((2, 2)), np.eye(2)],
                  [-np.linalg.solve(M, g * K0 + v * v * K2), -np.linalg.solve(M, v * C1)]])
    return np.linalg.eigvals(a)


def _deviation(got, want) -> float:
    """Largest distance between two sets of eigenvalues, matched one to one (nearest)."""
    got, want = list(np.asarray(got, complex)), list(np.asarray(want, complex))
    assert len(got) == len(want)
    worst = 0.0
    for w in want:
        k = int(np.argmin([abs(g - w) for g in got]))
        worst = max(worst, abs(got.pop(k) - w))
    return worst


def _weave(e: np.ndarray) -> float:
    return float(np.max(e[np.abs(e.imag) > 1e-9].real))


def _capsize(e: np.ndarray) -> float:
    real = e[np.abs(e.imag) <= 1e-9].real
    return float(real[np.argmin(np.abs(real))])


@pytest.fixture(scope="module")
def bicycle():
    lin = SteadyMotion(load_scene(SCENE), mode="vm")
    base = lin()  # the scene: v = 4 m/s
    return lin, base, base.v / 4.0


def test_the_reduction(bicycle):
    """Position on the plane and the spins are cyclic, the heading and the speed are the
    symmetries; four eigenvalues remain, named by roll and steer."""
    _, base, _ = bicycle
    assert base.cyclic == ["x.translation", "y.translation", "rear_axle.angle",
                           "front_axle.angle"]
    assert base.symmetries == ["yaw.angle", "speed"]
    assert base.stats["tangent_dimension"] == 10 and base.stats["reduced_dimension"] == 4
    assert base.stats["invariance_residual"] < 1e-12
    assert {m["coordinate"] for m in base.modes} <= {"roll.angle", "steer.angle"}
    castering = min(base.modes, key=lambda m: m["eigenvalue"][0])
    assert castering["coordinate"] == "steer.angle"


@pytest.mark.parametrize("speed", sorted(TABLE2))
def test_table2_eigenvalues(bicycle, speed):
    """Table 2 of the paper to 1e-10 (measured: ≤ 4e-13)."""
    lin, _, v1 = bicycle
    assert _deviation(lin(v=speed * v1).eigenvalues, TABLE2[speed]) <= TOL


def test_printed_matrices(bicycle):
    """The eigenvalues of the paper's M, C1, K0, K2 at 0 to 10 m/s in steps of 0.25 m/s."""
    lin, _, v1 = bicycle
    speeds = np.arange(0.0, 10.0001, 0.25)
    locus = root_locus(lin, speeds, state=lambda s: (None, s * v1))
    assert max(_deviation(row, _paper_eigenvalues(s)) for s, row in zip(speeds, locus)) <= TOL


def test_weave_and_capsize_speeds(bicycle):
    """Table 2 (a) to 1e-10, by Brent's method on the exact eigenvalues."""
    lin, _, v1 = bicycle

    def evaluate(s):
        return lin(v=s * v1).eigenvalues

    assert abs(parameter_root(evaluate, 3.0, 5.0, _weave) - WEAVE_SPEED) <= TOL
    assert abs(parameter_root(evaluate, 5.5, 6.5, _capsize) - CAPSIZE_SPEED) <= TOL


def test_bifurcation_speed(bicycle):
    """Table 2 (a): where the two largest real eigenvalues meet, (s₁ − s₂)² = 0 (analytic in
    the matrix, so accurate at the double root, where each eigenvalue is not)."""
    lin, _, v1 = bicycle

    def discriminant(e):
        top = e[np.argsort(-e.real)[:2]]
        return float(((top[0] - top[1]) ** 2).real)

    v_d = parameter_root(lambda s: lin(v=s * v1).eigenvalues, 0.3, 1.0, discriminant)
    assert abs(v_d - BIFURCATION_SPEED) <= TOL
    top = np.sort(lin(v=v_d * v1).eigenvalues.real)[-2:]
    assert np.all(np.abs(top - BIFURCATION_EIGENVALUE) <= 1e-6)  # a double root: √eps


def test_scene_speed_parameter(tmp_path):
    """The scene file itself at v = 6 m/s (its initial velocities from the parameter v)."""
    text = SCENE.read_text().replace("v = 4.0 ", "v = 6.0 ", 1)
    assert "v = 6.0 " in text
    path = tmp_path / "bicycle_6.toml"
    path.write_text(text)
    lin = SteadyMotion(load_scene(path), mode="vm")
    assert _deviation(lin().eigenvalues, TABLE2[6]) <= TOL


def test_not_a_steady_motion(bicycle):
    """A roll rate: refused, naming the coordinate and its rate."""
    lin, base, _ = bicycle
    v = base.v.copy()
    v[base.coordinate_names.index("roll.angle")] = 0.1
    with pytest.raises(AnalysisError, match=r"roll\.angle' moves \(rate"):
        lin(q=base.q, v=v)

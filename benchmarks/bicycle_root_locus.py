"""The benchmark bicycle's root locus (examples/bicycle.toml; Meijaard, Papadopoulos, Ruina &
Schwab, Proc. R. Soc. A 463 (2007), Fig. 3 and Table 2): the figure of docs/rolling.md.

``python -m benchmarks.bicycle_root_locus`` (a few seconds, CasADi's VM)

* linearises the bicycle about straight upright rolling at 0–10 m/s
  (:mod:`casmbd.analysis.statics.steady_motion`: position on the plane and the spins cyclic,
  heading and speed removed as symmetries) and prints the largest distance of the eigenvalues
  from the paper's Table 2 (b, c) and from the eigenvalues of the paper's printed matrices
  M, C1, K0, K2 (eq. 5.4);
* finds the weave and capsize speeds by Brent's method on the eigenvalues and prints their
  distance from Table 2 (a);
* draws ``docs/figures/bicycle_root_locus.png``: real and imaginary parts against the speed,
  the Table 2 values as markers, the self-stable range shaded.
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT / "tests" / "analysis" / "statics"))
from test_bicycle_benchmark import (  # noqa: E402
    CAPSIZE_SPEED,
    TABLE2,
    WEAVE_SPEED,
    _capsize,
    _deviation,
    _paper_eigenvalues,
    _weave,
)

from casmbd.analysis.statics.steady_motion import (  # noqa: E402
    SteadyMotion,
    parameter_root,
    root_locus,
)
from casmbd.io.scene import load_scene  # noqa: E402

SPEEDS = np.linspace(0.0, 10.0, 401)


def main(figure: Path = ROOT / "docs" / "figures" / "bicycle_root_locus.png") -> dict:
    lin = SteadyMotion(load_scene(ROOT / "examples" / "bicycle.toml"), mode="vm")
    v1 = lin().v / 4.0  # the scene rolls at 4 m/s; straight rolling scales with the speed

    def state(s):
        return None, s * v1

    table = max(_deviation(lin(v=s * v1).eigenvalues, want) for s, want in TABLE2.items())
    locus = root_locus(lin, SPEEDS, state=state)
    matrices = max(_deviation(row, _paper_eigenvalues(s)) for s, row in zip(SPEEDS, locus))
    v_w = parameter_root(lambda s: lin(v=s * v1).eigenvalues, 3.0, 5.0, _weave)
    v_c = parameter_root(lambda s: lin(v=s * v1).eigenvalues, 5.5, 6.5, _capsize)
    out = {"table2_max_deviation": table, "matrices_max_deviation": matrices,
           "weave_speed": v_w, "weave_speed_deviation": abs(v_w - WEAVE_SPEED),
           "capsize_speed": v_c, "capsize_speed_deviation": abs(v_c - CAPSIZE_SPEED)}
    for key, val in out.items():
        print(f"{key:26s} {val:.16g}")
    _draw(locus, v_w, v_c, figure)
    results = ROOT / "benchmarks" / "results" / "bicycle_root_locus.json"
    results.write_text(json.dumps({**out, "command": "python -m benchmarks.bicycle_root_locus",
                                   "speeds": len(SPEEDS)}, indent=1) + "\n")
    print(f"wrote {results}")
    return out


def _draw(locus: np.ndarray, v_w: float, v_c: float, figure: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(7.0, 4.6))
    ax.axvspan(v_w, v_c, color="0.9", label=f"self-stable {v_w:.4f}–{v_c:.4f} m/s")
    speeds = np.repeat(SPEEDS[:, None], locus.shape[1], axis=1)
    ax.plot(speeds.ravel(), locus.real.ravel(), ".", ms=2.0, color="k",
            label="Re s (casmbd, steady motion)")
    imag = np.abs(locus.imag) > 1e-9
    ax.plot(speeds[imag], np.abs(locus.imag[imag]), ".", ms=2.0, color="tab:blue",
            label="|Im s|")
    for k, (s, want) in enumerate(TABLE2.items()):
        want = np.asarray(want, complex)
        ax.plot([s] * len(want), want.real, "o", mfc="none", color="tab:red", ms=6,
                label="Table 2 (Meijaard et al. 2007)" if k == 0 else None)
        pos = want.imag > 0
        ax.plot([s] * int(pos.sum()), want.imag[pos], "o", mfc="none", color="tab:red", ms=6)
    ax.axhline(0.0, color="0.5", lw=0.6)
    ax.set_xlim(0, 10)
    ax.set_ylim(-10, 10)
    ax.set_xlabel("forward speed v [m/s]")
    ax.set_ylabel("eigenvalue s [1/s]")
    ax.set_title("Benchmark bicycle, examples/bicycle.toml: linearize --steady-motion")
    ax.legend(loc="lower left", fontsize=8)
    fig.tight_layout()
    figure.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(figure, dpi=130)
    plt.close(fig)
    print(f"wrote {figure}")


if __name__ == "__main__":
    main()

"""The spin-up beam of ``examples/spinup_beam.toml`` (issue 23): tip deflection and the beam.

Runs the scene from the command line as the page shows it::

    casmbd simulate examples/spinup_beam.toml --t-end 20 --steps 400 --out spinup.npz

and the same scene with ``stiffening = false`` (the linear floating-frame formulation), then
draws ``docs/figures/flexible_spinup.png``: left, the tip deflection in the hub frame
v_tip = (Aᵀ (r_tip − R))_y against time (r_tip the node marker ``beam@tip``, R and A the
frame of the beam); with ``--reference`` also the co-rotational (geometrically exact) beam of
``tests/flexible_references.py`` (same mesh, rtol 1e-7, about 15 s); right, the beam at the
largest deflection with earlier poses faded and the tip path, elastic displacements magnified
(the factor is printed on the picture).

Run from the repository root::

    python examples/spinup_beam.py [--reference]
"""

from __future__ import annotations

import argparse
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

import casmbd
from casmbd import cli
from casmbd.viz.animation import draw_frame
from casmbd.viz.plots import new_figure, save_figure

ROOT = Path(__file__).resolve().parent.parent
SCENE = ROOT / "examples" / "spinup_beam.toml"
OUT = ROOT / "docs" / "figures" / "flexible_spinup.png"
T_END, STEPS = 20.0, 400
#: magnification of the elastic displacements in the picture of the beam
SCALE = 3.0


def tip_deflection(result) -> np.ndarray:
    """v_tip = −sin θ (x_tip − x_R) + cos θ (y_tip − y_R): the tip's displacement across the
    hub frame (θ and R the beam frame's angle and origin from q)."""
    names = result.names["coordinates"]
    q = result.arrays["q"]
    x, y, th = (q[:, names.index(f"beam.{c}")] for c in ("x", "y", "angle"))
    tip = result.marker("beam@tip")["position"]
    return -np.sin(th) * (tip[:, 0] - x) + np.cos(th) * (tip[:, 1] - y)


def simulate(scene: Path, folder: Path) -> tuple[casmbd.Result, float]:
    """``casmbd simulate SCENE --t-end 20 --steps 400 --out FILE`` and its result."""
    npz = folder / f"{scene.stem}.npz"
    started = time.perf_counter()
    status = cli.main(["simulate", str(scene), "--t-end", str(T_END), "--steps", str(STEPS),
                       "--out", str(npz)])
    if status != 0:
        raise SystemExit(f"casmbd simulate {scene} failed")
    return casmbd.load_result(npz), time.perf_counter() - started


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--reference", action="store_true",
                        help="also the co-rotational beam of tests/flexible_references.py")
    args = parser.parse_args(argv)
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        stiff, wall = simulate(SCENE, folder)
        linear_scene = folder / "spinup_beam_linear.toml"
        text = SCENE.read_text()
        if "stiffening = true" not in text:
            raise SystemExit(f"{SCENE}: expected 'stiffening = true'")
        linear_scene.write_text(text.replace("stiffening = true", "stiffening = false"))
        linear, wall_linear = simulate(linear_scene, folder)
    v_stiff, v_linear = tip_deflection(stiff), tip_deflection(linear)
    print(f"stiffened: peak tip deflection {v_stiff.min():+.4f} m at "
          f"{stiff.t[np.argmin(v_stiff)]:.2f} s, |v| after Ts = 15 s <= "
          f"{np.abs(v_stiff[stiff.t >= 15.0]).max() * 1e3:.2f} mm ({wall:.1f} s wall)")
    over = np.flatnonzero(np.abs(v_linear) > 10.0)
    print(f"linear: |tip| passes L = 10 m at t = "
          f"{linear.t[over[0]] if over.size else float('nan'):.2f} s ({wall_linear:.1f} s wall)")

    fig, (left, right) = new_figure(ncols=2, figsize=(10.0, 4.2))
    shown = np.abs(v_linear) <= 2.0
    first_out = np.flatnonzero(~shown)
    end = first_out[0] if first_out.size else len(shown)
    left.plot(linear.t[:end], v_linear[:end], color="tab:red", lw=1.2, ls="--",
              label="casmbd, stiffening = false (diverges)")
    if args.reference:
        sys.path.insert(0, str(ROOT))
        from tests.flexible_references import corotational_spinup

        started = time.perf_counter()
        ref = corotational_spinup(6.0, elements=10, t_end=T_END, n_out=STEPS + 1, rtol=1e-7)
        print(f"co-rotational reference: peak {ref.tip.min():+.4f} m at "
              f"{ref.t[np.argmin(ref.tip)]:.2f} s ({time.perf_counter() - started:.0f} s); "
              f"casmbd stiffened - reference: max "
              f"{np.abs(np.interp(ref.t, stiff.t, v_stiff) - ref.tip).max() * 1e3:.1f} mm")
        left.plot(ref.t, ref.tip, color="0.2", lw=3.0, alpha=0.35,
                  label="co-rotational beam (reference)")
    left.plot(stiff.t, v_stiff, color="tab:blue", lw=1.4,
              label="casmbd, stiffening = true")
    left.axvline(15.0, color="0.6", lw=0.8, ls=":")
    left.set_ylim(-1.0, 0.6)
    left.set_xlabel("t [s]")
    left.set_ylabel("tip deflection in the hub frame [m]")
    left.set_title("spin-up to Ω = 6 rad/s (Ts = 15 s)", fontsize=10)
    left.legend(fontsize=8, loc="lower right")
    k = int(np.argmin(v_stiff))
    draw_frame(stiff, index=k, ghosts=6, trace="beam@tip", ax=right, deformation_scale=SCALE,
               title=f"beam at the largest deflection (t = {stiff.t[k]:.2f} s)")
    save_figure(fig, OUT, 100)
    print(f"saved {OUT.relative_to(ROOT)}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())

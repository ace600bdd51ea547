"""Figures of docs/contact.md (issue 24): the bouncing ball, the pendulum on its stop and the
compliant contact, each against its closed form or a hand-written ODE.

Runs the example scenes as the page shows them (``casmbd simulate … --out FILE``) and draws

* ``docs/figures/contact_ball.png`` — ``examples/bouncing_ball.toml``: height of the ball's
  lowest point against time with the impact events, and the apex heights of the flights
  (y − r + v_y²/2g at every sample) against e^(2k) h0;
* ``docs/figures/contact_stop.png`` — ``examples/pendulum_stops.toml``: joint angle against
  time with the stop and the impacts (solve_ivp with events as reference), and the stop's
  torque reaching m g L/2 cos(1) once the rod rests;
* ``docs/figures/contact_compliant.png`` — the ball with ``model = "compliant"``: penetration
  history against solve_ivp of m ÿ = −m g + F_n, and the force–penetration loop (damping).

Run from the repository root::

    python examples/contact_figures.py
"""

from __future__ import annotations

import math
import tempfile
from pathlib import Path

import numpy as np
from scipy.integrate import solve_ivp

import casmbd
from casmbd import cli
from casmbd.viz.plots import new_figure, save_figure

ROOT = Path(__file__).resolve().parent.parent
BALL = ROOT / "examples" / "bouncing_ball.toml"
STOPS = ROOT / "examples" / "pendulum_stops.toml"
FIGURES = ROOT / "docs" / "figures"
G = 9.81
COMPLIANT = {"stiffness": 1e6, "exponent": 1.5, "damping": 50.0, "penetration": 1e-3}


def run(scene: Path, folder: Path, t_end: float, steps: int, rtol: float) -> casmbd.Result:
    """``casmbd simulate SCENE --t-end T --steps N --rtol R --out FILE`` and its result."""
    npz = folder / f"{scene.stem}.npz"
    status = cli.main(["simulate", str(scene), "--t-end", str(t_end), "--steps", str(steps),
                       "--rtol", str(rtol), "--out", str(npz)])
    if status != 0:
        raise SystemExit(f"casmbd simulate {scene} failed")
    return casmbd.load_result(npz)


def ball_figure(folder: Path) -> None:
    res = run(BALL, folder, 5.0, 1000, 1e-12)
    e, h0, r = 0.8, 1.0, 0.1
    body = res.body("ball")
    y, vy = body["position"][:, 1], body["velocity"][:, 1]
    impacts = np.array([ev["time"] for ev in res.events if ev["kind"] == "impact"])
    rest = next(ev["time"] for ev in res.events if ev["kind"] == "contact")
    t1 = math.sqrt(2 * h0 / G)
    closed = t1 + np.concatenate([[0.0], np.cumsum(2 * t1 * e ** np.arange(1, len(impacts))
                                                   )])
    print(f"ball: {len(impacts)} impacts, |t_k - closed form| max "
          f"{np.abs(impacts - closed).max():.2g} s (first 20: "
          f"{np.abs(impacts - closed)[:20].max():.2g} s); rest at {rest:.6f} s (Zeno point "
          f"{t1 * (1 + e) / (1 - e):.6f} s); resting force "
          f"{res.arrays['contact_forces'][-1, 0]:.6g} N")
    fig, (left, right) = new_figure(ncols=2, figsize=(10.0, 3.8))
    left.plot(res.t, y - r, color="tab:blue", lw=1.0, label="casmbd (events, e = 0.8)")
    left.plot(impacts, np.zeros_like(impacts), "v", color="tab:red", ms=4,
              label="impact events")
    left.axvline(rest, color="0.5", lw=0.8, ls=":", label=f"rest (contact) {rest:.4f} s")
    left.set_xlabel("t [s]")
    left.set_ylabel("height of the lowest point [m]")
    left.set_title("bouncing ball: examples/bouncing_ball.toml", fontsize=10)
    left.legend(fontsize=8)
    k = np.searchsorted(impacts, res.t)
    flying = res.t < rest
    apex = y - r + vy ** 2 / (2 * G)
    err = np.abs(apex - e ** (2 * k) * h0)[flying].max()
    kk = np.unique(k[flying])
    right.semilogy(kk, [apex[flying & (k == j)].mean() for j in kk], "o", ms=4,
                   color="tab:blue", label="casmbd: y − r + v²/2g in each flight")
    right.semilogy(kk, e ** (2 * kk) * h0, "-", color="0.3", lw=0.8,
                   label=f"e^(2k) h0 (max difference {err:.1g} m)")
    right.set_xlabel("flight k (after k impacts)")
    right.set_ylabel("apex height [m]")
    right.set_title("apex heights", fontsize=10)
    right.legend(fontsize=8)
    save_figure(fig, FIGURES / "contact_ball.png", 100)


def stop_reference(t_end: float, e: float, theta_s: float, alpha: float):
    """θ'' = −α cos θ from rest at θ = 0 onto the stop (solve_ivp with events)."""
    def rhs(t, y):
        return [y[1], -alpha * math.cos(y[0])]

    def hit(t, y):
        return y[0] - theta_s
    hit.terminal, hit.direction = True, -1
    t, y, ts, th, hits = 0.0, [0.0, 0.0], [], [], []
    while t < t_end and (not hits or abs(y[1]) > 1e-3):
        step = 0.2 * abs(y[1]) / (alpha * math.cos(theta_s)) if y[1] else 0.01
        sol = solve_ivp(rhs, (t, t_end), y, events=hit, rtol=1e-12, atol=1e-12,
                        method="DOP853", max_step=min(step, 0.01))
        ts.append(sol.t)
        th.append(sol.y[0])
        if sol.status != 1:
            break
        t = float(sol.t_events[0][0])
        hits.append(t)
        y = [theta_s, -e * float(sol.y_events[0][0][1])]
    return np.concatenate(ts), np.concatenate(th), np.array(hits)


def stop_figure(folder: Path) -> None:
    res = run(STOPS, folder, 2.0, 800, 1e-12)
    m, length, e, theta_s = 1.0, 1.0, 0.5, -1.0
    alpha = m * G * length / 2 / (m * length ** 2 / 3)
    theta = res.joint("pin")["coordinate"]
    impacts = np.array([ev["time"] for ev in res.events if ev["kind"] == "limit"])
    rest = next(ev["time"] for ev in res.events if ev["kind"] == "contact")
    t_ref, th_ref, hits = stop_reference(2.0, e, theta_s, alpha)
    n = len(hits)
    torque = res.arrays["contact_forces"][:, res.names["contacts"].index("pin.limit.lower")]
    print(f"stop: {len(impacts)} impacts, first {n} vs solve_ivp max "
          f"{np.abs(impacts[:n] - hits).max():.2g} s; rest at {rest:.6f} s; stop torque "
          f"{torque[-1]:.6f} N m (m g L/2 cos 1 = {m * G * length / 2 * math.cos(1):.6f})")
    fig, (left, right) = new_figure(ncols=2, figsize=(10.0, 3.8))
    left.plot(t_ref, th_ref, color="0.2", lw=3.0, alpha=0.3, label="solve_ivp with events")
    left.plot(res.t, theta, color="tab:blue", lw=1.0, label="casmbd (e = 0.5)")
    left.plot(impacts, np.full_like(impacts, theta_s), "^", color="tab:red", ms=4,
              label="limit events")
    left.axhline(theta_s, color="k", lw=0.8, ls="--", label="stop, lower = −1 rad")
    left.set_xlabel("t [s]")
    left.set_ylabel("joint angle [rad]")
    left.set_title("pendulum on a stop: examples/pendulum_stops.toml", fontsize=10)
    left.legend(fontsize=8, loc="upper right")
    right.plot(res.t, torque, color="tab:blue", lw=1.0, label="casmbd: stop torque")
    right.axhline(m * G * length / 2 * math.cos(1), color="0.3", lw=0.8, ls="--",
                  label="m g L/2 cos(1) = 2.650 N m")
    right.set_xlabel("t [s]")
    right.set_ylabel("stop torque [N m]")
    right.set_title("resting on the stop (closed gap)", fontsize=10)
    right.legend(fontsize=8, loc="center right")
    save_figure(fig, FIGURES / "contact_stop.png", 100)


def compliant_figure(folder: Path) -> None:
    scene = folder / "ball_compliant.toml"
    keys = "".join(f"\n{k} = {v}" for k, v in COMPLIANT.items())
    scene.write_text(BALL.read_text().replace('model = "impact"', f'model = "compliant"{keys}'))
    res = run(scene, folder, 0.6, 6000, 1e-10)
    m, r = 1.0, 0.1
    k_, ex, c, d = (COMPLIANT[k] for k in ("stiffness", "exponent", "damping", "penetration"))

    def force(delta, rate):
        x = np.clip(delta / d, 0.0, 1.0)
        return np.where(delta > 0, np.maximum(k_ * np.maximum(delta, 0) ** ex
                                              + c * x * x * (3 - 2 * x) * rate, 0.0), 0.0)

    def rhs(t, s):
        return [s[1], -G + float(force(r - s[0], -s[1])) / m]

    ref = solve_ivp(rhs, (0.0, 0.6), [1.1, 0.0], t_eval=res.t, rtol=1e-12, atol=1e-14,
                    method="DOP853", max_step=1e-4)
    body = res.body("ball")
    y, vy = body["position"][:, 1], body["velocity"][:, 1]
    pen, pen_ref = np.maximum(r - y, 0.0), np.maximum(r - ref.y[0], 0.0)
    print(f"compliant: max penetration {pen.max() * 1e3:.4f} mm, max |casmbd - ODE| "
          f"{np.abs(pen - pen_ref).max():.2g} m (penetration), "
          f"{np.abs(y - ref.y[0]).max():.2g} m (height)")
    on = np.flatnonzero(pen_ref > 0)
    window = slice(max(on[0] - 20, 0), min(on[-1] + 20, len(res.t)))
    fig, (left, right) = new_figure(ncols=2, figsize=(10.0, 3.8))
    left.plot(res.t[window] * 1e3, pen_ref[window] * 1e3, color="0.2", lw=3.0, alpha=0.3,
              label="solve_ivp of m ÿ = −m g + F_n")
    left.plot(res.t[window] * 1e3, pen[window] * 1e3, color="tab:blue", lw=1.0,
              label="casmbd, model = \"compliant\"")
    left.set_xlabel("t [ms]")
    left.set_ylabel("penetration δ [mm]")
    left.set_title("ball on a compliant floor (k = 1e6, e = 1.5, c = 50)", fontsize=10)
    left.legend(fontsize=8)
    right.plot(pen[window] * 1e3, force(pen[window], -vy[window]), color="tab:blue", lw=1.0,
               label="k δ^1.5 + STEP(δ, 0, 0, d, c) δ̇")
    right.plot(pen[window] * 1e3, k_ * pen[window] ** ex, color="0.3", lw=0.8, ls="--",
               label="elastic part k δ^1.5")
    right.set_xlabel("penetration δ [mm]")
    right.set_ylabel("normal force [N]")
    right.set_title("force–penetration loop (energy lost to damping)", fontsize=10)
    right.legend(fontsize=8)
    save_figure(fig, FIGURES / "contact_compliant.png", 100)


def main() -> int:
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        ball_figure(folder)
        stop_figure(folder)
        compliant_figure(folder)
    print("saved docs/figures/contact_ball.png, contact_stop.png, contact_compliant.png")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())

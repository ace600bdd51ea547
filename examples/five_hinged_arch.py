"""The 5-hinged arch (seed 003, §5.3): four equal rods hinged between two ground pivots.

Hanging down, the chain has a stable equilibrium; turned upside down, the same shape is the
equilibrium of an arch — every tension becomes a compression — and it is unstable: a small
disturbance makes it collapse (seed 003, Fig. 3).  This script finds the hanging equilibrium,
mirrors it into the arch, confirms it is an equilibrium, classifies both, reports the arch's
unstable eigenvalue and simulates the collapse from an almost symmetric rest position.

Run: ``python examples/five_hinged_arch.py``.  The scene ``examples/five_hinged_arch.toml``
starts near the arch instead: ``casmbd statics`` finds the arch (the equilibrium nearest the
start, unstable), ``casmbd statics --stable`` the hanging chain.
"""

from __future__ import annotations

import numpy as np

import casmbd
from casmbd.analysis.statics.linearize import linearize
from casmbd.analysis.statics.statics import static_equilibrium

SPAN = 2.5      # distance between the ground pivots [m]; rods are 1 m, 1 kg


def chain(points: np.ndarray, name: str) -> casmbd.Mechanism:
    """Four slender rods through the five hinge points (the ends are pinned to the ground)."""
    m = casmbd.Mechanism(name, gravity=(0.0, -9.81))
    for i in range(4):
        a, b = points[i], points[i + 1]
        d = b - a
        m.add_body(f"rod{i}", 1.0, np.dot(d, d) / 12, (a + b) / 2,
                   angle=float(np.arctan2(d[1], d[0])))
    m.add_revolute("A", "ground", "rod0", points[0])
    for i in range(1, 4):
        m.add_revolute(f"H{i}", f"rod{i - 1}", f"rod{i}", points[i])
    m.add_revolute("B", "rod3", "ground", points[4])
    return m


def hinge_points(equilibrium) -> np.ndarray:
    """The five hinge points of a chain built by :func:`chain` at a static equilibrium.

    Read from the rods' centres and angles (``body_positions``, ``body_angles``), which do not
    depend on the generalized coordinates casmbd chose (joint coordinates for this chain).
    """
    pts = [np.zeros(2)]
    for (x, y), th in zip(equilibrium.body_positions, equilibrium.body_angles):
        pts.append(np.array([x, y]) + 0.5 * np.array([np.cos(th), np.sin(th)]))
    return np.array(pts)


def initial_hanging_points() -> np.ndarray:
    """A symmetric hanging polygon with unit sides (not yet the equilibrium)."""
    alpha = np.pi / 3
    beta = np.arccos(SPAN / 2 - np.cos(alpha))
    p1 = np.array([np.cos(alpha), -np.sin(alpha)])
    p2 = p1 + np.array([np.cos(beta), -np.sin(beta)])
    p3 = np.array([SPAN - p1[0], p1[1]])
    return np.array([[0.0, 0.0], p1, p2, p3, [SPAN, 0.0]])


def study() -> dict:
    """Hanging equilibrium, the mirrored arch, their stability and the arch's eigenvalues."""
    hanging = chain(initial_hanging_points(), "hanging_chain4")
    eq_h = static_equilibrium(hanging)
    points = hinge_points(eq_h)
    arch_points = points * np.array([1.0, -1.0])
    arch = chain(arch_points, "five_hinged_arch")
    eq_a = static_equilibrium(arch)
    lin = linearize(arch, q=eq_a.q)
    return {"hanging": eq_h, "arch": eq_a, "arch_mechanism": arch,
            "hanging_points": points, "arch_points": hinge_points(eq_a),
            "arch_linear": lin}


if __name__ == "__main__":
    out = study()
    print("hanging equilibrium:", "stable" if out["hanging"].stable else "not stable")
    print("arch equilibrium:   ", "stable" if out["arch"].stable else "unstable")
    print("arch hinge points:\n", np.round(out["arch_points"], 6))
    growth = max(e.real for e in out["arch_linear"].eigenvalues)
    print(f"fastest growth rate of the arch: {growth:.4f} 1/s")
    arch = out["arch_mechanism"]
    arch.bodies["rod1"].angular_velocity = 1e-3          # an almost symmetric start
    res = casmbd.simulate(arch, 3.0, 300)
    apex = res.body("rod1")["position"][:, 1]
    low = int(np.argmin(apex))
    print(f"collapse: apex-side rod centre height {apex[0]:.3f} m -> {apex[low]:.3f} m "
          f"at t = {res.t[low]:.2f} s")

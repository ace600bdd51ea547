"""Independent reference models for the flexible-body validation of issue 23 (test support).

Plain numpy/scipy (the linear model takes its stiffness matrix from
:func:`casmbd.model.fe_beam.beam_model`); no casmbd System, no modal reduction.  Two models of
the spin-up beam of Kane, Ryan & Banerjee, "Dynamics of a cantilever beam attached to a moving
base", *J. Guidance, Control, and Dynamics* 10(2), 1987, 139–151 (L = 10 m, ρA = 1.2 kg/m,
EI = 1.4e4 N m², EA = 2.8e7 N), clamped to a hub at the origin whose angle is prescribed,

    θ(t) = (Ω/Ts) (t²/2 + (Ts/2π)² (cos(2πt/Ts) − 1))      t < Ts  (Ts = 15 s)
    θ(t) = Ω (t − Ts/2)                                      t ≥ Ts,

(:func:`hub_angle` returns θ, θ̇, θ̈), and a static co-rotational solver for the cantilever
checks.  Both dynamic models use the same mesh of two-node Euler–Bernoulli elements and the same
lumped masses (node i: mass m_i = Σ ρA h/2 and rotary inertia J_i = Σ ρA (h/2)³/3 of its
half-elements, as :func:`beam_model` lumps them), so that at equal mesh they differ only by the
kinematics of the deformation (linear against geometrically exact).

Reference (a), :func:`linear_ffrf_spinup` — full (unreduced) floating-frame FE model in the
rotating hub frame (Shabana, *Dynamics of Multibody Systems*, 4th ed., 2013, ch. 5; the
"conventional" linear model of Kane et al. 1987).  Node i sits at (x_i + u_i, v_i) in the hub
frame, its section turned by θ + φ_i.  With the hub's angular velocity θ̇ ẑ the inertial
acceleration in hub components is a = r̈ + 2 θ̇ ẑ × ṙ + θ̈ ẑ × r − θ̇² r (r relative), so

    m_i (ü_i − 2 θ̇ v̇_i − θ̈ v_i − θ̇² (x_i + u_i)) + (K q)_{u_i} = 0
    m_i (v̈_i + 2 θ̇ u̇_i + θ̈ (x_i + u_i) − θ̇² v_i) + (K q)_{v_i} = 0
    J_i (φ̈_i + θ̈) + (K q)_{φ_i} = 0,

K the linear stiffness of :func:`beam_model` (root dofs clamped).  The −θ̇² m_i v_i term softens
the bending stiffness and nothing stiffens it: above the first bending frequency ω1 = 3.516
sqrt(EI/(ρA L⁴)) = 3.80 rad/s the model diverges (Kane et al. 1987, their "conventional"
approach).  With ``stiffening=True`` the geometric stiffness of the steady centrifugal tension is
added, K + θ̇² K_G: element e carries N_e = θ̇² Σ_{j beyond e} m_j x_j (the lumped centrifugal
load outboard of it) and K_G,e = N_e/(30 h) [[36, 3h, −36, 3h], [3h, 4h², −3h, −h²],
[−36, −3h, 36, −3h], [3h, −h², −3h, 4h²]] on (v1, φ1, v2, φ2) (Przemieniecki, *Theory of
Matrix Structural Analysis*, 1968, §15.2, the consistent geometric stiffness of the Hermite beam
element); this is the "stiffening" term of issue 23 item 1.

Reference (b), :func:`corotational_spinup` — geometrically exact plane beam in the inertial
frame, Crisfield's co-rotational Euler–Bernoulli element (Crisfield, *Non-linear Finite Element
Analysis of Solids and Structures*, vol. 1, 1991, §7.2; Battini, *Co-rotational beam elements in
instability problems*, KTH thesis, 2002, ch. 2).  Nodes carry (X, Y, ψ) (ψ the absolute section
rotation).  For an element of initial length l0 and chord angle β0, current chord length l and
angle β (c = cos β, s = sin β), the local deformations are

    u_l = l − l0,  θ̄_1 = ψ_1 − (β − β0),  θ̄_2 = ψ_2 − (β − β0)      (angles wrapped to (−π, π]),

the local forces of the linear element N = EA u_l/l0, M_{1,2} = EI/l0 (4 θ̄_{1,2} + 2 θ̄_{2,1}),
the internal force f = Bᵀ (N, M1, M2) with
B = [[−c, −s, 0, c, s, 0], [−s/l, c/l, 1, s/l, −c/l, 0], [−s/l, c/l, 0, s/l, −c/l, 1]] and the
tangent K_t = Bᵀ K_l B + z zᵀ N/l + (r zᵀ + z rᵀ)(M1 + M2)/l², r = (−c, −s, 0, c, s, 0),
z = (s, −c, 0, −s, c, 0) (Crisfield eqs. 7.23–7.32 in this notation).  With lumped masses the
plane kinetic energy ½ Σ (m_i (Ẋ_i² + Ẏ_i²) + J_i ψ̇_i²) has a constant mass matrix, so
M q̈ + f(q) = 0 exactly; the root node is (0, 0, θ(t)) (prescribed: it drives the beam through
the root element's forces).  The tip deflection relative to the rotating hub axis is
−sin θ X_tip + cos θ Y_tip.  The model converges to the continuum with the mesh (the lumped mass
to O(h²)).

Both are integrated with ``scipy.integrate.solve_ivp`` (Radau, analytic Jacobian, rtol 1e-9 by
default).  Static cantilever checks of the co-rotational element (:func:`corotational_cantilever`,
Newton on the tangent): small tip load P against P L³/(3 EI) (exact for cubic elements in the
linear limit), large load against the elastica of Mattiasson, "Numerical results from large
deflection beam and frame problems analysed by means of elliptic integrals", *Int. J. Numer.
Meth. Engng* 17, 1981, 145–153, table 1 (:data:`MATTIASSON_TIP_LOAD`; the values were reproduced
here to all quoted digits by shooting the elastica θ'' = −k cos θ, θ(0) = 0, θ'(L) = 0).

Figures (10 elements, measured 2026-11-25, load average ≈ 1.5 on 2 shared cores):

==================  ======================  ==================  ====================
Ω [rad/s]           linear (a)              stiffened (a)       co-rotational (b)
==================  ======================  ==================  ====================
2, peak tip         −0.2323 m at 8.2 s      −0.2091 m at 7.15 s −0.2091 m at 7.15 s
2, after Ts         ±4.0 mm                 ±0.79 mm            ±0.78 mm
6, peak tip         |tip| > L at 9.1 s      −0.5807 m at 6.8 s  −0.5811 m at 6.8 s
6, after Ts         (diverged)              ±4.3 mm             ±4.5 mm
==================  ======================  ==================  ====================

Max |(a) − (b)| over 0–20 s at Ω = 2: 0.043 m (linear), 1.2e-4 m (stiffened); at Ω = 6 over
0–12 s the stiffened model is within 2.3e-3 m of (b).  Closed-form check: the quasi-static tip
deflection under the peak tangential load q(x) = ρA θ̈_max x, θ̈_max = 2Ω/Ts, is
11 ρA θ̈_max L⁵/(120 EI) = 0.2095 m for Ω = 2 (the tables' peak is 0.2091 m: the spin-up is slow
against the first period 2π/ω1 = 1.65 s), and the steady centrifugal stretch ρA Ω² L³/(3 EA) =
5.71e-5 m (lumped mesh 5.74e-5 m).  Mesh convergence (stiffened model, 10 → 20 elements): peak
0.2091 → 0.2073 m (Ω = 2), 0.5807 → 0.5760 m (Ω = 6), i.e. ≈ 1 % at 10 elements.  Cost: 10
elements, (a) ≈ 1 s, (b) ≈ 5–7 s per run (rtol 1e-7; rtol 1e-6 and 1e-7 peaks agree to 3e-9 m);
20 elements are slow with Radau (≈ 2 min for (a)): the lumped rotary inertias give rotation
modes at ω ∝ h⁻², which the error control of the rotation dofs resolves.

Issue 35 adds the flexible slider-crank (:func:`corotational_slider_crank`: the same
co-rotational elements between a driven crank pin and a slider, stiffness-proportional damping of
the deformation rates; :func:`slider_crank_scene` is the casmbd model under test).  Figures
(measured 2026-11-29, 10 mm / 20 mm rod, steady maximum mid-span deflection over the last crank
turn at 0.4 s): 8 elements 1.34683 / 0.33711 mm, 16 elements 1.35845 / 0.34025 mm; Richardson
(h²) of 8 and 16 elements for the 10 mm rod 1.36232 mm against Exudyn's ANCF cable converged at
16 and 32 elements, 1.36234 mm (32 elements: 1.36137 mm, Richardson of 16/32 1.362337 mm);
energy balance T + U + D − W to 2.6e-8 J of 73 J; E × 1e4:
slider on the rigid mechanism's x(t) to 1.1e-9 m, deflection 6e-5 of the flexible one.  Cost:
8 elements ≈ 25–65 s, 16 ≈ 45–80 s per 0.4 s run (Radau, rtol 1e-7; the load of the shared
machine sets the spread), so the test reads the stored result.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.integrate import solve_ivp

from casmbd.model.fe_beam import beam_model

__all__ = ["KANE_BEAM", "MATTIASSON_TIP_LOAD", "SLIDER_CRANK_REFERENCE", "SLIDER_CRANK_ROD",
           "SliderCrankResult", "SpinupResult", "chord_deflection",
           "corotational_cantilever", "corotational_slider_crank",
           "corotational_spinup", "hub_angle", "linear_ffrf_spinup", "pinned_frequency",
           "rod_section", "slider_crank_damping", "slider_crank_scene",
           "steady_deflection", "write_slider_crank_reference"]

KANE_BEAM = {"length": 10.0, "rhoA": 1.2, "EI": 1.4e4, "EA": 2.8e7, "Ts": 15.0}
"""The spin-up beam of issue 23 (Kane, Ryan & Banerjee 1987)."""

MATTIASSON_TIP_LOAD = {1.0: (0.30172, 0.05643, 0.46135),
                       2.0: (0.49346, 0.16064, 0.78175),
                       10.0: (0.81061, 0.55500, 1.43029)}
"""Cantilever under a tip load P normal to its axis, k = P L²/EI → (w/L, u/L, ψ): tip deflection
normal to the axis, tip shortening along it and tip rotation [rad] (Mattiasson 1981, table 1)."""


def hub_angle(t: float, omega: float, ts: float = 15.0) -> tuple[float, float, float]:
    """Prescribed hub angle θ, rate θ̇ and acceleration θ̈ of the spin-up manoeuvre.

    θ = (Ω/Ts)(t²/2 + (Ts/2π)²(cos(2πt/Ts) − 1)), θ̇ = (Ω/Ts)(t − (Ts/2π) sin(2πt/Ts)),
    θ̈ = (Ω/Ts)(1 − cos(2πt/Ts)) for t < Ts; then Ω (t − Ts/2), Ω, 0 (Kane et al. 1987).
    """
    if t >= ts:
        return omega * (t - ts / 2.0), omega, 0.0
    w = 2.0 * np.pi / ts
    a = omega / ts
    return (a * (t * t / 2.0 + (np.cos(w * t) - 1.0) / w**2),
            a * (t - np.sin(w * t) / w), a * (1.0 - np.cos(w * t)))


@dataclass
class SpinupResult:
    """Tip deflection history of a spin-up run.

    Attributes
    ----------
    t : numpy.ndarray
        Output times [s].
    tip : numpy.ndarray
        Tip deflection normal to the rotating hub axis [m] (positive: towards +θ).
    tip_axial : numpy.ndarray
        Tip displacement along the hub axis relative to the undeformed length [m].
    status : int
        solve_ivp status (0 reached the end, 1 stopped by the divergence event).
    nfev : int
        Right-hand-side evaluations (cost figure).
    """

    t: np.ndarray
    tip: np.ndarray
    tip_axial: np.ndarray
    status: int
    nfev: int


def _lumped(length: float, elements: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Node positions, lumped masses and rotary inertias (per unit ρA) of a uniform mesh."""
    h = length / elements
    x = np.linspace(0.0, length, elements + 1)
    m = np.full(elements + 1, h)
    m[[0, -1]] = h / 2.0
    j = np.full(elements + 1, 2.0 * (h / 2.0) ** 3 / 3.0)
    j[[0, -1]] = (h / 2.0) ** 3 / 3.0
    return x, m, j


def _check(elements: int, omega: float, t_end: float) -> None:
    if isinstance(elements, bool) or not isinstance(elements, int) or elements < 1:
        raise ValueError(f"elements must be a positive integer, got {elements!r}")
    if not (np.isfinite(omega) and np.isfinite(t_end) and t_end > 0.0):
        raise ValueError(f"omega and t_end must be finite (t_end > 0), got {omega!r}, {t_end!r}")


def _diverged(limit: float, index: int):
    def event(t, y):
        return limit - abs(y[index])
    event.terminal = True
    return event


def linear_ffrf_spinup(omega: float, *, elements: int = 10, t_end: float = 20.0,
                       n_out: int = 401, stiffening: bool = False, rtol: float = 1e-9,
                       beam: dict | None = None, limit: float | None = None) -> SpinupResult:
    """Reference (a): full linear floating-frame FE model in the rotating hub frame.

    Parameters
    ----------
    omega : float
        Final hub rate Ω [rad/s].
    elements : int
        Uniform Euler–Bernoulli elements (lumped mass, module docstring).
    t_end : float
        End time [s].
    n_out : int
        Output samples (uniform in [0, t_end]).
    stiffening : bool
        Add the geometric stiffness of the centrifugal tension θ̇² K_G (module docstring).
    rtol : float
        solve_ivp relative tolerance (atol = rtol · 1e-2 m).
    beam : dict, optional
        length, rhoA, EI, EA, Ts (default :data:`KANE_BEAM`).
    limit : float, optional
        Stop when |tip deflection| exceeds it (default the beam length: divergence).

    Returns
    -------
    SpinupResult
    """
    _check(elements, omega, t_end)
    p = {**KANE_BEAM, **(beam or {})}
    L, ts = p["length"], p["Ts"]
    K = beam_model(L, elements, EA=p["EA"], rhoA=p["rhoA"], EI=p["EI"]).stiffness_matrix
    K = K.toarray()[3:, 3:]                               # root clamped in the hub frame
    x, m, j = _lumped(L, elements)
    x, m, j = x[1:], p["rhoA"] * m[1:], p["rhoA"] * j[1:]
    n = 3 * elements
    iu, iv, ip = np.arange(0, n, 3), np.arange(1, n, 3), np.arange(2, n, 3)
    minv = np.empty(n)
    minv[iu], minv[iv], minv[ip] = 1.0 / m, 1.0 / m, 1.0 / j
    KG = np.zeros((n + 3, n + 3))                          # per unit θ̇², root included
    h = L / elements
    for e in range(elements):
        N = float(np.sum(m[e:] * x[e:]))                  # centrifugal tension / θ̇²
        kg = N / (30.0 * h) * np.array([[36.0, 3 * h, -36.0, 3 * h],
                                        [3 * h, 4 * h * h, -3 * h, -h * h],
                                        [-36.0, -3 * h, 36.0, -3 * h],
                                        [3 * h, -h * h, -3 * h, 4 * h * h]])
        idx = [3 * e + 1, 3 * e + 2, 3 * e + 4, 3 * e + 5]
        KG[np.ix_(idx, idx)] += kg
    KG = KG[3:, 3:] if stiffening else np.zeros((n, n))

    def accel_matrix(t: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        _, w, a = hub_angle(t, omega, ts)
        A = -minv[:, None] * (K + w * w * KG)            # q̈ = A q + C q̇ + b
        A[iu, iu] += w * w
        A[iu, iv] += a
        A[iv, iu] -= a
        A[iv, iv] += w * w
        C = np.zeros((n, n))
        C[iu, iv] = 2.0 * w
        C[iv, iu] = -2.0 * w
        b = np.zeros(n)
        b[iu] = w * w * x
        b[iv] = -a * x
        b[ip] = -a
        return A, C, b

    def rhs(t, y):
        A, C, b = accel_matrix(t)
        return np.concatenate([y[n:], A @ y[:n] + C @ y[n:] + b])

    def jac(t, y):
        A, C, _ = accel_matrix(t)
        return np.block([[np.zeros((n, n)), np.eye(n)], [A, C]])

    t_eval = np.linspace(0.0, t_end, n_out)
    sol = solve_ivp(rhs, (0.0, t_end), np.zeros(2 * n), method="Radau", jac=jac, rtol=rtol,
                    atol=rtol * 1e-2, t_eval=t_eval, events=_diverged(limit or L, n - 2))
    return SpinupResult(sol.t, sol.y[n - 2], sol.y[n - 3], sol.status, sol.nfev)


def _element_forces(q: np.ndarray, l0: float, beta0: np.ndarray, EA: float, EI: float,
                    tangent: bool) -> tuple[np.ndarray, np.ndarray | None]:
    """Co-rotational internal forces (and tangent) of a chain of elements, q = (X, Y, ψ) per
    node (module docstring, Crisfield 1991 §7.2)."""
    qn = q.reshape(-1, 3)
    d = qn[1:, :2] - qn[:-1, :2]
    length = np.hypot(d[:, 0], d[:, 1])
    c, s = d[:, 0] / length, d[:, 1] / length
    alpha = np.arctan2(s * np.cos(beta0) - c * np.sin(beta0),
                       c * np.cos(beta0) + s * np.sin(beta0))           # β − β0
    t1 = np.angle(np.exp(1j * (qn[:-1, 2] - alpha)))
    t2 = np.angle(np.exp(1j * (qn[1:, 2] - alpha)))
    N = EA * (length - l0) / l0
    M1 = EI / l0 * (4.0 * t1 + 2.0 * t2)
    M2 = EI / l0 * (2.0 * t1 + 4.0 * t2)
    ne = len(length)
    zero, one = np.zeros(ne), np.ones(ne)
    r = np.stack([-c, -s, zero, c, s, zero], axis=1)
    z = np.stack([s, -c, zero, -s, c, zero], axis=1)
    g = np.stack([-s / length, c / length, zero, s / length, -c / length, zero], axis=1)
    b1 = g + np.stack([zero, zero, one, zero, zero, zero], axis=1)
    b2 = g + np.stack([zero, zero, zero, zero, zero, one], axis=1)
    fe = r * N[:, None] + b1 * M1[:, None] + b2 * M2[:, None]
    f = np.zeros_like(q)
    fn = f.reshape(-1, 3)
    fn[:-1] += fe[:, :3]
    fn[1:] += fe[:, 3:]
    if not tangent:
        return f, None
    Kt = np.zeros((q.size, q.size))
    kl = EI / l0 * np.array([[4.0, 2.0], [2.0, 4.0]])
    for e in range(ne):
        Bm = np.stack([b1[e], b2[e]])
        ke = (EA / l0 * np.outer(r[e], r[e]) + Bm.T @ kl @ Bm
              + np.outer(z[e], z[e]) * N[e] / length[e]
              + (np.outer(r[e], z[e]) + np.outer(z[e], r[e])) * (M1[e] + M2[e]) / length[e]**2)
        Kt[3 * e:3 * e + 6, 3 * e:3 * e + 6] += ke
    return f, Kt


def corotational_spinup(omega: float, *, elements: int = 10, t_end: float = 20.0,
                        n_out: int = 401, rtol: float = 1e-9, beam: dict | None = None,
                        limit: float | None = None) -> SpinupResult:
    """Reference (b): co-rotational plane beam in the inertial frame, root rotation prescribed.

    Parameters and return as :func:`linear_ffrf_spinup` (no stiffening option: the geometric
    stiffening is part of the exact kinematics).
    """
    _check(elements, omega, t_end)
    p = {**KANE_BEAM, **(beam or {})}
    L, ts, EA, EI = p["length"], p["Ts"], p["EA"], p["EI"]
    x, m, j = _lumped(L, elements)
    n = 3 * elements
    minv = 1.0 / (p["rhoA"] * np.column_stack([m, m, j])[1:].ravel())
    beta0 = np.zeros(elements)
    l0 = L / elements
    q0 = np.column_stack([x, np.zeros_like(x), np.zeros_like(x)]).ravel()

    def full(t, y):
        q = np.concatenate([[0.0, 0.0, hub_angle(t, omega, ts)[0]], y[:n]])
        return q

    def rhs(t, y):
        f, _ = _element_forces(full(t, y), l0, beta0, EA, EI, False)
        return np.concatenate([y[n:], -minv * f[3:]])

    def jac(t, y):
        _, Kt = _element_forces(full(t, y), l0, beta0, EA, EI, True)
        return np.block([[np.zeros((n, n)), np.eye(n)],
                         [-minv[:, None] * Kt[3:, 3:], np.zeros((n, n))]])

    t_eval = np.linspace(0.0, t_end, n_out)
    sol = solve_ivp(rhs, (0.0, t_end), np.concatenate([q0[3:], np.zeros(n)]), method="Radau",
                    jac=jac, rtol=rtol, atol=rtol * 1e-2, t_eval=t_eval)
    th = np.array([hub_angle(t, omega, ts)[0] for t in sol.t])
    X, Y = sol.y[n - 3], sol.y[n - 2]
    tip = -np.sin(th) * X + np.cos(th) * Y
    axial = np.cos(th) * X + np.sin(th) * Y - L
    if limit is not None and np.any(np.abs(tip) > limit):
        return SpinupResult(sol.t, tip, axial, 1, sol.nfev)
    return SpinupResult(sol.t, tip, axial, sol.status, sol.nfev)


def corotational_cantilever(load: float, *, elements: int = 20, length: float = 1.0,
                            EI: float = 1.0, EA: float = 1.0e7, steps: int = 10,
                            tol: float = 1e-10) -> tuple[float, float, float]:
    """Static cantilever (clamped at x = 0) under a fixed vertical tip load P (+y).

    Newton iterations on the co-rotational tangent (Crisfield 1991 §7.2) over ``steps`` equal
    load increments.

    Returns
    -------
    tuple of float
        (w, u, ψ): tip deflection along +y, tip shortening along −x and tip rotation [rad].
    """
    if isinstance(elements, bool) or not isinstance(elements, int) or elements < 1:
        raise ValueError(f"elements must be a positive integer, got {elements!r}")
    x = np.linspace(0.0, length, elements + 1)
    q = np.column_stack([x, np.zeros_like(x), np.zeros_like(x)]).ravel()
    l0, beta0 = length / elements, np.zeros(elements)
    fext = np.zeros_like(q)
    for k in range(1, steps + 1):
        fext[-2] = load * k / steps
        for _ in range(50):
            f, Kt = _element_forces(q, l0, beta0, EA, EI, True)
            res = (fext - f)[3:]
            dq = np.linalg.solve(Kt[3:, 3:], res)
            q[3:] += dq
            if np.linalg.norm(dq) <= tol * length:
                break
        else:
            raise RuntimeError(f"co-rotational cantilever: Newton did not converge at P={load}")
    return float(q[-2]), float(length - q[-3]), float(q[-1])


def spinup_scene(omega: float = 2.0, *, elements: int = 6, modes: int = 3,
                 stiffening: bool = False, gravity: float = 0.0, hub: bool = True) -> str:
    """The spin-up beam of :data:`KANE_BEAM` as a casmbd scene (the system under test, for the
    tests that run it): a flexible beam (Craig–Bampton, reference node ``root``) on a driven
    hub revolute at its root with the hub angle of :func:`hub_angle`; ``hub=False`` leaves the
    beam free (no joint, no driver)."""
    b = KANE_BEAM
    text = f"""
[scene]
name = "spinup"
dimension = 2
gravity = [0.0, {gravity}]
[parameters]
Omega = {omega}
Ts = {b['Ts']}
[[bodies]]
name = "beam"
type = "flexible"
position = [0.0, 0.0]
modes = {modes}
reduction = "craig_bampton"
interfaces = ["root"]
stiffening = {str(stiffening).lower()}
[bodies.beam]
length = {b['length']}
elements = {elements}
EI = {b['EI']}
EA = {b['EA']}
rhoA = {b['rhoA']}
nodes = {{ root = 0.0, tip = {b['length']} }}
"""
    if not hub:
        return text
    return text + """
[[joints]]
name = "hub"
type = "revolute"
body1 = "ground"
body2 = "beam"
node2 = "root"
point = [0.0, 0.0]
[[drivers]]
name = "spin"
joint = "hub"
position = "(Omega/Ts)*(min(t,Ts)**2/2 + (Ts/(2*pi))**2*(cos(2*pi*min(t,Ts)/Ts) - 1))\
 + Omega*max(t - Ts, 0)"
"""


# --- issue 35: the flexible slider-crank -----------------------------------------------------

SLIDER_CRANK_ROD = {"crank": 0.152, "length": 0.304, "omega": 150.0, "E": 2.07e11,
                    "rho": 7870.0, "zeta": 0.05}
"""The flexible slider-crank of issue 35: crank radius 0.152 m turning at a constant 150 rad/s,
steel connecting rod 0.304 m long of circular section (E = 2.07e11 Pa, ρ = 7870 kg/m³), 5 %
damping on its first (pinned–pinned) bending mode; no gravity."""


def rod_section(diameter: float, *, E: float | None = None, rho: float | None = None) -> dict:
    """Section properties of the circular rod: EA, EI = E π d⁴/64, rhoA = ρ π d²/4 and the
    rod's mass (:data:`SLIDER_CRANK_ROD` unless E or ρ is given)."""
    p = SLIDER_CRANK_ROD
    E = p["E"] if E is None else E
    rho = p["rho"] if rho is None else rho
    area = np.pi * diameter**2 / 4.0
    return {"EA": E * area, "EI": E * np.pi * diameter**4 / 64.0, "rhoA": rho * area,
            "mass": rho * area * p["length"]}


def pinned_frequency(section: dict, length: float | None = None) -> float:
    """First bending frequency of the pinned–pinned rod, ω1 = π² sqrt(EI/(ρA L⁴)) [rad/s]."""
    L = SLIDER_CRANK_ROD["length"] if length is None else length
    return float(np.pi**2 * np.sqrt(section["EI"] / (section["rhoA"] * L**4)))


@dataclass
class SliderCrankResult:
    """History of the co-rotational slider-crank.

    Attributes
    ----------
    t : numpy.ndarray
        Output times [s].
    deflection : numpy.ndarray
        Mid-span deflection [m]: signed distance of the middle node from the chord between the
        pins (positive to the left of the chord A → B).
    slider : numpy.ndarray
        Slider (pin B) position along x [m].
    energy_residual : numpy.ndarray or None
        T + U + D − W [J] (kinetic, strain energy, dissipated energy, work of the crank-pin
        force), constant for an exact solution; ``None`` unless ``energy=True``.
    status, nfev : int
        solve_ivp status and right-hand-side evaluations.
    """

    t: np.ndarray
    deflection: np.ndarray
    slider: np.ndarray
    energy_residual: np.ndarray | None
    status: int
    nfev: int


def _deformation_rates(q: np.ndarray, v: np.ndarray, l0: float, EA: float, EI: float,
                       beta: float) -> tuple[np.ndarray, np.ndarray]:
    """Stiffness-proportional damping on the co-rotational deformation rates.

    The local deformation rates of element e are d_e = B_e q̇ (B of the module docstring:
    u̇_l = r·q̇, θ̄̇_{1,2} = b_{1,2}·q̇); the damping forces f_d = Σ_e B_eᵀ β K_l B_e q̇ with
    K_l = diag(EA/l0, EI/l0 [[4, 2], [2, 4]]) — a dissipation function ½ β ḋᵀ K_l ḋ of the
    deformation only (rigid motion is not damped).  Returns f_d and ∂f_d/∂q̇.
    """
    qn = q.reshape(-1, 3)
    d = qn[1:, :2] - qn[:-1, :2]
    length = np.hypot(d[:, 0], d[:, 1])
    c, s = d[:, 0] / length, d[:, 1] / length
    ne = len(length)
    zero, one = np.zeros(ne), np.ones(ne)
    r = np.stack([-c, -s, zero, c, s, zero], axis=1)
    g = np.stack([-s / length, c / length, zero, s / length, -c / length, zero], axis=1)
    b1 = g + np.stack([zero, zero, one, zero, zero, zero], axis=1)
    b2 = g + np.stack([zero, zero, zero, zero, zero, one], axis=1)
    Bm = np.stack([r, b1, b2], axis=1)                                   # (ne, 3, 6)
    kl = np.diag([EA / l0, 0.0, 0.0])
    kl[1:, 1:] = EI / l0 * np.array([[4.0, 2.0], [2.0, 4.0]])
    ke = beta * np.einsum("eia,ij,ejb->eab", Bm, kl, Bm)                # (ne, 6, 6)
    D = np.zeros((q.size, q.size))
    for e in range(ne):
        D[3 * e:3 * e + 6, 3 * e:3 * e + 6] += ke[e]
    return D @ v, D


def _strain_energy(q: np.ndarray, l0: float, beta0: np.ndarray, EA: float, EI: float) -> float:
    """U = Σ_e ½ (EA/l0 u_l² + EI/l0 (4θ̄1² + 4θ̄1θ̄2 + 4θ̄2²)/2) of the co-rotational chain."""
    qn = q.reshape(-1, 3)
    d = qn[1:, :2] - qn[:-1, :2]
    length = np.hypot(d[:, 0], d[:, 1])
    alpha = np.arctan2(d[:, 1], d[:, 0]) - beta0
    t1 = np.angle(np.exp(1j * (qn[:-1, 2] - alpha)))
    t2 = np.angle(np.exp(1j * (qn[1:, 2] - alpha)))
    return float(np.sum(0.5 * EA / l0 * (length - l0) ** 2
                        + EI / l0 * (2.0 * t1**2 + 2.0 * t1 * t2 + 2.0 * t2**2)))


def corotational_slider_crank(diameter: float, *, elements: int = 8, t_end: float = 0.4,
                              n_out: int = 801, rtol: float = 1e-9,
                              slider_mass: float | None = None, stiffness_scale: float = 1.0,
                              beta: float | None = None, energy: bool = False,
                              method: str = "Radau") -> SliderCrankResult:
    """Geometrically exact flexible slider-crank (issue 35 item 3's reference).

    The rod of :data:`SLIDER_CRANK_ROD` (section :func:`rod_section` of ``diameter``) is a
    chain of Crisfield co-rotational Euler–Bernoulli elements (module docstring, Crisfield 1991
    §7.2) with the lumped masses m_i, J_i of :func:`casmbd.model.fe_beam.beam_model`; node 0
    is pinned to the crank pin, whose motion is prescribed, X0 = r cos θ, Y0 = r sin θ,
    θ = π/2 + ω t (the crank is rigid and driven: its own inertia does not reach the rod); node
    N is pinned to the slider (mass ``slider_mass``, default half the rod's mass) that moves
    on the x axis: Y_N = 0, and the slider mass adds to node N's x inertia.  Both pins leave
    the section rotations ψ0, ψN free.  The constraints fix node coordinates, so they are
    eliminated: the remaining 3N coordinates have a constant diagonal mass matrix and

        M q̈ = −f(q) − f_d(q, q̇)

    with f the co-rotational internal force (:func:`_element_forces`, prescribed node 0
    included) and f_d the stiffness-proportional damping of the deformation rates
    (:func:`_deformation_rates`), β = 2 ζ / ω1 with ω1 = π² sqrt(EI/(ρA L⁴)) the first
    pinned–pinned bending frequency (ζ = 0.05): 5 % on that mode and ζ_k = β ω_k/2 on the
    others (the same operator as a floating-frame model with C = β K).  Start: the rigid
    motion at θ = π/2 with zero deformation — the rod lies on the line from (0, r) to
    (sqrt(L² − r²), 0) and translates, every node at velocity (−ω r, 0), ψ̇ = 0 (the node
    rotations ψ count from this initial configuration, the chord angles from β0 =
    −asin(r/L), as :func:`_element_forces` takes them).  No gravity.

    Parameters
    ----------
    diameter : float
        Rod diameter [m].
    elements : int
        Co-rotational elements (even: the middle node is the mid-span point).
    t_end, n_out : float, int
        End time [s] and uniform output samples.
    rtol : float
        solve_ivp relative tolerance (atol = rtol · 1e-3 in m, rad, m/s).
    slider_mass : float, optional
        Slider mass [kg] (default half the rod's mass).
    stiffness_scale : float
        Factor on E (the rigid-limit check).
    beta : float, optional
        Stiffness-proportional damping coefficient [s] (default 2 ζ/ω1).
    energy : bool
        Integrate the crank-pin work and the dissipated energy with the motion and return
        T + U + D − W.

    Returns
    -------
    SliderCrankResult
    """
    if isinstance(elements, bool) or not isinstance(elements, int) or elements < 2 \
            or elements % 2:
        raise ValueError(f"elements must be an even integer >= 2, got {elements!r}")
    p = SLIDER_CRANK_ROD
    sec = rod_section(diameter, E=p["E"] * stiffness_scale)
    EA, EI, rhoA = sec["EA"], sec["EI"], sec["rhoA"]
    L, r, w = p["length"], p["crank"], p["omega"]
    ms = 0.5 * rod_section(diameter)["mass"] if slider_mass is None else slider_mass
    if beta is None:
        beta = 2.0 * p["zeta"] / pinned_frequency(rod_section(diameter))
    N = elements
    x, m, j = _lumped(L, N)
    mdiag = rhoA * np.column_stack([m, m, j]).ravel()
    mdiag[3 * N] += ms
    nfull = 3 * (N + 1)
    free = np.setdiff1d(np.arange(nfull), [0, 1, 3 * N + 1])
    n = free.size
    minv = 1.0 / mdiag[free]
    beta0 = np.full(N, -np.arcsin(r / L))
    l0 = L / N
    c0, s0 = np.cos(beta0[0]), np.sin(beta0[0])
    q0 = np.column_stack([x * c0, r + x * s0, np.zeros(N + 1)]).ravel()     # ψ from the start
    v0 = np.zeros(nfull)
    v0[0::3] = -w * r

    def pin(t):
        th = np.pi / 2.0 + w * t
        c, s = np.cos(th), np.sin(th)
        return (np.array([r * c, r * s]), np.array([-r * w * s, r * w * c]),
                np.array([-r * w * w * c, -r * w * w * s]))

    def full(t, y):
        (a, va, _), q, v = pin(t), np.zeros(nfull), np.zeros(nfull)
        q[free], v[free] = y[:n], y[n:2 * n]
        q[:2], v[:2] = a, va
        return q, v

    def forces(t, y):
        q, v = full(t, y)
        f, _ = _element_forces(q, l0, beta0, EA, EI, False)
        fd, _ = _deformation_rates(q, v, l0, EA, EI, beta)
        return q, v, f, fd

    def rhs(t, y):
        _q, v, f, fd = forces(t, y)
        out = [y[n:2 * n], -minv * (f + fd)[free]]
        if energy:
            acc = pin(t)[2]
            work = float((mdiag[:2] * acc + f[:2] + fd[:2]) @ v[:2])   # crank-pin power
            out.append([work, float(v @ fd)])
        return np.concatenate(out)

    def jac(t, y):
        q, v = full(t, y)
        _, Kt = _element_forces(q, l0, beta0, EA, EI, True)
        _, D = _deformation_rates(q, v, l0, EA, EI, beta)
        J = np.zeros((y.size, y.size))
        J[:n, n:2 * n] = np.eye(n)
        J[n:2 * n, :n] = -minv[:, None] * Kt[np.ix_(free, free)]
        J[n:2 * n, n:2 * n] = -minv[:, None] * D[np.ix_(free, free)]
        return J

    y0 = np.concatenate([q0[free], v0[free]] + ([np.zeros(2)] if energy else []))
    t_eval = np.linspace(0.0, t_end, n_out)
    sol = solve_ivp(rhs, (0.0, t_end), y0, method=method, jac=jac, rtol=rtol,
                    atol=rtol * 1e-3, t_eval=t_eval)
    defl = np.empty(sol.t.size)
    slider = np.empty(sol.t.size)
    res = np.empty(sol.t.size) if energy else None
    for k, t in enumerate(sol.t):
        q, v = full(t, sol.y[:, k])
        qn = q.reshape(-1, 3)
        a, b, mid = qn[0, :2], qn[N, :2], qn[N // 2, :2]
        e = (b - a) / np.linalg.norm(b - a)
        dm = mid - 0.5 * (a + b)
        defl[k] = e[0] * dm[1] - e[1] * dm[0]
        slider[k] = qn[N, 0]
        if energy:
            kinetic = 0.5 * float(mdiag @ v**2)
            res[k] = (kinetic + _strain_energy(q, l0, beta0, EA, EI)
                      + sol.y[-1, k] - sol.y[-2, k])
    return SliderCrankResult(sol.t, defl, slider, res, sol.status, sol.nfev)


def steady_deflection(t: np.ndarray, deflection: np.ndarray, *, revolutions: float = 1.0,
                      omega: float | None = None) -> float:
    """Largest |mid-span deflection| over the last ``revolutions`` crank turns [m]."""
    w = SLIDER_CRANK_ROD["omega"] if omega is None else omega
    last = t >= t[-1] - revolutions * 2.0 * np.pi / w - 1e-12
    return float(np.abs(deflection[last]).max())


#: the stored reference of the slider-crank test (written by :func:`write_slider_crank_reference`)
SLIDER_CRANK_REFERENCE = "data/slider_crank_reference.npz"


def write_slider_crank_reference(path=None, *, cases=((0.01, 8), (0.02, 8), (0.01, 16),
                                                      (0.02, 16), (0.01, 32)),
                                 t_end: float = 0.4, rtol: float = 1e-7,
                                 dt: float = 1e-4) -> dict:
    """Run :func:`corotational_slider_crank` for each (diameter, elements) and store the
    mid-span deflection and slider position of the last crank revolution (times, values) and
    the steady maximum |deflection| in an .npz (``tests/data/slider_crank_reference.npz``).

    Command: ``python -m tests.flexible_references`` (about 25 minutes on a loaded machine, 18
    of them for the 32-element run).
    """
    import pathlib
    import time

    out = {}
    period = 2.0 * np.pi / SLIDER_CRANK_ROD["omega"]
    n_out = round(t_end / dt) + 1
    for diameter, elements in cases:
        t0 = time.perf_counter()
        res = corotational_slider_crank(diameter, elements=elements, t_end=t_end, n_out=n_out,
                                        rtol=rtol)
        key = f"d{round(diameter * 1e3)}_e{elements}"
        last = res.t >= res.t[-1] - period - 1e-12
        out[f"{key}_t"] = res.t[last]
        out[f"{key}_deflection"] = res.deflection[last]
        out[f"{key}_slider"] = res.slider[last]
        out[f"{key}_steady"] = steady_deflection(res.t, res.deflection)
        # periodicity: the same maximum one revolution earlier
        before = res.t < res.t[-1] - period - 1e-12
        out[f"{key}_steady_before"] = steady_deflection(res.t[before], res.deflection[before])
        out[f"{key}_seconds"] = time.perf_counter() - t0
        out[f"{key}_status"] = res.status
        print(key, out[f"{key}_steady"], out[f"{key}_steady_before"], out[f"{key}_seconds"],
              flush=True)
    out["t_end"], out["rtol"] = t_end, rtol
    path = pathlib.Path(__file__).parent / SLIDER_CRANK_REFERENCE if path is None else path
    pathlib.Path(path).parent.mkdir(parents=True, exist_ok=True)
    np.savez(path, **out)
    return out


if __name__ == "__main__":
    write_slider_crank_reference()


def slider_crank_damping(diameter: float, *, elements: int = 8, modes: int = 4,
                         beta: float | None = None) -> list[float]:
    """Modal damping ratios ζ_k = β ω_k / 2 of casmbd's rod modes (built-in beam, lumped mass,
    Craig–Bampton with interfaces A and B, ``modes`` fixed-interface modes), ω_k the
    frequencies of the reduced stiffness over casmbd's lumped flexible mass M_ff: with them
    casmbd's modal damping C = M_ff V diag(2 ζ_k ω_k) Vᵀ M_ff is exactly β K_red, the damping
    operator of :func:`corotational_slider_crank` (β = 2 ζ/ω1 by default)."""
    import scipy.linalg

    from casmbd.model.modal_reduction import craig_bampton

    sec = rod_section(diameter)
    L = SLIDER_CRANK_ROD["length"]
    beta = 2.0 * SLIDER_CRANK_ROD["zeta"] / pinned_frequency(sec) if beta is None else beta
    fe = beam_model(L, elements, EA=sec["EA"], rhoA=sec["rhoA"], EI=sec["EI"], mass="lumped",
                    nodes={"A": 0.0, "mid": L / 2.0, "B": L})
    modal = craig_bampton(fe, modes, ["A", "B"])
    m_ff = (np.einsum("i,iak,ial->kl", modal.masses, modal.phi_t, modal.phi_t)
            + np.einsum("i,ik,il->kl", modal.inertias, modal.phi_r, modal.phi_r))
    lam = scipy.linalg.eigh(np.asarray(modal.stiffness), m_ff, eigvals_only=True)
    return [float(beta * np.sqrt(max(v, 0.0)) / 2.0) for v in lam]


def slider_crank_scene(diameter: float, *, elements: int = 8, modes: int = 4,
                       stiffening: bool = True, damping: list[float] | None = None) -> str:
    """The slider-crank of :func:`corotational_slider_crank` as a casmbd scene (the system
    under test): driven rigid crank, the rod a built-in beam (lumped mass, Craig–Bampton with
    interfaces at the pins A and B, ``modes`` fixed-interface modes, modal damping
    :func:`slider_crank_damping`), a slider of half the rod's mass on a prismatic joint along
    x, no gravity; the same start (rigid translation at θ = π/2).  Node ``mid`` is the
    mid-span point."""
    p = SLIDER_CRANK_ROD
    sec = rod_section(diameter)
    zeta = slider_crank_damping(diameter, elements=elements, modes=modes) if damping is None \
        else damping
    return f"""
[scene]
name = "slider_crank_issue35"
dimension = 2
gravity = [0.0, 0.0]
[parameters]
omega = {p['omega']}
r = {p['crank']}
l = {p['length']}
[[bodies]]
name = "crank"
mass = 0.3
inertia = "0.3 * r**2 / 12"
position = [0.0, "r / 2"]
angle = "pi / 2"
velocity = ["-omega * r / 2", 0.0]
angular_velocity = "omega"
[[bodies]]
name = "rod"
type = "flexible"
position = [0.0, "r"]
angle = "-asin(r / l)"
velocity = ["-omega * r", 0.0]
modes = {modes}
reduction = "craig_bampton"
interfaces = ["A", "B"]
damping_ratio = {[float(z) for z in zeta]}
stiffening = {str(stiffening).lower()}
[bodies.beam]
length = "l"
elements = {elements}
EI = {sec['EI']!r}
EA = {sec['EA']!r}
rhoA = {sec['rhoA']!r}
mass = "lumped"
nodes = {{ A = 0.0, mid = "l / 2", B = "l" }}
[[bodies]]
name = "slider"
mass = {0.5 * sec['mass']!r}
inertia = 1e-6
position = ["sqrt(l**2 - r**2)", 0.0]
velocity = ["-omega * r", 0.0]
[[joints]]
name = "O"
type = "revolute"
body1 = "ground"
body2 = "crank"
point = [0.0, 0.0]
[[joints]]
name = "A"
type = "revolute"
body1 = "crank"
body2 = "rod"
node2 = "A"
point = [0.0, "r"]
[[joints]]
name = "B"
type = "revolute"
body1 = "rod"
node1 = "B"
body2 = "slider"
point = ["sqrt(l**2 - r**2)", 0.0]
[[joints]]
name = "slide"
type = "prismatic"
body1 = "ground"
body2 = "slider"
point = ["sqrt(l**2 - r**2)", 0.0]
axis = [1.0, 0.0]
[[drivers]]
name = "crank_speed"
joint = "O"
position = "pi / 2 + omega * t"
"""


def chord_deflection(a: np.ndarray, b: np.ndarray, mid: np.ndarray) -> np.ndarray:
    """Signed distance of ``mid`` from the chord a → b (positive to its left), (n_t, 2)
    arrays → (n_t,) [m] (the sign convention of :class:`SliderCrankResult`)."""
    e = (b - a) / np.linalg.norm(b - a, axis=1)[:, None]
    d = mid - 0.5 * (a + b)
    return e[:, 0] * d[:, 1] - e[:, 1] * d[:, 0]

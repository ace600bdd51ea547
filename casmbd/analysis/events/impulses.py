"""Impulses at an impact: Newton's restitution law with the bilateral constraints (issue 24).

At an impact of the gaps I, the post-impact velocity v⁺ and the impulses (μ of the bilateral
constraints, P ≥ 0 of the gaps) solve

    [M  C_qᵀ G_Iᵀ] [v⁺]   [M v⁻       ]
    [C_q 0    0  ] [μ ] = [−C_t       ]
    [G_I 0    0  ] [P ]   [−e G_I v⁻  ]

(Pfeiffer & Glocker, *Multibody Dynamics with Unilateral Contacts*, 1996, ch. 6); a gap with
P_k < 0 leaves I.  Coulomb's law on the impulse level: the tangential impulse first sticks
(T v⁺ = 0); where |P_t| > μ P_n the contact slips, P_t = −μ P_n ŝ with ŝ the pre-impact slip
direction, so the impulse direction of that gap becomes G − μ ŝᵀ T.  A gap whose rebound speed is
below the rest velocity closes (:mod:`casmbd.analysis.events.events`).
"""

from __future__ import annotations

import numpy as np

__all__ = ["impact", "project"]


def impact(model, gaps, closed, i_ev, q, v, t, p, v_rest):
    """v⁺ after an impact of gap ``i_ev`` (module docstring, step 3; ``v_rest`` the rest
    velocity, one number or one per gap), the new set of closed gaps, and the events as
    (label, kind): every gap struck at this instant (``impact``/``limit``, in row order), then
    stick/slip and contact; None when the gap is not closing in."""
    g, gq, tv = gaps(q, v, t, p)
    if gq[i_ev] @ v >= 0.0:
        return None
    m_mat = model.mass_matrix(q)  # once (it was evaluated twice, three times when sparse)
    m_mat = m_mat.toarray() if hasattr(m_mat, "toarray") else np.asarray(m_mat)
    n = len(v)
    if model.nc:
        cq = model.constraint_jacobian(q, t)
        cq = cq.toarray() if hasattr(cq, "toarray") else np.asarray(cq).reshape(-1, n)
    else:  # no bilateral constraint (a free body): nothing to evaluate
        cq = np.zeros((0, n))
    ct = np.asarray(model.constraint_time_derivative(q, t), float).ravel() if model.nc else \
        np.zeros(0)
    stick = getattr(gaps, "stick", [False] * len(g))  # stick-slip rows never impact
    active = sorted({i_ev} | {i for i in range(len(g)) if i not in closed and not stick[i]
                              and abs(g[i]) < 1e-9 and gq[i] @ v < 0.0})
    extra: list[tuple[str, str]] = []
    for _ in range(len(active) + 1):
        rows, rhs, kinds = [], [], []
        for i in active:
            rows.append(gq[i])
            rhs.append(-gaps.restitution(i, t, p) * (gq[i] @ v))
            kinds.append(i)
        directions = np.array(rows)
        # friction: try sticking at frictional contacts
        tangential = []
        for i in active:
            element, _ = gaps.rows[i]
            idx = gaps.tangent_of[i]
            if idx is not None and element.friction > 0:
                ts = gaps.tangent_size
                t_mat = tv[idx * ts:(idx + 1) * ts]
                if not _implied(np.vstack([cq.reshape(-1, n), directions]), t_mat):
                    tangential.append((i, t_mat))
                # else the joints and the normal rows already fix the contact point's slip
                # (a pinned rod's tip striking the floor): no tangential impulse of its own
        stick_rows = [t_row for _, t_mat in tangential for t_row in t_mat]
        a_mat, b_vec = _saddle(m_mat, cq, ct, directions, np.array(rhs), stick_rows, v)
        sol = np.linalg.lstsq(a_mat, b_vec, rcond=None)[0]
        v_plus = sol[:n]
        nc = cq.shape[0]
        impulses = sol[n + nc:n + nc + len(active)]
        tang = sol[n + nc + len(active):]
        slipping = []
        for m, (i, t_mat) in enumerate(tangential):
            ts = t_mat.shape[0]
            p_t = tang[m * ts:(m + 1) * ts]
            p_n = impulses[active.index(i)]
            if np.linalg.norm(p_t) > gaps.rows[i][0].friction * abs(p_n):
                slipping.append((i, t_mat))
        if slipping:  # Coulomb: P_t = −μ P_n ŝ, ŝ the pre-impact slip direction
            dirs = directions.copy()
            keep_stick = [r for i, t_mat in tangential if i not in dict(slipping)
                          for r in t_mat]
            for i, t_mat in slipping:
                vt = t_mat @ v
                s_hat = vt / max(np.linalg.norm(vt), 1e-300)
                dirs[active.index(i)] = gq[i] - gaps.rows[i][0].friction * (s_hat @ t_mat)
            a_mat, b_vec = _saddle(m_mat, cq, ct, dirs, np.array(rhs), keep_stick, v,
                                   normal_rows=directions)
            sol = np.linalg.lstsq(a_mat, b_vec, rcond=None)[0]
            v_plus = sol[:n]
            impulses = sol[n + nc:n + nc + len(active)]
        negative = [active[m] for m in range(len(active)) if impulses[m] < -1e-12 and
                    active[m] != i_ev]
        if not negative:
            for i, _ in tangential:
                extra.append((gaps.label(i), "slip" if i in dict(slipping) else "stick"))
            break
        active = [i for i in active if i not in negative]
    # every gap that takes part in the impact is named (two gaps of a Newton's cradle
    # closing together: both), in row order whichever was located first
    extra = [(gaps.label(i), gaps.rows[i][0].event_kind) for i in active] + extra
    new_closed = set(closed)
    for i in active:
        if gq[i] @ v_plus < (v_rest[i] if np.ndim(v_rest) else v_rest):  # per gap, or one
            new_closed.add(i)
            extra.append((gaps.label(i), "contact"))
            v_plus = v_plus  # the closed gap's rebound speed is below the rest threshold
    if new_closed != set(closed):  # project onto the closed gaps: G v = 0 exactly
        v_plus = project(model, gaps, new_closed, q, v_plus, t, p)
    return v_plus, frozenset(new_closed), extra


def project(model, gaps, closed, q, v, t, p):
    """The velocity nearest to v in the M-norm with G_i v = 0 on the closed gaps and the
    bilateral constraints (C_q v + C_t = 0)."""
    _, gq, _ = gaps(q, v, t, p)
    m_mat = model.mass_matrix(q)
    m_mat = m_mat.toarray() if hasattr(m_mat, "toarray") else np.asarray(m_mat)
    n = len(v)
    cq = model.constraint_jacobian(q, t)
    cq = cq.toarray() if hasattr(cq, "toarray") else np.asarray(cq).reshape(-1, n)
    ct = np.asarray(model.constraint_time_derivative(q, t), float).ravel() if model.nc else \
        np.zeros(0)
    rows = np.array([gq[i] for i in sorted(closed)])
    a_mat, b_vec = _saddle(m_mat, cq, ct, rows, np.zeros(len(rows)), [], v)
    return np.linalg.lstsq(a_mat, b_vec, rcond=None)[0][:n]


def _implied(rows: np.ndarray, dirs: np.ndarray) -> bool:
    """Whether every row of ``dirs`` is a combination of ``rows`` (relative 1e-8)."""
    for d in dirs:
        x = np.linalg.lstsq(rows.T, d, rcond=None)[0]
        if np.linalg.norm(rows.T @ x - d) > 1e-8 * max(np.linalg.norm(d), 1e-300):
            return False
    return True


def _saddle(m_mat, cq, ct, directions, normal_rhs, stick_rows, v, normal_rows=None):
    """[M, C_qᵀ, Dᵀ, Tᵀ; C_q; N; T] [v⁺; μ; P; P_t] = [M v⁻; −C_t; e-law; 0] with D the
    impulse directions and N the gap rows of the restitution law (N = D without friction)."""
    n = m_mat.shape[0]
    normal_rows = directions if normal_rows is None else normal_rows
    blocks_t = [cq, directions] + ([np.array(stick_rows)] if len(stick_rows) else [])
    blocks_c = [cq, normal_rows] + ([np.array(stick_rows)] if len(stick_rows) else [])
    lower_t = np.vstack([b.reshape(-1, n) for b in blocks_t])
    lower_c = np.vstack([b.reshape(-1, n) for b in blocks_c])
    k = lower_t.shape[0]
    a_mat = np.block([[m_mat, -lower_t.T], [lower_c, np.zeros((k, k))]])
    rhs = np.concatenate([m_mat @ v, -ct if len(ct) else np.zeros(cq.shape[0]), normal_rhs,
                          np.zeros(len(stick_rows))])
    return a_mat, rhs

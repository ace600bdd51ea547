"""Which element keeps a mechanism from assembling, and what to change.

When Newton-Raphson cannot satisfy C(q, t) = 0 the largest residuals at its last iterate are
a poor guide: the least-squares compromise spreads the contradiction over every equation of
the loop, and the element at fault (a distance that cannot be reached, a driver asking for a
pose the joints forbid) often shows a smaller residual than the joints it contradicts.

:func:`rank_culprits` asks instead how much *removing* each element reduces the residual: for
each of at most :data:`MAX_CANDIDATES` elements (joints and drivers; those with the largest
residual at the last iterate or at the starting guess), the assembly is re-solved in the
least-squares sense without that element's equations (Gauss-Newton from the last iterate)
and the residual left over is recorded.  Elements whose removal lets the rest assemble come
first; among them, those with fewer equations (the smaller change: one length or one driven
coordinate before a joint's point), then those already violated at the starting guess (the
drawn pose at t = 0: every joint defined by global points is satisfied there by
construction, so only explicit lengths and drivers can contradict it), then the smaller
mismatch of their own equations.  For the first element a hint says what to
change, with the range of values the other equations allow (a local search: a bounded
SLSQP minimisation and maximisation of the element's equation over the poses that satisfy
the others).

The re-solves are dense (one least-squares solve per Gauss-Newton iteration): the ranking is
skipped, and said to be, above :data:`MAX_ENTRIES` entries of C_q.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass, field

import casadi as ca
import numpy as np

from casmbd.errors import CasmbdError
from casmbd.lazy import lazy_module
from casmbd.model.bodies import GROUND
from casmbd.model.values import resolve

sla = lazy_module("scipy.linalg")


def _minimize():
    """``scipy.optimize.minimize``, imported when a failed assembly is first diagnosed:
    scipy.optimize costs about 0.2 s at start-up, and most runs never need it."""
    from scipy.optimize import minimize

    return minimize


#: elements re-solved without their equations (the ones with the largest residuals)
MAX_CANDIDATES = 10
#: C_q entries (free coordinates × equations) above which no ranking is attempted
MAX_ENTRIES = 40_000
#: Gauss-Newton iterations per re-solve
MAX_ITERATIONS = 30
#: random starting poses (besides the re-solved one) of the search for the allowed range
EXTRA_STARTS = 3
#: free coordinates above which the hint gives no range (each SLSQP iteration is dense in
#: them: 0.3 s for 30 coordinates, 100 s for 200)
RANGE_MAX_COORDINATES = 30


@dataclass
class Culprit:
    """One element of a failed assembly, ranked by the residual left without it.

    Attributes
    ----------
    kind, element : str
        ``"joint"`` or ``"driver"`` and its name.
    equations : list of str
        Labels of its equations.
    fixes : bool
        The other equations can all be satisfied without it.
    remaining : float
        max |C| of the other equations after the re-solve without it.
    mismatch : float
        max |C| of its own equations there: how far it is from what the others allow.
    hint : str
        What to change (for the first culprit: with the values the others allow).
    """

    kind: str
    element: str
    equations: list[str] = field(default_factory=list)
    fixes: bool = False
    remaining: float = float("nan")
    mismatch: float = float("nan")
    violated_at_start: bool = False
    hint: str = ""

    def to_dict(self) -> dict:
        """Plain JSON-ready dict (``casmbd info --json`` key ``assembly_culprits``)."""
        return asdict(self)

    def __str__(self) -> str:
        return f"{self.kind} '{self.element}'"


def _least_squares(model, q: np.ndarray, t: float, rows: np.ndarray, free: np.ndarray,
                   stop: float) -> tuple[np.ndarray, np.ndarray]:
    """Gauss-Newton on min ‖C_rows(q)‖² over the free coordinates (minimum-norm steps,
    backtracking on the squared norm); returns q and C_rows(q)."""
    q = q.copy()
    c = model.constraints(q, t)[rows]
    f = float(c @ c)
    for _ in range(MAX_ITERATIONS):
        if not c.size or float(np.max(np.abs(c))) <= stop:
            break
        jac = model.constraint_jacobian(q, t)[rows][:, free].toarray()
        step, *_ = sla.lstsq(jac, -c, lapack_driver="gelsd")
        alpha, accepted = 1.0, False
        for _ in range(12):
            trial = q.copy()
            trial[free] += alpha * step
            c_trial = model.constraints(trial, t)[rows]
            f_trial = float(c_trial @ c_trial)
            if np.isfinite(f_trial) and f_trial < f * (1.0 - 1e-4 * alpha):
                accepted = True
                break
            alpha *= 0.5
        if not accepted:
            break
        q, c, f = trial, c_trial, f_trial
    return q, c


def _starts(model, q: np.ndarray, t: float, rest: np.ndarray, free: np.ndarray,
            tol: float) -> list[np.ndarray]:
    """``q`` and :data:`EXTRA_STARTS` poses reached from it by random motions the equations
    ``rest`` allow (steps of norm 1, 2, 3 in their tangent space, brought back onto them by
    Gauss-Newton): a local search started where the equation is stationary, as at the pose
    the re-solve ends in, would not move."""
    rng = np.random.default_rng(0)
    jac = model.constraint_jacobian(q, t)[rest][:, free].toarray() if rest.size else \
        np.zeros((0, len(free)))
    _, sigma, vt = np.linalg.svd(jac, full_matrices=True)
    rank = int(np.sum(sigma > 1e-8 * max(float(sigma[0]) if sigma.size else 0.0, 1e-300)))
    tangent = vt[rank:].T
    out = [q]
    if not tangent.shape[1]:
        return out
    for k in range(EXTRA_STARTS):
        step = tangent @ rng.normal(0.0, 1.0, tangent.shape[1])
        trial = q.copy()
        trial[free] += (k + 1.0) * step / max(float(np.linalg.norm(step)), 1e-300)
        trial, c = _least_squares(model, trial, t, rest, free, tol)
        if not c.size or float(np.max(np.abs(c))) <= tol:
            out.append(trial)
    return out


def _range(model, q: np.ndarray, t: float, row: int, rest: np.ndarray, free: np.ndarray,
           tol: float) -> tuple[float | None, float | None]:
    """Smallest and largest value of equation ``row`` over the poses that satisfy the
    equations ``rest`` (local searches from ``q`` and a few poses near it; None where they
    all fail, e.g. unbounded)."""
    found: list[list[float]] = [[], []]
    for start in _starts(model, q, t, rest, free, tol):
        for k, value in enumerate(_extrema(model, start, t, row, rest, free, tol)):
            if value is not None:
                found[k].append(value)
    return (min(found[0]) if found[0] else None, max(found[1]) if found[1] else None)


def _extrema(model, q: np.ndarray, t: float, row: int, rest: np.ndarray, free: np.ndarray,
             tol: float) -> list[float | None]:
    """One local minimisation and maximisation of equation ``row`` from ``q`` subject to
    the equations ``rest`` (SLSQP).

    Angles (coordinates ``*.angle``) are kept within ±2π of ``q``: every equation is
    2π-periodic in them, so an unbounded search may jump to the same branch of poses a few
    turns away (a crank driver's range came out as -165.3 to 20.78 rad instead of ±1.928 in
    joint coordinates).  A branch that does not turn fully spans less than 2π in each angle,
    so its extrema lie inside the bounds, and those of the branches a turn away beyond them:
    an extremum on a bound is not reported."""
    names = list(getattr(model, "coordinate_names", []))
    angle = [i < len(names) and names[i].endswith(".angle") for i in free]
    bounds = [(q[i] - 2 * np.pi, q[i] + 2 * np.pi) if a else (None, None)
              for i, a in zip(free, angle, strict=True)]
    out: list[float | None] = []
    for sign in (1.0, -1.0):
        def fun(x, sign=sign):
            trial = q.copy()
            trial[free] = x
            return sign * float(model.constraints(trial, t)[row])

        def grad(x, sign=sign):
            trial = q.copy()
            trial[free] = x
            return sign * model.constraint_jacobian(trial, t)[row][:, free].toarray().ravel()

        def cons(x):
            trial = q.copy()
            trial[free] = x
            return model.constraints(trial, t)[rest]

        def cons_jac(x):
            trial = q.copy()
            trial[free] = x
            return model.constraint_jacobian(trial, t)[rest][:, free].toarray()

        constraints = [{"type": "eq", "fun": cons, "jac": cons_jac}] if rest.size else []
        res = _minimize()(fun, q[free], jac=grad, constraints=constraints, method="SLSQP",
                       bounds=bounds if any(angle) else None,
                       options={"maxiter": 100, "ftol": 1e-12})
        on_bound = any(a and abs(abs(x - q[i]) - 2 * np.pi) <= 1e-9
                       for i, a, x in zip(free, angle, res.x, strict=True))
        ok = res.success and not on_bound and (
            not rest.size or float(np.max(np.abs(cons(res.x)))) <= tol)
        out.append(sign * float(res.fun) if ok and np.isfinite(res.fun) else None)
    return out


def _closest(model, q: np.ndarray, t: float, rows: np.ndarray, rest: np.ndarray,
             free: np.ndarray, tol: float) -> float:
    """Smallest ‖C_rows‖ over the poses that satisfy the equations ``rest`` (SLSQP from ``q``
    and the poses of :func:`_starts`; ‖C_rows(q)‖ if every search fails)."""
    best = float(np.linalg.norm(model.constraints(q, t)[rows]))

    def at(x):
        trial = q.copy()
        trial[free] = x
        return trial

    def fun(x):
        c = model.constraints(at(x), t)[rows]
        return 0.5 * float(c @ c)

    def grad(x):
        trial = at(x)
        c = model.constraints(trial, t)[rows]
        return model.constraint_jacobian(trial, t)[rows][:, free].toarray().T @ c

    constraints = [{"type": "eq", "fun": lambda x: model.constraints(at(x), t)[rest],
                    "jac": lambda x: model.constraint_jacobian(at(x), t)[rest][:, free]
                    .toarray()}] if rest.size else []
    for start in _starts(model, q, t, rest, free, tol):
        res = _minimize()(fun, start[free], jac=grad, constraints=constraints, method="SLSQP",
                       options={"maxiter": 100, "ftol": 1e-14})
        trial = at(res.x)
        if rest.size and float(np.max(np.abs(model.constraints(trial, t)[rest]))) > tol:
            continue
        best = min(best, float(np.linalg.norm(model.constraints(trial, t)[rows])))
    return best


def _bounds(lo: float | None, hi: float | None, value: float, between: str,
            and_: str) -> str:
    """"between lo and hi" (or "from lo to hi"), or the one bound ``value`` lies beyond
    ("at least lo", "at most hi") when the other was not found or equals it: a local
    search that did not leave a stationary pose returns lo = hi."""
    distinct = lo is not None and hi is not None and hi - lo > 1e-6 * max(1.0, abs(hi))
    if distinct:
        return f"{between} {lo:.6g} {and_} {hi:.6g}"
    if lo is not None and value < lo:
        return f"at least {lo:.6g}"
    if hi is not None and value > hi:
        return f"at most {hi:.6g}"
    return ""


def _fmt(values) -> str:
    return ", ".join(f"{float(v):.4g}" for v in np.ravel(values))


def _body(name: str) -> str:
    return "the ground" if name == GROUND else f"body '{name}'"


def _driver_value(model, driver, t: float) -> float | None:
    """f(t) of a driver (None when the model does not expose its symbols); a Function of the
    symbolic ``model.system`` built for a failure message only."""
    system = model.system
    try:
        expr = resolve(driver.position, system.t, system.ctx.p, f"driver '{driver.name}'")
        fun = ca.Function("f", [system.t, system.p], [ca.vec(expr)[0]])
        return float(fun(t, np.asarray(model.p, float)))
    except (AttributeError, CasmbdError):
        return None


def _others(culprit: Culprit, fixers: list[Culprit]) -> str:
    names = [str(c) for c in fixers if c is not culprit][:4]
    return ", ".join(names) if names else "the joints"


def _hint(model, culprit: Culprit, q: np.ndarray, t: float, rows: np.ndarray,
          rest: np.ndarray, free: np.ndarray, tol: float, fixers: list[Culprit]) -> str:
    """What to change about ``culprit``, with the values the other equations allow."""
    mech = model.mechanism
    if not culprit.fixes:
        return (f"{culprit}: without it the residual is still {culprit.remaining:.3g} "
                "(other elements contradict each other too)")
    lo = hi = None
    if rows.size == 1 and len(free) <= RANGE_MAX_COORDINATES:
        lo, hi = _range(model, q, t, int(rows[0]), rest, free, tol)
    if culprit.kind == "driver" and culprit.element in mech.drivers:
        driver = mech.drivers[culprit.element]
        f = None if driver.orientation_row else _driver_value(model, driver, t)  # 3 rows
        asked = f"{driver.target} = {f:.6g}" if f is not None else driver.target
        allowed = "" if f is None else _bounds(None if lo is None else f + lo,
                                               None if hi is None else f + hi, f, "from", "to")
        allowed = f", but the joints allow only {driver.target} {allowed}" if allowed else ""
        return (f"driver '{driver.name}' asks for {asked} at t = {t:g}{allowed}, "
                f"contradicting {_others(culprit, fixers)}; change its position "
                "expression, the initial pose, or the joint points that set the range")
    joint = mech.joints.get(culprit.element) if culprit.kind == "joint" else None
    if joint is not None and hasattr(joint, "point1") and getattr(joint, "length", None):
        length = float(joint.length)
        drawn = float(np.linalg.norm(np.asarray(joint.point2) - np.asarray(joint.point1)))

        def distance(c):
            return float(np.sqrt(max(0.0, length * length + 2.0 * length * c)))

        reach = _bounds(None if lo is None else distance(lo),
                        None if hi is None else distance(hi), length, "between", "and")
        reach = f"{reach} apart" if reach else "not that far apart"
        where = (f"its points ({_fmt(joint.point1)}) on {_body(joint.body1)} and "
                 f"({_fmt(joint.point2)}) on {_body(joint.body2)}")
        if len(free) > RANGE_MAX_COORDINATES:
            where += (f" are {drawn:.4g} apart as drawn (no search for the reachable "
                      f"distances above {RANGE_MAX_COORDINATES} coordinates)")
        else:
            where += (f" are {reach} in the poses the other equations allow ({drawn:.4g} "
                      "as drawn)")
        return (f"distance joint '{joint.name}': the length L = {length:.6g} cannot be "
                f"reached: {where}; change the distance or move a point")
    pin = np.array([r for r, lab in zip(rows, culprit.equations, strict=True)
                    if lab in ("x", "y", "z")], dtype=int)  # the rows p1 − p2 of its point
    if joint is not None and getattr(joint, "point", None) is not None and pin.size:
        if len(free) <= RANGE_MAX_COORDINATES:
            gap = f"{_closest(model, q, t, pin, rest, free, tol):.4g} apart at least"
        else:
            gap = (f"{float(np.linalg.norm(model.constraints(q, t)[pin])):.4g} apart in the "
                   f"pose found (no search above {RANGE_MAX_COORDINATES} coordinates)")
        return (f"joint '{joint.name}' point ({_fmt(joint.point)}): with the other equations "
                f"satisfied, the points of {_body(joint.body1)} and {_body(joint.body2)} "
                f"would have to be {gap}; move the point or the body's initial position")
    return (f"{culprit}: with the other equations satisfied its equations "
            f"({', '.join(culprit.equations)}) are off by {culprit.mismatch:.3g}; check its "
            "definition and the bodies' initial positions")


def rank_culprits(model, q_start: np.ndarray, q_fail: np.ndarray, t: float,
                  free: np.ndarray, tol: float) -> tuple[list[Culprit], str]:
    """Elements of a failed assembly, most likely culprit first, and a note on the ranking.

    Parameters
    ----------
    q_start, q_fail : array
        The starting guess and the last Newton iterate.
    free : array of int
        The coordinates assembly may change.
    tol : float
        The assembly tolerance on max |C| at ``q_fail``: an element "fixes" the assembly when
        the others are then satisfied to ``100 · tol``.
    """
    labels = model.constraint_labels
    nc = len(labels)
    if len(free) * nc > MAX_ENTRIES:
        return [], (f"no culprit ranking: {len(free)} coordinates × {nc} equations exceed "
                    f"{MAX_ENTRIES} entries")
    c_fail = model.constraints(q_fail, t)
    c_start = model.constraints(q_start, t)
    groups: dict[tuple[str, str], list[int]] = {}
    for i, lab in enumerate(labels):
        if lab.kind != "body":  # a body's own equations (unit quaternion, …) are never at fault
            groups.setdefault((lab.kind, lab.element), []).append(i)
    score = {key: max(float(np.max(np.abs(c_fail[r]))), float(np.max(np.abs(c_start[r]))))
             for key, r in groups.items()}
    candidates = sorted((k for k in groups if np.isfinite(score[k])), key=lambda k: -score[k])
    tried = candidates[:MAX_CANDIDATES]
    fix_tol = 100.0 * tol
    all_rows = np.arange(nc)
    found: list[tuple[Culprit, np.ndarray, np.ndarray, np.ndarray]] = []
    for key in tried:
        rows = np.asarray(groups[key], dtype=int)
        rest = np.setdiff1d(all_rows, rows)
        q, c_rest = _least_squares(model, q_fail, t, rest, free, tol)
        remaining = float(np.max(np.abs(c_rest))) if c_rest.size else 0.0
        own = model.constraints(q, t)[rows]
        culprit = Culprit(key[0], key[1], [labels[i].label for i in rows],
                          fixes=bool(remaining <= fix_tol), remaining=remaining,
                          mismatch=float(np.max(np.abs(own))),
                          violated_at_start=bool(np.max(np.abs(c_start[rows])) > fix_tol))
        found.append((culprit, q, rows, rest))
    found.sort(key=lambda item: (not item[0].fixes, 0.0 if item[0].fixes else item[0].remaining,
                                 len(item[2]), not item[0].violated_at_start,
                                 item[0].mismatch))
    fixers = [c for c, *_ in found if c.fixes]
    for k, (culprit, q, rows, rest) in enumerate(found):
        if k == 0:
            culprit.hint = _hint(model, culprit, q, t, rows, rest, free, 10.0 * fix_tol,
                                 fixers)
        elif culprit.fixes:
            culprit.hint = f"{culprit}: the others assemble without it too"
        else:
            culprit.hint = f"{culprit}: residual {culprit.remaining:.3g} left without it"
    note = (f"ranked by the residual left when each of the {len(tried)} elements with the "
            "largest residuals is removed" + (f" (of {len(candidates)})"
                                              if len(candidates) > len(tried) else ""))
    return [c for c, *_ in found], note


def explain(model, q_start: np.ndarray, q_fail: np.ndarray, t: float, free: np.ndarray,
            tol: float) -> tuple[list[Culprit], str]:
    """The ranking and the sentence that follows an assembly failure's first clause."""
    culprits, note = rank_culprits(model, q_start, q_fail, t, free, tol)
    if not culprits:
        return culprits, f" ({note})" if note else ""
    text = f"; most likely culprit: {culprits[0].hint}"
    if len(culprits) > 1:
        text += ". Next: " + "; ".join(c.hint for c in culprits[1:4])
    return culprits, text + f" ({note})"

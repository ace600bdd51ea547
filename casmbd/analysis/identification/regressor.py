"""The joint-torque regressor Y(q, v, a): τ = Y π, exact by algorithmic differentiation.

The equations of motion are linear in the standard parameters π
(:mod:`casmbd.analysis.identification.parameters`; Atkeson, An & Hollerbach 1986; Khalil &
Dombre 2002, §9.3).  casmbd writes them here with π as CasADi symbols and takes the Jacobian
with respect to π, which is exact since the expression is linear in π (no finite differences,
no hand-derived regressor).

**The equations written with π.**  For each moving body b with origin O (a body point),
rotation A, angular velocity ω and the symbols (m, h̄ = m c̄, Ī_O) in the body axes, let
h = A h̄, I = A Ī_O Aᵀ, a_O = d/dt (J_O q̇) and α = d/dt (J_ω q̇).  Newton–Euler about O
(Khalil & Dombre, eqs. 9.53–9.54), with gravity g:

    F_b = m (a_O − g) + α × h + ω × (ω × h),
    N_b = I α + ω × (I ω) + h × (a_O − g),

and in the plane F_b = m (a_O − g) + α k × h − ω² h, N_b = I_zz α + h × (a_O − g) (a scalar).
By virtual power the generalized force of the inertia and weight of every body plus the joint
friction (casmbd's law, :mod:`casmbd.model.joint_friction`: Q_j = −F_v q̇_j −
F_c tanh(q̇_j / v_s), the *regularised* Coulomb law with v_s the element's ``regularization``,
default 1e-3) is

    f(q, q̇, q̈; π) = Σ_b (J_Oᵀ F_b + J_ωᵀ N_b) + Σ_j (∂s_j/∂q)ᵀ (F_v ṡ_j + F_c tanh(ṡ_j / v_s))

— the M q̈ + b of :func:`casmbd.compile` (b = −Q_v − Q_e), which Lagrange's equations give
up to terms along the constraint gradients (the Euler-parameter normalisation), absorbed by
the multipliers.  The generalized regressor is Y_f = ∂f/∂π.

**Floating bases** (a spatial body without a tree joint in joint coordinates): the per-call
API's free-flyer velocity v (:mod:`casmbd.compiled.free_flyer`, q̇ = G(q) v, Pinocchio's
convention), τ_v = Gᵀ f(q, G v, G a + Ġ v): the first six rows of a floating root are the
wrench on it (force, moment about its reference point, in its own axes), as Pinocchio's.

**Closed chains** (constraint equations C_q q̈ = γ besides the bodies' normalisations):
the inverse dynamics with multipliers, as :func:`casmbd.analysis.driven.inverse.
inverse_dynamics` and :meth:`casmbd.compiled.robot.CompiledModel.inverse_dynamics`.  With
the efforts τ_a along the actuation directions B (a driver's row of C_q: the driver efforts
−λ_d of ``inverse_dynamics``; with drivers *and* actuators the actuators' B = ∂Q_e/∂u, the
actuator efforts of ``inverse_dynamics``' mixed case, the drivers only describing the motion;
or unit columns of the *actuated* coordinates of the per-call API) and the multipliers λ of
the other rows,

    [B  −C_qᵀ] [τ_a; λ] = f(q, v, a; π),

a linear system with a matrix independent of π: τ_a = [K⁻¹ Y_f]_a π is linear in π at every
(q, v, a) consistent with the constraints (C_q a = γ).  K is solved in the generated code
(CasADi's ``qr`` linear solver); a tall K (more rows than unknowns) by its normal equations.
Without drivers nor a choice of actuated coordinates every coordinate is actuated and the
efforts are the least-norm ones, τ = (1 − C_qᵀ (C_q C_qᵀ)⁻¹ C_q) f, as the per-call API.

Forces other than gravity and joint friction (springs, dampers, user forces, contacts) are not
linear in π and are refused, naming the element.
"""

from __future__ import annotations

import math
import re
from collections.abc import Sequence
from dataclasses import dataclass, field

import casadi as ca
import numpy as np

from casmbd.analysis.identification.parameters import (
    StandardParameters,
    check_linear_friction,
    default_friction_joints,
    standard_parameters,
)
from casmbd.compiled.buffered import BufferedFunction
from casmbd.compiled.build import compile_blocks
from casmbd.compiled.free_flyer import VelocityMap, is_normalization
from casmbd.errors import ModelError, SingularConfigurationError
from casmbd.interrupts import reraise_interrupt
from casmbd.model.joint_friction import JointFriction
from casmbd.system.equations import System

__all__ = ["BATCH_CHUNK", "JointTorqueRegressor", "joint_torque_regressor"]

#: samples per call of the compiled batch Function (``Function.map`` over a fixed number of
#: columns); N samples make ⌈N / BATCH_CHUNK⌉ calls, the last one padded with its last state
BATCH_CHUNK = 32


@dataclass
class JointTorqueRegressor:
    """Y(q, v, a) of a mechanism, compiled (module docstring).

    Attributes
    ----------
    parameters : StandardParameters
        π: names, nominal values, frames, friction coordinates.
    rows : list of str
        What each row of Y is: with drivers, the actuator names when the mechanism has
        actuators (their efforts u, the mixed case of ``inverse_dynamics``), else the driver
        names (efforts −λ_d); without drivers, the actuated coordinates (velocity names of
        the per-call API; actuators are then ignored, u = 0, as :func:`casmbd.compile`).
    function : casadi.Function
        ``regressor(q, v, a) -> Y`` (n_rows × n_π), compiled (or CasADi's VM).
    batch : casadi.Function
        ``regressor_batch``: ``function`` mapped over :data:`BATCH_CHUNK` columns (q, v, a
        of shape n × BATCH_CHUNK, Y horizontally stacked; :meth:`stacked` pads the last
        chunk with its last state, since q = 0 is no pose of a body with Euler parameters).
    symbolic : casadi.Function
        The same Y before compilation, for embedding in other expressions (an OCP, the C
        export).
    nq, nv : int
        Sizes of q and of v, a (n_v = n_q − 1 per floating base).
    coordinate_names, velocity_names : list of str
    kinematics : casadi.Function or None
        With constraint equations (besides drivers and normalisations): ``(q, v) -> (C,
        C_q G, γ − C_q Ġ v, ∂C/∂q)`` of those rows at t = 0 (CasADi's VM), for consistent
        states (:func:`~casmbd.analysis.identification.base_parameters.random_states`).
    initial_coordinates : ndarray
        q at the design pose (the bodies' initial poses).
    floating_blocks : list of int
        Where each floating base's 7 coordinates start in q.
    """

    parameters: StandardParameters
    rows: list[str]
    function: ca.Function
    batch: ca.Function
    symbolic: ca.Function
    nq: int
    nv: int
    coordinate_names: list[str]
    velocity_names: list[str]
    kinematics: ca.Function | None = None
    initial_coordinates: np.ndarray | None = None
    floating_blocks: list[int] | None = None
    _calls: dict = field(default_factory=dict, init=False, repr=False)

    def _call(self, which: str) -> BufferedFunction:
        """The compiled Function bound to NumPy buffers (no CasADi conversion per call)."""
        if which not in self._calls:
            self._calls[which] = BufferedFunction(getattr(self, which))
        return self._calls[which]

    @property
    def names(self) -> list[str]:
        """The names of π (columns of Y)."""
        return self.parameters.names

    def _check(self, x, n: int, what: str) -> np.ndarray:
        arr = np.asarray(x, dtype=float)
        if arr.shape != (n,) or not np.all(np.isfinite(arr)):
            raise ModelError(f"regressor: {what} must be a finite vector of length {n}, got "
                             f"shape {arr.shape}")
        return arr

    def __call__(self, q, v, a) -> np.ndarray:
        """Y at one state, shape (n_rows, n_π)."""
        call = self._call("function")
        try:  # the buffers' shapes check the lengths; finiteness is checked on Y
            if len(q) != self.nq or len(v) != self.nv or len(a) != self.nv:
                raise ValueError
            y = self._evaluate(call, q, v, a)
        except (ValueError, TypeError):
            y = None
        if y is None or not math.isfinite(float(y.sum())):
            self._check(q, self.nq, "q")  # name a bad argument, else the singular state
            self._check(v, self.nv, "v")
            self._check(a, self.nv, "a")
            y = self._finite(self._evaluate(call, q, v, a), "this state")
        return y.reshape((len(self.rows), -1), order="F")

    def _evaluate(self, function: BufferedFunction, *args) -> np.ndarray:
        try:
            return function(*args)
        except RuntimeError as exc:  # CasADi's linear solver at a singular configuration
            reraise_interrupt(exc)
            raise SingularConfigurationError(
                "regressor: the effort system [B −C_qᵀ] is singular at this configuration "
                f"(efforts {', '.join(self.rows)})") from None

    def _finite(self, y: np.ndarray, where: str) -> np.ndarray:
        if not np.all(np.isfinite(y)):
            raise SingularConfigurationError(
                f"regressor: Y is not finite at {where}: the effort system [B −C_qᵀ] is "
                f"singular there (efforts {', '.join(self.rows)})")
        return y

    def torques(self, q, v, a, pi=None) -> np.ndarray:
        """τ = Y(q, v, a) π (default the nominal π)."""
        pi = self.parameters.values if pi is None else np.asarray(pi, float)
        return self(q, v, a) @ pi

    def stacked(self, Q, V, A) -> np.ndarray:
        """Y at N states stacked by rows, shape (N · n_rows, n_π): rows k n_rows … (k + 1)
        n_rows − 1 are state k (the compiled batch, no Python loop per sample; a failed
        evaluation — a singular constraint system at some state — is a CasADi error)."""
        mats = [np.asarray(x, dtype=float) for x in (Q, V, A)]
        n = mats[0].shape[0] if mats[0].ndim == 2 else -1
        widths = (self.nq, self.nv, self.nv)
        if n < 0 or any(x.shape != (n, w) for x, w in zip(mats, widths, strict=True)):
            raise ModelError(f"regressor: Q, V, A must be arrays of shape (N, {self.nq}), "
                             f"(N, {self.nv}), (N, {self.nv}); got {[x.shape for x in mats]}")
        if not all(np.all(np.isfinite(x)) for x in mats):
            raise ModelError("regressor: Q, V, A must be finite")
        nr, npi, c = len(self.rows), len(self.names), BATCH_CHUNK
        out = np.empty((n, nr, npi))
        for start in range(0, n, c):
            m = min(c, n - start)
            args = [np.zeros((w, c)) for w in widths]
            for arg, x in zip(args, mats, strict=True):
                arg[:, :m] = x[start:start + m].T
                arg[:, m:] = x[start + m - 1][:, None]  # padded with a valid state
            y = self._finite(self._evaluate(self._call("batch"), *args),
                             f"a state of {start} … {start + m - 1}")
            y = y.reshape((nr, c * npi), order="F")  # state blocks of npi columns
            out[start:start + m] = y.reshape(nr, c, npi).transpose(1, 0, 2)[:m]
        return out.reshape(n * nr, npi)


def _refuse_nonlinear_forces(mech, params: StandardParameters) -> None:
    """Every force must be joint friction on a coordinate of π with its laws (or zero)."""
    carried = {(fc.joint, fc.coordinate) for fc in params.friction_coordinates}
    for force in mech.forces.values():
        if not isinstance(force, JointFriction):
            raise ModelError(
                f"force '{force.name}' ({force.kind}): the regressor covers gravity and joint "
                "friction (viscous, Coulomb), whose forces are linear in the parameters; "
                "remove this element (or subtract its known force from the measured efforts)")
        check_linear_friction(force)  # no reaction-proportional level, no stick-slip
        pairs = {"viscous": force.damping, "coulomb": force.friction}
        missing = [law for law, val in pairs.items()
                   if not (isinstance(val, (int, float)) and val == 0.0)
                   and ((force.joint, force.coordinate) not in carried
                        or law not in params.friction)]
        if missing:
            raise ModelError(
                f"force '{force.name}': joint '{force.joint}' has {' and '.join(missing)} "
                f"friction that the parameters do not carry; pass friction=("
                f"{', '.join(repr(x) for x in ('viscous', 'coulomb'))}) to include it")
    for kind in ("contacts",):
        items = getattr(mech, kind, None)
        if items:
            raise ModelError(f"{kind[:-1]} '{next(iter(items))}': contact forces are not linear "
                             "in the inertial parameters; the regressor refuses them")


def generalized_regressor(system: System, params: StandardParameters
                          ) -> tuple[ca.SX, ca.SX, ca.SX]:
    """(f, π, q̈): the generalized efforts f(q, q̇, q̈; π) of the bodies' inertia and weight
    and the joint friction (module docstring) as expressions of the system's q, v (= q̇), the
    returned symbols π and q̈; linear in π."""
    ctx, mech, dim = system.ctx, system.mechanism, system.dimension
    q, qd = system.q, system.v
    qdd = ca.SX.sym("qdd", system.nq)
    pi = ca.SX.sym("pi", len(params))
    grav = ca.DM(np.asarray(mech.gravity, float))
    per = params.per_body
    total = ca.SX.zeros(system.nq)
    for k, name in enumerate(params.bodies):
        blk = pi[k * per:(k + 1) * per]
        point = ctx.point(name, params.origins[name])
        rot = ctx.rotation(name)
        omega = ctx.angular_velocity(name)
        vel = ca.jtimes(point, q, qd)
        acc = ca.jtimes(vel, q, qd) + ca.jtimes(vel, qd, qdd) - grav
        alpha = ca.jtimes(omega, q, qd) + ca.jtimes(omega, qd, qdd)
        mass = blk[0]
        if dim == 3:
            h = ca.mtimes(rot, blk[1:4])
            tensor = ca.vertcat(ca.horzcat(blk[4], blk[5], blk[6]),
                                ca.horzcat(blk[5], blk[7], blk[8]),
                                ca.horzcat(blk[6], blk[8], blk[9]))
            tensor = ca.mtimes([rot, tensor, rot.T])
            force = mass * acc + ca.cross(alpha, h) + ca.cross(omega, ca.cross(omega, h))
            moment = (ca.mtimes(tensor, alpha) + ca.cross(omega, ca.mtimes(tensor, omega))
                      + ca.cross(h, acc))
        else:
            h = ca.mtimes(rot, blk[1:3])
            force = mass * acc + alpha * ca.vertcat(-h[1], h[0]) - omega ** 2 * h
            moment = blk[3] * alpha + h[0] * acc[1] - h[1] * acc[0]
        total += ca.jtimes(vel, qd, force, True) + ca.jtimes(omega, qd, moment, True)
    base = per * len(params.bodies)
    laws = params.friction
    for i, fc in enumerate(params.friction_coordinates):
        measure = mech.joints[fc.joint].coordinate(ctx, fc.coordinate)
        rate = ca.jtimes(measure, q, qd)
        weight = ca.SX(0.0)
        for j, law in enumerate(laws):
            coef = pi[base + i * len(laws) + j]
            weight += coef * (rate if law == "viscous" else ca.tanh(rate / fc.regularization))
        total += ca.jtimes(measure, q, weight, True)
    # a call has no time and no actuator input (as the per-call API)
    total = ca.substitute([total], [system.t, system.u],
                          [ca.SX(0.0), ca.SX.zeros(system.u.numel())])[0]
    return total, pi, qdd


def _c_name(text: str) -> str:
    return re.sub(r"\W", "_", text)


def joint_torque_regressor(mechanism, friction: Sequence[str] | str | None = (), *,
                           frame: str = "body", coordinates: str | None = "joint",
                           actuated: Sequence[str] | None = None,
                           friction_joints: Sequence[str] | None = None,
                           regularization: float | None = None,
                           mode: str = "auto") -> JointTorqueRegressor:
    """The compiled joint-torque regressor Y(q, v, a) of ``mechanism``: τ = Y π.

    Parameters
    ----------
    mechanism : Mechanism
        Bodies, joints, drivers, gravity and joint friction (``joint_friction`` elements,
        viscous and constant Coulomb level); other forces are refused.
    friction : sequence of {"viscous", "coulomb"} or str
        Friction laws whose coefficients join π (default none).
    frame : {"body", "joint"}
        The origin of each body's inertial parameters
        (:mod:`casmbd.analysis.identification.parameters`).
    coordinates : {"joint", "absolute", "natural"} or None
        Generalized coordinates (default ``"joint"``, as :func:`casmbd.compile`; None: the
        mechanism's choice).
    actuated : sequence of str, optional
        Without drivers: the coordinates (velocity names) that carry the efforts, as
        :func:`casmbd.compile`'s ``actuated``; default all.  With drivers the rows are the
        drivers' efforts and ``actuated`` must be None.
    friction_joints : sequence of str, optional
        Joints with friction parameters; default the joints of the efforts' coordinates
        (driven joints with drivers) and every joint with a ``joint_friction`` element.
    regularization : float, optional
        v_s of the Coulomb law (default each element's own, else 1e-3).
    mode : {"auto", "compiled", "vm"}
        Compile the C code (cached) or use CasADi's virtual machine.

    Returns
    -------
    JointTorqueRegressor
        ``reg(q, v, a)`` is Y (n_rows × n_π), ``reg.stacked(Q, V, A)`` N states stacked,
        ``reg.function``/``reg.batch`` the compiled Functions, ``reg.parameters`` π.

    Raises
    ------
    ModelError
        A force that is not linear in π, unknown names, a closed chain whose effort system
        [B −C_qᵀ] has more unknowns than equations.
    """
    mech = mechanism
    mech.validate()
    system = System(mech, coordinates=coordinates)
    vmap = VelocityMap(system)
    coordinate_names = list(system.coordinate_names)
    velocity_names = vmap.velocity_names(coordinate_names)
    labels = system.constraint_labels
    drivers = [i for i, lab in enumerate(labels) if lab.kind == "driver"]
    kept = [i for i, lab in enumerate(labels)
            if lab.kind != "driver" and not is_normalization(lab, vmap.bodies)]
    if drivers and actuated is not None:
        raise ModelError("regressor: the mechanism has drivers, whose efforts are the rows; "
                         "'actuated' applies to a mechanism without drivers")
    actuators = list(mech.actuators) if drivers else []
    if actuators:  # the mixed case of inverse_dynamics: the actuators produce the motion
        rows = actuators
        effort_joints = [mech.actuators[name].joint for name in rows]
    elif drivers:
        rows = [labels[i].element for i in drivers]
        effort_joints = [mech.drivers[d].joint for d in rows if mech.drivers[d].joint]
    else:
        rows = list(velocity_names) if actuated is None else (
            [actuated] if isinstance(actuated, str) else list(actuated))
        for name in rows:
            if name not in velocity_names:
                raise ModelError(f"regressor: actuated coordinate '{name}' unknown "
                                 f"(coordinates: {', '.join(velocity_names)})")
        if len(set(rows)) != len(rows):
            raise ModelError(f"regressor: actuated coordinates repeated: {rows}")
        effort_joints = [n.rsplit(".", 1)[0] for n in rows
                         if n.rsplit(".", 1)[0] in mech.joints]
    if friction_joints is None:
        friction_joints = default_friction_joints(mech, effort_joints)
    params = standard_parameters(mech, friction, frame=frame, friction_joints=friction_joints,
                                 regularization=regularization)
    _refuse_nonlinear_forces(mech, params)

    force_q, pi, qdd = generalized_regressor(system, params)
    y_q = ca.jacobian(force_q, pi)
    q, nq, nv = system.q, system.nq, vmap.nv
    vel, acc = ca.SX.sym("v", nv), ca.SX.sym("a", nv)
    rates = vmap.rates(q, vel)
    g_mat = ca.jacobian(rates, vel)
    rate_acc = ca.mtimes(g_mat, acc) + ca.jtimes(rates, q, rates)
    y_v = ca.mtimes(g_mat.T, ca.substitute([y_q], [system.v, qdd], [rates, rate_acc])[0])
    y_v = ca.densify(y_v)
    at_rest = [system.t, system.u]
    zeros = [ca.SX(0.0), ca.SX.zeros(system.u.numel())]
    jac = ca.substitute([system.constraint_jacobian], at_rest, zeros)[0]
    jac = ca.mtimes(jac, g_mat)  # rows of C_q acting on v
    n_pi = len(params)
    if not kept and not drivers:  # a tree: the rows of the actuated coordinates
        sel = [velocity_names.index(n) for n in rows]
        symbolic = ca.Function("regressor", [q, vel, acc], [y_v[sel, :]], ["q", "v", "a"],
                               ["Y"])
    else:
        y_fun = ca.Function("regressor_free", [q, vel, acc], [y_v])
        c_rows = ca.densify(jac[kept, :]) if kept else ca.SX(0, nv)
        if actuators:  # B = ∂Q_e/∂u: each actuator's coordinate gradient (on v)
            grads = [ca.jacobian(mech.joints[act.joint].coordinate(system.ctx, act.coordinate),
                                 q).T for act in mech.actuators.values()]
            b_mat = ca.densify(ca.mtimes(g_mat.T, ca.horzcat(*grads)))
        elif drivers:
            b_mat = ca.densify(jac[drivers, :]).T
        elif len(rows) < nv:
            b_mat = ca.SX(ca.DM.eye(nv)[:, [velocity_names.index(n) for n in rows]])
        else:
            b_mat = None
        qm, vm, am = ca.MX.sym("q", nq), ca.MX.sym("v", nv), ca.MX.sym("a", nv)
        y_free = y_fun(qm, vm, am)
        c_fun = ca.Function("regressor_constraints", [q], [c_rows])
        c_mx = c_fun(qm)
        if b_mat is None:  # every coordinate actuated: the least-norm efforts
            lam = ca.solve(ca.mtimes(c_mx, c_mx.T), ca.mtimes(c_mx, y_free), "qr")
            y_out = y_free - ca.mtimes(c_mx.T, lam)
        else:
            k_fun = ca.Function("regressor_kkt", [q], [ca.horzcat(b_mat, -c_rows.T)])
            k_mx = k_fun(qm)
            n_unknown = k_mx.size2()
            if n_unknown > nv:
                raise ModelError(
                    f"regressor: {len(rows)} efforts ({', '.join(rows)}) and {len(kept)} "
                    f"constraint equations exceed the {nv} coordinates: the efforts and "
                    "multipliers are not unique (redundant constraints or actuation)")
            if n_unknown == nv:
                sol = ca.solve(k_mx, y_free, "qr")
            else:
                sol = ca.solve(ca.mtimes(k_mx.T, k_mx), ca.mtimes(k_mx.T, y_free), "qr")
            y_out = sol[:len(rows), :]
        symbolic = ca.Function("regressor", [qm, vm, am], [ca.densify(y_out)],
                               ["q", "v", "a"], ["Y"])
    kinematics = None
    if kept:
        cons = ca.substitute([system.constraints[kept]], at_rest, zeros)[0]
        gamma = ca.substitute([system.acceleration_rhs[kept]], at_rest, zeros)[0]
        cq_rows = ca.substitute([system.constraint_jacobian[kept, :]], at_rest, zeros)[0]
        gamma = (ca.substitute([gamma], [system.v], [rates])[0]
                 - ca.mtimes(cq_rows, ca.jtimes(rates, q, rates)))
        kinematics = ca.Function("regressor_kinematics", [q, vel], [
            ca.densify(cons), ca.densify(jac[kept, :]), ca.densify(gamma),
            ca.densify(ca.jacobian(cons, q))])
    assert symbolic.size_out(0) == (len(rows), n_pi)
    batch = symbolic.map("regressor_batch", "serial", BATCH_CHUNK, [], [])
    compiled, _ = compile_blocks([symbolic, batch], f"regressor_{_c_name(mech.name)}",
                                 mode=mode)
    return JointTorqueRegressor(params, rows, compiled["regressor"],
                                compiled["regressor_batch"], symbolic, nq, nv,
                                coordinate_names, velocity_names, kinematics,
                                system.initial_coordinates(), [b.q for b in vmap.blocks])

"""A per-call numeric API of a compiled mechanism: :func:`compile` and :class:`CompiledModel`.

Like Pinocchio's ``aba``/``rnea``/``crba`` on a ``Model`` and its ``Data``, a
:class:`CompiledModel` evaluates the dynamics of one mechanism at one state per call, numpy in
and numpy out, with no CasADi conversion on the way: every method owns a compiled CasADi
Function whose inputs and outputs are bound once, through ``Function.buffer()``, to numpy
arrays allocated when the model is built
(:class:`~casmbd.compiled.buffered.BufferedFunction`).  A call copies its arguments into
those arrays, runs the compiled C code and returns a *copy* of the result, so a caller
cannot alias the buffers; a model serves one caller at a time (take one per thread).

Conventions (n_q coordinates, joint coordinates by default):

* equations of motion ``M(q) q̈ + b(q, v) = τ`` with τ the generalized forces on the
  coordinates (joint torques and forces in joint coordinates).  casmbd writes Lagrange's
  equations as ``M q̈ = Q_e + Q_v`` (:attr:`System.quadratic_velocity_forces
  <casmbd.system.equations.System.quadratic_velocity_forces>`), so the bias is
  ``b = −Q_v − Q_e`` with Q_e the mechanism's own applied forces (gravity, springs, dampers)
  at t = 0 and actuator inputs u = 0 — Pinocchio's ``nle`` (Coriolis, centrifugal and gravity
  terms);
* a tree of revolute and prismatic joints under gravity (mimic followers substituted) is
  written by Featherstone's recursions in local body frames, as Pinocchio
  (:mod:`casmbd.compiled.spatial_recursions`: CRBA, RNEA, ABA, kinematics and Jacobians;
  :data:`SPATIAL_RECURSIONS`); other trees as follows;
* ``forward_dynamics`` of a tree in joint coordinates is the articulated-body recursion with τ
  as the joint efforts (:mod:`casmbd.compiled.tree_dynamics`: O(N), as are the mass matrix,
  the Newton–Euler τ and b, and the frame Jacobians there); a tree the recursion does not
  cover solves ``M q̈ = τ − b`` by a dense LDLᵀ factorisation written into the generated code
  (no pivoting: M is symmetric positive definite); with constraint equations (closed chains,
  Euler parameters) it solves the KKT system ``[M C_qᵀ; C_q 0] [q̈; λ] = [τ − b; γ]`` in numpy
  from the compiled pieces;
* ``inverse_dynamics`` returns ``τ = M a + b``, for a tree in joint coordinates by the
  recursive Newton–Euler algorithm (:func:`newton_euler`, also used for b), else from M.  With
  constraint equations (closed loops, gears, Euler parameters) the equations of motion are
  ``M a + b + C_qᵀ λ = τ`` (Shabana's sign: the constraint forces are −C_qᵀ λ) and the efforts
  act only on the *actuated* coordinates, τ = S τ_a (S the columns of the identity for
  :attr:`CompiledModel.actuated`): the loop-closure multipliers λ and τ_a solve the linear system
  ``[S  −C_qᵀ] [τ_a; λ] = M a + b`` — square and regular when the actuated coordinates are a set
  of independent coordinates (as many as degrees of freedom, C_q restricted to the others
  regular), as the driver efforts of seed 000's inverse dynamics.  Without a choice every
  coordinate is actuated (a redundantly actuated machine) and τ is the least-norm effort, the
  projection of M a + b on the null space of C_q, λ = −(C_q C_qᵀ)⁻¹ C_q (M a + b);
* a *frame* is a body (origin at its centre of mass, axes the body axes) or a marker (its
  point, its own axes: the body's times the marker's fixed orientation offset).
  ``jacobian(q, frame)`` is the ``(3 + 3) × n_q`` (spatial) or ``(2 + 1) × n_q`` (planar)
  matrix J with
  ``(ṙ, ω) = J v``: rows the linear velocity of the frame's point then the angular velocity,
  global components — Pinocchio's ``LOCAL_WORLD_ALIGNED`` convention (not ``WORLD``, whose
  linear part is the velocity of the body point at the world origin);
* a floating base (a spatial body without a tree joint in joint coordinates, e.g.
  ``load_urdf(path, floating_base=True)``) takes Pinocchio's free-flyer velocity: v and τ have
  n_v = n_q − 1 entries per floating root (the root's linear and angular velocity in its own
  axes, q̇ = G(q) v), M is n_v × n_v, and :meth:`CompiledModel.integrate` /
  :meth:`CompiledModel.difference` move on SE(3) (:mod:`casmbd.compiled.free_flyer`).
"""

from __future__ import annotations

import math
import os
from collections.abc import Sequence

import casadi as ca
import numpy as np

from casmbd.compiled.buffered import BufferedFunction
from casmbd.compiled.build import compile_model
from casmbd.compiled.free_flyer import VelocityMap, is_normalization, velocity_functions
from casmbd.compiled.spatial_recursions import SpatialTree, unsupported
from casmbd.compiled.tree_dynamics import FUNCTION_OPTIONS, forward_dynamics, frame_jacobian
from casmbd.errors import ModelError, SingularConfigurationError, SingularMassMatrixError
from casmbd.model.bodies import GROUND
from casmbd.model.needs import Handling, check
from casmbd.system.articulated_body import motion_transform, supported
from casmbd.system.equations import System

__all__ = ["BATCH_CHUNK", "SPATIAL_RECURSIONS", "CompiledModel", "compile"]

#: write the per-call Functions of a covered tree (single-coordinate revolute and prismatic
#: joints, rigid links, gravity only) by Featherstone's spatial algebra in local body frames
#: (:mod:`casmbd.compiled.spatial_recursions`); False: the global-component tree recursions
#: (environment: ``CASMBD_SPATIAL_RECURSIONS=0`` turns it off, for comparisons)
SPATIAL_RECURSIONS = os.environ.get("CASMBD_SPATIAL_RECURSIONS", "1") != "0"

#: samples per call of the compiled batch Functions (``Function.map`` over a fixed number of
#: columns, compiled once with the model); a batch of N samples makes ⌈N / BATCH_CHUNK⌉ calls,
#: the last one padded with zeros
BATCH_CHUNK = 64


def ldl_solve(m: ca.SX, rhs: ca.SX) -> ca.SX:
    """x with ``m x = rhs`` by a dense LDLᵀ factorisation without pivoting, as expressions.

    ``m`` must be symmetric positive definite (a mass matrix).  ``L`` unit lower triangular,
    ``D`` diagonal: ``d_j = m_jj − Σ_k L_jk² d_k``, ``L_ij = (m_ij − Σ_k L_ik L_jk d_k) / d_j``
    (Golub & Van Loan, Matrix Computations, alg. 4.1.2), then forward, diagonal and back
    substitution; n³/6 multiplications, structural zeros of ``m`` kept out.
    """
    n = m.size1()
    low = [[None] * n for _ in range(n)]
    d = [None] * n
    for j in range(n):
        ld = [low[j][k] * d[k] for k in range(j)]
        d[j] = m[j, j] - sum((ld[k] * low[j][k] for k in range(j)), ca.SX(0))
        for i in range(j + 1, n):
            s = m[i, j] - sum((low[i][k] * ld[k] for k in range(j)), ca.SX(0))
            low[i][j] = s / d[j]
    y = [None] * n
    for i in range(n):
        y[i] = rhs[i] - sum((low[i][k] * y[k] for k in range(i)), ca.SX(0))
    x = [None] * n
    for i in reversed(range(n)):
        x[i] = y[i] / d[i] - sum((low[k][i] * x[k] for k in range(i + 1, n)), ca.SX(0))
    return ca.vertcat(*x) if n else ca.SX(0, 1)


def newton_euler(system: System, a: ca.SX) -> ca.SX:
    """Σ_i J_iᵀ (I_i A_i + (ω_i × I_i ω_i, 0)) of a tree in joint coordinates, recursively.

    The recursive Newton–Euler algorithm (Featherstone, Rigid Body Dynamics Algorithms, §5.3)
    in the articulated recursion's conventions (:mod:`casmbd.system.articulated_body`: twists
    (ω, ṙ_G) at the centres of mass, global components): outward A_i = X_i A_P + S_i a_i
    + c_i with c_i = J̇_i q̇ − X_i J̇_P q̇, body wrench F_i = (I_G α + ω × I_G ω, m a_G);
    inward F_P += X_iᵀ F_i and τ_i = S_iᵀ F_i.  This is M a − Q_v; the caller subtracts the
    applied forces Q_e.  O(N) operations against the O(N²) of M a.
    """
    ctx, dim, desc, tk = system.ctx, system.dimension, system.descriptions, system.tree_kinematics
    nw = 1 if dim == 2 else 3
    order: list[str] = []

    def visit(name: str) -> None:
        if name not in order:
            if desc[name].parent != GROUND:
                visit(desc[name].parent)
            order.append(name)

    for name in system.body_names:
        visit(name)
    acc, force, xform = {}, {}, {}
    for name in order:
        parent = desc[name].parent
        step = tk.bias[name] + ca.mtimes(tk.motion[name], system.body_part(a, tk.owner[name]))
        if parent == GROUND:
            acc[name] = step
        else:
            xform[name] = motion_transform(ctx.centre_of_mass(name) - ctx.centre_of_mass(parent),
                                           dim)
            acc[name] = step + ca.mtimes(xform[name], acc[parent] - tk.bias[parent])
        mass, tensor = system._mass_inertia(system.mechanism.bodies[name])
        if dim == 2:
            moment = tensor * acc[name][0]
        else:
            rot, omega = ctx.rotation(name), tk.twist[name][:3]
            tensor = ca.mtimes([rot, tensor, rot.T])
            moment = ca.mtimes(tensor, acc[name][:3]) + ca.cross(omega,
                                                                 ca.mtimes(tensor, omega))
        force[name] = ca.vertcat(moment, mass * acc[name][nw:])
    tau = {name: ca.SX.zeros(system.body_part(a, name).numel(), 1) for name in order}
    for name in reversed(order):  # a mimic follower's torque adds into its leader's (r S_fᵀ F)
        owner = tk.owner[name]
        tau[owner] = tau[owner] + ca.mtimes(tk.motion[name].T, force[name])
        if desc[name].parent != GROUND:
            parent = desc[name].parent
            force[parent] = force[parent] + ca.mtimes(xform[name].T, force[name])
    return ca.vertcat(*[tau[name] for name in system.body_names])



def _offset_matrix(offset, dim: int) -> np.ndarray:
    """A marker's fixed rotation relative to its body (:meth:`Marker.offset`: a 3×3 matrix in
    space, an angle in the plane) as a ``dim × dim`` matrix."""
    if dim == 3:
        return np.asarray(offset, dtype=float)
    c, s = np.cos(float(offset)), np.sin(float(offset))
    return np.array([[c, -s], [s, c]])

class _Call:
    """One compiled Function bound to numpy buffers: fill ``a0, a1, a2``, ``trigger()``, read
    ``outs`` (``view``: output 0 in the shape the method returns)."""

    __slots__ = ("a0", "a1", "a2", "buffered", "ins", "outs", "trigger", "view")

    def __init__(self, f: ca.Function, p: np.ndarray, shape=None):
        # the model's parameter vector itself bound to p: set_parameters applies at once
        self.buffered = BufferedFunction(f, [None] * (f.n_in() - 1) + [p])
        self.trigger, self.outs = self.buffered.evaluate, self.buffered.outputs
        args = self.ins = self.buffered.inputs
        self.a0, self.a1, self.a2 = [*args[:-1], None, None, None][:3]
        self.view = self.outs[0] if shape is None else shape(self.outs[0])


class CompiledModel:
    """Compiled dynamics and kinematics of a mechanism, one state per call (module docstring).

    Parameters
    ----------
    mechanism : Mechanism or System
        The description (or its symbolic equations, used as they are).
    coordinates : {"joint", "absolute", "natural"} or None
        Generalized coordinates (default ``"joint"``; None: the mechanism's own choice).
    mode : {"auto", "compiled", "vm"}
        As :class:`~casmbd.compiled.model.NumericModel`: C code compiled and cached, or
        CasADi's virtual machine.
    actuated : sequence of str, optional
        Coordinates (names of :attr:`coordinate_names`) that carry the efforts of
        :meth:`inverse_dynamics` when the mechanism has constraint equations; default all.

    Attributes
    ----------
    numeric : NumericModel
        The compiled library (sizes, names, parameter values :attr:`p`).
    frame_names : list of str
        Bodies then markers: the rows of :meth:`forward_kinematics` and the frames of
        :meth:`jacobian`.
    """

    def __init__(self, mechanism, coordinates: str | None = "joint", mode: str = "auto",
                 actuated: Sequence[str] | None = None):
        system = (mechanism if isinstance(mechanism, System)
                  else System(mechanism, coordinates=coordinates))
        self.dimension = dim = system.dimension
        self.nq, self.nc = system.nq, system.nc
        #: q̇ = G(q) v: v of size n_v (free-flyer velocities of floating bases,
        #: :mod:`casmbd.compiled.free_flyer`), n_v = n_q without one
        self.velocity_map = vmap = VelocityMap(system)
        self.nv = vmap.nv
        q, v, p, nq = system.q, system.v, system.p, system.nq
        tau = ca.SX.sym("tau", nq)
        a = ca.SX.sym("a", nq)
        zero_tu = [system.t, system.u]
        zeros = [ca.SX(0.0), ca.SX.zeros(system.u.numel())]

        def at_rest(expr):  # t = 0, actuator inputs u = 0
            return ca.substitute([expr], zero_tu, zeros)[0]

        # a tree of revolute and prismatic joints: Featherstone's recursions in body frames
        spatial = (SPATIAL_RECURSIONS and vmap.identity and system.coordinates == "joint"
                   and unsupported(system) is None)
        tree = SpatialTree(system, q) if spatial else None
        mass = ca.densify(tree.mass_matrix() if spatial else system.mass_matrix)
        applied = None if spatial else at_rest(system.applied_forces)
        # a tree in joint coordinates (mimic followers substituted too): Newton–Euler
        recursive = spatial or supported(system, mimic=True) is None
        # the articulated-body recursion (and the frame Jacobians by motion subspaces): a tree
        # without substituted mimic followers (their subspace is on the leader's coordinate)
        articulated = spatial or supported(system) is None
        if spatial:
            inverse = tree.inverse_dynamics(v, a)
            bias = ca.densify(tree.inverse_dynamics(v, ca.SX.zeros(nq)))
        elif recursive:
            inverse = newton_euler(system, a) - applied
            bias = ca.densify(ca.substitute(inverse, a, ca.SX.zeros(nq)))
        else:
            bias = ca.densify(-at_rest(system.quadratic_velocity_forces) - applied)
            inverse = ca.mtimes(mass, a) + bias
        # every output dense: the bound arrays hold every entry (a ground marker's rotation
        # or a joint free of gravity would otherwise leave structural zeros out)
        # a tree: O(N) recursions with shared subexpressions (casmbd.compiled.tree_dynamics)
        opts = dict(FUNCTION_OPTIONS) if recursive else {}
        fns = [ca.Function("robot_mass_matrix", [q, p], [mass], ["q", "p"], ["M"], opts),
               ca.Function("robot_bias", [q, v, p], [bias], ["q", "v", "p"], ["b"], opts)]
        if self.nc == 0:
            qdd = ca.densify(tree.forward_dynamics(v, tau) if spatial and tree.articulated
                             else forward_dynamics(system, tau) if articulated and not spatial
                             else ldl_solve(mass, tau - bias))
            # Σ q̈ᵢ, finite iff q̈ is (a zero pivot or a zero articulated inertia gives inf or
            # nan): the per-call test of a singular mass matrix
            fd = ca.Function("robot_fd", [q, v, tau, p], [qdd, ca.sum1(qdd)],
                             ["q", "v", "tau", "p"], ["a", "sum"], opts)
            ind = ca.Function("robot_id", [q, v, a, p], [ca.densify(inverse)],
                              ["q", "v", "a", "p"], ["tau"], opts)
            fns += [fd, ind, fd.map("robot_fd_batch", "serial", BATCH_CHUNK, [3], []),
                    ind.map("robot_id_batch", "serial", BATCH_CHUNK, [3], [])]
        else:
            cq = ca.densify(at_rest(system.constraint_jacobian))
            gamma = ca.densify(at_rest(system.acceleration_rhs))
            fns.append(ca.Function("robot_kkt", [q, v, tau, p],
                                   [mass, ca.densify(tau - bias), cq, gamma],
                                   ["q", "v", "tau", "p"], ["M", "r", "Cq", "gamma"]))
            fns.append(ca.Function("robot_id_terms", [q, v, a, p],
                                   [ca.densify(inverse), cq, gamma],
                                   ["q", "v", "a", "p"], ["f", "Cq", "gamma"]))
        ctx, mech = system.ctx, system.mechanism
        frames = [(b, None) for b in system.body_names]
        frames += [(mk.body, mk.point) for mk in mech.markers.values()]
        self.frame_names: list[str] = list(system.body_names) + list(mech.markers)
        if spatial:  # world placements of the bodies, markers at their body-frame points
            poses = tree.world_poses()
            poses[GROUND] = (ca.SX.zeros(3), ca.SX.eye(3))
            pos = [poses[body][0] if point is None else
                   poses[body][0] + ca.mtimes(poses[body][1], ca.DM(ctx.local(body, point)))
                   for body, point in frames]
        else:
            pos = [ctx.position(body, point) for body, point in frames]
        # a frame's axes: the body's, times a marker's fixed offset (Marker.offset)
        axes = [np.eye(dim)] * len(system.body_names) + [
            _offset_matrix(mk.offset(mech.bodies.get(mk.body)), dim)
            for mk in mech.markers.values()]
        rot = [ca.vec(ca.mtimes(poses[body][1] if spatial else ctx.rotation(body),
                                ca.DM(off)).T)  # row by row
               for (body, _), off in zip(frames, axes)]
        fns.append(ca.Function("robot_fk", [q, p],
                               [ca.densify(ca.vertcat(*pos)), ca.densify(ca.vertcat(*rot))],
                               ["q", "p"], ["positions", "rotations"], opts))
        for k, ((body, _), r) in enumerate(zip(frames, pos)):
            if spatial:
                jac = tree.frame_jacobian(poses, body, r)
            elif articulated:
                jac = frame_jacobian(system, body, r)
            else:
                jac = ca.vertcat(ca.jacobian(r, q), ca.jacobian(ctx.angular_velocity(body), v))
            fns.append(ca.Function(f"robot_jacobian_{k}", [q, p], [ca.densify(jac)],
                                   ["q", "p"], ["J"], opts))
        rows = list(range(self.nc))
        if not vmap.identity:  # floating bases: every Function in the velocities v (n_v)
            fns, rows = velocity_functions(system, vmap, fns, BATCH_CHUNK, ldl_solve)
            self.nc, nq = len(rows), vmap.nv
        # a Jacobian's output as Jᵀ: CasADi's column-major Jᵀ is J row by row, so the method
        # returns a copy of a contiguous view (a transposed view's copy costs ~0.05 µs more)
        fns = [ca.Function(f.name(), [q, p], [ca.densify(f(q, p).T)], ["q", "p"], ["J"], opts)
               if f.name().startswith("robot_jacobian_") else f for f in fns]
        #: the compiled library: sizes, names, parameter values ``numeric.p``
        self.numeric = compile_model(system, (), mode=mode, extra=fns)
        self.coordinate_names: list[str] = self.numeric.coordinate_names
        #: names of the entries of v, τ and a (the coordinate names unless a base floats)
        self.velocity_names: list[str] = vmap.velocity_names(self.coordinate_names)
        self.p = self.numeric.p
        nw, d = (1 if dim == 2 else 3), dim
        shapes = {"robot_mass_matrix": lambda x: x.reshape(nq, nq),  # symmetric: order moot
                  "robot_fk": lambda x: x.reshape(-1, d)}
        shapes.update({f"robot_jacobian_{k}": lambda x: x.reshape(d + nw, nq)
                       for k in range(len(frames))})  # Jᵀ column-major: J row by row
        self._calls = {f.name(): _Call(self.numeric.function(f.name()), self.p,
                                       shapes.get(f.name())) for f in fns}
        self._frame_index = {name: k for k, name in enumerate(self.frame_names)}
        self._m, self._b = self._calls["robot_mass_matrix"], self._calls["robot_bias"]
        self._fk = self._calls["robot_fk"]
        self._jac = [self._calls[f"robot_jacobian_{k}"] for k in range(len(frames))]
        self._jac_by_frame = dict(zip(self.frame_names, self._jac))
        self._fd = self._calls.get("robot_fd", self._calls.get("robot_kkt"))
        self._id = self._calls.get("robot_id", self._calls.get("robot_id_terms"))
        self.constraint_labels: list[str] = [
            str(lab) for lab in self.numeric.constraint_labels
            if not is_normalization(lab, vmap.bodies)]
        self.actuated: list[str] = self._actuated(actuated)
        self._selection = np.array([self.velocity_names.index(c) for c in self.actuated],
                                   dtype=int)
        #: the body of each coordinate, for the named error of a singular mass matrix
        self._coordinate_bodies = [b for b, d in system.descriptions.items()
                                   for _ in range(d.size)]
        for blk in reversed(vmap.blocks):  # v: a floating block's 7 coordinates are 6 entries
            self._coordinate_bodies[blk.q:blk.q + 7] = [blk.body] * 6
        self._body_inertia = {b: (body.mass, body.inertia) for b, body in mech.bodies.items()}

    # ------------------------------------------------------------------ helpers
    def _shape_error(self, what: str, *args) -> ModelError:
        sizes = (f"n_q = {self.nq}" if self.nv == self.nq else
                 f"n_q = {self.nq} (q), n_v = {self.nv} (v, a, τ)")
        return ModelError(f"{what}: arguments must be vectors of length {sizes}, got "
                          f"shapes {[np.shape(x) for x in args]}")

    def _load(self, c: _Call, what: str, q, v=None, w=None) -> None:
        """Copy the arguments into the bound buffers (checked lengths), then evaluate."""
        n, nv = self.nq, self.nv
        try:
            if len(q) != n or (v is not None and len(v) != nv) or (
                    w is not None and len(w) != nv):
                raise ValueError
            c.a0[...] = q
            if v is not None:
                c.a1[...] = v
                if w is not None:
                    c.a2[...] = w
        except (ValueError, TypeError):
            raise self._shape_error(what, *(x for x in (q, v, w) if x is not None)) from None
        c.trigger()

    def _singular(self, q, what: str, cq: np.ndarray | None = None) -> None:
        """Raise naming the coordinates and bodies of a singular mass matrix at ``q``
        (with ``cq``: on the null space of C_q), else return (the caller's result stands).

        Called only when a result is not finite (or the KKT solve failed), so the per-call
        path costs one finiteness test.  As :func:`casmbd.analysis.instant.checks.
        check_mass_matrix`: N an orthonormal basis of null(C_q) (the identity for a tree), the
        eigenvectors x = N y of the eigenvalues of Nᵀ M N at most 1e-12 of the largest are
        motions without kinetic energy; the coordinates carrying ≥ 10 % of the largest share
        of |x|² are named with their bodies' mass and inertia.  An eigenvalue below −1e-12 of
        the largest is not rounding: the message says "indefinite" (negative kinetic energy)
        and names the coordinates of those eigenvectors instead.
        """
        self._load(self._m, what, q)
        m = 0.5 * (self._m.view + self._m.view.T)
        basis = np.eye(self.nv)  # M acts on v (n_v entries)
        if cq is not None and cq.size:
            _, sv, vt = np.linalg.svd(cq)
            tol = max(cq.shape) * np.finfo(float).eps * (sv[0] if sv.size else 0.0)
            basis = vt[int(np.sum(sv > tol)):].T
        if not np.all(np.isfinite(m)) or basis.shape[1] == 0:
            return
        eig, vec = np.linalg.eigh(basis.T @ m @ basis)
        tol = 1e-12 * max(float(np.max(np.abs(eig))), np.finfo(float).tiny)
        if eig[0] > tol:
            return
        indefinite = eig[0] < -tol  # negative kinetic energy, beyond rounding
        share = np.sum((basis @ vec[:, eig < -tol if indefinite else eig <= tol]) ** 2, axis=1)
        named = [k for k in np.argsort(-share, kind="stable") if share[k] >= 0.1 * share.max()]
        parts = []
        for k in named[:4]:
            body = self._coordinate_bodies[k]
            mass, inertia = self._body_inertia.get(body, ("?", "?"))
            parts.append(f"'{self.velocity_names[k]}' (body '{body}': mass {mass}, inertia "
                         f"{inertia})")
        state, cause = ("indefinite", " has negative kinetic energy, not zero: an inertia that "
                        "is not physical (a link's mass or inertia tensor); check the links' "
                        "<inertial> data") if indefinite else (
            "singular", " has no inertia (a massless end link); give the link mass and inertia "
            "(load_urdf(..., links={NAME: {'mass': ..., 'inertia': [...]}})) or lock its joint")
        raise SingularMassMatrixError(
            f"{what}: the mass matrix is {state} at this q (smallest eigenvalue {eig[0]:.3g} "
            f"of {eig[-1]:.3g}"
            + (", on the null space of the constraint Jacobian" if cq is not None else "")
            + "): a motion of " + ", ".join(parts) + cause,
            coordinates=[self.velocity_names[k] for k in named],
            bodies=list(dict.fromkeys(self._coordinate_bodies[k] for k in named)))

    def _actuated(self, names) -> list[str]:
        if names is None:
            return list(self.velocity_names)
        if isinstance(names, str):
            names = [names]
        names = list(names)
        for name in names:
            if name not in self.velocity_names:
                raise ModelError(f"compile: actuated coordinate '{name}' unknown (coordinates: "
                                 f"{', '.join(self.velocity_names)})")
        if len(set(names)) != len(names):
            raise ModelError(f"compile: actuated coordinates repeated: {names}")
        return names

    # ------------------------------------------------------------------ one state
    def mass_matrix(self, q) -> np.ndarray:
        """M(q), dense n_q × n_q (Pinocchio's ``crba``, both triangles filled)."""
        c = self._m
        try:  # _load inlined: the call costs a tenth of a small robot's call
            if len(q) != self.nq:
                raise ValueError
            c.a0[...] = q
        except (ValueError, TypeError):
            raise self._shape_error("mass_matrix", q) from None
        c.trigger()
        return c.view.copy()

    def bias_forces(self, q, v) -> np.ndarray:
        """b(q, v) = −Q_v − Q_e at t = 0, u = 0, so that M q̈ + b = τ (Pinocchio's ``nle``)."""
        c = self._b
        try:  # _load inlined
            if len(q) != self.nq or len(v) != self.nv:
                raise ValueError
            c.a0[...] = q
            c.a1[...] = v
        except (ValueError, TypeError):
            raise self._shape_error("bias_forces", q, v) from None
        c.trigger()
        return c.view.copy()

    def forward_dynamics(self, q, v, tau) -> np.ndarray:
        """q̈ from M q̈ + b = τ (and C_q q̈ = γ with constraint equations; module docstring)."""
        c = self._fd
        try:  # _load inlined
            if len(q) != self.nq or len(v) != self.nv or len(tau) != self.nv:
                raise ValueError
            c.a0[...] = q
            c.a1[...] = v
            c.a2[...] = tau
        except (ValueError, TypeError):
            raise self._shape_error("forward_dynamics", q, v, tau) from None
        c.trigger()
        if not self.nc:
            if not math.isfinite(c.outs[1][0]):  # a zero pivot: named (else q̈ stands)
                self._singular(q, "forward_dynamics")
            return c.view.copy()
        m, r, cq, gamma = c.outs
        nq, nc = self.nv, self.nc  # the size of v
        kkt = np.zeros((nq + nc, nq + nc))
        kkt[:nq, :nq] = m.reshape(nq, nq)
        jac = cq.reshape(nc, nq, order="F")
        kkt[nq:, :nq] = jac
        kkt[:nq, nq:] = jac.T
        try:
            return np.linalg.solve(kkt, np.concatenate([r, gamma]))[:nq]
        except np.linalg.LinAlgError:
            jac = jac.copy()
            self._singular(q, "forward_dynamics", jac)
            raise SingularConfigurationError(
                f"forward_dynamics: the KKT matrix [M C_qᵀ; C_q 0] is singular at this q with "
                f"M regular on the constraint manifold: the constraint equations are redundant "
                f"here (rank {np.linalg.matrix_rank(jac)} of {nc}: "
                f"{', '.join(self.constraint_labels[:6])})") from None

    def inverse_dynamics(self, q, v, a, return_multipliers: bool = False, tol: float = 1e-8):
        """τ = M(q) a + b(q, v) of a tree (Pinocchio's ``rnea``); with constraint equations,
        the efforts on the actuated coordinates and the multipliers of
        ``M a + b + C_qᵀ λ = S τ_a`` (module docstring).

        Parameters
        ----------
        q, v, a : array_like, shape (n_q,)
            Coordinates, velocities and accelerations; with constraint equations the
            accelerations must satisfy ``C_q a = γ`` (relative residual ≤ ``tol``).
        return_multipliers : bool
            Also return λ (shape (n_c,), the order of :attr:`constraint_labels`; empty for a
            tree).
        tol : float
            Relative tolerance of the consistency checks (acceleration constraint and, with a
            choice of :attr:`actuated`, the residual of the effort equations).

        Returns
        -------
        tau : ndarray, shape (n_q,)
            Generalized efforts, zero on the coordinates that are not actuated.
        lam : ndarray, shape (n_c,)
            Only with ``return_multipliers``.

        Raises
        ------
        ModelError
            Inconsistent accelerations (naming the worst constraint equation), or actuated
            coordinates that cannot produce the motion.
        """
        c = self._id
        try:  # _load inlined
            if len(q) != self.nq or len(v) != self.nv or len(a) != self.nv:
                raise ValueError
            c.a0[...] = q
            c.a1[...] = v
            c.a2[...] = a
        except (ValueError, TypeError):
            raise self._shape_error("inverse_dynamics", q, v, a) from None
        c.trigger()
        if not self.nc and len(self.actuated) == self.nv:
            tau = c.view.copy()
            return (tau, np.zeros(0)) if return_multipliers else tau
        return self._constrained_efforts(c, np.asarray(a, float), return_multipliers, tol)

    def _constrained_efforts(self, c, a, return_multipliers: bool, tol: float):
        """[S  −C_qᵀ] [τ_a; λ] = f with f = M a + b (module docstring)."""
        nq, nc = self.nv, self.nc  # the size of v
        f = c.outs[0].copy()
        if nc:
            jac = c.outs[1].reshape(nc, nq, order="F").copy()
            gamma = c.outs[2]
            resid = jac @ a - gamma
            scale = max(1.0, float(np.max(np.abs(gamma))),
                        float(np.max(np.abs(jac)) * np.max(np.abs(a))))
            worst = int(np.argmax(np.abs(resid)))
            if abs(resid[worst]) > tol * scale:
                raise ModelError(
                    f"inverse_dynamics: the accelerations violate the acceleration constraint "
                    f"C_q a = γ of {self.constraint_labels[worst]} by {resid[worst]:.3g} "
                    f"(relative tolerance {tol:g}); give a consistent a")
        else:
            jac = np.zeros((0, nq))
        sel = self._selection
        if len(sel) == nq:  # every coordinate: the least-norm effort, f projected on null(C_q)
            lam = -np.linalg.lstsq(jac @ jac.T, jac @ f, rcond=None)[0] if nc else jac[:, 0]
            tau = f + jac.T @ lam
        else:
            mat = np.hstack([np.eye(nq)[:, sel], -jac.T])
            sol, _, rank, _ = np.linalg.lstsq(mat, f, rcond=None)
            miss = float(np.max(np.abs(mat @ sol - f), initial=0.0))
            if miss > tol * max(1.0, float(np.max(np.abs(f)))):
                raise ModelError(
                    f"inverse_dynamics: the actuated coordinates ({', '.join(self.actuated)}) "
                    f"cannot produce these accelerations (residual {miss:.3g}): actuate a set "
                    f"of independent coordinates ({nq - nc} degrees of freedom, if C_q has "
                    "full rank)")
            if rank < mat.shape[1]:
                raise ModelError(
                    f"inverse_dynamics: the efforts on ({', '.join(self.actuated)}) and the "
                    f"multipliers are not unique (rank {rank} of {mat.shape[1]} unknowns): "
                    "actuate fewer coordinates or every one (least-norm efforts)")
            tau = np.zeros(nq)
            tau[sel] = sol[:len(sel)]
            lam = sol[len(sel):]
        return (tau, lam) if return_multipliers else tau

    def forward_kinematics(self, q) -> tuple[np.ndarray, np.ndarray]:
        """Positions (n_frames × dim) and rotation matrices (n_frames × dim × dim, body to
        global) of every frame of :attr:`frame_names`: bodies at their centres of mass,
        then markers."""
        c = self._fk
        self._load(c, "forward_kinematics", q)
        d = self.dimension
        return c.view.copy(), c.outs[1].copy().reshape(-1, d, d)

    def jacobian(self, q, frame: str) -> np.ndarray:
        """J(q) of a body or marker with (ṙ, ω) = J v, rows linear then angular, global
        components (Pinocchio's ``LOCAL_WORLD_ALIGNED``; module docstring)."""
        c = self._jac_by_frame.get(frame)
        if c is None:
            raise ModelError(f"jacobian: unknown frame '{frame}' (bodies and markers: "
                             f"{', '.join(self.frame_names)})")
        try:  # _load inlined
            if len(q) != self.nq:
                raise ValueError
            c.a0[...] = q
        except (ValueError, TypeError):
            raise self._shape_error("jacobian", q) from None
        c.trigger()
        return c.view.copy()

    def integrate(self, q, v, dt: float = 1.0) -> np.ndarray:
        """q ⊕ v Δt: the coordinates reached from q at constant velocity v (n_v) after Δt —
        q + v Δt, exactly on SE(3) for a floating base (Pinocchio's ``integrate``;
        :mod:`casmbd.compiled.free_flyer`)."""
        return self.velocity_map.integrate(q, v, dt)

    def difference(self, q0, q1) -> np.ndarray:
        """v (n_v) with q1 = integrate(q0, v, 1) (Pinocchio's ``difference``)."""
        return self.velocity_map.difference(q0, q1)

    # ------------------------------------------------------------------ many states
    def _batch(self, name: str, arrays) -> np.ndarray:
        mats = [np.asarray(x, dtype=float) for x in arrays]
        n = mats[0].shape[0] if mats[0].ndim == 2 else -1
        widths = [self.nq] + [self.nv] * (len(mats) - 1)  # q, then v and τ or a
        if any(x.shape != (n, w) for x, w in zip(mats, widths)):
            raise ModelError(f"{name.removeprefix('robot_')}: arguments must be arrays of "
                             f"shape (N, n_q = {self.nq}) (q) and (N, n_v = {self.nv}) (v, "
                             f"τ, a), got {[x.shape for x in mats]}")
        call, c = self._calls[name], BATCH_CHUNK
        views = [buf.reshape(c, w) for buf, w in zip(call.ins[:-1], widths)]  # column-major
        res = call.outs[0].reshape(c, self.nv)
        out = np.empty((n, self.nv))
        for start in range(0, n, c):
            m = min(c, n - start)
            for view, x in zip(views, mats):
                view[:m] = x[start:start + m]
                if m < c:
                    view[m:] = 0.0
            call.trigger()
            out[start:start + m] = res[:m]
        return out

    def forward_dynamics_batch(self, Q, V, TAU) -> np.ndarray:
        """:meth:`forward_dynamics` at N states, arrays of shape (N, n_q) in and out.

        Trees: compiled ``Function.map`` over :data:`BATCH_CHUNK` columns (no Python loop per
        sample); with constraint equations, a loop of single calls.
        """
        if self.nc:
            return np.array([self.forward_dynamics(*s) for s in zip(Q, V, TAU)]).reshape(
                -1, self.nv)
        out = self._batch("robot_fd_batch", (Q, V, TAU))
        if not math.isfinite(float(np.sum(out))):  # name the first state with a zero pivot
            for k in np.flatnonzero(~np.all(np.isfinite(out), axis=1)):
                self._singular(np.asarray(Q, float)[k], f"forward_dynamics_batch (state {k})")
        return out

    def inverse_dynamics_batch(self, Q, V, A) -> np.ndarray:
        """:meth:`inverse_dynamics` at N states, arrays of shape (N, n_q) in and out.

        Trees with every coordinate actuated: compiled ``Function.map``; otherwise a loop of
        single calls.
        """
        if self.nc or len(self.actuated) != self.nv:
            return np.array([self.inverse_dynamics(*s) for s in zip(Q, V, A)]).reshape(
                -1, self.nv)
        return self._batch("robot_id_batch", (Q, V, A))


#: what the per-call API handles (casmbd.model.needs): the smooth equations at one state
HANDLING = Handling(
    "the per-call API (casmbd.compile)", frozenset({"modal_coordinates", "inputs", "drivers",
                                                    "velocity_constraints"}),
    why={"events": "its equations have no contact or stop rows and no impulses",
         "contact_friction": "its equations have no contact rows",
         "stick_slip": "the exact Coulomb law switches at events, which one call has not",
         "reaction_forces": "the bias b = −Q_v − Q_e is evaluated without multipliers"},
    instead={"events": "simulate, or model = 'compliant' (a force in the bias)",
             "contact_friction": "simulate",
             "stick_slip": "the regularised law (stick_slip = false), or simulate",
             "reaction_forces": "inverse dynamics (casmbd.inverse_dynamics)"},
    notes={"inputs": "τ are the efforts; actuator inputs u = 0 in the bias",
           "drivers": "driver rows are constraint equations at t = 0 (a call has no time)",
           "velocity_constraints": "rolling rows enter the KKT system as C_q q̈ = γ (their λ "
                                   "the tyre forces); q and v are the caller's, on them"})


def compile(mechanism, coordinates: str | None = "joint", mode: str = "auto",
            actuated: Sequence[str] | None = None) -> CompiledModel:
    """Compiled robot model of ``mechanism`` for per-call numeric evaluation.

    ``model = casmbd.compile(mechanism)``; then ``model.forward_dynamics(q, v, tau)``,
    ``inverse_dynamics``, ``mass_matrix``, ``bias_forces``, ``forward_kinematics``,
    ``jacobian`` and the ``*_batch`` versions (see :class:`CompiledModel`).
    """
    check(mechanism, HANDLING)
    return CompiledModel(mechanism, coordinates=coordinates, mode=mode, actuated=actuated)

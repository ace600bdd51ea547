"""Outputs of a :class:`~casmbd.system.equations.System`: body, marker and joint positions,
velocities and accelerations as one CasADi Function, and the rows of C by joint and driver.

:class:`Outputs` is a mixin of :class:`~casmbd.system.equations.System`: it reads the system's
symbols (``q``, ``v``, ``t``, ``p``, ``ctx``, ``nq``, ``dimension``, ``mechanism``,
``body_names``), its ``constraint_labels`` and its Function cache ``_functions``.
"""

from __future__ import annotations

from functools import cached_property

import casadi as ca

from casmbd.system.requests import output_groups


class Outputs:
    """Output Function and row bookkeeping of a System (a mixin, see the module docstring)."""

    @cached_property
    def joint_coordinate_names(self) -> list[str]:
        """Joint coordinates, in declaration order: the joint's name for its first coordinate,
        ``joint.coordinate`` for further ones (the angle of a cylindrical joint)."""
        out = []
        for joint in self.mechanism.joints.values():
            for k, coord in enumerate(joint.coordinate_names):
                out.append(joint.name if k == 0 else f"{joint.name}.{coord}")
        return out

    def _joint_coordinate(self, key: str) -> ca.SX:
        name, _, coord = key.partition(".")
        return self.mechanism.joints[name].coordinate(self.ctx, coord or None)

    def outputs_function(self) -> ca.Function:
        """Body, marker and joint outputs of (q, v, a, t, p), every output a column.

        Positions are stacked per point (x0, y0, x1, y1, …); velocities are J v and
        accelerations J a + J̇ v of the same expressions.  Planar bodies give their angle
        (``angle_*``); spatial bodies their rotation matrix (``rotation_matrices``, 9 per body,
        row by row) and global angular velocity and acceleration (3 per body).  With markers,
        their frames: ``marker_rotations`` (9 per marker, row by row) in space, ``marker_angles``
        in the plane.  Requests (``outputs``) and force-element reports (``force_outputs``)
        when the mechanism has them (:mod:`casmbd.system.requests`).
        """
        if "outputs" not in self._functions:
            ctx, mech = self.ctx, self.mechanism
            a = ca.SX.sym("a", self.nq)
            com = ca.vertcat(*[ctx.centre_of_mass(b) for b in self.body_names])
            mk = [ctx.position(m.body, m.point) for m in mech.markers.values()]
            markers = ca.vertcat(*mk) if mk else ca.SX(0, 1)
            jc = [self._joint_coordinate(j) for j in self.joint_coordinate_names]
            joints = ca.vertcat(*jc) if jc else ca.SX(0, 1)
            groups = [("body_", com)]
            if self.dimension == 2:
                groups.append(("angle_", ca.vertcat(*[ctx.angle(b) for b in self.body_names])))
            groups += [("marker_", markers), ("joint_", joints)]
            names, exprs = [], []
            rates = None if self.local else self._tree_rates(a)
            for label, expr in groups:
                if rates is not None and label in rates:
                    vel, acc = rates[label]
                else:
                    vel = ca.jtimes(expr, self.q, self.v)
                    acc = ca.jtimes(expr, self.q, a) + ca.jtimes(vel, self.q, self.v)
                exprs += [expr, vel, acc]
                names += [label + "positions", label + "velocities", label + "accelerations"]
            if self.dimension == 3:
                rot = ca.vertcat(*[ca.vec(ctx.rotation(b).T) for b in self.body_names])
                if rates is None:
                    omega = ca.vertcat(*[ctx.angular_velocity(b) for b in self.body_names])
                    alpha = ca.jtimes(omega, self.q, self.v) + ca.jtimes(omega, self.v, a)
                else:
                    omega, alpha = rates["spin"]
                exprs += [rot, omega, alpha]
                names += ["rotation_matrices", "angular_velocities", "angular_accelerations"]
            if mech.markers:  # their frames: A_body (Aᵦᵀ A_m), θ_body + θ_m − θᵦ
                exprs.append(self._marker_rotations())
                names.append("marker_rotations" if self.dimension == 3 else "marker_angles")
            for label, expr in output_groups(self):  # requests and force reports
                exprs.append(expr)
                names.append(label)
            self._functions["outputs"] = ca.Function(
                "outputs", [self.q, self.v, a, self.t, self.p], exprs,
                ["q", "v", "a", "t", "p"], names)
        return self._functions["outputs"]

    def _tree_rates(self, a: ca.SX) -> dict[str, tuple[ca.SX, ca.SX]]:
        """Velocities and accelerations of the body and marker outputs of a coupled
        (joint-coordinate) system from the recursive twists and accelerations of
        :class:`~casmbd.system.tree.TreeKinematics`, O(1) per body and marker — ∂r/∂q q̇ by
        AD would sweep every body's ancestors (240 operations per body of a 100-rod chain).
        A marker P of body B with d = r_P − r_G moves as v_P = ṙ_G + ω × d and
        a_P = r̈_G + α × d + ω × (ω × d) (seed 001, eqs. 256–290)."""
        ctx, dim = self.ctx, self.dimension
        tk = self.tree_kinematics
        nw = 1 if dim == 2 else 3
        acc = tk.accelerations(a)

        def cross(w: ca.SX, d: ca.SX) -> ca.SX:
            return ca.vertcat(-w[0] * d[1], w[0] * d[0]) if dim == 2 else ca.cross(w, d)

        zero = ca.SX.zeros(dim)
        mv, ma = [], []
        for m in self.mechanism.markers.values():
            if m.body not in tk.twist:  # on the ground
                mv.append(zero)
                ma.append(zero)
                continue
            w, alpha = tk.twist[m.body][:nw], acc[m.body][:nw]
            d = ctx.position(m.body, m.point) - ctx.centre_of_mass(m.body)
            mv.append(tk.twist[m.body][nw:] + cross(w, d))
            ma.append(acc[m.body][nw:] + cross(alpha, d) + cross(w, cross(w, d)))
        names = self.body_names
        stack = ca.vertcat
        out = {"body_": (stack(*[tk.twist[b][nw:] for b in names]),
                         stack(*[acc[b][nw:] for b in names])),
               "spin": (stack(*[tk.twist[b][:nw] for b in names]),
                        stack(*[acc[b][:nw] for b in names]))}
        if dim == 2:
            out["angle_"] = out["spin"]
        if mv:
            out["marker_"] = (stack(*mv), stack(*ma))
        return out

    def _marker_rotations(self) -> ca.SX:
        """Marker frames stacked: 9 entries (A row by row) per marker in space, the angle in
        the plane (:meth:`casmbd.model.bodies.Marker.offset` is the fixed part)."""
        ctx, mech = self.ctx, self.mechanism
        out = []
        for m in mech.markers.values():
            offset = m.offset(mech.attachment(m.body))
            if self.dimension == 2:
                out.append(ctx.angle(m.body) + offset)
            else:
                out.append(ca.vec(ca.mtimes(ctx.rotation(m.body), ca.DM(offset)).T))
        return ca.vertcat(*out)

    @cached_property
    def joint_rows(self) -> dict[str, list[int]]:
        """Rows of C belonging to each joint."""
        rows: dict[str, list[int]] = {name: [] for name in self.mechanism.joints}
        for i, lab in enumerate(self.constraint_labels):
            if lab.kind == "joint":
                rows[lab.element].append(i)
        return rows

    @cached_property
    def driver_rows(self) -> dict[str, int]:
        """Row of C of each driver."""
        return {lab.element: i for i, lab in enumerate(self.constraint_labels)
                if lab.kind == "driver"}


"""Joint reactions of a :class:`~casmbd.system.equations.System` from the multipliers λ.

Joints with constraint rows: virtual work of a rigid displacement of one body (seed 000,
eqs. 6.145–6.151); tree joints of joint coordinates: Newton–Euler from the leaves (seed 002,
"Joint Forces Calculation").  See :meth:`Reactions.reactions_function`.

:class:`Reactions` is a mixin of :class:`~casmbd.system.equations.System`: it reads the system's
symbols and context, its constraints (``constraint_labels``, ``joint_rows``, ``nc``,
``_driver_residual``), its inertia (``_mass_inertia``, ``tree_kinematics``, ``local``) and the
applied-force terms (``_force_terms`` of :mod:`casmbd.system.applied_forces`).
"""

from __future__ import annotations

from functools import cached_property

import casadi as ca

from casmbd.model.bodies import GROUND


class Reactions:
    """Joint reactions of a System (a mixin, see the module docstring)."""

    def _cross(self, arm: ca.SX, force: ca.SX) -> ca.SX:
        if self.dimension == 2:
            return arm[0] * force[1] - arm[1] * force[0]
        return ca.cross(arm, force)

    def _perturbation(self, body: str):
        if not hasattr(self, "_perturbed"):
            self._perturbed: dict[str, tuple] = {}
        if body not in self._perturbed:
            self._perturbed[body] = self.ctx.perturbed(body)
        return self._perturbed[body]

    def _constraint_wrench(self, body: str, lam: ca.SX, rows=None) -> ca.SX:
        """Force and moment about G that constraint rows (with multipliers λ) exert on ``body``:
        −(∂C/∂e)ᵀ λ, the virtual-work counterpart of Q_c = −C_qᵀ λ (seed 000, eq. 6.145)."""
        ctx, e = self._perturbation(body)
        rows = list(range(self.nc)) if rows is None else rows
        # e moves ``body`` alone: only the equations of elements attached to it depend on e,
        # so only those are written again (all of them per body made the build O(N²))
        cons, index = self._constraints_touching(ctx, body)
        wanted = set(rows)
        keep = [k for k, r in enumerate(index) if r in wanted]
        if not keep:
            return ca.SX.zeros(e.numel())
        jac = ca.jacobian(cons[keep], e)
        lam_k = ca.vertcat(*[lam[index[k]] for k in keep])
        return ctx.resolve(-ca.mtimes(jac.T, lam_k))

    @cached_property
    def _element_rows(self) -> dict[tuple[str, str], list[int]]:
        """Rows of C by (kind, element) in the order of :meth:`_constraints_with`."""
        out: dict[tuple[str, str], list[int]] = {}
        for i, lab in enumerate(self.constraint_labels):
            out.setdefault((lab.kind, lab.element), []).append(i)
        return out

    def _constraints_touching(self, ctx, body: str) -> tuple[ca.SX, list[int]]:
        """The equations of C that involve ``body`` (its own description's, its joints', the
        drivers of those joints or of the body) written with ``ctx``, and their row indices."""
        rows, index = [], []
        elements = self._element_rows
        if not elements:  # no constraint equations (a tree in joint coordinates)
            return ca.SX(0, 1), index
        desc = self.descriptions.get(body)
        if desc is not None and ("body", body) in elements:
            eqs, _ = desc.constraints(ctx.coordinates(body))
            rows.append(ca.vec(eqs))
            index += elements[("body", body)]
        touching = set()
        for joint in self.mechanism.joints.values():
            # a gear involves the bodies of both its joints; a node frame is its body's
            if body in joint.bodies or body in (ctx.owner(b) for b in joint.bodies):
                touching.add(joint.name)
                if ("joint", joint.name) in elements:
                    # a joint with velocity rows writes them as virtual displacements
                    write = getattr(joint, "virtual_equations", joint.equations)
                    rows.append(ca.vec(write(ctx)))
                    index += elements[("joint", joint.name)]
        for driver in self.mechanism.drivers.values():
            if (driver.joint in touching or (driver.body and ctx.owner(driver.body) == body)) and \
                    ("driver", driver.name) in elements:
                rows.append(ca.vec(self._driver_residual(driver, ctx)))
                index += elements[("driver", driver.name)]
        return (ca.vertcat(*rows) if rows else ca.SX(0, 1)), index

    def _applied_wrench(self, body: str) -> tuple[ca.SX, list[str]]:
        """Force and moment about G of every applied force on ``body``, and the names of user
        generalized forces that cannot be attributed to bodies (built once per body: the
        articulated recursion and the tree reactions share it)."""
        if not hasattr(self, "_wrenches"):
            self._wrenches: dict[str, tuple[ca.SX, list[str]]] = {}
        if body not in self._wrenches:
            self._wrenches[body] = self._build_applied_wrench(body)
        return self._wrenches[body]

    def _build_applied_wrench(self, body: str) -> tuple[ca.SX, list[str]]:
        ctx, e = self._perturbation(body)
        total = ca.SX.zeros(e.numel())
        unknown, exprs, weights = [], [], []
        dim = self.dimension
        for term in self._force_terms(ctx, gravity_of=body):  # e moves ``body`` alone
            if term.kind == "measure":
                exprs.append(ca.vec(term.expr))
                weights.append(ca.vec(term.weight))
            elif term.kind == "torque":
                if ctx.owner(term.body) == body:
                    total[dim:] += term.weight
            else:
                unknown.append(term.name)
        # Σ (∂s_k/∂e)ᵀ w_k in one reverse sweep, as applied_forces does for q (a Jacobian per
        # term made the build O(N²): 20 000 Jacobians for a 100-body tree's ABA and reactions)
        if exprs:
            total += ca.jtimes(ca.vertcat(*exprs), e, ca.vertcat(*weights), True)
        return ctx.resolve(total), unknown

    def _inertial_wrench(self, body: str, a: ca.SX) -> ca.SX:
        """(m a_G, Ḣ_G): Newton–Euler's rate of momentum of ``body`` (seed 001; seed 004)."""
        ctx = self.ctx
        mass, inertia = self._mass_inertia(self.mechanism.bodies[body])
        if not self.local:
            nw = 1 if self.dimension == 2 else 3
            if getattr(self, "_tree_acc", (None,))[0] is not a:
                self._tree_acc = (a, self.tree_kinematics.accelerations(a))
            full = self._tree_acc[1][body]
            omega = self.tree_kinematics.twist[body][:nw]
            alpha, acc = full[:nw], full[nw:]
        else:
            r_g = ctx.centre_of_mass(body)
            vel = ca.jtimes(r_g, self.q, self.v)
            acc = ca.jtimes(vel, self.q, self.v) + ca.jtimes(r_g, self.q, a)
            omega = ctx.angular_velocity(body)
            alpha = ca.jtimes(omega, self.q, self.v) + ca.jtimes(omega, self.v, a)
        if self.dimension == 2:
            return ca.vertcat(mass * acc, inertia * alpha)
        rot = ctx.rotation(body)
        tensor = ca.mtimes([rot, inertia, rot.T])
        h_dot = ca.mtimes(tensor, alpha) + ca.cross(omega, ca.mtimes(tensor, omega))
        return ca.vertcat(mass * acc, h_dot)

    def _reaction_point(self, joint, body: str) -> ca.SX:
        point = joint.reaction_point()
        if point is None:
            point = self.ctx.initial_position(joint.body2)
        return self.ctx.point(body, self.ctx.local(body, point))

    def reactions_function(self) -> ca.Function:
        """Joint reactions, one column per joint: the action of body1 on body2 at the joint
        point, global components — (F_x, F_y, M) in the plane, (F, M) in space.

        Joints with constraint rows (absolute and natural coordinates, loop joints of joint
        coordinates): the force and moment about G of body2 (body1 when body2 is the ground,
        with the sign changed) are −(∂C_k/∂e)ᵀ λ_k for a virtual rigid displacement e of that
        body — the virtual-work form of Q_c = −C_qᵀ λ (seed 000, eq. 6.145) — and the moment
        is carried to the joint point, M_P = M_G − (r_P − r_G) × F (eqs. 6.146–6.151).

        Joints of the spanning tree (joint coordinates) have no multipliers: their reactions
        follow from Newton–Euler body by body, from the leaves to the root (seed 002, "Joint
        Forces Calculation"): F = m a_G − F_applied − F_constraints + Σ F_children,
        M_G = Ḣ_G − M_applied − M_constraints + Σ (M_child + (r_child − r_G) × F_child).
        Driver multipliers are not included: a driver's effort is reported on its own.  A user
        generalized force that is not attached to a body makes tree reactions undeterminable
        (NaN).
        """
        if "joint_reactions" not in self._functions:
            lam = ca.SX.sym("lambda", self.nc)
            a = ca.SX.sym("a", self.nq)
            cols: dict[str, ca.SX] = {}
            mech = self.mechanism
            joint_only = [i for i, lab in enumerate(self.constraint_labels)
                          if lab.kind == "joint"]
            for name, rows in self.joint_rows.items():
                if name in self.tree_joints:
                    continue
                joint = mech.joints[name]
                attach, sign = (joint.body2, 1.0) if joint.body2 != GROUND else \
                    (joint.body1, -1.0)
                body = self.ctx.owner(attach)  # a node frame's body moves as a whole
                wrench = sign * self._constraint_wrench(body, lam, rows)
                cols[name] = self._at_point(joint, attach, wrench, body)
            if self.tree_joints:
                cols.update(self._tree_reactions(a, lam, joint_only))
            size = self.reaction_size
            out = ca.horzcat(*[cols[n] for n in mech.joints]) if mech.joints else \
                ca.SX(size, 0)
            normals = self.friction_normal_symbols
            if normals:  # the friction of closed contacts (loop joints) from the multipliers
                out = ca.substitute(out, ca.vertcat(*normals.values()),
                                    self.friction_normals_of(lam))
            self._functions["joint_reactions"] = ca.Function(
                "joint_reactions", [self.q, self.v, a, self.t, self.u, self.p, lam], [out],
                ["q", "v", "a", "t", "u", "p", "lambda"], ["reactions"])
        return self._functions["joint_reactions"]

    def _at_point(self, joint, body: str, wrench: ca.SX, owner: str | None = None) -> ca.SX:
        """Carry a wrench (force, moment about G of ``owner``, default ``body``) to the joint's
        point on ``body`` (a node frame of a flexible ``owner``: the deformed node)."""
        dim = self.dimension
        force, moment = wrench[:dim], wrench[dim:]
        arm = self._reaction_point(joint, body) - self.ctx.centre_of_mass(owner or body)
        return ca.vertcat(force, moment - self._cross(arm, force))

    def _tree_reactions(self, a: ca.SX, lam: ca.SX, rows: list[int]) -> dict[str, ca.SX]:
        """Reactions of the tree joints by the recursion from the leaves (see
        :meth:`reactions_function`); ``rows`` are the loop-joint rows whose multipliers act
        on the bodies (driver rows excluded, like in absolute coordinates)."""
        dim = self.dimension
        order = [name for name in self.body_names]
        children: dict[str, list[str]] = {name: [] for name in order}
        for name in order:
            parent = self.descriptions[name].parent
            if parent != GROUND:
                children[parent].append(name)
        # bodies after their parents: reverse topological order for the recursion
        ranked, seen = [], set()

        def visit(name):
            if name in seen:
                return
            parent = self.descriptions[name].parent
            if parent != GROUND:
                visit(parent)
            seen.add(name)
            ranked.append(name)

        for name in order:
            visit(name)
        driver_rows = [i for i, lab in enumerate(self.constraint_labels) if lab.kind == "driver"]
        joint_wrench: dict[str, ca.SX] = {}  # on the body from its parent, about the joint pt
        out: dict[str, ca.SX] = {}
        for name in reversed(ranked):
            desc = self.descriptions[name]
            applied, unknown = self._applied_wrench(name)
            # drivers act inside their joints: like absolute coordinates, reactions exclude
            # the driver efforts, so driver rows count with the applied loads here
            loads = applied + self._constraint_wrench(name, lam, rows + driver_rows)
            wrench = self._inertial_wrench(name, a) - loads
            r_g = self.ctx.centre_of_mass(name)
            for child in children[name]:
                child_joint = self.mechanism.joints[self.descriptions[child].joint.name]
                on_child = joint_wrench[child]
                point = self._reaction_point(child_joint, child)
                force = on_child[:dim]
                moment = on_child[dim:] + self._cross(point - r_g, force)
                wrench = wrench + ca.vertcat(force, moment)
            if desc.joint is None:
                continue
            joint = self.mechanism.joints[desc.joint.name]
            at_point = self._at_point(joint, name, wrench)
            if unknown:
                at_point = at_point * float("nan")
            joint_wrench[name] = at_point
            out[joint.name] = at_point if joint.body2 == name else -at_point
        if any(getattr(d, "mimic", None) for d in self.descriptions.values()):
            self._split_mimic_reactions(out)
        return out

    def _axial(self, joint, wrench: ca.SX) -> tuple[ca.SX, ca.SX]:
        """(τ, u): the component τ = Sᵀ w of a joint-point wrench w = (F, M) along the
        joint's own motion S (the twist of its coordinate at the joint point P: (ω_S, v_P)
        with v_P = v_G + ω_S × (P − G) from the tree's motion subspace at the centre of mass
        G), and the wrench u = (v_P, ω_S) / (|ω_S|² + |v_P|²) with Sᵀ u = 1 that carries a
        unit component: a moment about a revolute axis (v_P = 0), a force along a prismatic
        one (ω_S = 0)."""
        dim, body = self.dimension, joint.body2
        nw = 1 if dim == 2 else 3
        tk, desc = self.tree_kinematics, self.descriptions[body]
        motion = tk.motion[body]
        if desc.mimic is not None:  # S' = r S_f e_kᵀ on the leader's block
            motion = motion[:, desc.mimic[2]] / desc.mimic[3]
        omega, vel = motion[:nw, 0], motion[nw:, 0]
        arm = self._reaction_point(joint, body) - self.ctx.centre_of_mass(body)
        vel = vel + (ca.vertcat(-omega[0] * arm[1], omega[0] * arm[0]) if dim == 2
                     else ca.cross(omega, arm))
        tau = ca.dot(vel, wrench[:dim]) + ca.dot(omega, wrench[dim:])
        unit = ca.vertcat(vel, omega) / (ca.dot(omega, omega) + ca.dot(vel, vel))
        return tau, unit

    def _split_mimic_reactions(self, out: dict[str, ca.SX]) -> None:
        """Reactions with substituted gears (mimic joints, :mod:`casmbd.system.tree`): a tree
        joint's reaction carries no component along its own motion (the equation of motion of
        its coordinate), so the component τ_J = S_Jᵀ w of the reaction of each joint of a
        substituted gear is the gears' action on its body.  The gear's column is its action on
        the follower's body, a pure moment (force) a_g along the follower's axis with
        a_g = τ_f − Σ_h (−r_h a_h) over the gears h led by that follower; on the leader's
        body it acts with −r_g a_g (the multiplier form: −λ and +r λ, :mod:`casmbd.model.gear`).
        The joints' columns keep the rest, as in the constrained form."""
        mech = self.mechanism
        gears = {d.mimic[0]: mech.joints[d.mimic[0]] for d in self.descriptions.values()
                 if getattr(d, "mimic", None)}
        involved = dict.fromkeys(n for g in gears.values() for n in (g.joint1, g.joint2))
        axial = {name: self._axial(mech.joints[name], out[name]) for name in involved}
        action: dict[str, ca.SX] = {}

        def on_follower(gear_name: str) -> ca.SX:
            if gear_name not in action:
                gear = gears[gear_name]
                value = axial[gear.joint2][0]
                for other, led in gears.items():
                    if led.joint1 == gear.joint2:
                        value = value + led.ratio * on_follower(other)
                action[gear_name] = value
            return action[gear_name]

        for gear_name, gear in gears.items():
            out[gear_name] = on_follower(gear_name) * axial[gear.joint2][1]
        for name in involved:
            tau, unit = axial[name]
            out[name] = out[name] - tau * unit


"""The result of the statics analysis and the reports at one state.

:class:`StaticsResult` (the equilibrium, its multipliers, reactions, stability and the search's
notes) and :func:`equilibrium_result` that fills it at a solution; :func:`state_reports` and
:func:`state_summary` give the requests, force reports and flexible nodes at one state (the
equilibrium; the operating point of :func:`~casmbd.analysis.statics.linearize.linearize`).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from casmbd.analysis.instant.independent import check_removed, minimum_norm, scatter
from casmbd.analysis.instant.undetermined_reactions import flag_undetermined
from casmbd.analysis.statics.equilibrium_problem import wrap
from casmbd.analysis.statics.stability import Stability
from casmbd.model.measures import result_names
from casmbd.system.descriptions import quaternions_from_matrices

__all__ = ["StaticsResult", "equilibrium_result", "state_reports", "state_summary"]

@dataclass
class StaticsResult:
    """A static equilibrium configuration.

    Attributes
    ----------
    q : ndarray (n_q,)
    lagrange_multipliers : ndarray (n_c,)
    iterations : int
        Newton iterations taken.
    residual : float
        max |F| at the solution (forces and constraint residuals).
    residual_history : list of float
        max |F| at the start and after every iteration.
    method : str
    stable : bool or None
        True (stable), False (unstable) or None (neutral: a zero eigenvalue).
    eigenvalues : ndarray
        Eigenvalues of the projected stiffness K̄ = Nᵀ K N, ascending.
    stability : Stability
        The verdict, its eigenvalue tolerance and, when neutral, the named null directions
        (:func:`casmbd.analysis.statics.stability.classify_stability`).
    search : {"nearest", "stable"}
        What was looked for: the equilibrium nearest the start (default) or a stable one.
    notes : list of str
        What the search did that matters for the answer (empty normally).
    body_angles, body_quaternions : ndarray
        Planar angles (n_bodies,) or spatial unit quaternions (n_bodies, 4).
    joint_reactions : ndarray (n_joints, 3 or 6)
        (F_x, F_y, M) or (F, M) of each joint, action of body1 on body2 (see
        :meth:`casmbd.system.equations.System.reactions_function`).
    """

    q: np.ndarray
    lagrange_multipliers: np.ndarray
    iterations: int
    residual: float
    residual_history: list
    method: str
    stable: bool | None
    eigenvalues: np.ndarray
    joint_reactions: np.ndarray
    t: float = 0.0
    potential_energy: float = 0.0
    names: dict = field(default_factory=dict)
    body_positions: np.ndarray = field(default_factory=lambda: np.zeros((0, 2)))
    body_angles: np.ndarray = field(default_factory=lambda: np.zeros(0))
    body_quaternions: np.ndarray = field(default_factory=lambda: np.zeros((0, 4)))
    joint_coordinates: np.ndarray = field(default_factory=lambda: np.zeros(0))
    marker_positions: np.ndarray = field(default_factory=lambda: np.zeros((0, 2)))
    #: requests and force-element reports at the equilibrium ("outputs": name -> value,
    #: "forces": element -> quantity -> value), as in the JSON of the grid analyses
    reports: dict = field(default_factory=dict)
    #: closed contacts and stops: name -> {"normal_force", "gap"}
    #: (:func:`casmbd.analysis.statics.resting.resting_equilibrium`)
    contacts: dict = field(default_factory=dict)
    stats: dict = field(default_factory=dict)
    stability: Stability | None = None
    #: "nearest" (the equilibrium nearest the start, stable or not: the default) or "stable"
    #: (a stable one asked for: the search descends the potential energy)
    search: str = "nearest"
    #: what the search did that the caller should know (a stall handed over to the descent,
    #: an unstable equilibrium left, a stable one asked for and not found)
    notes: list = field(default_factory=list)
    #: the text summary's values at the equilibrium: requests with their units and named
    #: nodes' deflections (:func:`state_summary`)
    summary: dict = field(default_factory=dict)

    def to_json(self) -> dict:
        """The JSON object of the ``casmbd statics`` command."""
        bodies = {}
        for k, name in enumerate(self.names.get("bodies", [])):
            bodies[name] = {"position": [float(x) for x in self.body_positions[k]]}
            if len(self.body_quaternions):
                bodies[name]["quaternion"] = [float(x) for x in self.body_quaternions[k]]
            else:
                bodies[name]["angle"] = float(self.body_angles[k])
            modal = [float(x) for x, c in zip(self.q, self.names.get("coordinates", []),
                                              strict=False) if c.startswith(f"{name}.eta")]
            if modal:  # a flexible body's modal coordinates η
                bodies[name]["modal_coordinates"] = modal
        markers = {name: {"position": [float(x) for x in self.marker_positions[k]]}
                   for k, name in enumerate(self.names.get("markers", []))}
        joints: dict = {name: {} for name in self.names.get("all_joints", [])}
        for k, name in enumerate(self.names.get("joints", [])):  # "joint.angle": 2nd coordinate
            joint, key = (name, "coordinate") if name in joints else name.rsplit(".", 1)
            joints.setdefault(joint, {})[key] = float(self.joint_coordinates[k])
        for k, name in enumerate(self.names.get("all_joints", [])):
            joints[name]["reaction"] = [float(x) for x in self.joint_reactions[k]]
        return {"kind": "statics", "t": float(self.t), "bodies": bodies, "joints": joints,
                "markers": markers,
                "q": [float(x) for x in self.q],
                "lagrange_multipliers": [float(x) for x in self.lagrange_multipliers],
                "stable": self.stable, "iterations": int(self.iterations),
                "residual": float(self.residual),
                "residual_history": [float(x) for x in self.residual_history],
                "eigenvalues": [float(x) for x in self.eigenvalues], "method": self.method,
                "search": self.search, "notes": list(self.notes),
                "potential_energy": float(self.potential_energy), "stats": dict(self.stats),
                "stability": self.stability.to_json() if self.stability else None,
                **({"contacts": self.contacts} if self.contacts else {}),
                **self.reports, **({"summary": self.summary} if self.summary else {})}


def state_reports(mech, out: dict) -> dict:
    """Requests (``outputs``), force reports (``forces``) and flexible bodies' named nodes
    (``nodes``: position, deflection and rotation relative to the undeformed body frame) at one
    state (the equilibrium; linearize's operating point), from the outputs Function's groups
    evaluated there (:mod:`casmbd.system.requests`)."""
    names = result_names(mech)
    reports: dict = {}
    if "outputs" in out:
        values = np.ravel(out["outputs"][0])
        reports["outputs"] = {n: float(v) for n, v in zip(names["outputs"], values,
                                                            strict=True)}
    if "force_outputs" in out:
        forces: dict = {}
        values = np.ravel(out["force_outputs"][0])
        for label, v in zip(names["force_outputs"], values, strict=True):
            element, _, quantity = label.rpartition(".")
            forces.setdefault(element, {})[quantity] = float(v)
        reports["forces"] = forces
    if "node_positions" in out:  # flexible bodies' named nodes (casmbd.system.requests)
        dim = mech.dimension
        rdim = 1 if dim == 2 else 3
        pos, defl, rot = (np.ravel(out[f"node_{k}"][0])
                          for k in ("positions", "deflections", "rotations"))
        reports["nodes"] = {
            name: {"position": [float(x) for x in pos[dim * i:dim * i + dim]],
                   "deflection": [float(x) for x in defl[dim * i:dim * i + dim]],
                   "rotation": float(rot[i]) if dim == 2 else
                   [float(x) for x in rot[rdim * i:rdim * i + rdim]]}
            for i, name in enumerate(names["nodes"])}
    return reports


def state_summary(reports: dict, names: dict) -> dict:
    """The text summaries' values at one state (an equilibrium, an operating point), in the
    form :meth:`casmbd.results.Result.summary` gives on a grid: ``{"outputs": {name: {"unit",
    "value"}}, "node_deflections": {name: {"unit": "m", "value": |u_i|, "deflection": u_i}}}``
    from the ``reports`` of :func:`state_reports` (u_i = Φ_i η, the node's elastic displacement
    relative to its undeformed position, body axes; seed 002, eq. 5–26); {} when there is
    neither."""
    out: dict = {}
    units = dict(zip(names.get("outputs", []), names.get("output_units", []), strict=False))
    if reports.get("outputs"):
        out["outputs"] = {name: {"unit": units.get(name, ""), "value": value}
                          for name, value in reports["outputs"].items()}
    if reports.get("nodes"):
        out["node_deflections"] = {
            name: {"unit": "m", "value": float(np.linalg.norm(node["deflection"])),
                   "deflection": list(node["deflection"])}
            for name, node in reports["nodes"].items()}
    return out


def _periodic_joint_outputs(mech, names: list[str]) -> list[int]:
    """Indices of the reported joint coordinates that are free angles: revolute angles and
    cylindrical ``.angle`` of joints without a rotational spring or a driver (whose winding
    matters)."""
    wound = {f.wound_joint() for f in mech.forces.values()} - {None}
    wound |= {d.joint for d in mech.drivers.values() if d.joint is not None}
    out = []
    for k, name in enumerate(names):
        joint, _, coord = name.partition(".")
        declared = mech.joints[joint].coordinate_names
        if joint not in wound and (coord or (declared[0] if declared else "")) == "angle":
            out.append(k)
    return out

def equilibrium_result(model, prob, plan, q, lam, f: np.ndarray, it: int, history: list,
                       notes: list, stability: Stability, n: np.ndarray, method: str,
                       stable: bool, solve_seconds: float) -> StaticsResult:
    """The :class:`StaticsResult` at the solution (q, λ) of ``prob`` on ``model`` (F its
    residual there; ``plan`` the redundant rows removed: the multipliers of the full set are
    then the least-norm ones), with the joint reactions (undetermined components flagged),
    the outputs and reports at the equilibrium, and the statistics of the search."""
    t = prob.t
    mech = model.mechanism
    check_removed(model, plan, q, t, "statics")
    if plan.removes:  # the least-norm multipliers of the full set
        lam = minimum_norm(model.constraint_jacobian(q, t), scatter(lam, plan.kept_rows,
                                                                    model.nc))
    all_joints = list(mech.joints)
    flags: dict = {}
    if all_joints:
        zero = np.zeros(prob.nq)
        u0 = np.zeros(len(mech.actuators))
        reactions = np.asarray(model.function("joint_reactions")(
            q, zero, zero, t, u0, model.p, lam)).T
        lams = np.asarray(lam, dtype=float)[None, :].copy()
        reactions, flags = flag_undetermined(model, q[None, :], zero[None, :], zero[None, :],
                                             np.array([t]), u0[None, :], lams,
                                             reactions[None], steps=[0],
                                             stacklevel=4)  # static_equilibrium's caller
        reactions, lam = reactions[0], lams[0]
        flags.pop("redundant_steps", None)
        flags.pop("undetermined_rows", None)
    else:
        reactions = np.zeros((0, model.reaction_size))
    out = model.outputs(q[None, :], np.zeros((1, prob.nq)), np.zeros((1, prob.nq)),
                        np.array([t]))
    nb = len(model.body_names)
    names = {"coordinates": model.coordinate_names, "bodies": list(model.body_names),
             "joints": list(model.joint_coordinate_names), "all_joints": all_joints,
             "markers": list(mech.markers),
             **{k: v for k, v in result_names(mech).items() if k == "nodes"}}
    stats = dict(model.report_dict)
    stats.update({"coordinates": model.coordinates, "coordinate_choice": model.coordinates,
                  "coordinate_reason": model.coordinate_reason,
                  "solve_seconds": solve_seconds, "n_coordinates": prob.nq,
                  "n_constraints": model.nc, "degrees_of_freedom": int(n.shape[1]),
                  "search": "stable" if stable else "nearest", **plan.stats(), **flags})
    joint_coordinates = np.ravel(out["joint_positions"][0]).copy()
    for k in _periodic_joint_outputs(mech, model.joint_coordinate_names):
        joint_coordinates[k] = wrap(joint_coordinates[k])
    reports = state_reports(mech, out)
    quats = np.zeros((0, 4))
    if model.dimension == 3:
        quats = quaternions_from_matrices(out["rotation_matrices"][0].reshape(nb, 9))
        quats *= np.where(quats[:, :1] < 0.0, -1.0, 1.0)  # e0 >= 0
    return StaticsResult(
        q=q, lagrange_multipliers=lam, iterations=it,
        residual=float(np.max(np.abs(f), initial=0.0)), residual_history=history,
        method=method, stable=stability.stable, eigenvalues=stability.eigenvalues,
        joint_reactions=reactions, t=t, potential_energy=model.potential_energy(q, t),
        names=names, body_positions=np.reshape(out["body_positions"][0], (nb, model.dimension)),
        body_angles=np.array([wrap(a) for a in np.ravel(out["angle_positions"][0])])
        if model.dimension == 2 else np.zeros(0), body_quaternions=quats,
        joint_coordinates=joint_coordinates, stats=stats, stability=stability,
        marker_positions=np.reshape(out["marker_positions"][0], (-1, model.dimension)),
        reports=reports, search="stable" if stable else "nearest", notes=notes,
        summary=state_summary(reports, result_names(mech)))

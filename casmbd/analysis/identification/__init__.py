"""Dynamic parameter identification (issue 38): the regressor, base parameters, estimation.

* :mod:`.parameters` — the standard parameters π (10 inertial per spatial body, 4 per planar
  body, viscous and Coulomb friction per joint coordinate), their names and nominal values:
  :func:`~casmbd.analysis.identification.parameters.standard_parameters`;
* :mod:`.regressor` — Y(q, v, a) with τ = Y π, exact by AD and compiled (per call and
  batched): :func:`~casmbd.analysis.identification.regressor.joint_torque_regressor`;
* :mod:`.base_parameters` — the identifiable combinations π_b = K π by QR with column
  pivoting: :func:`~casmbd.analysis.identification.base_parameters.base_parameters`.

docs/identification.md describes the equations and their sources.
"""

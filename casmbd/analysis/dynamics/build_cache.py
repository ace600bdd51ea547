"""A simulator found by what its model is: the cache hit that skips the symbolic build.

A mixin of :class:`casmbd.analysis.dynamics.simulate.Simulator`.  Before anything symbolic is built,
:meth:`CachedBuild._from_cache` computes :func:`casmbd.compiled.modelkey.model_key` of the
mechanism and the simulator's options (formulation, its options, actuator inputs, redundancy
policy); when a model record of that key exists and its libraries pass the cache's checks
(record, build key, size, SHA-256, signatures before ``dlopen``, signatures after), the
simulator is made from the loaded Functions and the recorded metadata —
:meth:`NumericModel.from_record <casmbd.compiled.model.NumericModel.from_record>`, the chosen
formulation, the redundancy plan, the name of the dynamics Function — without a
:class:`~casmbd.system.System`.  :attr:`system`, :attr:`formulation` and the
integrated system (``_dyn_system``) are then built on first use only (fixed-step integrators
compile their own step from the symbolic formulation; sensitivities and diagnostics build new
Functions).  After a miss, :meth:`CachedBuild._remember` writes the record.

A description without an exact canonical form (a Python callable as a value or an input, a
CasADi expression), a System given instead of a Mechanism, the virtual machine, and a
formulation registered from outside casmbd are never looked up: they build every time.
"""

from __future__ import annotations

import os
import warnings
from collections.abc import Mapping

import casadi as ca
import numpy as np

from casmbd.analysis.formulations import FORMULATIONS, formulation_kind
from casmbd.compiled import modelkey
from casmbd.compiled.model import NumericModel, c_symbol_name
from casmbd.errors import AnalysisError, CasmbdError
from casmbd.model.mechanism import Mechanism
from casmbd.model.values import resolve
from casmbd.system.equations import System
from casmbd.system.subset import ConstraintSubset

__all__ = ["CachedBuild", "input_expression"]

#: name of the compiled actuator-input Function u(t, p) in the simulator's library
INPUTS_FUNCTION = "actuator_inputs"


def input_expression(system: System, inputs: Mapping | None) -> ca.SX:
    """u(t, p) of the actuators: given values/expressions, zero for the others."""
    inputs = dict(inputs or {})
    names = list(system.mechanism.actuators)
    for key in inputs:
        if key not in names:
            raise AnalysisError(f"inputs: unknown actuator '{key}' (known: "
                                f"{', '.join(names) or 'none'})")
    exprs = [resolve(inputs[n], system.t, system.ctx.p, f"input of actuator '{n}'")
             if n in inputs else ca.SX(0.0) for n in names]
    return ca.vertcat(*exprs) if exprs else ca.SX(0, 1)


def _json_ready(value):
    """Numpy scalars and arrays inside a redundancy plan as plain Python values."""
    if isinstance(value, dict):
        return {k: _json_ready(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_json_ready(v) for v in value]
    if isinstance(value, np.ndarray):
        return value.tolist()
    if isinstance(value, np.generic):
        return value.item()
    return value


class _Deferred:
    """The formulation of a simulator from the cache: its name and kind ("ode", "dae",
    "numeric") at once, the symbolic rest (``function``, ``extra``, ``options``, …) built on
    first use."""

    def __init__(self, owner: CachedBuild, name: str, kind: str):
        self.name, self.kind, self._owner = name, kind, owner

    def __getattr__(self, attribute: str):
        if attribute.startswith("__"):
            raise AttributeError(attribute)
        return getattr(self._owner._symbolic_formulation(), attribute)


class CachedBuild:
    """Model-keyed cache of the :class:`~casmbd.analysis.dynamics.simulate.Simulator` (see
    module)."""

    #: simulator attributes kept in the record beside the model's
    _RECORDED = ("formulation_reason",)

    # -------------------------------------------------------------- lazily built on a hit
    @property
    def system(self) -> System:
        """The symbolic equations (on a cache hit built on first use)."""
        found = self.__dict__.get("_system")
        return found if found is not None else self.model.system

    @system.setter
    def system(self, value: System) -> None:
        self.__dict__["_system"] = value

    @property
    def formulation(self):
        """The :class:`~casmbd.analysis.formulations.Formulation` (on a cache hit a stand-in
        whose symbolic parts are built on first use)."""
        return self.__dict__["_formulation"]

    def _symbolic_formulation(self):
        if isinstance(self.formulation, _Deferred):
            self._build_symbolic()
        return self.formulation

    @formulation.setter
    def formulation(self, value) -> None:
        self.__dict__["_formulation"] = value

    @property
    def _dyn_system(self) -> System:
        if "_dyn_system_" not in self.__dict__:
            self._symbolic_formulation()
        return self.__dict__["_dyn_system_"]

    @_dyn_system.setter
    def _dyn_system(self, value: System) -> None:
        self.__dict__["_dyn_system_"] = value

    def _build_symbolic(self) -> None:
        system = self.system
        keep = self.redundancy.get("kept_rows")
        dyn = ConstraintSubset(system, keep) if keep is not None else system
        self._dyn_system = dyn
        self.formulation = self.kind.build(dyn, inputs=input_expression(system, self._inputs),
                                           **dict(self._formulation_options or {}))

    # -------------------------------------------------------------- lookup and record
    def _from_cache(self, mechanism, formulation: str | None, inputs: Mapping | None,
                    mode: str, formulation_options: Mapping | None, redundancy: str) -> bool:
        """Set the simulator up from the model record of its key; False on a miss."""
        self._inputs, self._formulation_options = inputs, formulation_options
        self._cache_key = None
        if not isinstance(mechanism, Mechanism) or mode == "vm" or (
                mode == "auto" and os.environ.get("CASMBD_COMPILE", "").strip() == "0"):
            return False
        if any(not type(k).__module__.startswith("casmbd.") for k in FORMULATIONS.values()):
            return False  # a formulation's code outside casmbd is not in the key
        key = modelkey.model_key(mechanism, "simulator", {
            "formulation": formulation, "inputs": dict(inputs or {}),
            "formulation_options": dict(formulation_options or {}),
            "redundancy": redundancy})
        if key is None:
            return False
        self._cache_key = key
        found = modelkey.load(c_symbol_name(mechanism.name), key, stacklevel=4)
        if found is None:
            return False
        functions, meta, report = found
        try:
            model = NumericModel.from_record(mechanism, functions, report, meta["model"],
                                             report.load_seconds)
            kind = formulation_kind(meta["formulation"])
            dyn, ufun = functions[meta["dyn"]], functions[INPUTS_FUNCTION]
            plan = dict(meta["redundancy"])
            deferred = _Deferred(self, kind.name, str(meta["formulation_kind"]))
            recorded = dict(meta.get("attributes") or {})
        except (KeyError, TypeError, ValueError, CasmbdError) as exc:
            warnings.warn(f"casmbd: the model record of {mechanism.name!r} is not used "
                          f"({type(exc).__name__}: {exc}); building the model again",
                          RuntimeWarning, stacklevel=4)
            return False
        self.model, self.kind, self.dyn, self.ufun = model, kind, dyn, ufun
        self.formulation_name, self.redundancy, self.formulation = kind.name, plan, deferred
        for name, value in recorded.items():
            setattr(self, name, value)
        return True

    def _remember(self) -> None:
        """Write the model record after a build that compiled (or found) its libraries."""
        key = getattr(self, "_cache_key", None)
        if key is None or self.model.report.mode != "compiled":
            return
        meta = {"model": self.model.record(), "formulation": self.formulation_name,
                "redundancy": _json_ready(self.redundancy), "dyn": self.dyn.name(),
                "formulation_kind": self.formulation.kind,
                "attributes": {k: getattr(self, k) for k in self._RECORDED if hasattr(self, k)}}
        modelkey.store(c_symbol_name(self.model.mechanism.name), key, self.model.report, meta)

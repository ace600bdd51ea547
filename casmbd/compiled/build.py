"""The one compiler of casmbd: every compiled model and every compiled block is built here.

Like MuJoCo's single compiler (``mj_compile``: a model description in, an ``mjModel`` out)
and Pinocchio's ``buildModel``, :func:`compile_model` turns a scene (a
:class:`~casmbd.model.mechanism.Mechanism` or its symbolic
:class:`~casmbd.system.equations.System`) and the set of equations an analysis needs into a
:class:`~casmbd.compiled.model.NumericModel`; the analyses then evaluate through a
:class:`~casmbd.compiled.workspace.Workspace` of their own (``data = model.workspace()``,
Pinocchio's ``aba(model, data, …)``).  :func:`compile_blocks` compiles Functions that are not
equations of a model (an integrator's fused step blocks, the OCP's element derivatives) into
a cached library of their own.  No other module of casmbd constructs a NumericModel or calls
the code generator (``tests/compiled/test_one_compile.py``).
"""

from __future__ import annotations

from collections.abc import Collection, Iterable, Sequence

import casadi as ca

from casmbd.compiled.codegen import BuildReport, compile_functions
from casmbd.compiled.model import NumericModel

__all__ = ["compile_blocks", "compile_model"]


def compile_model(system, needs: Iterable[str] | str = "kinematics", *, mode: str = "auto",
                  extra: Iterable[ca.Function] = (),
                  hot: Iterable[str] | None = None) -> NumericModel:
    """The compiled model of a scene for a set of needs.

    Parameters
    ----------
    system : Mechanism or System
        The scene (a Mechanism is wrapped in a System with its own coordinate choice) or its
        symbolic equations.
    needs : iterable of str or str
        The Functions to build (names of :data:`casmbd.system.SIGNATURES`, plus
        ``"outputs"``), or the name of an analysis in :data:`casmbd.compiled.model.NEEDS`
        (``"info"``, ``"kinematics"``, ``"dynamics"``, ``"ode_dynamics"``).  A known equation
        not built is built on first use in CasADi's virtual machine.
    mode : {"auto", "compiled", "vm"}
        Compile to C (cached on disk; ``"auto"`` falls back to the virtual machine with a
        warning) or use CasADi's virtual machine.
    extra : iterable of casadi.Function
        Further Functions compiled into the same library (a formulation's dynamics, the
        statics residual and its Jacobian, an integrator's step block).
    hot : iterable of str, optional
        The Functions evaluated often (an integrator's right-hand side): only these are
        optimised, the others compiled at ``-O0``; default: all optimised.

    Returns
    -------
    NumericModel
        The fixed part (Functions, sizes, names, parameter values ``p``); its
        :meth:`~casmbd.compiled.model.NumericModel.workspace` gives the buffers of a run.

    Raises
    ------
    CompileError
        In ``"compiled"`` mode when the C code cannot be compiled or loaded.
    ModelError
        For a scene whose equations cannot be built.
    """
    return NumericModel(system, needs, mode=mode, extra=extra, hot=hot)


def compile_blocks(functions: Sequence[ca.Function], name: str, *, mode: str = "auto",
                   flags: Sequence[str] | None = None,
                   hot: Collection[str] | None = None
                   ) -> tuple[dict[str, ca.Function], BuildReport]:
    """Compile Functions that are not a model's equations into one cached library.

    The code generation, cache and flags of
    :func:`~casmbd.compiled.codegen.compile_functions` (same parameters, same library for
    the same Functions): ``functions`` with distinct C-identifier names, ``name`` the
    library's C prefix, ``mode`` as in :func:`compile_model`, ``flags`` the optimisation
    flags (default ``$CASMBD_CFLAGS`` or ``-O2``), ``hot`` the Functions to optimise.

    Returns
    -------
    functions : dict of str to casadi.Function
        The loaded (or, in the virtual machine, the given) Functions by name.
    report : BuildReport
        What was done and how long it took.
    """
    return compile_functions(functions, name, mode=mode, flags=flags, hot=hot)

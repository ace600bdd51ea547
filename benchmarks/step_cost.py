"""Cost of one integrator step against the cost of the right-hand side (issue 22, item 5).

For the pendulum chains of :func:`benchmarks.chains.pendulum_chain` (N = 8 and 32 rods, joint
and absolute coordinates, each with the formulation ``Simulator`` chooses) this measures, in
one process and on one compiled model:

* *RHS*: µs per evaluation of the compiled right-hand side through ``Function.buffer()``
  (what an integrator calls; the fastest of ``--repeat`` timeit runs);
* the default integrator (``Simulator.run`` without ``integrator``: CVODES-Adams) at rtol =
  atol = :data:`TOL` over t ∈ [0, :data:`T_END`] with one output interval: *µs/step* is
  ``stats['solve_seconds'] / stats['steps']`` (fastest of ``--repeat`` runs), *µs/eval* the
  same time per right-hand-side evaluation; *raw call* is the CasADi integrator called
  directly (no casmbd around it), and *floor* the same CVODES-Adams call on a right-hand side
  that costs next to nothing (uncoupled oscillators with as many states: CasADi's and
  SUNDIALS' own cost per step);
* fixed-step RK4 (``integrator="rk4"``, step :data:`RK4_STEP`) with one output interval and
  with :data:`OUTPUTS` output intervals (10 steps each).

*ratio* = µs/step ÷ RHS: the issue's target is ≤ 3 on chain8 and chain32.

Per right-hand-side evaluation (issue 36, item 4: ≤ :data:`EVAL_TARGET` × the bare compiled
function), on chain8 and chain32 in joint coordinates and the four-bar (each with the path
``Simulator`` chooses), all in processor time of the measuring thread (``time.thread_time``,
fastest of ``--repeat``; the load average is recorded): *DOPRI5* the compiled stepping alone
(``Dopri.start`` + ``Dopri.advance`` to t_end: blocks of 64/16/4 attempts, compiled start)
and, in the same process, the previous configuration (one block size of 16, the first step
in NumPy); *RK4* the compiled folds (``FixedStep.advance``); *Adams*, *CVODES* (BDF) and
*IDAS* the CasADi integrator called directly, per right-hand side it evaluated
(``n_call_daeF``), with the share of time in the Jacobian (``t_proc_jacF``); and
``Simulator.run``'s ``solve_cpu_seconds`` per evaluation for DOPRI5 and RK4.

Timings are the fastest of the repeats because the machine is shared; the solve's numbers
(steps, errors) do not depend on them.

Run ``python -m benchmarks.step_cost [--repeat 5] [--update-docs]``; ``--render`` rewrites
the docs section from ``benchmarks/results/step_cost.json``.
"""

from __future__ import annotations

import json
import platform
import time
from pathlib import Path

import casadi as ca
import numpy as np

from benchmarks.bench_equations import buffer_evaluator
from benchmarks.chains import pendulum_chain
from benchmarks.docs import run_study, study_parser

ROOT = Path(__file__).resolve().parent.parent
RESULTS = ROOT / "benchmarks" / "results" / "step_cost.json"
#: the same study on the code before issue 22 item 5 (commit d9ae833: fixed-step folds called
#: with CasADi's argument conversion, progress callback at every step), for the "before"
#: columns; kept as measured
BEFORE = ROOT / "benchmarks" / "results" / "step_cost_before.json"
DOC = ROOT / "docs" / "performance.md"
HEAD = "## Integrator steps against the right-hand side"

#: the chains and coordinates measured
CASES = ((8, "joint"), (32, "joint"), (8, "absolute"), (32, "absolute"))
#: time span [s], tolerance of the default integrator, RK4 step [s], RK4 output intervals
T_END, TOL, RK4_STEP, OUTPUTS = 2.0, 1e-7, 1e-3, 200
#: the issue's target: µs per step ≤ TARGET × µs per right-hand side
TARGET = 3.0
#: issue 36 item 4: µs per right-hand-side evaluation ≤ EVAL_TARGET × the bare function
EVAL_TARGET = 1.2
#: the problems of the per-evaluation table (benchmarks.work_precision.problem, path "auto")
EVAL_PROBLEMS = ("chain8", "fourbar", "chain32")


#: where the default integrator's time goes (``perf record`` of CVODES-Adams on chain8 in joint
#: coordinates over t ∈ [0, 200] s, 114 272 steps, 181 323 right-hand sides: ``perf record -o
#: p.data python run.py; perf report -i p.data --sort dso``), measured once on 2026-11-25
WHERE = (
    "Where a default (CVODES-Adams) step goes, by `perf record` of chain8 in joint coordinates "
    "over t ∈ [0, 200] s (114 272 steps, 1.6 right-hand sides per step; `perf report --sort "
    "dso`; the process's set-up included): the kernel 36 % — almost all of it "
    "`clock_gettime(CLOCK_PROCESS_CPUTIME_ID)`, the processor-time clock CasADi's `FStats` "
    "reads before and after every right-hand-side evaluation "
    "(`OracleFunction::calc_function`, unconditionally; `record_time` does not switch it "
    "off) —, the compiled right-hand side 14 % (with libm), CasADi's dispatch 10 %, SUNDIALS "
    "12 %, libc 5 %. The *floor* column is that fixed cost alone (the same CVODES call on a "
    "right-hand side that costs nothing): 2–7 µs per step here, more than 3× the right-hand "
    "side of chain8 (0.35 µs on a quiet machine, docs above), so the ratio cannot reach 3 on "
    "chain8 through CasADi's integrator whatever casmbd does; it does on larger models. "
    "casmbd's own code in a run costs 34 µs (`CapturedOutput`: a temporary file and two "
    "`dup2`; since issue 36 only around SUNDIALS runs and projections, not compiled "
    "stepping) plus 8 µs (`stats()`), measured alone; *raw* is the integrator called in a "
    "tight loop, 0.3–0.5 ms per run faster than inside `Simulator.run`. Cut in casmbd: "
    "the fixed-step loops (compiled folds of 256, 64, 16, 4 and 1 steps called through "
    "`Function.buffer()` on arrays bound once instead of CasADi's argument conversion: "
    "50–150 µs a call) and the progress bar of SUNDIALS runs (its Python callback ran at "
    "every step, about 2 µs; now only for the steps ending in the first eighth of an output "
    "interval).",
)


def _fastest(fn, repeat: int, min_seconds: float = 0.05, clock=time.perf_counter) -> float:
    """Seconds per call of ``fn`` on ``clock`` (wall time, or ``time.thread_time``: processor
    time of this thread, which waiting for a shared core does not count): the fastest of
    ``repeat`` runs of enough calls to last ``min_seconds``."""
    fn()
    number = 1
    while True:
        t0 = clock()
        for _ in range(number):
            fn()
        elapsed = clock() - t0
        if elapsed >= max(min_seconds, 1e-3):
            break
        number *= 2
    best = elapsed / number
    for _ in range(repeat - 1):
        t0 = clock()
        for _ in range(number):
            fn()
        best = min(best, (clock() - t0) / number)
    return best


def _rhs_us(sim, repeat: int, clock=time.perf_counter) -> float:
    f = sim.dyn
    nx = f.nnz_in(1)
    rng = np.random.default_rng(0)
    args = [np.zeros(f.nnz_in(i)) for i in range(f.n_in())]
    args[1][:] = np.concatenate([sim.model.initial_coordinates(),
                                 np.zeros(nx - sim.model.nq)]) + 1e-3 * rng.standard_normal(nx)
    args[3][:] = sim.model.p
    trigger, outs = buffer_evaluator(f, args)
    trigger()
    if not np.all(np.isfinite(outs[0])):
        raise RuntimeError("non-finite right-hand side at the timing state")
    return 1e6 * _fastest(trigger, repeat, 0.02, clock)


def _run(sim, repeat: int, **kw) -> dict:
    """The fastest of ``repeat`` runs of ``sim.run(T_END, …, **kw)``: solve time and counts."""
    best, outputs = None, kw.pop("outputs", 1)
    for _ in range(repeat):
        res = sim.run(T_END, outputs, **kw)
        st = res.stats
        row = {"outputs": len(res.t) - 1, "solve_s": st["solve_seconds"],
               "steps": int(st["steps"]), "evals": int(st["rhs_evaluations"]),
               "integrator": st["integrator"],
               "tip": np.asarray(res.marker("tip")["position"][-1], float)[:2].tolist()}
        if best is None or row["solve_s"] < best["solve_s"]:
            best = row
    best["us_step"] = 1e6 * best["solve_s"] / best["steps"]
    best["us_eval"] = 1e6 * best["solve_s"] / best["evals"]
    return best


def _raw_call(sim, name: str, repeat: int, clock=time.perf_counter) -> dict:
    """The CasADi integrator of the run called directly (no casmbd code around it)."""
    from casmbd.analysis.integrators import sundials as sun

    solver = sun.sundials(sim.dyn, name, 0.0, [T_END], TOL, TOL, 500_000)
    x0 = np.concatenate([sim.model.initial_coordinates(), sim.model.initial_velocities()])
    z0, p = np.zeros(sim.dyn.nnz_in(2)), sim.model.p
    seconds = _fastest(lambda: solver(x0=x0, z0=z0, p=p), repeat, 0.0, clock)
    return {"seconds": seconds, "steps": int(solver.stats()["nsteps"])}


def _fixed_cpu(sim, repeat: int) -> float:
    """Processor µs per step of the compiled RK4 folds (``FixedStep.advance`` over
    T_END / RK4_STEP steps in one call, what ``Simulator.run`` does with one output)."""
    from casmbd.analysis.integrators import fixed_step as fixed

    runner = fixed.FixedStep(sim.formulation.function, "rk4", mode="auto",
                             name=f"{getattr(sim.model, 'name', 'step_cost')}_rk4")
    x0 = np.concatenate([sim.model.initial_coordinates(), sim.model.initial_velocities()])
    p, count = sim.model.p, round(T_END / RK4_STEP)
    start = runner.start(x0, 0.0, p)
    seconds = _fastest(lambda: runner.advance(start, p, RK4_STEP, count), repeat, 0.0,
                       time.thread_time)
    return 1e6 * seconds / count


def _floor(nx: int, name: str, repeat: int, clock=time.perf_counter) -> dict:
    """CVODES through CasADi on nx / 2 uncoupled oscillators q̈ = −ω² q (ω = 2π·(1 … 2)
    rad/s, a right-hand side of nx multiplications in CasADi's virtual machine): µs per step
    of CasADi's and SUNDIALS' own work."""
    from casmbd.analysis.integrators import kinds as integ

    m = nx // 2
    q, v, t = ca.SX.sym("q", m), ca.SX.sym("v", m), ca.SX.sym("t")
    omega2 = (2 * np.pi * np.linspace(1.0, 2.0, m)) ** 2
    kind = integ.integrator_kind(name)
    solver = ca.integrator("floor", kind.plugin,
                           {"x": ca.vertcat(q, v), "t": t, "ode": ca.vertcat(v, -omega2 * q)},
                           0.0, [T_END], {"reltol": TOL, "abstol": TOL, **dict(kind.options)})
    x0 = np.concatenate([np.ones(m), np.zeros(m)])
    seconds = _fastest(lambda: solver(x0=x0), repeat, 0.0, clock)
    steps = int(solver.stats()["nsteps"])
    return {"us_step": 1e6 * seconds / steps, "steps": steps}


def _dopri_cpu(sim, t_end: float, repeat: int, previous: bool = False) -> dict:
    """Processor µs per right-hand side of DOPRI5's compiled stepping over [0, t_end] at
    rtol = atol = TOL (start and advance, one output): the blocks compiled with the model
    or, with ``previous``, one block size of 16 and the first step in NumPy (the code
    before issue 36), compiled on its own."""
    from casmbd.analysis.integrators import INTEGRATORS
    from casmbd.analysis.integrators import dopri as dp

    x0 = np.concatenate([sim.model.initial_coordinates(), sim.model.initial_velocities()])
    p = sim.model.p
    if previous:
        runner = dp.Dopri(sim.formulation.function, mode="auto", blocks=(dp.BLOCK,),
                          compiled_start=False, name=f"{sim.model.name}_dopri5_previous")
    else:
        kind = INTEGRATORS["dopri5"]
        functions = {n: sim.model.functions[n] for n in kind.model_function_names
                     if n in sim.model.functions}
        runner = kind.runner(sim.dyn if functions else sim.formulation.function, "auto",
                             f"{sim.model.name}_dopri5", functions)

    def march():
        state = runner.start(x0, 0.0, t_end, p, TOL, TOL)
        return runner.advance(state, p, t_end, TOL, TOL, 10 ** 6)

    st = march().stats()
    runner.calls = 0
    march()
    calls = runner.calls
    seconds = _fastest(march, repeat, 0.0, time.thread_time)
    return {"us_eval": 1e6 * seconds / st["rhs_evaluations"], "evals": st["rhs_evaluations"],
            "steps": st["steps"], "calls": calls}


def _rk4_cpu(sim, t_end: float, repeat: int) -> dict:
    """Processor µs per right-hand side of the compiled RK4 folds (step RK4_STEP, one
    ``FixedStep.advance`` over [0, t_end])."""
    from casmbd.analysis.integrators import fixed_step as fixed

    runner = fixed.FixedStep(sim.formulation.function, "rk4", mode="auto",
                             name=f"{sim.model.name}_rk4")
    x0 = np.concatenate([sim.model.initial_coordinates(), sim.model.initial_velocities()])
    p, count = sim.model.p, round(t_end / RK4_STEP)
    start = runner.start(x0, 0.0, p)
    seconds = _fastest(lambda: runner.advance(start, p, RK4_STEP, count), repeat, 0.0,
                       time.thread_time)
    return {"us_eval": 1e6 * seconds / (4 * count), "evals": 4 * count, "steps": count}


def _jacobian_kind(dyn, name: str) -> str:
    """How the integrator ``name`` forms its Newton matrix from ``dyn``."""
    from casmbd.analysis.integrators import sundials as sun

    kind = sun.integrator_kind(name)
    if not getattr(kind, "newton", False):
        return "none"
    g = ca.integrator("jacobian_kind", kind.plugin, dyn, 0.0, [1.0],
                      dict(kind.options)).get_function("jacF")
    called = {g.instruction_MX(i).which_function().class_name()
              for i in range(g.n_instructions()) if g.instruction_MX(i).op() == ca.OP_CALL}
    return "central differences" if "CentralDiff" in called else \
        "forward differences" if "ForwardDiff" in called else "exact"


def _sundials_cpu(sim, name: str, t_end: float, repeat: int, previous: bool = False) -> dict:
    """Processor µs per right-hand side of the CasADi SUNDIALS integrator ``name`` called
    directly over [0, t_end] at rtol = atol = TOL, and the share of its time in Jacobians;
    on the dynamics ``Simulator`` gives that method (``sundials_dynamics``: exact or
    forward-difference Jacobians), or with ``previous`` on the model's dynamics as loaded
    (CasADi's central differences, the path before issue 36 item 4)."""
    from casmbd.analysis.integrators import sundials as sun

    dyn = sim.dyn if previous else sim.sundials_dynamics(name)
    solver = sun.sundials(dyn, name, 0.0, [t_end], TOL, TOL, 10 ** 6)
    x0 = np.concatenate([sim.model.initial_coordinates(), sim.model.initial_velocities()])
    z0, p = np.zeros(sim.dyn.nnz_in(2)), sim.model.p  # ODE formulations: no z
    seconds = _fastest(lambda: solver(x0=x0, z0=z0, p=p), repeat, 0.0, time.thread_time)
    st = solver.stats()
    evals = int(st.get("n_call_daeF") or st.get("nfevals"))
    return {"us_eval": 1e6 * seconds / evals, "evals": evals, "steps": int(st["nsteps"]),
            "ms_run": 1e3 * seconds, "jacobian": _jacobian_kind(dyn, name),
            "jacobians": int(st.get("n_call_jacF", 0)),
            "jacobian_share": float(st.get("t_proc_jacF", 0.0)) / seconds}


def _run_cpu(sim, t_end: float, repeat: int, **kw) -> dict:
    """``Simulator.run``'s ``solve_cpu_seconds`` (processor time of the solve, fastest of
    ``repeat`` after one run that builds the solver) per evaluation, and the wall time."""
    sim.run(t_end, 1, **kw)
    best = None
    for _ in range(repeat):
        st = sim.run(t_end, 1, **kw).stats
        best = st if best is None or st["solve_cpu_seconds"] < best["solve_cpu_seconds"] \
            else best
    return {"us_eval": 1e6 * best["solve_cpu_seconds"] / best["rhs_evaluations"],
            "wall_us_eval": 1e6 * best["solve_seconds"] / best["rhs_evaluations"],
            "evals": int(best["rhs_evaluations"]), "steps": int(best["steps"])}


def per_evaluation(repeat: int, problems=EVAL_PROBLEMS) -> list[dict]:
    """The per-evaluation rows (issue 36 item 4), one per problem."""
    import os

    from benchmarks.work_precision import problem
    from casmbd.analysis.dynamics.simulate import Simulator

    rows = []
    for name in problems:
        mech, t_end, _, _ = problem(name, "auto")
        mech.name = f"step_cost_{name}"
        sim = Simulator(mech)
        row = {"problem": name, "formulation": sim.formulation_name, "t_end": t_end,
               "nx": int(sim.dyn.nnz_in(1)), "load": os.getloadavg()[0],
               "rhs_us": _rhs_us(sim, repeat, time.thread_time), "paths": {}}
        paths = row["paths"]
        paths["dopri5"] = _dopri_cpu(sim, t_end, repeat)
        paths["dopri5 previous"] = _dopri_cpu(sim, t_end, repeat, previous=True)
        paths["rk4"] = _rk4_cpu(sim, t_end, repeat)
        for plugin, previous in (("adams", False), ("cvodes", False), ("cvodes", True),
                                 ("idas", False), ("idas", True)):
            key = f"{plugin} previous" if previous else plugin
            try:
                paths[key] = _sundials_cpu(sim, plugin, t_end, repeat, previous)
            except (RuntimeError, ValueError) as exc:  # e.g. IDAS on an ODE without z
                paths[key] = {"error": str(exc).splitlines()[-1][:120]}
        paths["dopri5 Simulator.run"] = _run_cpu(sim, t_end, repeat, integrator="dopri5",
                                                  rtol=TOL, atol=TOL)
        paths["rk4 Simulator.run"] = _run_cpu(sim, t_end, repeat, integrator="rk4",
                                               step=RK4_STEP)
        # the bare function again, after the paths: the ratio uses the faster of the two
        row["rhs_us"] = min(row["rhs_us"], _rhs_us(sim, repeat, time.thread_time))
        row["load_end"] = os.getloadavg()[0]
        rows.append(row)
        print(f"{name}: RHS {row['rhs_us']:.3g} µs; " + "; ".join(
            f"{k} {v['us_eval'] / row['rhs_us']:.2f}" for k, v in paths.items()
            if "us_eval" in v), flush=True)
    return rows


def measure(repeat: int = 10) -> dict:
    from casmbd.analysis.dynamics.simulate import Simulator

    rows = []
    for n, coords in CASES:
        mech = pendulum_chain(n)
        mech.coordinates = coords
        mech.name = f"step_cost_chain{n}_{coords}"
        sim = Simulator(mech)
        row = {"n": n, "coordinates": coords, "formulation": sim.formulation_name,
               "nx": int(sim.dyn.nnz_in(1)), "rhs_us": _rhs_us(sim, repeat)}
        row["default"] = _run(sim, repeat, rtol=TOL, atol=TOL)
        # the raw and floor columns are CVODES: the default integrator when it is a SUNDIALS
        # one, else Adams (the compiled dopri5 of the articulated recursion has no raw call)
        sundials = row["default"]["integrator"]
        sundials = sundials if sundials in ("adams", "cvodes") else "adams"
        row["sundials"] = sundials
        raw = _raw_call(sim, sundials, repeat)
        row["raw_us_step"] = 1e6 * raw["seconds"] / raw["steps"]
        row["floor"] = _floor(row["nx"], sundials, repeat)
        row["rk4_one"] = _run(sim, repeat, integrator="rk4", step=RK4_STEP)
        row["rk4_grid"] = _run(sim, repeat, integrator="rk4", step=RK4_STEP, outputs=OUTPUTS)
        cpu = time.thread_time
        raw = _raw_call(sim, sundials, repeat, cpu)
        row["cpu"] = {"rhs_us": _rhs_us(sim, repeat, cpu),
                      "raw_us_step": 1e6 * raw["seconds"] / raw["steps"],
                      "floor_us_step": _floor(row["nx"], sundials, repeat,
                                              cpu)["us_step"],
                      "rk4_us_step": _fixed_cpu(sim, repeat)}
        rows.append(row)
        d = row["default"]
        print(f"chain{n} {coords}: RHS {row['rhs_us']:.3g} µs; {d['integrator']} "
              f"{d['us_step']:.3g} µs/step (raw {row['raw_us_step']:.3g}, floor "
              f"{row['floor']['us_step']:.3g}); rk4 {row['rk4_one']['us_step']:.3g} / "
              f"{row['rk4_grid']['us_step']:.3g} µs/step", flush=True)
    return {"date": time.strftime("%Y-%m-%d"), "machine": platform.machine(),
            "python": platform.python_version(), "casadi": ca.__version__, "repeat": repeat,
            "rows": rows, "per_eval": per_evaluation(repeat)}


def _f(x: float) -> str:
    return f"{x:.3g}"


def markdown(data: dict) -> str:
    """The docs section."""
    lines = [
        HEAD, "",
        "Written by `python -m benchmarks.step_cost --update-docs` "
        f"({data['date']}, CasADi {data['casadi']}, fastest of {data['repeat']} runs on a "
        "shared 2-core machine). Pendulum chains released horizontally, t ∈ [0, "
        f"{T_END:g}] s, each with the formulation `Simulator` chooses. *RHS*: µs per "
        "evaluation of the compiled right-hand side through `Function.buffer()`. *default*: "
        f"`Simulator.run` without an integrator (rtol = atol = {TOL:g}, one output interval); "
        "*µs/step* = `solve_seconds / steps`, *µs/eval* = `solve_seconds / rhs_evaluations`, "
        "*ratio* = µs/step ÷ RHS (target ≤ 3); *raw*: the CVODES integrator (the default "
        "one, or Adams where the default is the compiled dopri5) called directly; *floor*: "
        "the same CVODES call on uncoupled oscillators with as many states "
        "(a right-hand side that costs next to nothing: CasADi's and SUNDIALS' own cost per "
        "step). *rk4*: "
        f"fixed step {RK4_STEP:g} s ({round(T_END / RK4_STEP)} steps, 4 evaluations "
        f"each) with 1 and with {OUTPUTS} output intervals.", "",
        "| chain | coordinates | formulation | nx | RHS [µs] | default | steps | µs/step | "
        "µs/eval | ratio | raw µs/step | floor µs/step | rk4 µs/step (1 output) | ratio | "
        f"rk4 µs/step ({OUTPUTS} outputs) | ratio |",
        "|---|---|---|---:|---:|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|"]
    for r in data["rows"]:
        d, one, grid = r["default"], r["rk4_one"], r["rk4_grid"]
        lines.append(
            f"| chain{r['n']} | {r['coordinates']} | {r['formulation']} | {r['nx']} | "
            f"{_f(r['rhs_us'])} | {d['integrator']} | {d['steps']} | {_f(d['us_step'])} | "
            f"{_f(d['us_eval'])} | {d['us_step'] / r['rhs_us']:.2f} | "
            f"{_f(r['raw_us_step'])} | {_f(r['floor']['us_step'])} | {_f(one['us_step'])} | "
            f"{one['us_step'] / r['rhs_us']:.2f} | {_f(grid['us_step'])} | "
            f"{grid['us_step'] / r['rhs_us']:.2f} |")
    met = [f"chain{r['n']} {r['coordinates']} {r['default']['us_step'] / r['rhs_us']:.2f}"
           for r in data["rows"]]
    lines += ["", "Ratio µs/step ÷ RHS of the default integrator (target ≤ "
              f"{TARGET:g}): " + "; ".join(met) + "."]
    if all("cpu" in r for r in data["rows"]):
        lines += ["", "The same in processor time of the measuring thread (`time.thread_time`, "
                  "fastest of the repeats; waiting for a shared core does not count, so these "
                  "are the figures of an idle machine): *raw* is the CVODES integrator called "
                  "directly, *rk4* the compiled folds over the 2000 steps in one "
                  "`FixedStep.advance` (4 right-hand sides a step: *per eval* = µs/step / 4).",
                  "", "| chain | coordinates | RHS [µs] | default µs/step | ratio | "
                  "floor µs/step | rk4 µs/step | ratio | rk4 per eval ÷ RHS |",
                  "|---|---|---:|---:|---:|---:|---:|---:|---:|"]
        for r in data["rows"]:
            c = r["cpu"]
            lines.append(
                f"| chain{r['n']} | {r['coordinates']} | {_f(c['rhs_us'])} | "
                f"{_f(c['raw_us_step'])} | {c['raw_us_step'] / c['rhs_us']:.2f} | "
                f"{_f(c['floor_us_step'])} | {_f(c['rk4_us_step'])} | "
                f"{c['rk4_us_step'] / c['rhs_us']:.2f} | "
                f"{c['rk4_us_step'] / 4 / c['rhs_us']:.2f} |")
    if BEFORE.exists():
        before = {(r["n"], r["coordinates"]): r
                  for r in json.loads(BEFORE.read_text())["rows"]}
        lines += ["", "Fixed-step RK4 before and after (µs/step; *before*: the same script on "
                  "commit d9ae833, where every compiled fold was called with CasADi's argument "
                  f"conversion, measured {json.loads(BEFORE.read_text())['date']}):", "",
                  "| chain | coordinates | 1 output, before | 1 output, now | "
                  f"{OUTPUTS} outputs, before | {OUTPUTS} outputs, now |",
                  "|---|---|---:|---:|---:|---:|"]
        for r in data["rows"]:
            b = before.get((r["n"], r["coordinates"]))
            if b:
                lines.append(f"| chain{r['n']} | {r['coordinates']} | "
                             f"{_f(b['rk4_one']['us_step'])} | {_f(r['rk4_one']['us_step'])} | "
                             f"{_f(b['rk4_grid']['us_step'])} | "
                             f"{_f(r['rk4_grid']['us_step'])} |")
    if "per_eval" in data:
        lines += ["", *per_eval_markdown(data["per_eval"])]
    lines += ["", *WHERE]
    return "\n".join(lines) + "\n\n"


#: the columns of the per-evaluation table: (path key, heading)
EVAL_COLUMNS = (("dopri5", "DOPRI5"), ("dopri5 previous", "DOPRI5 before"), ("rk4", "RK4"),
                ("adams", "Adams"), ("cvodes", "CVODES (BDF)"),
                ("cvodes previous", "CVODES before"), ("idas", "IDAS"),
                ("idas previous", "IDAS before"),
                ("dopri5 Simulator.run", "DOPRI5 `run`"), ("rk4 Simulator.run", "RK4 `run`"))


def _cell(path: dict, rhs: float) -> str:
    if "us_eval" not in path:
        return "failed"
    ratio = path["us_eval"] / rhs
    mark = "" if ratio <= EVAL_TARGET else " ✗"
    return f"{ratio:.2f}{mark} ({_f(path['us_eval'])})"


def per_eval_markdown(rows: list[dict]) -> list[str]:
    """The per-evaluation table (issue 36 item 4) and what stays above the target."""
    lines = [
        f"### Per right-hand-side evaluation (target ≤ {EVAL_TARGET:g}× the bare function)",
        "",
        "Each cell: µs per right-hand-side evaluation ÷ *RHS* (µs per evaluation in "
        "parentheses; ✗ above the target), processor time of the measuring thread, fastest "
        "of the repeats, rtol = atol = "
        f"{TOL:g}, one output interval, the path `Simulator` chooses (chain8, chain32: joint "
        "coordinates, articulated ODE; four-bar: augmented Lagrangian ODE). *RHS*: the bare "
        "compiled right-hand side through `Function.buffer()` from Python (the faster of a "
        "measurement before and after the paths). *DOPRI5*: the compiled stepping (start + "
        "advance: blocks of 64/16/4 attempts chosen by the attempts left, Hairer's start "
        "compiled with the model); *DOPRI5 before*: the same code in the previous "
        "configuration (one block size of 16 attempts, the start's two right-hand sides "
        "from Python), same process; *RK4*: the compiled folds, step "
        f"{RK4_STEP:g} s; *Adams*, *CVODES*, *IDAS*: the CasADi SUNDIALS integrator called "
        "directly, per right-hand side it evaluated (`n_call_daeF`; the Jacobians' own "
        "calls not counted, their time is: *Jacobian share*), CVODES and IDAS on the "
        "dynamics `Simulator` gives a Newton method (`Simulator.sundials_dynamics`: the "
        "exact compiled Jacobian `jac_<name>` up to 32 states, forward differences of the "
        "compiled right-hand side above); *before*: the same integrator on the model's "
        "dynamics as loaded before (the Newton matrix by CasADi's central differences), "
        "same process; *`run`*: "
        "`Simulator.run`'s `solve_cpu_seconds` (processor time of the solve) per evaluation, "
        "casmbd's own code in the run included (start, output, statistics). *load*: the "
        "1-minute load average at the start and end of the row.", "",
        "| problem | formulation | nx | RHS [µs] | load | "
        + " | ".join(h for _, h in EVAL_COLUMNS)
        + " | CVODES / IDAS Jacobian share, now (before) |",
        "|---|---|---:|---:|---|" + "---:|" * len(EVAL_COLUMNS) + "---:|"]
    for r in rows:
        paths, rhs = r["paths"], r["rhs_us"]
        share = " / ".join(
            f"{100 * paths.get(k, {}).get('jacobian_share', 0.0):.0f} % "
            f"({100 * paths.get(k + ' previous', {}).get('jacobian_share', 0.0):.0f} %)"
            for k in ("cvodes", "idas"))
        lines.append(f"| {r['problem']} | {r['formulation']} | {r['nx']} | {_f(rhs)} | "
                     f"{r['load']:.1f}–{r['load_end']:.1f} | "
                     + " | ".join(_cell(paths.get(k, {}), rhs) for k, _ in EVAL_COLUMNS)
                     + f" | {share} |")
    calls = "; ".join(f"{r['problem']} {r['paths']['dopri5 previous']['calls']} → "
                      f"{r['paths']['dopri5']['calls']}" for r in rows
                      if "calls" in r["paths"].get("dopri5", {}))
    runs = "; ".join(
        f"{r['problem']} " + ", ".join(
            f"{k.upper()} {r['paths'][k + ' previous']['ms_run']:.2f} → "
            f"{r['paths'][k]['ms_run']:.2f} ms ({r['paths'][k]['jacobian']}, "
            f"{r['paths'][k + ' previous']['evals']} → {r['paths'][k]['evals']} evaluations)"
            for k in ("cvodes", "idas")
            if "ms_run" in r["paths"].get(k, {}) and "ms_run" in
            r["paths"].get(k + " previous", {}))
        for r in rows)
    lines += ["", "Compiled calls from Python per DOPRI5 run, before → now: " + calls + ".",
              "", "Whole SUNDIALS Newton runs (processor ms, fastest of the repeats), before "
              "→ now, the Jacobian now, and the right-hand sides evaluated: " + runs + ".",
              "", eval_notes(rows), "", OPTIONS_NOTE]
    return lines


def eval_notes(rows: list[dict]) -> str:
    """Why some paths stay above the per-evaluation target, with the ranges of ``rows``."""
    sun = [r["paths"][k]["us_eval"] / r["rhs_us"] for r in rows
           for k in ("adams", "cvodes", "idas") if "us_eval" in r["paths"].get(k, {})]
    jac = [100 * r["paths"][k]["jacobian_share"] for r in rows for k in ("cvodes", "idas")
           if "jacobian_share" in r["paths"].get(k, {})]
    fixed = [(r["paths"]["dopri5 Simulator.run"]["us_eval"] - r["paths"]["dopri5"]["us_eval"])
             * r["paths"]["dopri5"]["evals"] for r in rows
             if "us_eval" in r["paths"].get("dopri5 Simulator.run", {})]
    return EVAL_NOTES.format(sun_lo=min(sun, default=0), sun_hi=max(sun, default=0),
                             jac_lo=min(jac, default=0), jac_hi=max(jac, default=0),
                             fixed_lo=min(fixed, default=0), fixed_hi=max(fixed, default=0))


#: why some paths stay above the per-evaluation target (issue 36 item 4); the ranges are
#: filled from the results, the expansion figures were measured once (2026-11-29, load 5.5)
EVAL_NOTES = (
    "Where the ratio stays above the target, and why: DOPRI5 and RK4 run every step, the "
    "error norm, the PI step-size control and the clipping to the output time in compiled "
    "code (no Python per step; Python only once per block of up to 64 attempts and per "
    "output); what remains above 1× is the Runge–Kutta arithmetic itself (seven stage "
    "combinations and the error norm over nx states per six evaluations, and the copies of "
    "each stage's arguments in CasADi's generated code for an MX call), which weighs most "
    "on the smallest right-hand sides (the four-bar: nx = 6, 0.4 µs). `Simulator.run` adds "
    "a fixed cost per run, not per step ({fixed_lo:.0f}–{fixed_hi:.0f} µs here: the start, "
    "the run's own Python, the output and the statistics), which the runs of 0.5–5 ms above "
    "feel and longer runs do not. Inlining the six "
    "right-hand sides into one SX step (`Function.expand()`) was measured and rejected: "
    "chain8 1.16× instead of 1.12×, and the four-bar's augmented-Lagrangian solve expanded "
    "16× slower with a 62 s compile (measured once, 2026-11-29). The SUNDIALS paths are "
    "{sun_lo:.1f}–{sun_hi:.1f}× and cannot reach 1.2× "
    "through `casadi.integrator`: the right-hand side is the compiled function, called "
    "from CasADi's C++ with no Python in the loop, but every call goes through CasADi's "
    "`OracleFunction::calc_function` (two `clock_gettime` of the process-time clock for "
    "its statistics, not switchable; the *floor* column above) and SUNDIALS' own work per "
    "step (vector operations, the Nordsieck history, the error test: Adams takes 1.7 right-"
    "hand sides a step; the four-bar's and chain8's right-hand sides cost 0.3–0.4 µs, so "
    "this fixed cost per call is 5–6× the function). The BDF paths (CVODES, IDAS) also "
    "solve a Newton system each step: its Jacobian is now the exact compiled `jac_<name>` "
    "(CasADi's AD of the formulation's Function, compiled in a library of its own on first "
    "use by a Newton method: chain8 2.6 s, chain32 8.6 s, the 100-rod chain 7.8 s cold at "
    "load 2.5) up to 32 states, and above that forward differences of the compiled "
    "right-hand side (nx + 1 calls; the exact chain32 Jacobian, 250 000 operations "
    "expanded, cost more than that: 76 µs per evaluation against 26), {jac_lo:.0f}–"
    "{jac_hi:.0f} % of their time. What remains is SUNDIALS' Newton iteration, the sparse "
    "LU of I − γJ (CSparse) at every Jacobian, and the same per-call floor. The "
    "Jacobians were never exact before: no ODE formulation compiled one, and the DAE "
    "formulations' `jac_<name>`, compiled with the model, is loaded with `enable_fd`, with "
    "which CasADi prefers central differences (`fwd16_<name>` by `CentralDiff`, 2 calls per "
    "direction) to the compiled Jacobian; it stays so (loaded exact, index1 on IDAS gives "
    "up at another place near a singular pose of the 3-rod chain, t = 2.62 instead of the "
    "pass at 1.2333 that tests/analysis/formulations/test_singular_chains.py expects). "
    "On the four-bar (the "
    "augmented Lagrangian's penalty makes it stiff) CVODES takes more steps with the exact "
    "Jacobian than with central differences (see the whole runs above): the Newton "
    "iteration's convergence there steers the step size, and the per-evaluation ratio "
    "falls while the run does not get faster."
)

#: the integrator options measured for their overhead (issue 36 item 4), once: the CasADi
#: integrator called directly as in the table, rtol = atol = 1e-7, 2026-11-29, load 3.0
OPTIONS_NOTE = (
    "Integrator options measured for their overhead (once, 2026-11-29, load 3.0, the "
    "same calls as the table; µs per right-hand side, chain8 / four-bar / chain32): "
    "`print_stats` is already off; `record_time` off and `regularity_check` off change "
    "nothing (±1 %: CasADi 3.8 keeps the per-call process-time statistics, "
    "`t_proc_daeF`, with `record_time` off); linear solver: CSparse (the default) against "
    "dense `lapacklu` CVODES 3.18 / 3.37 / 62.6 against 3.22 / 3.33 / 59.0, IDAS 2.97 / "
    "3.60 / 26.0 against 3.27 / 3.47 / 23.7 (chain32 then still with central differences; "
    "lapacklu also changes the four-bar's step sequence), `qr` no better; "
    "`newton_scheme` GMRES (matrix-free) 2.4–2.6× slower per "
    "evaluation; `max_multistep_order` 3 for IDAS lowers the cost per evaluation (2.7 / "
    "3.1 / 16.0) by taking 1.9–2.5× as many evaluations, slower runs; Adams' order 5 or 8 "
    "instead of 12 changes nothing on these runs. None is adopted."
)


def main(argv=None) -> int:
    parser = study_parser(__doc__.splitlines()[0], RESULTS)
    args = parser.parse_args(argv)
    return run_study(args, RESULTS, lambda: measure(args.repeat), markdown, DOC, HEAD)


if __name__ == "__main__":
    raise SystemExit(main())

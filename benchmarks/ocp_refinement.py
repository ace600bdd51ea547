"""Grid refinement of the trajectory-optimisation problems (issue 8): the objective against the
number of control intervals N, for collocation and multiple shooting on the same problem.

With piecewise-constant controls on N intervals the optimum of the continuous problem is
approached from above as the control space grows; the successive differences
d_N = J_N − J_2N shrink by the ratio r = d_N / d_2N (r ≈ 2^p for a method of order p in the
control discretisation; p = 2 for the effort of a smooth optimal control sampled at interval
means).  The Richardson estimate J_∞ ≈ J_2N − d_N / (r − 1) at the finest pair is the limit
each row is compared with.  The replay error (controls forward-simulated on IDAS) shows the
transcription's state error at each N.

Problems: the double-pendulum swing-up (``ocp/double_pendulum_swingup.toml``: Radau
collocation as in the file, Gauss–Legendre degree 4, RK4 multiple shooting with 8 steps per
interval) and the cart-pole (``ocp/cart_pole.toml``: Radau as in the file, RK4 shooting with 4
steps).  The NLPs run in CasADi's virtual machine (no compilation: this study is about values,
not speed).

Run ``python -m benchmarks.ocp_refinement --update-docs`` (about five minutes): writes
``benchmarks/results/ocp_refinement.json`` and the section ``## Grid refinement`` of
``docs/ocp.md``.
"""

from __future__ import annotations

import datetime
import math
import pathlib
import platform
import time

from benchmarks.docs import run_study, study_parser

ROOT = pathlib.Path(__file__).resolve().parent.parent
RESULTS = ROOT / "benchmarks" / "results" / "ocp_refinement.json"
OCP_DOC = ROOT / "docs" / "ocp.md"
HEAD = "## Grid refinement"
SIZES = (10, 20, 40, 80)
#: problem -> {label: Ocp attribute overrides}
CASES: dict[str, dict[str, dict]] = {
    "double_pendulum_swingup": {
        "Radau (as in the file)": {},
        "Gauss–Legendre, degree 4, 1 element": {"transcription": "legendre", "degree": 4,
                                                "subintervals": 1},
        "RK4 multiple shooting, 8 steps": {"transcription": "multiple_shooting",
                                           "integrator": "rk4", "steps": 8},
    },
    "cart_pole": {
        "Radau (as in the file)": {},
        "RK4 multiple shooting, 4 steps": {"transcription": "multiple_shooting",
                                           "integrator": "rk4", "steps": 4},
    },
}


def solve(problem: str, overrides: dict, n: int) -> dict:
    """One solve of ``ocp/<problem>.toml`` with N = ``n`` and the overrides, replayed."""
    from casmbd.io.ocp_table import load_ocp

    ocp = load_ocp(ROOT / "ocp" / f"{problem}.toml")
    ocp.compile, ocp.intervals = False, n
    for key, value in overrides.items():
        setattr(ocp, key, value)
    t0 = time.perf_counter()
    sol = ocp.solve()
    wall = time.perf_counter() - t0
    sol.replay()
    shooting = ocp.transcription == "multiple_shooting"
    detail = (f" {ocp.integrator} × {ocp.steps}" if shooting
              else f" d={ocp.degree}, {ocp.subintervals} el.")
    return {"N": n, "objective": sol.objective, "iterations": sol.iterations,
            "success": bool(sol.success), "replay_error": sol.stats["replay_error"],
            "transcription": ocp.transcription + detail, "wall_s": wall}


def run(sizes=SIZES) -> dict:
    rows = []
    for problem, cases in CASES.items():
        for label, overrides in cases.items():
            for n in sizes:
                r = solve(problem, overrides, n)
                r.update(problem=problem, case=label)
                print(f"{problem:26s} {label:38s} N={n:3d} J={r['objective']:.10g} "
                      f"it={r['iterations']} replay={r['replay_error']:.2e}", flush=True)
                rows.append(r)
    import casadi

    info = {"date": datetime.datetime.now(datetime.UTC).strftime("%Y-%m-%d %H:%M UTC"),
            "python": platform.python_version(), "casadi": casadi.__version__,
            "command": "python -m benchmarks.ocp_refinement --update-docs"}
    return {"info": info, "rows": rows}


def analyse(rows: list[dict]) -> dict[tuple[str, str], dict]:
    """Per (problem, case): differences, ratios and the Richardson limit."""
    out = {}
    for key in dict.fromkeys((r["problem"], r["case"]) for r in rows):
        series = sorted((r for r in rows if (r["problem"], r["case"]) == key),
                        key=lambda r: r["N"])
        J = [r["objective"] for r in series]
        d = [J[i] - J[i + 1] for i in range(len(J) - 1)]
        ratios = [d[i] / d[i + 1] if d[i + 1] != 0 else math.nan for i in range(len(d) - 1)]
        r_last = ratios[-1] if ratios else math.nan
        # refinement enlarges the control space, so a converging series decreases; a rise
        # means IPOPT ended in another local optimum on that grid
        monotone = all(x > 0 for x in d)
        limit = (J[-1] - d[-1] / (r_last - 1.0)) if monotone and ratios and r_last > 1.0 \
            else math.nan
        out[key] = {"series": series, "differences": d, "ratios": ratios, "limit": limit,
                    "monotone": monotone}
    return out


def markdown(data: dict) -> str:
    rows, info = data["rows"], data["info"]
    res = analyse(rows)
    lines = [HEAD, "",
             f"Generated by `benchmarks/ocp_refinement.py` (`{info['command']}`, "
             f"{info['date']}, CasADi {info['casadi']}); the NLPs in the virtual machine. "
             "J_N: optimal objective on N control intervals; d_N = J_N − J_2N; ratio "
             "d_N / d_2N (4 for a second-order convergence); J_∞: Richardson estimate from the "
             "finest three grids; replay: largest state error of the controls "
             "forward-simulated on IDAS (rtol 1e-12, the default of `OcpSolution.replay`).", ""]
    for problem in CASES:
        keys = [k for k in res if k[0] == problem]
        lines += [f"`ocp/{problem}.toml`:", "",
                  "| transcription | N | J_N | d_N | ratio | J_N − J_∞ (rel.) | iterations | "
                  "replay |", "| --- | ---: | ---: | ---: | ---: | ---: | ---: | ---: |"]
        for key in keys:
            a = res[key]
            for i, r in enumerate(a["series"]):
                d = a["differences"][i] if i < len(a["differences"]) else None
                q = a["ratios"][i] if i < len(a["ratios"]) else None
                rel = ((r["objective"] - a["limit"]) / abs(a["limit"])
                       if math.isfinite(a["limit"]) else math.nan)
                lines.append(
                    f"| {key[1] if i == 0 else ''} ({r['transcription']}) | {r['N']} | "
                    f"{r['objective']:.8f} | {'' if d is None else f'{d:.3e}'} | "
                    f"{'' if q is None or not a['monotone'] else f'{q:.2f}'} | "
                    f"{'–' if math.isnan(rel) else f'{rel:.1e}'} | "
                    f"{r['iterations']} | {r['replay_error']:.1e} |")
        good = [k for k in keys if res[k]["monotone"]]
        bad = [k for k in keys if not res[k]["monotone"]]
        text = []
        if good:
            limits = [(k[1], res[k]["limit"]) for k in good]
            finest = [(k[1], res[k]["series"][-1]["objective"]) for k in good]
            ref = finest[0][1]
            spread = max(abs(v - ref) for _, v in finest) / abs(ref)
            lim_spread = max(abs(v - limits[0][1]) for _, v in limits) / abs(limits[0][1])
            text.append(f"At N = {res[good[0]]['series'][-1]['N']} the converging "
                        f"transcriptions agree to {spread:.1e} relative; their Richardson "
                        f"limits to {lim_spread:.1e} (J_∞ = "
                        + ", ".join(f"{v:.8f} ({n})" for n, v in limits) + ").")
        for k in bad:
            ups = [r["N"] for r, dn in zip(res[k]["series"][1:], res[k]["differences"],
                                           strict=False) if dn <= 0]
            text.append(f"{k[1]}: not monotone — on N = {', '.join(map(str, ups))} IPOPT "
                        "ended in another local optimum from the same linear guess (the "
                        "swing-up is non-convex); the other grids agree with collocation.")
        lines += ["", " ".join(text), ""]
    return "\n".join(lines) + "\n"


def main(argv=None) -> int:
    parser = study_parser(__doc__.splitlines()[0], RESULTS, repeat=False)
    parser.add_argument("--sizes", nargs="+", type=int, default=list(SIZES))
    args = parser.parse_args(argv)
    return run_study(args, RESULTS, lambda: run(tuple(args.sizes)), markdown, OCP_DOC, HEAD)

if __name__ == "__main__":
    raise SystemExit(main())

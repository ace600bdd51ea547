"""Regenerate the default figures of ``casmbd plot`` shown in docs/cli.md (run from the
repository root).

    python docs/figures/plots/make_plots.py

Runs the commands of docs/cli.md (``simulate … --out``, ``plot RESULT --out``, ``ocp --plot``)
and writes the figures next to this file at low resolution; prints each command's notes.
"""

from __future__ import annotations

import contextlib
import io
import pathlib
import tempfile

from casmbd import cli

HERE = pathlib.Path(__file__).resolve().parent
ROOT = HERE.parents[2]

#: figure name -> (scene, simulate options, extra plot options)
RUNS = {"slider_crank": ("examples/slider_crank.toml", ["--t-end", "1", "--steps", "100"], []),
        "spinup_beam": ("examples/spinup_beam.toml", ["--t-end", "20", "--steps", "400"], []),
        "bouncing_ball": ("examples/bouncing_ball.toml",
                          ["--t-end", "3", "--steps", "300", "--rtol", "1e-10"], []),
        "pd_pendulum": ("examples/pd_pendulum.toml", ["--t-end", "3", "--steps", "300"], []),
        "pd_pendulum_outputs": ("examples/pd_pendulum.toml", ["--t-end", "3", "--steps", "300"],
                                ["--what", "outputs"])}


def run(argv: list[str]) -> str:
    out = io.StringIO()
    with contextlib.redirect_stdout(out):
        assert cli.main(argv) == 0, argv
    return out.getvalue()


def main() -> None:
    with tempfile.TemporaryDirectory() as tmp:
        for name, (scene, options, extra) in RUNS.items():
            npz = str(pathlib.Path(tmp) / f"{name}.npz")
            run(["simulate", str(ROOT / scene), *options, "--out", npz])
            text = run(["plot", npz, *extra, "--out", str(HERE / f"{name}.png"),
                        "--dpi", "60"])
            print(f"$ casmbd plot {name}.npz {' '.join(extra)}\n{text}")
        text = run(["ocp", str(ROOT / "ocp/double_pendulum_swingup.toml"), "--plot",
                    str(HERE / "ocp_swingup.png")])
        print(text)


if __name__ == "__main__":
    main()

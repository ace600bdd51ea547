"""``--json`` prints exactly one JSON object on stdout, whatever C libraries print (issue 30,
item 4i: LAPACK's "On entry to DTRSV parameter number 6 had an illegal value" and IPOPT's
banner are written to file descriptor 1 by C code, before the JSON, so stdout did not parse).
The CLI points fd 1 at stderr while the verb runs and writes the JSON to the real stdout after.
Each test runs the command in a fresh process with stdout a pipe (C stdio fully buffered)."""

from __future__ import annotations

import json
import pathlib
import subprocess
import sys

ROOT = pathlib.Path(__file__).resolve().parents[2]
PENDULUM = str(ROOT / "examples" / "double_pendulum.toml")
SWINGUP = ROOT / "ocp" / "double_pendulum_swingup.toml"

#: runs ``simulate --json`` with the analysis patched to write, during the run, through C's
#: printf (buffered by libc), straight to fd 1, and through Python's print
NOISY_RUN = """
import ctypes, os, sys
from casmbd import cli
from casmbd.cli import analyses
libc = ctypes.CDLL(None)
real = analyses.simulate
def noisy(*args, **kwargs):
    libc.printf(b"On entry to DTRSV parameter number 6 had an illegal value\\n")
    os.write(1, b"raw write to fd 1\\n")
    print("python print")
    return real(*args, **kwargs)
analyses.simulate = noisy
sys.exit(cli.main(sys.argv[1:]))
"""


def _one_json_object(stdout: str) -> dict:
    """The whole of stdout is one JSON object (json.loads fails on anything before or after
    it but whitespace)."""
    data = json.loads(stdout)
    assert isinstance(data, dict)
    assert stdout.count("\n") == 1 and stdout.endswith("}\n")
    return data


def test_c_and_python_output_during_the_run_goes_to_stderr():
    proc = subprocess.run([sys.executable, "-c", NOISY_RUN, "simulate", PENDULUM, "--t-end",
                           "0.2", "--steps", "4", "--mode", "vm", "--json"],
                          capture_output=True, text=True, cwd=ROOT, timeout=600)
    assert proc.returncode == 0, proc.stderr
    data = _one_json_object(proc.stdout)
    assert data["t"][-1] == 0.2
    for text in ("On entry to DTRSV parameter number 6 had an illegal value",
                 "raw write to fd 1", "python print"):
        assert text in proc.stderr, text


def test_without_json_the_text_summary_still_goes_to_stdout():
    proc = subprocess.run([sys.executable, "-c", NOISY_RUN, "simulate", PENDULUM, "--t-end",
                           "0.2", "--steps", "4", "--mode", "vm"],
                          capture_output=True, text=True, cwd=ROOT, timeout=600)
    assert proc.returncode == 0, proc.stderr
    assert "simulation of " in proc.stdout and "python print" in proc.stdout


def test_ipopt_banner_and_iterations_go_to_stderr(tmp_path):
    """An OCP with ``ipopt.print_level = 5``: IPOPT prints its banner and iteration table
    from C++ on fd 1; stdout is the JSON alone, stderr has IPOPT's text."""
    scene = tmp_path / "swingup.toml"
    scene.write_text(SWINGUP.read_text() + '\n[ocp.solver_options]\n"ipopt.print_level" = 5\n')
    proc = subprocess.run([sys.executable, "-m", "casmbd", "ocp", str(scene), "--json",
                           "--mode", "vm", "--intervals", "10", "--no-replay"],
                          capture_output=True, text=True, cwd=ROOT, timeout=900)
    assert proc.returncode == 0, proc.stderr
    data = _one_json_object(proc.stdout)
    assert data["success"] is True
    assert "This is Ipopt version" in proc.stderr and "iter    objective" in proc.stderr

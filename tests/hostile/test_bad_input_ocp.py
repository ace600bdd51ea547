"""Bad input, OCP and names of solvers: a missing [ocp] table, unknown NLP solver,
transcription, integrator, dynamics; unknown --integrator/--formulation of simulate.

Through ``casmbd.cli.main``: exit status ≠ 0, one ``error:`` line naming the bad name and the
choices, nothing written.  The checks run before any NLP is built, so the file is fast.
"""

from __future__ import annotations

import pathlib

import pytest
from conftest import private_cache

from casmbd.cli import main
from casmbd.errors import SceneError
from casmbd.io.ocp_table import ocp_from_scene
from casmbd.io.scene import load_scene

EXAMPLES = pathlib.Path(__file__).resolve().parents[2] / "examples"
BASE = (EXAMPLES / "double_pendulum.toml").read_text()
OCP = '\n[ocp]\nhorizon = 1.0\nintervals = 3\n{extra}\n[ocp.controls]\nshoulder_torque = [-1, 1]\n'


_vm = private_cache("cache_ocp", CASMBD_COMPILE="0")


def run(argv, capsys) -> tuple[int, list[str]]:
    code = main(argv)
    captured = capsys.readouterr()
    assert "Traceback" not in captured.err and "internal error" not in captured.err
    return code, captured.err.strip().splitlines()


@pytest.mark.parametrize("extra_args", [[], ["--intervals", "3"], ["--transcription", "radau"]])
def test_scene_without_ocp_table_fails(extra_args, tmp_path, capsys):
    """Used to solve an empty problem and exit 0 (any override made the table non-empty)."""
    scene = tmp_path / "plain.toml"
    scene.write_text(BASE)
    out = tmp_path / "sol.npz"
    code, err = run(["ocp", str(scene), "--mode", "vm", "--out", str(out), *extra_args],
                    capsys)
    assert code == 1 and len(err) == 1, err
    assert err[0].startswith("error: ") and "plain.toml" in err[0] and "no [ocp] table" in err[0]
    assert not out.exists()


@pytest.mark.parametrize("extra, fragments", [
    ('solver = "foo"', ("'foo'", "ipopt")),
    ('solver = "../../tmp/evil"', ("evil", "ipopt")),
    ("solver = 3", ("3", "ipopt")),
    ('transcription = "foo"', ("'foo'", "radau", "legendre", "multiple_shooting")),
    ('integrator = "foo"', ("'foo'", "rk4", "cvodes")),
    ('dynamics = "foo"', ("'foo'", "implicit", "explicit")),
    # used to be accepted silently: a path constraint without a bound, misspelt keys
    ('path = [{ expression = "shoulder" }]', ("[[ocp.path]] entry 1", "'shoulder'", "'min'")),
    ('path = [{ expression = "shoulder", maximum = 1.0 }]',
     ("[[ocp.path]] entry 1", "unknown key 'maximum'", "max")),
    ('tracking = [{ expression = "shoulder", referenc = 0.0 }]',
     ("[[ocp.tracking]] entry 1", "unknown key 'referenc'", "reference")),
])
def test_unknown_names_in_ocp_table(extra, fragments, tmp_path, capsys):
    scene = tmp_path / "bad_ocp.toml"
    scene.write_text(BASE + OCP.format(extra=extra))
    with pytest.raises(SceneError) as exc:
        ocp_from_scene(load_scene(scene), source=str(scene))
    for fragment in fragments:
        assert fragment in str(exc.value), str(exc.value)
    out = tmp_path / "sol.npz"
    code, err = run(["ocp", str(scene), "--mode", "vm", "--no-replay", "--out", str(out)],
                    capsys)
    assert code == 1 and len(err) == 1 and err[0].startswith("error: "), err
    assert "bad_ocp.toml" in err[0] and all(f in err[0] for f in fragments), err[0]
    assert not out.exists()


def test_free_horizon_bounds_out_of_order_name_the_horizon(tmp_path, capsys):
    scene = tmp_path / "free.toml"
    scene.write_text(BASE + OCP.format(extra="").replace(
        "horizon = 1.0", "horizon = { free = true, guess = 2.0, min = 3.0, max = 1.0 }"))
    with pytest.raises(SceneError, match=r"\[ocp\]: ocp: horizon: free time needs 0 < lower "
                                         r"<= guess <= upper < inf, got .*lower=3\.0"):
        ocp_from_scene(load_scene(scene), source=str(scene))


def test_unknown_transcription_on_the_command_line(tmp_path, capsys):
    scene = tmp_path / "ocp.toml"
    scene.write_text(BASE + OCP.format(extra=""))
    code, err = run(["ocp", str(scene), "--transcription", "foo"], capsys)
    assert code == 2 and len(err) == 1 and "'foo'" in err[0] and "radau" in err[0], err


@pytest.mark.parametrize("option, choice", [("--integrator", "idas"),
                                            ("--formulation", "augmented_lagrangian")])
def test_unknown_integrator_or_formulation_of_simulate(option, choice, tmp_path, capsys):
    out = tmp_path / "run.npz"
    code, err = run(["simulate", str(EXAMPLES / "double_pendulum.toml"), "--t-end", "0.1",
                     "--steps", "2", option, "foo", "--out", str(out)], capsys)
    assert code == 2 and len(err) == 1 and err[0].startswith("error: "), err
    assert option in err[0] and "'foo'" in err[0] and choice in err[0], err[0]
    assert not out.exists()

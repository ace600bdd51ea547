"""A scene that cannot be assembled names the element at fault first, with what to change.

Three broken scenes (issue 19): an unreachable distance, a misplaced joint point (a four-bar
whose coupler pin is far off) and a contradictory driver.  Each is checked through the Python
API (``AssemblyError.culprits[0]`` and the message) and through the CLI (``casmbd info`` and
``casmbd kinematics`` exit 1 and their stderr line names the culprit before any other
element).  The allowed ranges in the hints are compared with the closed-form values to 1e-3
(the hints print 4 significant digits).

A revolute joint is defined by one global point at the drawn pose, from which both bodies'
local points are taken, so it is satisfied at the drawn pose whatever the point: a misplaced
revolute pin cannot stop assembly at t = 0.  It changes the link lengths, which shows either
as an explicit length that can no longer be reached (the massless coupler below) or as a limit
position later in the motion (the last test: the driver is named, with the range of crank
angles the mis-drawn loop allows).
"""

from __future__ import annotations

import math
import re

import pytest
from conftest import private_cache

from casmbd import cli
from casmbd.analysis.driven.kinematics import info, kinematics
from casmbd.errors import AssemblyError
from casmbd.io.scene import loads_scene

_no_compiler = private_cache(CASMBD_COMPILE="0")


def entry(table: str, **fields) -> str:
    """An array-of-tables entry; values are TOML text."""
    return f"\n[[{table}]]\n" + "".join(f"{k} = {v}\n" for k, v in fields.items())


HEAD = '[scene]\nname = "broken"\ngravity = [0.0, -9.81]\n'
ROD = entry("bodies", name='"rod"', mass="1.0", inertia="0.1", position="[0.5, 0.0]")
PIVOT = entry("joints", name='"pivot"', type='"revolute"', body1='"ground"', body2='"rod"',
              point="[0.0, 0.0]")

# A 1 m rod pinned at the origin whose tip (1, 0) is tied by a 1 m massless link to (3, 0):
# the tip is between 2 and 4 m from (3, 0) in every pose.
UNREACHABLE_DISTANCE = HEAD + ROD + PIVOT + entry(
    "joints", name='"tether"', type='"distance"', body1='"ground"', body2='"rod"',
    point1="[3.0, 0.0]", point2="[1.0, 0.0]", length="1.0")

# The 1 m rod pinned at the origin, its centre of mass driven to x = 3 m: it reaches ±0.5 m.
CONTRADICTORY_DRIVER = HEAD + ROD + PIVOT + entry(
    "drivers", name='"reach"', body='"rod"', coordinate='"x"', position="3.0")

# The crank-rocker four-bar of examples/four_bar.toml with a massless coupler (a distance
# joint of the design length 0.7 m) whose pin on the rocker was typed (0.6437, 4.75) instead
# of (0.6437, 0.475): the rocker's pin is then 4.7526 m from its pivot D.
PIN = (0.6437, 4.75)
MISPLACED_PIN = HEAD + (
    entry("bodies", name='"crank"', mass="0.4", inertia="0.0013", position="[0.0, 0.1]",
          angle="1.5707963267948966")
    + entry("bodies", name='"rocker"', mass="1.0", inertia="0.02", position="[0.72, 0.24]",
            angle="1.8886")
    + entry("joints", name='"A"', type='"revolute"', body1='"ground"', body2='"crank"',
            point="[0.0, 0.0]")
    + entry("joints", name='"D"', type='"revolute"', body1='"ground"', body2='"rocker"',
            point="[0.8, 0.0]")
    + entry("joints", name='"coupler"', type='"distance"', body1='"crank"', body2='"rocker"',
            point1="[0.0, 0.2]", point2=f"[{PIN[0]}, {PIN[1]}]", length="0.7")
    + entry("drivers", name='"crank_drive"', joint='"A"', position='"pi / 2 + 2 * pi * t"'))

ELEMENTS = ("tether", "pivot", "reach", "coupler", "crank_drive", "A", "B", "C", "D")


def first_named(message: str) -> str:
    """The element (of :data:`ELEMENTS`) whose quoted name comes first in ``message``."""
    found = [(message.find(f"'{name}'"), name) for name in ELEMENTS
             if f"'{name}'" in message]
    assert found, message
    return min(found)[1]


def numbers_after(text: str, words: str) -> list[float]:
    """The two numbers following ``words`` in ``text`` ("between 2 and 4 apart")."""
    match = re.search(re.escape(words) + r" (-?[\d.e+-]+) (?:and|to) (-?[\d.e+-]+)", text)
    assert match, text
    return [float(match.group(1)), float(match.group(2))]


def failure(text: str, coordinates: str = "auto") -> AssemblyError:
    mech = loads_scene(text)
    mech.coordinates = coordinates
    with pytest.raises(AssemblyError) as exc:
        kinematics(mech, t_end=1.0, steps=4)
    return exc.value


def run_cli(capsys, *argv: str) -> tuple[int, str, str]:
    status = cli.main(list(argv))
    out = capsys.readouterr()
    return status, out.out, out.err


# ---------------------------------------------------------------------- Python API
@pytest.mark.parametrize("coordinates", ["absolute", "auto"])
def test_unreachable_distance_names_the_distance_first(coordinates):
    """In absolute coordinates the pivot's equations are ranked second; in the automatic
    choice (joint coordinates) the pivot is a tree joint without equations: the tether alone."""
    exc = failure(UNREACHABLE_DISTANCE, coordinates)
    top = exc.culprits[0]
    assert (top.kind, top.element, top.fixes) == ("joint", "tether", True)
    assert first_named(str(exc)) == "tether"
    assert "change the distance" in top.hint
    low, high = numbers_after(top.hint, "are between")
    assert abs(low - 2.0) < 1e-3 and abs(high - 4.0) < 1e-3, top.hint
    # the pivot also lets the rest assemble, but is a 2-equation change: ranked second
    assert [c.element for c in exc.culprits] == (["tether", "pivot"] if coordinates == "absolute"
                                                 else ["tether"])


def test_misplaced_coupler_pin_names_the_coupler_first():
    exc = failure(MISPLACED_PIN)
    top = exc.culprits[0]
    assert (top.kind, top.element) == ("joint", "coupler")
    assert first_named(str(exc)) == "coupler"
    assert f"({PIN[0]:.4g}, {PIN[1]:.4g})" in top.hint and "move a point" in top.hint
    # the driven crank holds B at (0, 0.2) at t = 0; the rocker's pin turns about D
    arm, bd = math.hypot(PIN[0] - 0.8, PIN[1]), math.hypot(0.8, 0.2)
    low, high = numbers_after(top.hint, "are between")
    assert abs(low - (arm - bd)) < 1e-3 and abs(high - (arm + bd)) < 1e-3, top.hint
    # the driver alone cannot be blamed: without it the coupler still cannot close
    drive = next(c for c in exc.culprits if c.element == "crank_drive")
    assert not drive.fixes and drive.remaining > 1.0


@pytest.mark.parametrize("coordinates", ["absolute", "auto"])
def test_contradictory_driver_names_the_driver_first(coordinates):
    """The hint names what the driver contradicts: the pivot in absolute coordinates, "the
    joints" in the automatic choice (joint coordinates: the pivot is the tree)."""
    exc = failure(CONTRADICTORY_DRIVER, coordinates)
    top = exc.culprits[0]
    assert (top.kind, top.element) == ("driver", "reach")
    assert first_named(str(exc)) == "reach"
    assert "asks for body 'rod' x = 3 at t = 0" in top.hint
    assert ("contradicting joint 'pivot'" if coordinates == "absolute"
            else "contradicting the joints") in top.hint, top.hint
    low, high = numbers_after(top.hint, "allow only body 'rod' x from")
    assert abs(low + 0.5) < 1e-3 and abs(high - 0.5) < 1e-3, top.hint


def test_info_reports_culprits_and_skips_redundancy():
    """At a pose that violates the constraints the redundancy analysis is not trusted: the
    contradicting driver is not called 'redundant'."""
    data = info(loads_scene(CONTRADICTORY_DRIVER))
    assert data["assembled"] is False and data["rank_reliable"] is False
    assert data["redundant_equations"] == []
    assert data["assembly_culprits"][0]["element"] == "reach"
    assert first_named(data["assembly_error"]) == "reach"


@pytest.mark.parametrize("coordinates", ["absolute", "auto"])
def test_misdrawn_four_bar_reaches_a_limit_position_naming_the_driver(coordinates):
    """A revolute coupler pin B typed at (0, 0.6) instead of (0, 0.2): the crank (0.6 m)
    can no longer turn (non-Grashof); kinematics stops at the limit position with the crank
    driver first and the crank angles the loop allows, ±acos(−0.34975…) = ±1.9281 rad.
    In joint coordinates the range search used to jump whole turns (-165.3 to 20.78 rad)."""
    from pathlib import Path

    scene = (Path(__file__).resolve().parents[3] / "examples" / "four_bar.toml").read_text()
    exc = failure(scene.replace("point = [0.0, 0.2]", "point = [0.0, 0.6]"), coordinates)
    assert exc.culprits[0].element == "crank_drive"
    assert first_named(str(exc)) == "crank_drive" and "at t = " in str(exc)
    crank, coupler = 0.6, math.hypot(0.6437, 0.475 - 0.6)
    rocker, ground = math.hypot(0.8 - 0.6437, 0.475), 0.8
    limit = math.acos((crank**2 + ground**2 - (coupler + rocker) ** 2) / (2 * crank * ground))
    low, high = numbers_after(exc.culprits[0].hint, "allow only joint 'A' from")
    assert abs(low + limit) < 1e-3 and abs(high - limit) < 1e-3, exc.culprits[0].hint


# ---------------------------------------------------------------------- CLI
@pytest.mark.parametrize("text, culprit", [(UNREACHABLE_DISTANCE, "tether"),
                                           (MISPLACED_PIN, "coupler"),
                                           (CONTRADICTORY_DRIVER, "reach")])
def test_cli_info_and_kinematics_fail_naming_the_culprit(tmp_path, capsys, text, culprit):
    scene = tmp_path / "broken.toml"
    scene.write_text(text)
    status, out, err = run_cli(capsys, "info", str(scene))
    assert status == 1 and "cannot be assembled" in err and err.count("\n") == 1
    assert first_named(err) == culprit, err
    assert "redundant equations: not analysed" in out
    status, out, err = run_cli(capsys, "kinematics", str(scene), "--t-end", "1", "--steps", "2")
    assert status == 1 and first_named(err) == culprit, err


@pytest.mark.parametrize("coordinates, ranking", [("absolute", ["tether", "pivot"]),
                                                   ("auto", ["tether"])])
def test_cli_info_json_is_one_object_with_the_ranking(tmp_path, capsys, coordinates, ranking):
    """The pivot is ranked in absolute coordinates only (a tree joint has no equations)."""
    import json

    scene = tmp_path / "broken.toml"
    scene.write_text(UNREACHABLE_DISTANCE.replace(
        "[scene]\n", f'[scene]\ncoordinates = "{coordinates}"\n'))
    status, out, err = run_cli(capsys, "info", str(scene), "--json")
    data = json.loads(out)  # exactly one JSON object on stdout
    assert status == 1 and first_named(err) == "tether"
    assert data["assembled"] is False and data["rank_reliable"] is False
    assert [c["element"] for c in data["assembly_culprits"]] == ranking
    for key in ("rank", "degrees_of_freedom", "redundant_equations", "assembly_error",
                "coordinates", "constraints", "initial_coordinates"):
        assert key in data  # the keys other programs read are kept


def test_pin_named_when_no_single_driver_is_at_fault():
    """The 1 m rod's centre driven to x = 3 and y = 3: neither driver alone can be met
    (|x|, |y| <= 0.5), so the pin is the one element whose removal lets the rest assemble;
    its hint gives the least distance between the two points, |(3, 3)| − 0.5 m.  That needs
    the pin's equations: absolute coordinates.  In the automatic choice (joint coordinates)
    the pin is the tree and only the drivers are ranked, neither fixing it alone."""
    text = CONTRADICTORY_DRIVER + entry("drivers", name='"lift"', body='"rod"',
                                        coordinate='"y"', position="3.0")
    auto = failure(text)
    assert sorted(c.element for c in auto.culprits) == ["lift", "reach"]
    assert not any(c.fixes for c in auto.culprits)
    exc = failure(text, "absolute")
    top = exc.culprits[0]
    assert (top.kind, top.element, top.fixes) == ("joint", "pivot", True)
    assert [c.fixes for c in exc.culprits[1:]] == [False, False]
    match = re.search(r"would have to be ([\d.]+) apart", top.hint)
    assert match and abs(float(match.group(1)) - (math.hypot(3, 3) - 0.5)) < 1e-3, top.hint
    assert "point (0, 0)" in top.hint and "move the point" in top.hint

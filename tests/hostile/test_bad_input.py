"""Bad input: every mistake raises a specific casmbd error whose message names the culprit.

Scene files (``loads_scene``), the analyses (``kinematics``, ``info``) and the Python builder
API (``Mechanism``) are covered.  Each test checks the error class *and* that the message names
the table/entry/key or the body/joint at fault.
"""

from __future__ import annotations

import pathlib
import re

import pytest
from conftest import private_cache
from scene_builders import HEAD, PENDULUM, PIVOT, body, entry, joint

from casmbd.analysis.driven.kinematics import info, kinematics
from casmbd.errors import (
    AnalysisError,
    AssemblyError,
    CasmbdError,
    ExpressionError,
    ModelError,
    SceneError,
)
from casmbd.io.scene import load_scene, loads_scene
from casmbd.model import Mechanism

REPO_ROOT = pathlib.Path(__file__).resolve().parents[2]
EXAMPLES = REPO_ROOT / "examples"


_cache = private_cache("casmbd_cache_bad_input", scope="module", CASMBD_COMPILE="0")


def driver_scene(position_toml: str) -> str:
    """A pendulum whose pivot is driven by ``position`` (TOML text)."""
    return PENDULUM + entry("drivers", name='"spin"', joint='"pivot"', position=position_toml)


def raises_naming(exc_class, text: str, *fragments: str):
    """Load ``text``; assert the exact error class and that every fragment is in the message."""
    with pytest.raises(exc_class) as info_:
        loads_scene(text)
    assert isinstance(info_.value, CasmbdError)
    message = str(info_.value)
    for fragment in fragments:
        assert fragment in message, f"{fragment!r} not in {message!r}"
    return message


def test_good_pendulum_builds():
    """The base scene used below is valid, so each test only breaks one thing."""
    mech = loads_scene(PENDULUM)
    assert list(mech.bodies) == ["rod"] and list(mech.joints) == ["pivot"]


# ---------------------------------------------------------------------- file level
def test_malformed_toml_names_the_line():
    text = HEAD + '\n[[bodies]]\nname = "rod"\nmass = \n'  # line 7 has no value
    message = raises_naming(SceneError, text, "malformed TOML")
    assert re.search(r"line 7\b", message), message


def test_missing_scene_table():
    raises_naming(SceneError, body("rod") + PIVOT, "[scene]", "missing")


def test_unknown_table():
    raises_naming(SceneError, PENDULUM + "\n[bodys]\nx = 1\n", "unknown table", "[bodys]")


def test_scene_file_not_found(tmp_path):
    missing = tmp_path / "no_such_scene.toml"
    with pytest.raises(SceneError, match=re.escape(missing.name)):
        load_scene(missing)


def test_format_2_is_rejected():
    text = PENDULUM.replace("[scene]\n", "[scene]\nformat = 2\n")
    raises_naming(SceneError, text, "[scene]", "'format'", "2")


def test_dimension_3_is_rejected():
    text = PENDULUM.replace("[scene]\n", "[scene]\ndimension = 3\n")
    raises_naming(SceneError, text, "[scene]", "'dimension'", "3")


def test_format_true_is_rejected():
    text = PENDULUM.replace("[scene]\n", "[scene]\nformat = true\n")
    raises_naming(SceneError, text, "[scene]", "'format'")


# ---------------------------------------------------------------------- parameters
def test_parameter_value_a_string():
    text = HEAD + '\n[parameters]\nstiff = "abc"\n' + body("rod") + PIVOT
    raises_naming(SceneError, text, "[parameters]", "'stiff'", "abc")


def test_parameter_named_t_in_scene():
    text = HEAD + "\n[parameters]\nt = 1.0\n" + body("rod") + PIVOT
    raises_naming(SceneError, text, "[parameters]", "'t'")


def test_parameter_huge_integer():
    text = HEAD + "\n[parameters]\nbig = 1" + "0" * 400 + "\n" + body("rod") + PIVOT
    raises_naming(SceneError, text, "[parameters]", "'big'")


# ---------------------------------------------------------------------- bodies
def test_unknown_key_in_body_typo_mas():
    text = HEAD + body("rod", mass=None, mas="1.0") + PIVOT
    raises_naming(SceneError, text, "[[bodies]] entry 1", "'rod'", "'mas'", "unknown key")


def test_duplicate_body_name():
    text = HEAD + body("rod") + body("rod", x=1.5) + PIVOT
    raises_naming(SceneError, text, "[[bodies]] entry 2", "duplicate", "'rod'")


@pytest.mark.parametrize("mass", ["-1.0", '"-2 * 0.5"'])
def test_mass_negative(mass):
    """A zero mass is accepted by the model (forward dynamics checks M, see
    tests/model/test_mass_checks.py); a negative one is refused."""
    text = HEAD + body("rod", mass=mass) + PIVOT
    raises_naming(SceneError, text, "[[bodies]] entry 1", "'rod'", "'mass'", ">= 0")


def test_negative_inertia():
    text = HEAD + body("rod", inertia="-0.1") + PIVOT
    raises_naming(SceneError, text, "[[bodies]] entry 1", "'rod'", "'inertia'", ">= 0")


def test_mass_nan():
    text = HEAD + body("rod", mass="nan") + PIVOT
    raises_naming(SceneError, text, "'rod'", "'mass'", "finite")


def test_mass_huge_integer():
    text = HEAD + body("rod", mass="1" + "0" * 400) + PIVOT
    raises_naming(SceneError, text, "'rod'", "'mass'")


@pytest.mark.parametrize("position", ["[0.0, 0.0, 1.0]", "[0.5]"])
def test_position_of_wrong_length(position):
    text = HEAD + body("rod", position=position) + PIVOT
    raises_naming(SceneError, text, "[[bodies]] entry 1", "'rod'", "'position'", "2")


# ---------------------------------------------------------------------- joints
def test_joint_references_unknown_body():
    text = HEAD + body("rod") + joint("pivot", "revolute", body2="rdo", point="[0.0, 0.0]")
    raises_naming(SceneError, text, "[[joints]] entry 1", "'pivot'", "'rdo'", "unknown body")


def test_duplicate_joint_name():
    text = (HEAD + body("rod") + body("tip", x=1.5) + PIVOT
            + joint("pivot", "revolute", "rod", "tip", point="[1.0, 0.0]"))
    raises_naming(SceneError, text, "[[joints]] entry 2", "duplicate", "'pivot'")


def test_unknown_joint_type():
    text = HEAD + body("rod") + joint("pivot", "spherical", point="[0.0, 0.0]")
    raises_naming(SceneError, text, "[[joints]] entry 1", "'pivot'", "'type'", "spherical")


def test_same_body_twice_in_a_joint_scene():
    text = HEAD + body("rod") + joint("pivot", "revolute", "rod", "rod", point="[0.0, 0.0]")
    raises_naming(SceneError, text, "'pivot'", "same body", "'rod'")


def test_distance_joint_with_coincident_points():
    text = HEAD + body("rod") + joint("link", "distance", point1="[1.0, 0.0]",
                                      point2="[1.0, 0.0]")
    raises_naming(SceneError, text, "[[joints]] entry 1", "'link'", "length")


def test_prismatic_with_zero_axis():
    text = HEAD + body("rod") + joint("slide", "prismatic", point="[0.0, 0.0]",
                                      axis="[0.0, 0.0]")
    raises_naming(SceneError, text, "[[joints]] entry 1", "'slide'", "'axis'", "zero")


def test_spring_with_negative_free_length():
    """Used to simulate silently (the spring pushed the block through its anchor)."""
    text = PENDULUM + entry("forces", name='"coil"', type='"spring_damper"', body1='"ground"',
                            body2='"rod"', point1="[0.0, 1.0]", point2="[1.0, 0.0]",
                            stiffness="10.0", free_length="-0.5")
    raises_naming(SceneError, text, "[[forces]] entry 1", "'coil'", "'free_length'", ">= 0",
                  "-0.5")


def test_absurd_mass_refused_naming_the_body_and_field():
    """Mass 1e308 is beyond the plausible range [1e-15, 1e15] kg (issue 31; it used to reach
    the penalty check of the augmented Lagrangian)."""
    raises_naming(SceneError, HEAD + body("rod", mass="1e308", inertia="1e308") + PIVOT,
                  "'rod'", "'mass'", "1e+308", "1e+15")


def test_absurd_position_refused_naming_the_body_and_field():
    """A position of 1e308 m used to end in 'penalty must be > 0, got inf' (then, named by the
    penalty, 'C_q^T C_q diagonal up to inf'); it is refused where the body is declared, beyond
    the plausible 1e9 m (casmbd.model.bodies.POSITION_MAX: body-fixed offsets of its points
    would lose every digit)."""
    raises_naming(SceneError, HEAD + body("rod", position="[1e308, 0.0]") + PIVOT,
                  "'rod'", "'position'", "1e+308", "1e+09")


# ---------------------------------------------------------------------- drivers
def test_driver_with_both_joint_and_body():
    text = PENDULUM + entry("drivers", name='"spin"', joint='"pivot"', body='"rod"',
                            coordinate='"x"', position='"t"')
    raises_naming(SceneError, text, "[[drivers]] entry 1", "'spin'", "joint", "body")


def test_driver_coordinate_z():
    text = PENDULUM + entry("drivers", name='"lift"', body='"rod"', coordinate='"z"',
                            position='"t"')
    raises_naming(SceneError, text, "[[drivers]] entry 1", "'lift'", "coordinate", "'z'")


def test_driver_on_unknown_joint():
    text = PENDULUM + entry("drivers", name='"spin"', joint='"hinge"', position='"t"')
    raises_naming(SceneError, text, "[[drivers]] entry 1", "'spin'", "unknown joint", "'hinge'")


# ---------------------------------------------------------------------- expressions
def test_unsafe_expression_dunder_import():
    message = raises_naming(ExpressionError, driver_scene('"__import__(\'os\')"'),
                            "[[drivers]] entry 1", "'spin'", "key 'position'", "__import__")
    assert "[[drivers]]" in message


def test_expression_with_unknown_name():
    raises_naming(ExpressionError, driver_scene('"omega * t"'),
                  "[[drivers]] entry 1", "'spin'", "'position'", "unknown name", "'omega'")


def test_expression_using_os_system():
    raises_naming(ExpressionError, driver_scene('"os.system(\'true\')"'),
                  "[[drivers]] entry 1", "'spin'", "'position'", "os.system")


def test_expression_error_is_a_scene_error():
    """ExpressionError derives from SceneError, so callers can catch one class for scenes."""
    with pytest.raises(SceneError):
        loads_scene(driver_scene('"t +"'))


# ---------------------------------------------------------------------- forces
def test_unknown_force_type():
    text = PENDULUM + entry("forces", name='"push"', type='"magnet"', body='"rod"')
    raises_naming(SceneError, text, "[[forces]] entry 1", "'push'", "'type'", "magnet")


def test_rotational_spring_on_prismatic_joint():
    text = (HEAD + body("rod") + joint("slide", "prismatic", point="[0.0, 0.0]",
                                       axis="[1.0, 0.0]")
            + entry("forces", name='"coil"', type='"rotational_spring_damper"',
                    joint='"slide"', stiffness="10.0"))
    raises_naming(SceneError, text, "[[forces]] entry 1", "'coil'", "'slide'", "not revolute")


# ---------------------------------------------------------------------- analyses
UNASSEMBLABLE = (
    # A link of length 1 pinned at the origin ('pivot') whose tip (1, 0) is tied by a massless
    # link of length 1 ('tether') to the ground point (3, 0): the tip would have to be within
    # 1 m of both ground points, which are 3 m apart.
    HEAD + body("rod")
    + PIVOT
    + joint("tether", "distance", point1="[3.0, 0.0]", point2="[1.0, 0.0]", length="1.0")
)


@pytest.mark.parametrize("coordinates", ["absolute", "auto"])
def test_unassemblable_scene_names_worst_equations(coordinates):
    """The unreachable tether is named first (the culprit), then the residual equations; in
    absolute coordinates the pivot's equations follow, in the automatic choice (joint
    coordinates) the pivot is a tree joint without equations and the tether closes the loop."""
    mech = loads_scene(UNASSEMBLABLE)
    mech.coordinates = coordinates
    with pytest.raises(AssemblyError) as exc:
        kinematics(mech, t_end=1.0, steps=2)
    message = str(exc.value)
    assert "residual" in message
    assert exc.value.culprits[0].element == "tether"
    assert "its points (3, 0) on the ground and (1, 0) on body 'rod' are between 2 and 4 " \
           "apart" in message, message
    if coordinates == "absolute":
        assert 0 <= message.index("'tether'") < message.index("'pivot'"), message


@pytest.mark.parametrize("coordinates", ["absolute", "auto"])
def test_unassemblable_by_driver_names_driver(coordinates):
    """A driver that puts the centre of a 1 m link pinned at the origin 3 m away: the driver
    first, then (absolute coordinates) the joint it contradicts; in joint coordinates the
    joint is the tree and the message gives the range it allows."""
    text = PENDULUM + entry("drivers", name='"reach"', body='"rod"', coordinate='"x"',
                            position="3.0")
    mech = loads_scene(text)
    mech.coordinates = coordinates
    with pytest.raises(AssemblyError) as exc:
        kinematics(mech, t_end=1.0, steps=2)
    message = str(exc.value)
    assert "the joints allow only body 'rod' x from -0.5 to 0.5" in message, message
    if coordinates == "absolute":
        assert 0 <= message.index("'reach'") < message.index("'pivot'"), message
        assert [c.element for c in exc.value.culprits] == ["reach", "pivot"]
    else:
        assert [c.element for c in exc.value.culprits] == ["reach"]


def test_info_reports_assembly_failure_without_raising():
    """The Python ``info`` returns the failure (the CLI exits 1 on it, see
    tests/analysis/instant/test_assembly_culprit.py); no redundancy is claimed at the unassembled
    pose."""
    data = info(loads_scene(UNASSEMBLABLE))
    assert data["assembled"] is False and data["rank_reliable"] is False
    assert data["assembly_culprits"][0]["element"] == "tether"
    assert data["redundant_equations"] == []


FIXED_TWICE = (HEAD + body("block")
               + entry("joints", name='"weld1"', type='"fixed"', body='"block"')
               + entry("joints", name='"weld2"', type='"fixed"', body='"block"'))


def test_body_fixed_twice_is_redundant():
    """The second weld's equations are removed and named (issue 30, 4a), as info names them."""
    mech = loads_scene(FIXED_TWICE)
    res = kinematics(mech, t_end=1.0, steps=2)
    assert res.stats["redundancy"] == "removed"
    assert len(res.stats["redundant_equations"]) == 3
    assert all(e.startswith("joint 'weld2'") for e in res.stats["redundant_equations"])
    assert max(res["constraint_violation"]) < 1e-12
    data = info(mech)  # must not raise
    assert {d["joint"] for d in data["redundant_equations"]} == {"weld2"}
    assert len(data["redundant_equations"]) == 3


def _rod(name: str, a: tuple[float, float], b: tuple[float, float]) -> str:
    return body(name, x=(a[0] + b[0]) / 2, y=(a[1] + b[1]) / 2)


PARALLELOGRAM = (
    HEAD
    + _rod("crank1", (0.0, 0.0), (0.0, 1.0)) + _rod("coupler", (0.0, 1.0), (2.0, 1.0))
    + _rod("crank2", (2.0, 0.0), (2.0, 1.0)) + _rod("crank3", (1.0, 0.0), (1.0, 1.0))
    + joint("A", "revolute", "ground", "crank1", point="[0.0, 0.0]")
    + joint("B", "revolute", "crank1", "coupler", point="[0.0, 1.0]")
    + joint("C", "revolute", "coupler", "crank2", point="[2.0, 1.0]")
    + joint("D", "revolute", "ground", "crank2", point="[2.0, 0.0]")
    + joint("E", "revolute", "ground", "crank3", point="[1.0, 0.0]")
    + joint("F", "revolute", "crank3", "coupler", point="[1.0, 1.0]")
    + entry("drivers", name='"drive"', joint='"A"', position='"t"')
)


def test_parallelogram_with_redundant_link():
    """The redundant equation is removed and named by kinematics exactly as info names it."""
    mech = loads_scene(PARALLELOGRAM)
    res = kinematics(mech, t_end=1.0, steps=2)
    data = info(mech)
    assert data["degrees_of_freedom"] == 0
    assert len(data["redundant_equations"]) == 1
    assert data["redundant_equations"][0]["joint"] in {"A", "B", "C", "D", "E", "F"}
    assert res.stats["redundant_equations"] == [
        f"joint '{d['joint']}' equation '{d['equation']}'" for d in data["redundant_equations"]]
    assert max(res["constraint_violation"]) < 1e-12


def test_kinematics_of_undriven_mechanism():
    mech = load_scene(EXAMPLES / "double_pendulum.toml")
    with pytest.raises(AnalysisError, match=r"degree\(s\) of freedom|degrees of freedom") as exc:
        kinematics(mech, t_end=1.0, steps=2)
    assert "double_pendulum" in str(exc.value) and "2" in str(exc.value)


def test_driver_with_non_finite_derivative_names_the_driver():
    mech = loads_scene(driver_scene('"t**t"'))
    with pytest.raises(CasmbdError, match="spin"):
        kinematics(mech, t_end=1.0, steps=2)


# ---------------------------------------------------------------------- Python API
def api_mechanism() -> Mechanism:
    mech = Mechanism("api", gravity=(0.0, -9.81))
    mech.add_body("rod", mass=1.0, inertia=0.1, position=(0.5, 0.0))
    return mech


def test_api_add_body_negative_mass():
    with pytest.raises(ModelError, match=r"body 'beam' field 'mass'.*>= 0"):
        Mechanism("api").add_body("beam", mass=-1, inertia=0.1, position=(0.0, 0.0))


def test_api_add_body_duplicate_name():
    with pytest.raises(ModelError, match="duplicate body name 'rod'"):
        api_mechanism().add_body("rod", mass=1.0, inertia=0.1, position=(0.0, 0.0))


def test_api_add_revolute_unknown_body():
    with pytest.raises(ModelError, match=r"joint 'pin' field 'body2': unknown body 'rdo'"):
        api_mechanism().add_revolute("pin", "ground", "rdo", point=(0.0, 0.0))


def test_api_same_body_twice_in_a_joint():
    with pytest.raises(ModelError, match=r"joint 'pin'.*same body 'rod'"):
        api_mechanism().add_revolute("pin", "rod", "rod", point=(0.0, 0.0))


def test_api_add_parameter_named_t():
    with pytest.raises(ModelError, match="parameter 't'"):
        api_mechanism().add_parameter("t", 1.0)


def test_api_prismatic_zero_axis():
    with pytest.raises(ModelError, match=r"joint 'slide' field 'axis'"):
        api_mechanism().add_prismatic("slide", "ground", "rod", (0.0, 0.0), (0.0, 0.0))


def test_api_add_parameter_huge_integer():
    with pytest.raises(ModelError, match="parameter 'big'"):
        api_mechanism().add_parameter("big", 10**400)


def test_api_body_name_of_wrong_type():
    with pytest.raises(ModelError, match="joint 'pin'"):
        api_mechanism().add_revolute("pin", "ground", ["rod"], point=(0.0, 0.0))

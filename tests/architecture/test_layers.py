"""Import rules of the package: each module belongs to one layer and imports only its own
layer and the ones below it, at module level and inside functions alike; a casmbd import inside
a function is allowed only where it defers a heavy optional dependency (listed below with the
reason), never to dodge an import cycle.

The layers, lowest first (a module's layer is that of the longest prefix listed in LAYERS):

0. ``errors``, ``interrupts``, ``limits``, ``progress``, ``atomic``, ``lazy`` — helpers below
   everything;
1. ``model`` — what the user builds, with the expression parser (``model.expressions``);
2. ``system`` — the symbolic equations, with the named quantities analyses and the OCP share
   (``system.quantities``);
3. ``compiled`` — generated C, the cache, the numeric model;
4. ``results`` — the output data class ``Result`` and the file container helpers
   (``atomic_write``, ``read_npz``) that Result, SweepResult and OcpSolution write and read
   their own ``.npz`` files with; analyses build Results, so they sit below the analyses.
   Turning a result's embedded scene text back into a Mechanism is scene parsing: it stays in
   ``io`` (``casmbd.io.scene`` registers its reader with ``results`` when imported);
5. ``analysis`` — kinematics, dynamics, statics, linearisation, sweeps and sensitivities
   (they take a Mechanism; loading files is the caller's job);
6. ``ocp`` — trajectory optimisation;
7. ``io`` — scene files (TOML → Mechanism), the ``[ocp]`` table, a sweep point's scene;
8. ``viz`` — plots and animations;
9. ``cli`` — the ``casmbd`` command; ``casmbd/__init__.py`` and ``__main__.py`` (the public
   facade) sit on top with it.
"""

from __future__ import annotations

import ast
import pathlib
import subprocess
import sys

import pytest

PACKAGE = pathlib.Path(__file__).resolve().parents[2] / "casmbd"

LAYERS = {
    "casmbd.errors": 0, "casmbd.interrupts": 0, "casmbd.limits": 0, "casmbd.progress": 0,
    "casmbd.atomic": 0, "casmbd.lazy": 0,
    "casmbd.model": 1,
    "casmbd.system": 2,
    "casmbd.compiled": 3,
    "casmbd.results": 4,
    "casmbd.analysis": 5,
    "casmbd.ocp": 6,
    "casmbd.io": 7,
    "casmbd.viz": 8,
    "casmbd.cli": 9, "casmbd": 9, "casmbd.__main__": 9,
}

#: the rooms of the analysis layer (casmbd/analysis/<room>/), lowest floor first: a module of a
#: room imports, within the analysis layer, only its own room and the rooms of lower floors
#: (docs/architecture.md, "The analysis rooms"); ``casmbd.analysis`` itself is the face on top
ROOMS = {
    "casmbd.analysis.instant": 0,       # one instant: assembly, KKT, redundancy, checks, ...
    "casmbd.analysis.integrators": 1,   # integrator kinds and registry, dopri, numeric RHS
    "casmbd.analysis.formulations": 2,  # every formulation and its registry
    "casmbd.analysis.events": 2,        # event-driven simulation: contacts, stops, impacts
    "casmbd.analysis.driven": 3,        # kinematics and inverse dynamics of a driven mechanism
    "casmbd.analysis.dynamics": 3,      # the simulator, its stepping and post-processing
    "casmbd.analysis.statics": 3,       # statics, resting contacts, stability, linearize
    "casmbd.analysis.studies": 4,       # sweeps and sensitivities
    "casmbd.analysis.identification": 4,  # regressor, base parameters, identification
    "casmbd.analysis": 5,               # the face: the verbs, loaded on first use
}
#: the most modules (besides __init__) in one room
ROOM_MAX_MODULES = 9

#: (importing module, imported casmbd module) pairs allowed inside a function, each with the
#: reason: only to defer a heavy optional dependency (matplotlib, dask, tqdm) that the imported
#: module pulls in at its top.  None today: casmbd.viz and casmbd.progress import matplotlib
#: and tqdm inside the functions that draw (see test_heavy_optional_dependencies_are_deferred).
DEFERRED: dict[tuple[str, str], str] = {}


def _modules() -> dict[str, pathlib.Path]:
    mods = {}
    for path in sorted(PACKAGE.rglob("*.py")):
        parts = list(path.relative_to(PACKAGE.parent).with_suffix("").parts)
        if parts[-1] == "__init__":
            parts.pop()
        mods[".".join(parts)] = path
    return mods


def layer(module: str) -> int:
    """The layer of a casmbd module: that of the longest listed prefix."""
    parts = module.split(".")
    for k in range(len(parts), 0, -1):
        name = ".".join(parts[:k])
        if name in LAYERS:
            return LAYERS[name]
    raise KeyError(f"module {module} is in no layer: add it to LAYERS")


def _imports(module: str, path: pathlib.Path):
    """(imported casmbd module, line, inside a function?) for every import of the file."""
    tree = ast.parse(path.read_text(), str(path))
    package = module if path.name == "__init__.py" else module.rpartition(".")[0]
    found = []

    def visit(node, in_function: bool):
        for child in ast.iter_child_nodes(node):
            inner = in_function or isinstance(child, (ast.FunctionDef, ast.AsyncFunctionDef,
                                                      ast.Lambda))
            if isinstance(child, ast.Import):
                found.extend((a.name, child.lineno, in_function) for a in child.names
                             if a.name.split(".")[0] == "casmbd")
            elif isinstance(child, ast.ImportFrom):
                base = child.module or ""
                if child.level:
                    up = package.split(".")[:len(package.split(".")) - child.level + 1]
                    base = ".".join(up + ([base] if base else []))
                if base.split(".")[0] != "casmbd":
                    continue
                for a in child.names:  # `from casmbd import cli` names a module
                    sub = f"{base}.{a.name}"
                    found.append((sub if sub in MODULES else base, child.lineno, in_function))
            visit(child, inner)

    visit(tree, False)
    return found


MODULES = _modules()


def test_every_module_has_a_layer():
    for module in MODULES:
        layer(module)


@pytest.mark.parametrize("module", sorted(MODULES))
def test_no_lower_layer_imports_a_higher_one(module):
    own = layer(module)
    bad = sorted({f"line {line}: {target} (layer {layer(target)})"
                  for target, line, _ in _imports(module, MODULES[module])
                  if layer(target) > own})
    assert not bad, f"{module} (layer {own}) imports a higher layer: {'; '.join(bad)}"


@pytest.mark.parametrize("module", sorted(MODULES))
def test_function_level_imports_only_defer_heavy_dependencies(module):
    bad = sorted({f"line {line}: {target}"
                  for target, line, inside in _imports(module, MODULES[module])
                  if inside and (module, target) not in DEFERRED})
    assert not bad, (f"{module} imports casmbd modules inside functions (move them to the top "
                     f"or list them in DEFERRED with the reason): {'; '.join(bad)}")


def test_heavy_optional_dependencies_are_deferred():
    """``import casmbd`` and the CLI load no matplotlib, dask or tqdm: those are imported by the
    function that draws, distributes or shows a bar (a fresh interpreter, so that other tests'
    imports do not count)."""
    code = ("import sys, casmbd, casmbd.cli, casmbd.viz; "
            "print(sorted(m for m in ('matplotlib', 'dask', 'distributed', 'tqdm') "
            "if m in sys.modules))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         timeout=300, check=True).stdout.strip()
    assert out == "[]", f"imported at start-up: {out}"


def test_the_checker_sees_violations(tmp_path):
    """The walker finds a function-level upward import and a relative module import."""
    path = tmp_path / "m.py"
    path.write_text("from . import scene\n\ndef f():\n    from casmbd.io.scene import x\n")
    found = _imports("casmbd.model.m", path)
    assert ("casmbd.model", 1, False) in found and ("casmbd.io.scene", 4, True) in found
    assert layer("casmbd.io.scene") > layer("casmbd.model.m")


#: every registry: (the package or module that owns it, the dict within it); a name of each
#: registry must be there right after that import, in a fresh process (issue 33: registries
#: complete on import, never filled by a side-effect import of another module)
REGISTRIES = {
    "joint kinds": ("casmbd.model", "casmbd.model.registry.JOINT_KINDS"),
    "force element kinds": ("casmbd.model", "casmbd.model.registry.FORCE_KINDS"),
    "body kinds": ("casmbd.model", "casmbd.model.registry.BODY_KINDS"),
    "contact shapes": ("casmbd.model", "casmbd.model.contacts.CONTACT_SHAPES"),
    "body descriptions": ("casmbd.system", "casmbd.system.descriptions.DESCRIPTIONS"),
    "formulations": ("casmbd.analysis.formulations", "casmbd.analysis.formulations.FORMULATIONS"),
    "integrators": ("casmbd.analysis.integrators", "casmbd.analysis.integrators.INTEGRATORS"),
    "numeric right-hand sides": ("casmbd.analysis.dynamics.numeric_run",
                                 "casmbd.analysis.dynamics.numeric_run.RIGHT_HAND_SIDES"),
    "compiled analyses": ("casmbd.compiled", "casmbd.compiled.model.NEEDS"),
    "transcriptions": ("casmbd.ocp.methods", "casmbd.ocp.methods.TRANSCRIPTIONS"),
    "verbs": ("casmbd.cli", "casmbd.cli.VERBS"),
}

_NAMES = """
import importlib, json, sys
def names(path):
    module, _, attr = path.rpartition(".")
    reg = getattr(sys.modules[module], attr)
    return sorted(k if isinstance(k, str) else k.__name__ for k in reg)
"""


def _fresh_json(code: str):
    out = subprocess.run([sys.executable, "-c", _NAMES + code], capture_output=True,
                         text=True, timeout=300, cwd=PACKAGE.parent)
    assert out.returncode == 0, out.stderr[-2000:]
    return __import__("json").loads(out.stdout.strip().splitlines()[-1])


def test_every_registry_is_complete_when_its_package_is_imported():
    """A fresh interpreter that imports only a registry's own package sees every name that a
    fresh interpreter importing every casmbd module sees (same names, same count)."""
    modules = sorted(m for m in MODULES if not m.endswith("__main__"))
    everything = _fresh_json(
        f"for m in {modules!r}: importlib.import_module(m)\n"
        f"print(json.dumps({{k: names(p) for k, (_, p) in {REGISTRIES!r}.items()}}))")
    for label, (package, path) in REGISTRIES.items():
        alone = _fresh_json(f"importlib.import_module({package!r})\n"
                            f"print(json.dumps(names({path!r})))")
        assert alone == everything[label], (
            f"{label}: importing {package} gives {len(alone)} names, all of casmbd "
            f"{len(everything[label])}: missing {sorted(set(everything[label]) - set(alone))}")
        assert alone, f"{label}: empty registry"


def test_a_fresh_command_line_offers_every_formulation_and_integrator():
    """``casmbd simulate --formulation/--integrator`` list every registered name in a fresh
    process (issue 33: a fresh CLI process offered 5 of the 7 formulations)."""
    got = _fresh_json(
        "import casmbd.cli\n"
        "p = casmbd.cli.build_parser()\n"
        "sub = next(a for a in p._actions if a.dest == 'verb').choices['simulate']\n"
        "ch = {a.dest: sorted(a.choices) for a in sub._actions if a.choices}\n"
        "import casmbd.analysis.formulations, casmbd.analysis.integrators\n"
        "print(json.dumps([ch['formulation'], names('casmbd.analysis.formulations.FORMULATIONS'),"
        " ch['integrator'], names('casmbd.analysis.integrators.INTEGRATORS')]))")
    assert got[0] == got[1] and len(got[0]) == 7
    assert got[2] == got[3]


def room(module: str) -> str | None:
    """The analysis room of a module (the longest prefix in ROOMS), None outside the layer."""
    parts = module.split(".")
    for k in range(len(parts), 0, -1):
        name = ".".join(parts[:k])
        if name in ROOMS:
            return name
    return None


ANALYSIS = sorted(m for m in MODULES if room(m))


def test_every_analysis_module_is_in_a_room():
    """No module lies loose in casmbd/analysis/ besides the face, and no room is a pile."""
    loose = [m for m in ANALYSIS if room(m) == "casmbd.analysis" and m != "casmbd.analysis"]
    assert not loose, f"analysis modules outside a room: {loose}"
    for name in ROOMS:
        if name != "casmbd.analysis":
            members = [m for m in ANALYSIS if m.startswith(name + ".")]
            assert 0 < len(members) <= ROOM_MAX_MODULES, (name, members)


@pytest.mark.parametrize("module", ANALYSIS)
def test_analysis_rooms_point_down(module):
    """A room imports its own room and lower floors only (the face imports nothing)."""
    own = room(module)
    bad = sorted({f"line {line}: {target} ({room(target)}, floor {ROOMS[room(target)]})"
                  for target, line, _ in _imports(module, MODULES[module])
                  if room(target) and room(target) != own
                  and ROOMS[room(target)] >= ROOMS[own]})
    assert not bad, f"{module} (floor {ROOMS[own]}) imports a room not below it: {bad}"


def _cycle(graph: dict[str, set[str]]) -> list[str]:
    """One import circle of ``graph`` (module -> imported modules), [] when acyclic."""
    state: dict[str, int] = {}
    stack: list[str] = []

    def visit(node):
        state[node] = 1
        stack.append(node)
        for nxt in sorted(graph.get(node, ())):
            if state.get(nxt) == 1:
                return [*stack[stack.index(nxt):], nxt]
            if nxt not in state and (found := visit(nxt)):
                return found
        stack.pop()
        state[node] = 2
        return []

    for node in sorted(graph):
        if node not in state and (found := visit(node)):
            return found
    return []


def test_analysis_import_graph_is_acyclic():
    """The analysis modules' import graph (module-level imports, a package meaning its
    ``__init__``) has no circle — the one `integrators` <-> `dopri` held by a bottom-of-file
    import is gone."""
    graph = {m: {t for t, _, inside in _imports(m, MODULES[m]) if room(t) and not inside}
             for m in ANALYSIS}
    assert len(graph) > 40
    assert _cycle(graph) == [], f"import circle: {' -> '.join(_cycle(graph))}"


def test_the_cycle_finder_sees_a_circle():
    assert _cycle({"a": {"b"}, "b": {"c"}, "c": {"a"}}) == ["a", "b", "c", "a"]
    assert _cycle({"a": {"b"}, "b": set(), "c": {"a", "b"}}) == []


def test_the_analysis_face_exports_the_verbs():
    """``casmbd.analysis`` names every analysis verb of the public facade, from the same module
    (the facade reads the face's registry), and a fresh ``import casmbd.analysis`` loads no room
    (the verbs load on first use)."""
    import casmbd
    import casmbd.analysis as face

    assert not any(m.startswith("casmbd.analysis") for m in casmbd._LAZY.values())
    assert set(face.VERBS) <= set(casmbd.__all__)
    assert all(m.startswith("casmbd.analysis.") for m in face.VERBS.values())
    for name in face.VERBS:
        assert getattr(face, name) is getattr(casmbd, name)
    code = ("import sys, casmbd.analysis; "
            "print(sorted(m for m in sys.modules if m.startswith('casmbd.analysis.')))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         timeout=300, check=True).stdout.strip()
    assert out == "[]"


# -- private names stay in their module ----------------------------------------------------

#: cross-module uses of a private name not yet given a public one (issue 33 item 6): each is
#: "importer: source.name"; the list may only shrink (a stale entry fails too). Empty: every
#: name used by another module is public (84 such imports before issue 33).
PRIVATE_IMPORT_DEBT: set[str] = set()


def _private_uses(module: str, path: pathlib.Path) -> list[str]:
    """``importer: source._name`` for every ``from casmbd.x import _name`` and every
    ``alias._name`` attribute access on an imported casmbd module, in one file."""
    tree = ast.parse(path.read_text(), str(path))
    package = module if path.name == "__init__.py" else module.rpartition(".")[0]
    aliases: dict[str, str] = {}
    found = []

    def private(name: str) -> bool:
        return name.startswith("_") and not name.startswith("__")

    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            for a in node.names:
                if a.name.split(".")[0] == "casmbd":
                    aliases[a.asname or a.name.split(".")[0]] = a.name if a.asname else "casmbd"
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:
                up = package.split(".")[:len(package.split(".")) - node.level + 1]
                base = ".".join(up + ([base] if base else []))
            if base.split(".")[0] != "casmbd":
                continue
            for a in node.names:
                sub = f"{base}.{a.name}"
                if sub in MODULES:
                    aliases[a.asname or a.name] = sub
                elif private(a.name) and base != module:
                    found.append(f"{module}: {base}.{a.name}")
    for node in ast.walk(tree):
        if isinstance(node, ast.Attribute) and private(node.attr):
            chain, value = [], node.value
            while isinstance(value, ast.Attribute):
                chain.insert(0, value.attr)
                value = value.value
            if isinstance(value, ast.Name) and value.id in aliases:
                source = ".".join([aliases[value.id], *chain])
                if source in MODULES and source != module:
                    found.append(f"{module}: {source}.{node.attr}")
    return sorted(set(found))


def test_no_module_uses_another_modules_private_names():
    """A name used by another casmbd module is public in its defining module (no
    ``from casmbd.x import _y``, no ``x._y`` on an imported casmbd module)."""
    found = {use for module, path in MODULES.items() for use in _private_uses(module, path)}
    new = sorted(found - PRIVATE_IMPORT_DEBT)
    assert not new, "private names imported across modules:\n" + "\n".join(new)
    stale = sorted(PRIVATE_IMPORT_DEBT - found)
    assert not stale, "remove from PRIVATE_IMPORT_DEBT:\n" + "\n".join(stale)


def test_the_private_name_checker_sees_both_forms(tmp_path):
    path = tmp_path / "probe.py"
    path.write_text("from casmbd.compiled.model import _hidden, NumericModel\n"
                    "from casmbd.compiled import codegen\n"
                    "import casmbd.results as res\n"
                    "codegen._secret()\nres._other\ncodegen.public\n")
    assert _private_uses("casmbd.io.probe", path) == [
        "casmbd.io.probe: casmbd.compiled.codegen._secret",
        "casmbd.io.probe: casmbd.compiled.model._hidden",
        "casmbd.io.probe: casmbd.results._other"]

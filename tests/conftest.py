"""Make the repository root and the shared test helpers importable; the private compiled-code
cache.

The tests live in folders that mirror the package (tests/README.md); the helpers they share
(``mechanisms``, ``flexible_references``, ``symbolic_checks``, ``composition_scenes``, this
module's :func:`private_cache`, the scenes of ``tests/scenes/``) stay at ``tests/``, which is on
``sys.path`` for every folder.  The hooks of :mod:`peer_policy` make a skipped peer cross-check
fail when ``CASMBD_REQUIRE_PEERS`` is set (CI).
"""

import pathlib
import sys

import pytest

TESTS = pathlib.Path(__file__).resolve().parent
sys.path.insert(0, str(TESTS.parent))
if str(TESTS) not in sys.path:
    sys.path.insert(1, str(TESTS))

# the peer cross-checks' policy: a skipped one fails under CASMBD_REQUIRE_PEERS (peer_policy.py)
from peer_policy import (  # noqa: E402, F401
    pytest_collection_modifyitems,
    pytest_configure,
    pytest_make_collect_report,
    pytest_runtest_makereport,
)


def private_cache(name: str | None = None, *, scope: str = "function", autouse: bool = True,
                  **env: str | None):
    """A fixture that points ``CASMBD_CACHE_DIR`` at a temporary directory.

    The tests never touch the user's compiled-code cache. Assign the result to a module-level
    name (the fixture's name): ``_cache = private_cache("cache_gear")``.

    Parameters
    ----------
    name : str, optional
        Without a name, every test has a new directory (``tmp_path / "cache"``). With a name
        and ``scope="function"``: ``tmp_path_factory.getbasetemp() / name``, one directory for
        every test of the session that uses the name (several modules may share it). With
        ``scope="module"``: a new directory ``tmp_path_factory.mktemp(name)`` for the module.
    scope : {"function", "module"}
        ``"module"`` sets the variables once, before the module's other module-scoped
        fixtures run (they build models with the cache too), and restores them at its end.
    autouse : bool
        False for a fixture that the tests request by name.
    **env
        Further environment variables: a string sets one, None removes it
        (``CASMBD_COMPILE="0"`` selects the virtual machine, ``CASMBD_COMPILE=None`` the
        default).

    Returns
    -------
    The fixture; its value is the cache directory (``pathlib.Path``).
    """
    def apply(mp: pytest.MonkeyPatch, directory: pathlib.Path) -> pathlib.Path:
        mp.setenv("CASMBD_CACHE_DIR", str(directory))
        for variable, value in env.items():
            if value is None:
                mp.delenv(variable, raising=False)
            else:
                mp.setenv(variable, value)
        return directory

    if scope == "module":
        if name is None:
            raise ValueError("a module-scoped private cache needs a name")

        @pytest.fixture(autouse=autouse, scope="module")
        def module_cache(tmp_path_factory):
            with pytest.MonkeyPatch.context() as mp:
                yield apply(mp, tmp_path_factory.mktemp(name))

        return module_cache
    if scope != "function":
        raise ValueError(f"scope {scope!r}: 'function' or 'module'")

    @pytest.fixture(autouse=autouse)
    def function_cache(request, monkeypatch, tmp_path_factory):
        if name is None:
            return apply(monkeypatch, request.getfixturevalue("tmp_path") / "cache")
        return apply(monkeypatch, tmp_path_factory.getbasetemp() / name)

    return function_cache

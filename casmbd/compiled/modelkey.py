"""A cache key computed from what a model *is*, and the record that lets a hit skip the build.

:func:`casmbd.compiled.codegen.compile_functions` keys a library by its generated C source, so
finding it again means building every expression and writing all the C first (a 1000-rod
chain: minutes).  This module keys a *build* by its description instead, before anything
symbolic exists:

* :func:`canonical` turns a mechanism (bodies, joints, forces, drivers, markers, actuators,
  parameters, gravity, coordinates, spanning-tree choice) and the build options (formulation
  and its options, inputs, redundancy policy) into nested JSON lists: floats exactly
  (:meth:`float.hex`), dictionaries in insertion order (the order of bodies is the layout of
  q), objects by class and attributes.  A value it cannot describe exactly — a Python
  callable, a CasADi expression — makes the build unkeyable (:class:`UnkeyableError`) and the
  caller builds as before.  Parameter *values* are kept in the key although every Function
  takes them as its runtime input ``p``: the build reads their defaults (the augmented
  Lagrangian's default penalty, the redundancy check at the assembled start, joint-coordinate
  initial rates), so a model with other defaults is another build;
* :func:`model_key` is the SHA-256 of that text together with the SHA-256 of casmbd's own
  source files (any code change is a new key), the CasADi version, the compiler, the flags
  and the platform;
* :func:`store` writes, atomically, a *model record* ``<name>_<key[:16]>.model.json`` in the
  cache directory naming the libraries of the build (file, build key, function signatures)
  and the metadata the numeric model needs without a :class:`~casmbd.system.System` (sizes,
  names, labels, initial state — whatever :class:`~casmbd.compiled.model.NumericModel` and the
  simulator read);
* every record carries a content hash ``digest`` (:func:`record_digest`: SHA-256 of its
  canonical JSON without that field, which includes each library's SHA-256); a record whose
  fields do not give its digest — one tampered number of the metadata — is not used at all,
  never half-trusted: a :class:`RuntimeWarning` and a rebuild, as for any damaged entry.  (A
  hash, not a signature: it detects damage and edits, not someone who rewrites the digest too;
  the cache directory is the user's own);
* :func:`load` reads it back and opens each library only after the checks of
  :func:`casmbd.compiled.cache.check_entry` (record, build key, size, SHA-256, signatures
  equal to those of the model record) and, after loading, of the loaded signatures; any
  failed check is a :class:`RuntimeWarning` and a miss (the caller rebuilds).
"""

from __future__ import annotations

import functools
import hashlib
import json
import math
import os
import pathlib
import time
import warnings
from collections.abc import Mapping

import casadi
import numpy as np

from casmbd.compiled import cache, codegen
from casmbd.compiled.codegen import BuildReport
from casmbd.model.values import Samples

__all__ = ["MODEL_RECORD_FORMAT", "UnkeyableError", "canonical", "load", "model_key",
           "record_path", "source_digest", "store"]

#: version of the model record; a record of another version is a miss (2: content hash
#: ``digest`` and each library's SHA-256)
MODEL_RECORD_FORMAT = 2
MODEL_SUFFIX = ".model.json"
#: attributes of a mechanism that do not change what is built (the scene's text and parsed
#: tables, whose analysis settings — t_end, steps, tolerances — are the caller's, and a
#: sweep's points; the results take them from the mechanism at hand; the bodies' visuals for
#: the 3-D view)
_SKIPPED = frozenset({"scene_text", "scene_data", "scene_points", "scene_reader", "visuals"})
_MAX_DEPTH = 12


class UnkeyableError(Exception):
    """A part of the description has no exact canonical form (a callable, an expression)."""


def _float(value: float) -> list:
    return ["f", float(value).hex()] if math.isfinite(value) else ["f", repr(float(value))]


def canonical(obj, depth: int = 0):
    """Nested JSON-ready lists describing ``obj`` exactly (see the module notes).

    Raises
    ------
    UnkeyableError
        For a callable, a CasADi object or any type not listed.
    """
    if depth > _MAX_DEPTH:
        raise UnkeyableError("description nested too deeply")
    if obj is None or isinstance(obj, (bool, str)):
        return obj
    if isinstance(obj, (int, np.integer)):
        return ["i", int(obj)]
    if isinstance(obj, (float, np.floating)):
        return _float(float(obj))
    if isinstance(obj, np.ndarray):
        if obj.dtype.kind not in "biuf":
            raise UnkeyableError(f"array of dtype {obj.dtype}")
        return ["a", list(obj.shape), [_float(x) for x in obj.astype(float).ravel()]]
    if isinstance(obj, (list, tuple)):
        return ["l", [canonical(x, depth + 1) for x in obj]]
    if isinstance(obj, Mapping):
        return ["d", [[canonical(k, depth + 1), canonical(v, depth + 1)]
                      for k, v in obj.items()]]
    if isinstance(obj, Samples):
        return ["samples", canonical(obj.times), canonical(obj.values), obj.extrapolate,
                obj.name]
    if isinstance(obj, (casadi.SX, casadi.MX, casadi.DM, casadi.Function)) or callable(obj):
        raise UnkeyableError(f"{type(obj).__name__} value")
    attrs = getattr(obj, "__dict__", None)
    if attrs is None:
        raise UnkeyableError(f"{type(obj).__name__} value")
    cls = type(obj)
    return ["o", f"{cls.__module__}.{cls.__qualname__}",
            [[k, canonical(v, depth + 1)] for k, v in sorted(attrs.items())
             if depth or k not in _SKIPPED]]


@functools.lru_cache(maxsize=1)
def source_digest() -> str:
    """SHA-256 of casmbd's own ``.py`` files (names and bytes): a code change is a new key."""
    root = pathlib.Path(__file__).resolve().parent.parent
    digest = hashlib.sha256()
    for path in sorted(root.rglob("*.py")):
        digest.update(str(path.relative_to(root)).encode())
        digest.update(b"\x00")
        digest.update(path.read_bytes())
    return digest.hexdigest()


def model_key(mechanism, purpose: str, options: Mapping) -> str | None:
    """SHA-256 of what a build is: ``mechanism``, ``purpose`` (e.g. ``"simulator"``),
    ``options`` (formulation, its options, inputs, …), casmbd's sources, CasADi's version,
    compiler, flags and platform; None when the description has no exact canonical form
    (:class:`UnkeyableError`) or no compiler is found."""
    compiler = codegen.find_compiler()
    if compiler is None:
        return None
    try:
        described = canonical(mechanism)
        opts = canonical(dict(options))
    except UnkeyableError:
        return None
    text = json.dumps(["casmbd-model-v1", purpose, described, opts, source_digest(),
                       casadi.__version__, compiler, codegen.resolve_flags(None),
                       os.environ.get("CASMBD_CFLAGS", ""), codegen.platform_tag()],
                      separators=(",", ":"))
    return hashlib.sha256(text.encode()).hexdigest()


def record_path(name: str, key: str) -> pathlib.Path:
    """The model record of the build ``key`` of the model ``name`` in the cache directory."""
    return cache.cache_dir() / f"{name}_{key[:16]}{MODEL_SUFFIX}"


def record_digest(record: Mapping) -> str:
    """The content hash of a model record: SHA-256 of its canonical JSON (sorted keys, no
    spaces) without the ``digest`` field itself.  It covers the metadata and each library's
    build key, signatures and SHA-256, so that no field can change unseen."""
    body = {k: v for k, v in record.items() if k != "digest"}
    text = json.dumps(body, sort_keys=True, separators=(",", ":"), allow_nan=True)
    return hashlib.sha256(text.encode()).hexdigest()


def store(name: str, key: str, report: BuildReport, meta: dict) -> None:
    """Write the model record of ``key``: the libraries of ``report`` (their build keys and
    signatures, read from their own records) and ``meta`` (JSON-ready)."""
    if report.mode != "compiled" or not report.libraries:
        return
    libraries = []
    for library in report.libraries:
        record = cache.read_record(pathlib.Path(library))
        libraries.append({"file": pathlib.Path(library).name, "key": record["key"],
                          "functions": record["functions"], "sha256": record["sha256"]})
    content = {"format": MODEL_RECORD_FORMAT, "key": key, "libraries": libraries, "meta": meta}
    content = json.loads(json.dumps(content))  # the digest of what a reader will parse
    text = json.dumps({**content, "digest": record_digest(content)}, sort_keys=True)
    path = record_path(name, key)
    try:
        with cache.entry_lock(path.parent):
            cache.write_atomic(path, text)
    except OSError as exc:
        warnings.warn(f"casmbd: the model record {path} cannot be written ({exc}); the next "
                      "run builds the model again", RuntimeWarning, stacklevel=2)


def _read(path: pathlib.Path, key: str) -> tuple[dict | None, str | None]:
    try:
        record = json.loads(cache.read_record_text(path))
    except FileNotFoundError:
        return None, None
    except (OSError, ValueError) as exc:
        return None, f"it cannot be read ({exc})"
    if not isinstance(record, dict) or record.get("format") != MODEL_RECORD_FORMAT:
        return None, "it has an unknown format"
    if record.get("key") != key or not isinstance(record.get("libraries"), list) \
            or not record["libraries"] or not isinstance(record.get("meta"), dict):
        return None, "it is for another model or incomplete"
    if record.get("digest") != record_digest(record):
        return None, "its content hash differs from its fields: the record was changed"
    return record, None


def load(name: str, key: str, stacklevel: int = 2
         ) -> tuple[dict[str, casadi.Function], dict, BuildReport] | None:
    """The functions, metadata and report of the build ``key`` from its model record, or None
    (no record; or a failed check, with a :class:`RuntimeWarning`: the caller rebuilds)."""
    start = time.perf_counter()
    path = record_path(name, key)
    record, reason = _read(path, key)
    functions: dict[str, casadi.Function] = {}
    libraries = []
    for entry in (record or {}).get("libraries", ()):
        try:
            library = path.parent / str(entry["file"])
            lib_key, expected = str(entry["key"]), dict(entry["functions"])
            lib_sha = str(entry["sha256"])
        except (KeyError, TypeError, ValueError):
            reason = "a library entry is malformed"
            break
        # record, key, size, SHA-256 and signatures BEFORE dlopen (see cache.check_entry)
        reason = cache.check_entry(library, lib_key, expected) if library.exists() else \
            f"its library {library.name} is missing"
        if reason is None and cache.read_record(library).get("sha256") != lib_sha:
            reason = "its SHA-256 differs from the model record's (another build's library)"
        if reason is None:
            loaded, reason = codegen.load_verified(list(expected), library, expected)
        if reason is not None:
            reason = f"library {library.name}: {reason}"
            break
        functions.update(loaded)
        libraries.append(str(library))
    if reason is not None:
        warnings.warn(f"casmbd: the model record {path} is not used ({reason}); building the "
                      "model again", RuntimeWarning, stacklevel=stacklevel + 1)
        return None
    if record is None:
        return None
    report = BuildReport(mode="compiled", cache_hit=True, compiled=False, codegen_seconds=0.0,
                         compile_seconds=0.0, load_seconds=time.perf_counter() - start,
                         library=libraries[0], key=key, libraries=tuple(libraries))
    return functions, record["meta"], report

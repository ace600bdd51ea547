"""Measurement files for identification: a CSV of sampled joint data → :class:`Measurements`.

Format: one header line, then one line per sample, comma-separated numbers.  Columns:

* ``t`` — the sample time [s] (required, increasing);
* ``q.<coordinate>`` — position of each coordinate (required for every coordinate);
* ``tau.<coordinate>`` — the measured generalized effort on it (required for every
  coordinate: joint torque [N m] or force [N]);
* ``v.<coordinate>`` and ``a.<coordinate>`` — velocity and acceleration (optional: both for
  every coordinate, or neither; without them q is filtered and differentiated,
  :mod:`casmbd.analysis.identification.measurements`).

``<coordinate>`` is casmbd's coordinate name as ``casmbd info`` lists it and results CSV files
write it — ``<joint>.<field>``, e.g. ``shoulder_pan_joint.angle`` for a URDF revolute joint,
``slide.x`` for a prismatic one — and the bracket form of results files, ``q[<coordinate>]``,
is read the same.  Columns with other names (currents, temperatures) are ignored; the column
order is free.  The file is read bounded (:data:`casmbd.limits.MAX_MEASUREMENT_BYTES`);
a missing column, a malformed or non-finite number, a row with the wrong number of fields is
an :class:`~casmbd.errors.IdentificationError` naming the file, the line and the column.
"""

from __future__ import annotations

import io
import os
import re

import numpy as np

from casmbd.analysis.identification.measurements import Measurements
from casmbd.errors import IdentificationError
from casmbd.limits import MAX_MEASUREMENT_BYTES, read_bounded

__all__ = ["CHANNELS", "parse_measurements", "read_measurements"]

#: the column prefixes and what they hold
CHANNELS = {"q": "position", "v": "velocity", "a": "acceleration", "tau": "effort"}
_COLUMN = re.compile(r"^(q|v|a|tau)(?:\.(.+)|\[(.+)\])$")


def read_measurements(path: str | os.PathLike, coordinates: list[str]) -> Measurements:
    """Read a measurement CSV file (module docstring) for the coordinates ``coordinates``."""
    data = read_bounded(path, "measurement", MAX_MEASUREMENT_BYTES, IdentificationError)
    try:
        text = data.decode("utf-8-sig")
    except UnicodeDecodeError as exc:
        raise IdentificationError(f"measurement file '{path}' is not UTF-8 text: {exc}") \
            from None
    return parse_measurements(text, coordinates, str(path))


def _columns(header: list[str], coordinates: list[str], source: str) -> dict:
    """Channel → [column index per coordinate] (None where absent), and the time column."""
    known = set(coordinates)
    index: dict[str, dict[str, int]] = {key: {} for key in CHANNELS}
    time = None
    for k, raw in enumerate(header):
        name = raw.strip()
        if name == "t":
            if time is not None:
                raise IdentificationError(f"{source}: column 't' appears twice")
            time = k
            continue
        m = _COLUMN.match(name)
        if not m:
            continue
        channel, coord = m.group(1), m.group(2) or m.group(3)
        if coord not in known:
            raise IdentificationError(
                f"{source}: column '{name}' (column {k + 1}) names no coordinate of the model "
                f"(coordinates: {', '.join(coordinates)})")
        if coord in index[channel]:
            raise IdentificationError(f"{source}: column '{channel}.{coord}' appears twice")
        index[channel][coord] = k
    if time is None:
        raise IdentificationError(f"{source}: no column 't' (the sample times) in the header")
    for channel in ("q", "tau"):
        missing = [c for c in coordinates if c not in index[channel]]
        if missing:
            raise IdentificationError(
                f"{source}: missing column '{channel}.{missing[0]}'"
                + (f" (and {len(missing) - 1} more)" if len(missing) > 1 else "")
                + f": every coordinate needs its {CHANNELS[channel]}")
    for channel in ("v", "a"):
        given = index[channel]
        if given and len(given) < len(coordinates):
            missing = next(c for c in coordinates if c not in given)
            raise IdentificationError(f"{source}: missing column '{channel}.{missing}' "
                                      f"(give '{channel}.' for every coordinate or for none)")
    if bool(index["v"]) != bool(index["a"]):
        have, lack = ("v", "a") if index["v"] else ("a", "v")
        raise IdentificationError(f"{source}: '{have}.' columns without '{lack}.' columns: "
                                  "give both velocities and accelerations, or neither (q is "
                                  "then differentiated)")
    return {"t": time, **{ch: [index[ch][c] for c in coordinates] if index[ch] else None
                          for ch in CHANNELS}}


def _bad_cell(lines: list[str], width: int, header: list[str], source: str):
    """The first line with a wrong field count or a field that is not a number."""
    for number, line in enumerate(lines, start=2):
        if not line.strip():
            continue
        fields = line.split(",")
        if len(fields) != width:
            return IdentificationError(f"{source} line {number}: {len(fields)} fields, the "
                                       f"header has {width}")
        for k, field in enumerate(fields):
            try:
                float(field)
            except ValueError:
                return IdentificationError(f"{source} line {number} column "
                                           f"'{header[k].strip()}': {field.strip()!r} is not a "
                                           "number")
    return IdentificationError(f"{source}: cannot read the numbers")


def parse_measurements(text: str, coordinates: list[str],
                       source: str = "<measurements>") -> Measurements:
    """:func:`read_measurements` of CSV text."""
    lines = text.splitlines()
    if not lines or not lines[0].strip():
        raise IdentificationError(f"{source}: empty file (expected a header line: t, q.…, "
                                  "tau.…)")
    header = lines[0].split(",")
    cols = _columns(header, list(coordinates), source)
    body = [ln for ln in lines[1:]]
    if not any(ln.strip() for ln in body):
        raise IdentificationError(f"{source}: no samples after the header")
    try:
        values = np.loadtxt(io.StringIO("\n".join(body)), delimiter=",", ndmin=2,
                            dtype=float)
    except ValueError:
        raise _bad_cell(body, len(header), header, source) from None
    if values.shape[1] != len(header):
        raise _bad_cell(body, len(header), header, source)
    bad = np.argwhere(~np.isfinite(values))
    if bad.size:
        row, col = bad[0]
        rows = [k for k, ln in enumerate(body, start=2) if ln.strip()]
        raise IdentificationError(f"{source} line {rows[row]} column "
                                  f"'{header[col].strip()}': {values[row, col]} is not a "
                                  "finite number")
    t = values[:, cols["t"]]
    if np.any(np.diff(t) <= 0.0):
        k = int(np.argmax(np.diff(t) <= 0.0))
        rows = [j for j, ln in enumerate(body, start=2) if ln.strip()]
        raise IdentificationError(f"{source} line {rows[k + 1]} column 't': time {t[k + 1]:.9g}"
                                  f" does not increase (previous {t[k]:.9g})")

    def take(channel):
        return None if cols[channel] is None else values[:, cols[channel]]

    return Measurements(t=t, q=take("q"), tau=take("tau"), v=take("v"), a=take("a"),
                        coordinates=list(coordinates), source=source)

"""Measurement CSV files (casmbd.io.measurement_csv): the columns by casmbd's coordinate names,
both spellings, and every bad input named by file, line and column."""

from __future__ import annotations

import numpy as np
import pytest

from casmbd.errors import IdentificationError, LimitError
from casmbd.io import measurement_csv as mio

COORDS = ["shoulder.angle", "elbow.angle"]


def _text(header, rows):
    return ",".join(header) + "\n" + "\n".join(",".join(map(str, r)) for r in rows) + "\n"


def test_columns_in_any_order_and_both_spellings(tmp_path):
    """``q.NAME`` and ``q[NAME]`` (results CSV) read alike; other columns ignored; values
    read back exactly (17 digits)."""
    t = np.linspace(0, 1, 5)
    q = np.column_stack([np.sin(t), np.cos(t) / 3])
    tau = np.column_stack([t * 0.1, t ** 2])
    header = ["current", "tau.elbow.angle", "q[shoulder.angle]", "t", "q.elbow.angle",
              "tau[shoulder.angle]"]
    rows = [[1.0, repr(float(tau[k, 1])), repr(float(q[k, 0])), repr(float(t[k])),
             repr(float(q[k, 1])), repr(float(tau[k, 0]))]
            for k in range(5)]
    path = tmp_path / "m.csv"
    path.write_text(_text(header, rows))
    meas = mio.read_measurements(path, COORDS)
    assert np.array_equal(meas.q, q) and np.array_equal(meas.tau, tau)
    assert np.array_equal(meas.t, t) and meas.v is None and meas.a is None


@pytest.mark.parametrize("header, rows, message", [
    (["t", "q.shoulder.angle", "tau.shoulder.angle", "tau.elbow.angle"], [[0, 0, 0, 0]],
     r"m\.csv: missing column 'q\.elbow\.angle'"),
    (["t", "q.shoulder.angle", "q.elbow.angle", "tau.shoulder.angle", "tau.elbow.angle",
      "q.wrist.angle"], [[0, 0, 0, 0, 0, 0]],
     r"column 'q\.wrist\.angle' \(column 6\) names no coordinate"),
    (["q.shoulder.angle", "q.elbow.angle", "tau.shoulder.angle", "tau.elbow.angle"],
     [[0, 0, 0, 0]], r"no column 't'"),
    (["t", "q.shoulder.angle", "q.elbow.angle", "tau.shoulder.angle", "tau.elbow.angle"],
     [[0, 0, 0, 0, 0], [0.1, 0, "nan", 0, 0]],
     r"m\.csv line 3 column 'q\.elbow\.angle': nan is not a finite number"),
    (["t", "q.shoulder.angle", "q.elbow.angle", "tau.shoulder.angle", "tau.elbow.angle"],
     [[0, 0, 0, 0, 0], [0.1, 0, "x1", 0, 0]],
     r"m\.csv line 3 column 'q\.elbow\.angle': 'x1' is not a number"),
    (["t", "q.shoulder.angle", "q.elbow.angle", "tau.shoulder.angle", "tau.elbow.angle"],
     [[0, 0, 0, 0, 0], [0.1, 0, 0, 0]], r"m\.csv line 3: 4 fields, the header has 5"),
    (["t", "q.shoulder.angle", "q.elbow.angle", "tau.shoulder.angle", "tau.elbow.angle"],
     [[0, 0, 0, 0, 0], [0, 0, 0, 0, 0]], r"line 3 column 't': time 0 does not increase"),
    (["t", "q.shoulder.angle", "q.elbow.angle", "v.shoulder.angle", "v.elbow.angle",
      "tau.shoulder.angle", "tau.elbow.angle"], [[0, 0, 0, 0, 0, 0, 0]],
     r"'v\.' columns without 'a\.' columns"),
])
def test_bad_files_are_named(tmp_path, header, rows, message):
    path = tmp_path / "m.csv"
    path.write_text(_text(header, rows))
    with pytest.raises(IdentificationError, match=message):
        mio.read_measurements(path, COORDS)


def test_missing_empty_and_too_large(tmp_path, monkeypatch):
    with pytest.raises(IdentificationError, match="not found"):
        mio.read_measurements(tmp_path / "absent.csv", COORDS)
    (tmp_path / "e.csv").write_text("")
    with pytest.raises(IdentificationError, match="empty file"):
        mio.read_measurements(tmp_path / "e.csv", COORDS)
    monkeypatch.setattr(mio, "MAX_MEASUREMENT_BYTES", 10)
    (tmp_path / "big.csv").write_text("t,q.shoulder.angle\n" + "0,0\n" * 10)
    with pytest.raises(LimitError, match=r"big\.csv"):
        mio.read_measurements(tmp_path / "big.csv", COORDS)


def test_fifo_and_folder_are_refused_unread(tmp_path):
    """A named pipe is refused before it is opened (no hang), a folder by name."""
    import os

    fifo = tmp_path / "pipe.csv"
    os.mkfifo(fifo)
    with pytest.raises(IdentificationError, match="is a FIFO"):
        mio.read_measurements(fifo, COORDS)
    with pytest.raises(IdentificationError, match="measurement file"):
        mio.read_measurements(tmp_path, COORDS)

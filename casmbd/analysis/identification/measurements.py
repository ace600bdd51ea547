"""Sampled joint measurements for identification, and their filtering and differentiation.

A :class:`Measurements` holds the samples of one experiment on the model's coordinates:
times t (N), positions q (N × n), and optionally velocities v, accelerations a and the
measured generalized efforts τ (joint torques and forces, N × n each).  Reading them from a
CSV file is :func:`casmbd.io.measurement_csv.read_measurements` (the io layer); this module only
computes.

:func:`prepare` turns them into the (q, q̇, q̈, τ) samples the regressor needs:

* given v and a, they are used as measured (the same low-pass, if a cut-off is given, is
  applied to every channel alike);
* given q only, q is low-passed with a zero-phase Butterworth filter (order
  :data:`FILTER_ORDER`, ``scipy.signal.butter`` + ``filtfilt``: forward and backward, so no
  phase lag and the squared magnitude response), then differentiated by second-order central
  differences, q̇_k = (q_{k+1} − q_{k−1}) / (2 h), q̈_k = (q̇_{k+1} − q̇_{k−1}) / (2 h) (the
  filter removes the noise the differences would amplify: each difference multiplies the
  noise at frequency ω by up to 1/h);
* τ receives the *same* filter as q (Gautier's parallel filtering, Gautier 1997, "Dynamic
  identification of robots with power model", and Gautier & Poignet 2001): the regressor is
  linear in its samples only when the measured τ and the differentiated q have been filtered
  alike, so the fitted equation Y(q_f, q̇_f, q̈_f) π = τ_f holds to the filter's pass-band
  accuracy;
* ``filtfilt`` pads each end with the odd reflection of 3 / f_c seconds of the signal
  (``padlen``), and the first and last 2 / f_c seconds (at least :data:`EDGE_SAMPLES`
  samples) are dropped after filtering and differentiating: the start-up transients of the
  filter at both ends (an error of 3e-9 rad left on a 0.5 Hz arm trajectory at f_c = 10 Hz
  against 2e-2 rad without padding) and the one-sided differences; then the samples are
  decimated: every ``decimate``-th sample is kept (after the low-pass, so no aliasing when the
  cut-off is below the decimated Nyquist frequency f_s / (2 · decimate); otherwise refused);
* with Coulomb friction, :func:`velocity_reversals` marks, per joint, the samples within
  1 / f_c seconds of a change of sign of the filtered velocity: there the filtered τ holds
  the Coulomb step smeared over the filter's response while the regressor sees
  tanh(q̇_f / v_s) of the filtered velocity, a mismatch of up to the Coulomb level (the
  model of friction is the poorest at velocity reversals anyway); those rows are left out
  of the least squares.

Sampling must be uniform for the filter and the differences (the times may not deviate from
the mean step by more than :data:`UNIFORM_TOLERANCE` of it).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from casmbd.errors import IdentificationError

__all__ = ["EDGE_SAMPLES", "FILTER_ORDER", "UNIFORM_TOLERANCE", "Measurements", "prepare",
           "velocity_reversals"]

#: order of the Butterworth low-pass (applied forward and backward: order 8 in magnitude)
FILTER_ORDER = 4
#: samples dropped at each end after filtering and differentiating (times the decimation)
EDGE_SAMPLES = 10
#: largest deviation of a sampling interval from the mean one, relative
UNIFORM_TOLERANCE = 1e-6


@dataclass
class Measurements:
    """The samples of one experiment (module docstring).

    Attributes
    ----------
    t : ndarray (N,)
        Sample times [s], increasing.
    q : ndarray (N, n)
        Positions of the coordinates ``coordinates`` (rad or m).
    v, a : ndarray (N, n) or None
        Velocities and accelerations, when measured (or computed elsewhere).
    tau : ndarray (N, n)
        Measured generalized efforts on the coordinates (N m or N).
    coordinates : list of str
        casmbd's coordinate names, in the model's order.
    source : str
        Where the samples came from (a file name), for messages.
    """

    t: np.ndarray
    q: np.ndarray
    tau: np.ndarray
    v: np.ndarray | None = None
    a: np.ndarray | None = None
    coordinates: list[str] = field(default_factory=list)
    source: str = "<measurements>"

    def __post_init__(self):
        self.t = np.asarray(self.t, dtype=float).reshape(-1)
        n_t = self.t.size
        for key in ("q", "tau", "v", "a"):
            value = getattr(self, key)
            if value is None:
                continue
            arr = np.asarray(value, dtype=float)
            if arr.ndim == 1:
                arr = arr.reshape(-1, 1)
            if arr.ndim != 2 or arr.shape[0] != n_t:
                raise IdentificationError(f"{self.source}: '{key}' must have one row per "
                                          f"sample ({n_t}), got shape {arr.shape}")
            bad = np.argwhere(~np.isfinite(arr))
            if bad.size:
                row, col = bad[0]
                name = (self.coordinates[col] if col < len(self.coordinates) else str(col))
                raise IdentificationError(f"{self.source}: '{key}.{name}' is not finite at "
                                          f"sample {row} (t = {self.t[row]:.6g})")
            setattr(self, key, arr)
        n = self.q.shape[1]
        if not self.coordinates:
            self.coordinates = [f"q{k}" for k in range(n)]
        for key in ("tau", "v", "a"):
            value = getattr(self, key)
            if value is not None and value.shape[1] != n:
                raise IdentificationError(f"{self.source}: '{key}' has {value.shape[1]} "
                                          f"columns, q has {n}")
        if not np.all(np.isfinite(self.t)) or np.any(np.diff(self.t) <= 0.0):
            raise IdentificationError(f"{self.source}: the times 't' must be finite and "
                                      "increasing")


def sampling_step(t: np.ndarray, source: str) -> float:
    """The uniform sampling interval of ``t``, refused when the sampling is not uniform."""
    if t.size < 2:
        raise IdentificationError(f"{source}: at least two samples are needed")
    steps = np.diff(t)
    h = float(np.mean(steps))
    worst = int(np.argmax(np.abs(steps - h)))
    if abs(steps[worst] - h) > UNIFORM_TOLERANCE * h:
        raise IdentificationError(
            f"{source}: the sampling is not uniform (interval {steps[worst]:.6g} s at sample "
            f"{worst} against the mean {h:.6g} s); filtering and differentiation need uniform "
            "samples: resample the data first")
    return h


def lowpass(x: np.ndarray, h: float, cutoff: float, source: str) -> np.ndarray:
    """Zero-phase Butterworth low-pass of the columns of ``x`` (``filtfilt``, order
    :data:`FILTER_ORDER`, cut-off ``cutoff`` Hz at sampling interval ``h``)."""
    from scipy.signal import butter, filtfilt

    nyquist = 0.5 / h
    if not 0.0 < cutoff < nyquist:
        raise IdentificationError(f"{source}: the filter cut-off {cutoff:.6g} Hz must lie "
                                  f"between 0 and the Nyquist frequency {nyquist:.6g} Hz")
    b, a = butter(FILTER_ORDER, cutoff / nyquist)
    least = 3 * max(len(a), len(b))
    if x.shape[0] <= least:
        raise IdentificationError(f"{source}: {x.shape[0]} samples are too few for the "
                                  f"filter (more than {least} needed)")
    pad = min(x.shape[0] - 1, max(least, math.ceil(3.0 / (cutoff * h))))
    return filtfilt(b, a, x, axis=0, padlen=pad)


def velocity_reversals(t: np.ndarray, v: np.ndarray, window: float) -> np.ndarray:
    """(N, n) booleans: True where sample k of joint j lies within ``window`` seconds of a
    change of sign of v_j (module docstring)."""
    near = np.zeros(v.shape, dtype=bool)
    for j in range(v.shape[1]):
        flips = np.nonzero(np.signbit(v[1:, j]) != np.signbit(v[:-1, j]))[0]
        for k in flips:
            mid = 0.5 * (t[k] + t[k + 1])
            near[:, j] |= np.abs(t - mid) <= window
    return near


def central_difference(x: np.ndarray, h: float) -> np.ndarray:
    """Second-order central differences (x_{k+1} − x_{k−1}) / (2h), one-sided second-order
    at the ends (``numpy.gradient``, ``edge_order=2``)."""
    return np.gradient(x, h, axis=0, edge_order=2)


def prepare(meas: Measurements, cutoff: float | None = None, decimate: int = 1,
            edge: int = EDGE_SAMPLES) -> tuple[np.ndarray, ...]:
    """The samples (t, q, q̇, q̈, τ) for the regressor (module docstring).

    Parameters
    ----------
    meas : Measurements
    cutoff : float, optional
        Low-pass cut-off [Hz]; required when ``meas`` has no velocities or accelerations.
        None with measured v and a: the samples are used as they are.
    decimate : int
        Keep every ``decimate``-th sample after filtering.
    edge : int
        Samples dropped at each end (times ``decimate``) when filtering or differentiating.

    Returns
    -------
    t, q, v, a, tau : ndarray
        Rows are samples.
    """
    decimate = int(decimate)
    if decimate < 1:
        raise IdentificationError(f"{meas.source}: decimate must be a positive integer, got "
                                  f"{decimate}")
    t, q, tau, v, a = meas.t, meas.q, meas.tau, meas.v, meas.a
    differentiate = v is None or a is None
    if differentiate and cutoff is None:
        raise IdentificationError(
            f"{meas.source}: without measured velocities and accelerations ('v.' and 'a.' "
            "columns) q is differentiated: give the low-pass cut-off (cutoff=…, "
            "--cutoff HZ)")
    if cutoff is not None:
        h = sampling_step(t, meas.source)
        if decimate > 1 and cutoff >= 0.5 / (h * decimate):
            raise IdentificationError(
                f"{meas.source}: the cut-off {cutoff:.6g} Hz is above the Nyquist frequency "
                f"{0.5 / (h * decimate):.6g} Hz of the samples decimated by {decimate}: "
                "lower the cut-off or the decimation")
        q = lowpass(q, h, cutoff, meas.source)
        tau = lowpass(tau, h, cutoff, meas.source)
        if differentiate:
            v = central_difference(q, h)
            a = central_difference(v, h)
        else:
            v = lowpass(v, h, cutoff, meas.source)
            a = lowpass(a, h, cutoff, meas.source)
        drop = max(edge * decimate, math.ceil(2.0 / (cutoff * h)))
        if t.size <= 2 * drop:
            raise IdentificationError(f"{meas.source}: {t.size} samples leave none after "
                                      f"dropping {drop} at each end")
        keep = slice(drop, t.size - drop, decimate)
    else:
        keep = slice(0, t.size, decimate)
    return t[keep], q[keep], v[keep], a[keep], tau[keep]

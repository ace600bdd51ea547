"""How many frames an animation shows, which output steps, and for how long.

Drawing a frame costs milliseconds and a GIF kilobytes whatever the output grid, so the frame
count follows the playback, not the result: real time (or ``speed`` × real time) at no more
than :data:`FPS_CAP` frames per second and at most :data:`FRAME_BUDGET` frames, sampled at
evenly spaced times (issue 19: drawing all 1001 outputs of a 10 s run took 100 s, made a 4-7 MB
GIF and played 3.3 times slower than real time).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from casmbd.errors import AnalysisError

#: Default highest frame rate [frames/s]: real-time playback at up to 30 frames per second.
FPS_CAP = 30.0
#: Default size budget [frames]: 10 s of playback at 30 fps.  At the default size (5.6 × 4.2 in
#: at 80 dpi) a planar GIF takes 1-3 kB per frame, so the default stays under about 1 MB;
#: longer results play in real time at a lower frame rate.
FRAME_BUDGET = 301
#: Fastest frame rate of a GIF: delays are whole hundredths of a second and browsers show
#: delays under 0.02 s as 0.1 s.
GIF_MAX_FPS = 50.0


@dataclass(frozen=True)
class FramePlan:
    """Which output steps an animation shows and for how long (see :func:`plan_frames`).

    Attributes
    ----------
    indices : ndarray of int
        Output steps shown, first and last output included.
    times : ndarray
        Their output times [s].
    speed : float
        Playback speed factor (1 = real time).
    playback : float
        Seconds from the first to the last frame: (t_last - t_first) / speed.
    n_outputs : int
        Output times of the result.
    limit : str
        What fixed the frame count: "outputs", "fps", "budget" or "max_frames".
    """

    indices: np.ndarray
    times: np.ndarray
    speed: float
    playback: float
    n_outputs: int
    limit: str

    @property
    def fps(self) -> float:
        """Mean frame rate [frames/s] (10 for a single frame)."""
        n = len(self.indices)
        return (n - 1) / self.playback if n > 1 and self.playback > 0 else 10.0

    def delays_ms(self, tick: float = 0.0) -> np.ndarray:
        """How long each frame is shown [ms]: the time to the next frame divided by the
        speed; the last frame for the mean delay.  With ``tick`` > 0 (10 for a GIF) the
        delays are whole ticks rounded so that their running sum keeps real time (each frame
        appears within half a tick of its time)."""
        start = (self.times - self.times[0]) / self.speed * 1000.0
        last = 1000.0 / self.fps
        if tick > 0:
            start = np.round(start / tick) * tick
            last = max(tick, round(last / tick) * tick)
        return np.append(np.diff(start), last)

    def describe(self) -> str:
        """One line: the frames, rate and speed chosen, and how to change them."""
        pace = "real time" if self.speed == 1 else f"{self.speed:g}× real time"
        why = {"budget": f", size budget {FRAME_BUDGET} frames", "max_frames": ", --max-frames",
               "outputs": ", every output time"}.get(self.limit, "")
        return (f"animate: {len(self.indices)} of {self.n_outputs} output times at "
                f"{self.fps:.3g} fps{why}, {pace} ({self.playback:.3g} s); "
                "--max-frames / --fps / --speed to change")


def plan_frames(t, max_frames: int | None = None, fps: float | None = None,
                speed: float = 1.0) -> FramePlan:
    """Output steps for playback at ``speed`` × real time and at most ``fps`` frames/s.

    frames = min(output times, round(duration / speed × fps) + 1, max_frames), with
    ``fps`` defaulting to :data:`FPS_CAP` and ``max_frames`` to :data:`FRAME_BUDGET` (the
    drawing time and file size grow with the frames, not with the output times).  The frames
    are the output times nearest to evenly spaced times from the first output to the last, so
    the motion plays at an even pace on any output grid.

    Raises
    ------
    AnalysisError
        For no output times, ``max_frames`` < 1 or a ``speed`` that is not finite and > 0.
    """
    t = np.asarray(t, float).ravel()
    n_t = len(t)
    if n_t == 0:
        raise AnalysisError("animation: the result has no output times")
    if max_frames is not None and max_frames < 1:
        raise AnalysisError(f"max_frames (--max-frames) must be >= 1, got {max_frames}")
    if not (isinstance(speed, (int, float, np.number)) and np.isfinite(speed) and speed > 0):
        raise AnalysisError(f"animation: speed (--speed) must be a finite number > 0, "
                            f"got {speed!r}")
    duration = float(t[-1] - t[0])
    playback = duration / speed
    if n_t == 1 or not duration > 0:
        return FramePlan(np.zeros(1, int), t[:1], float(speed), 0.0, n_t, "outputs")
    counts = {"outputs": n_t,
              "fps": round(playback * (fps or FPS_CAP)) + 1,
              "max_frames" if max_frames is not None else "budget":
                  max_frames if max_frames is not None else FRAME_BUDGET}
    limit = min(counts, key=lambda key: (counts[key], key != "outputs"))
    n = counts[limit]
    if n == 1:
        idx = np.zeros(1, int)
    else:
        targets = t[0] + duration * np.arange(n) / (n - 1)
        right = np.clip(np.searchsorted(t, targets), 1, n_t - 1)
        left = right - 1
        idx = np.where(targets - t[left] <= t[right] - targets, left, right)
        idx[0], idx[-1] = 0, n_t - 1
    return FramePlan(idx.astype(int), t[idx], float(speed), playback, n_t, limit)


__all__ = ["FPS_CAP", "FRAME_BUDGET", "GIF_MAX_FPS", "FramePlan", "plan_frames"]

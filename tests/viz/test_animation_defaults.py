"""Animation defaults (issue 19 item 1): real-time playback at no more than 30 fps within a
frame budget, frames at evenly spaced times, GIF delays that add up to duration / speed, the
overrides --max-frames / --fps / --speed, the line saying what was chosen, a progress bar per
frame."""

from __future__ import annotations

import json
import pathlib

import numpy as np
import pytest

import casmbd
from casmbd import cli, progress
from casmbd.errors import AnalysisError
from casmbd.viz import animation
from casmbd.viz.animation import animate, save_animation
from casmbd.viz.playback import FPS_CAP, FRAME_BUDGET, plan_frames

Image = pytest.importorskip("PIL.Image")

ROOT = pathlib.Path(__file__).resolve().parents[2]
PENDULUM = ROOT / "examples" / "double_pendulum.toml"


@pytest.fixture(scope="module")
def run2s(tmp_path_factory):
    """Double pendulum, 2 s, 201 output times, scene embedded; and its .npz file."""
    with pytest.MonkeyPatch.context() as mp:
        mp.setenv("CASMBD_COMPILE", "0")
        mech = casmbd.load_scene(PENDULUM)
        result = casmbd.simulate(mech, t_end=2.0, steps=200).attach_scene(mech)
    path = tmp_path_factory.mktemp("anim") / "dp.npz"
    result.save(path)
    return result, path


def gif_delays(path) -> list[int]:
    """Every frame's duration [ms] as Pillow reads it back."""
    with Image.open(path) as im:
        delays = []
        for i in range(im.n_frames):
            im.seek(i)
            delays.append(int(im.info["duration"]))
    return delays


# ---------------------------------------------------------------------- the frame plan
def test_ten_seconds_of_1001_outputs_give_301_evenly_spaced_frames():
    """round(10 s × 30 fps) + 1 = 301 frames; first and last output included; frame times
    evenly spaced to within half an output step (0.005 s) of 10/300 s."""
    t = np.linspace(0.0, 10.0, 1001)
    plan = plan_frames(t)
    assert len(plan.indices) == 301 == FRAME_BUDGET
    assert plan.indices[0] == 0 and plan.indices[-1] == 1000
    targets = np.linspace(0.0, 10.0, 301)
    assert np.max(np.abs(plan.times - targets)) <= 0.005 + 1e-12
    np.testing.assert_array_equal(plan.times, t[plan.indices])
    assert plan.fps == pytest.approx(FPS_CAP, rel=1e-12)
    assert plan.playback == pytest.approx(10.0, rel=1e-12)
    assert plan.describe() == ("animate: 301 of 1001 output times at 30 fps, real time (10 s); "
                               "--max-frames / --fps / --speed to change")


def test_short_result_shows_every_output_and_long_one_keeps_the_budget():
    short = plan_frames(np.linspace(0.0, 0.5, 13))  # 0.5 s × 30 fps + 1 = 16 > 13 outputs
    np.testing.assert_array_equal(short.indices, np.arange(13))
    assert short.fps == pytest.approx(12 / 0.5, rel=1e-12)
    assert "every output time" in short.describe()
    long = plan_frames(np.linspace(0.0, 60.0, 6001))  # 1801 frames at 30 fps: over budget
    assert len(long.indices) == FRAME_BUDGET
    assert long.fps == pytest.approx(300 / 60.0, rel=1e-12)  # still real time, fewer fps
    assert np.all(np.diff(long.indices) == 20)  # 6000 / 300 output steps apart, exactly
    assert f"size budget {FRAME_BUDGET} frames" in long.describe()


def test_overrides_max_frames_fps_speed():
    t = np.linspace(0.0, 10.0, 1001)
    fast = plan_frames(t, fps=10.0, speed=2.0)  # 5 s of playback × 10 fps + 1
    assert len(fast.indices) == 51 and np.all(np.diff(fast.indices) == 20)
    assert fast.fps == pytest.approx(10.0, rel=1e-12) and fast.playback == 5.0
    assert "2× real time (5 s)" in fast.describe()
    few = plan_frames(t, max_frames=11)
    np.testing.assert_array_equal(few.indices, np.arange(0, 1001, 100))
    assert few.fps == pytest.approx(1.0, rel=1e-12) and "--max-frames," in few.describe()
    with pytest.raises(AnalysisError, match=r"speed \(--speed\).*got 0"):
        plan_frames(t, speed=0)
    with pytest.raises(AnalysisError, match=r"max_frames \(--max-frames\) must be >= 1"):
        plan_frames(t, max_frames=0)


def test_uneven_output_grid_frames_follow_time():
    """On a non-uniform grid the frames are the outputs nearest to evenly spaced times."""
    t = np.concatenate([np.linspace(0.0, 1.0, 1001), np.linspace(1.1, 2.0, 10)])
    plan = plan_frames(t, fps=10.0)  # 2 s × 10 fps + 1 = 21 frames
    assert len(plan.indices) == 21
    assert np.max(np.abs(plan.times - np.linspace(0.0, 2.0, 21))) <= 0.05 + 1e-12


# ---------------------------------------------------------------------- the GIF written
@pytest.mark.parametrize("kwargs, frames, playback", [
    ({}, 61, 2.0),                             # real time at 30 fps
    ({"speed": 2.0, "fps": 10.0}, 11, 1.0),    # twice as fast at 10 fps
    ({"max_frames": 7, "speed": 0.5}, 7, 4.0),  # slow motion, 7 frames
])
def test_gif_delays_add_up_to_duration_over_speed(run2s, tmp_path, kwargs, frames, playback):
    """Each frame appears within half a GIF tick (5 ms) of (t_k - t_0) / speed, so the frames
    before the last last duration / speed within 5 ms and the whole loop within one frame
    more."""
    result, _ = run2s
    anim = animate(result, **kwargs)
    out = save_animation(anim, tmp_path / "a.gif", dpi=30)
    delays = gif_delays(out)
    assert len(delays) == frames == anim.casmbd_frames
    assert all(d % 10 == 0 and d >= 20 for d in delays)
    speed = kwargs.get("speed", 1.0)
    starts = np.concatenate([[0], np.cumsum(delays[:-1])])
    expected = (result.t[anim.casmbd_plan.indices] - result.t[0]) / speed * 1000.0
    assert np.max(np.abs(starts - expected)) <= 5.0 + 1e-9
    assert abs(sum(delays[:-1]) - 1000.0 * playback) <= 5.0 + 1e-9
    frame_ms = 1000.0 / anim.casmbd_fps
    assert abs(sum(delays) - 1000.0 * playback) <= frame_ms + 5.0


def test_gif_faster_than_50_fps_refused(run2s, tmp_path):
    result, _ = run2s
    anim = animate(result, fps=100.0)  # 201 frames over 2 s
    with pytest.raises(AnalysisError, match=r"a\.gif' at 100 frames/s: a GIF plays at most 50"):
        save_animation(anim, tmp_path / "a.gif", dpi=30)
    assert not (tmp_path / "a.gif").exists()


def test_progress_bar_counts_every_frame(run2s, tmp_path, monkeypatch):
    result, _ = run2s
    seen = []

    class Recorder:
        def __init__(self, total, desc, unit="it"):
            seen.append([total, desc, unit, 0])

        def update(self, n=1):
            seen[-1][3] += n

        def __enter__(self):
            return self

        def __exit__(self, *exc):
            return False

    monkeypatch.setattr(progress, "bar", Recorder)
    save_animation(animate(result, max_frames=9), tmp_path / "a.gif", dpi=30)
    assert seen == [[9, "animate a.gif", "frame", 9]]
    assert animation.progress is progress  # the bar comes from casmbd.progress


# ---------------------------------------------------------------------- the CLI
def test_cli_prints_its_choice_and_honours_overrides(run2s, tmp_path, capsys):
    _, npz = run2s
    gif = tmp_path / "a.gif"
    assert cli.main(["animate", str(npz), "--out", str(gif), "--dpi", "30"]) == 0
    out = capsys.readouterr().out.splitlines()
    assert out[0] == ("animate: 61 of 201 output times at 30 fps, real time (2 s); "
                      "--max-frames / --fps / --speed to change")
    assert len(gif_delays(gif)) == 61
    assert cli.main(["animate", str(npz), "--out", str(gif), "--dpi", "30", "--fps", "10",
                     "--speed", "4", "--json"]) == 0
    data = json.loads(capsys.readouterr().out)  # --json: the choice is in the object only
    assert (data["frames"], data["fps"], data["speed"]) == (6, 10.0, 4.0)
    assert data["playback_seconds"] == 0.5 and data["output_times"] == 201
    assert sum(gif_delays(gif)[:-1]) == 500
    assert cli.main(["animate", str(npz), "--out", str(gif), "--dpi", "30",
                     "--max-frames", "5"]) == 0
    assert capsys.readouterr().out.startswith("animate: 5 of 201 output times at 2 fps, "
                                              "--max-frames, real time (2 s)")
    assert len(gif_delays(gif)) == 5

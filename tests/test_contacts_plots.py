"""Plots of results whose mechanism has no joints (a free ball, a ball on a contact): the
default kinds skip what has nothing to show instead of failing (H8's finding: `casmbd plot`
raised TypeError on any such result)."""

from __future__ import annotations

from conftest import private_cache

from casmbd.cli import main

_cache = private_cache(CASMBD_COMPILE="0")

BALL = """
[scene]
name = "fall"
gravity = [0.0, -9.81]
[[bodies]]
name = "ball"
mass = 1.0
inertia = 0.004
position = [0.0, 1.1]
"""
FLOOR = """
[[contacts]]
name = "floor"
body = "ball"
point = [0.0, 1.1]
radius = 0.1
restitution = 0.5
"""


def test_plot_of_a_mechanism_without_joints(tmp_path):
    for k, text in enumerate((BALL, BALL + FLOOR)):
        scene = tmp_path / f"s{k}.toml"
        scene.write_text(text)
        npz, png = tmp_path / f"r{k}.npz", tmp_path / f"r{k}.png"
        assert main(["simulate", str(scene), "--t-end", "1", "--steps", "20",
                     "--out", str(npz)]) == 0
        assert main(["plot", str(npz), "--out", str(png)]) == 0
        assert png.stat().st_size > 1000

"""Screenshots of ``casmbd view`` (live page, headless Chromium) for docs/view.md.

Each example is simulated (or shown at its initial pose), served live, moved to a chosen time
with ``ViewHandle.set_time`` and photographed with the side panel.  Run
``python -m benchmarks.view_screenshots [--out docs/figures]``: writes ``view_<name>.png``.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
#: name -> (scene, t_end, steps or None for the initial pose, time shown, view options)
SHOTS = {
    "bouncing_ball": ("bouncing_ball.toml", 2.0, 400, 1.17, {}),
    "spinup_beam": ("spinup_beam.toml", 2.0, 200, 1.5, {"deformation_scale": 20.0}),
    "ur5_arm": ("ur5_arm.urdf", 5.0, 1000, 2.5, {}),
    "bricard": ("bricard.toml", None, None, 0.0, {}),
    "mesh_arm": ("../tests/robots/mesh_arm/mesh_arm.urdf", 2.0, 200, 1.0, {}),
}


def shoot(b, name: str, out: Path) -> Path:
    import casmbd
    from casmbd.viz.view_server import view
    from tests import browser_probe as bp

    scene, t_end, steps, t_show, options = SHOTS[name]
    mech = casmbd.load_scene(ROOT / "examples" / scene)
    source = mech
    if steps is not None:
        source = casmbd.simulate(mech, t_end=t_end, steps=steps)
        source.attach_scene(mech)
    bp.VIEWPORT.update(width=1280, height=860)
    with view(source, **options) as handle:
        handle.set_time(t_show)
        page = bp.Page(b, handle.url)
        page.page.wait_for_function("window.__scenes.length > 0", timeout=60_000)
        time.sleep(4.0)  # the scene's meshes and the new poses
        close = page.page.locator(".mantine-Notification-closeButton")
        if close.count():
            close.first.click()
            time.sleep(0.5)
        path = out / f"view_{name}.png"
        page.page.screenshot(path=str(path))
        page.close()
    return path


def main(argv=None) -> int:
    from tests import browser_probe as bp

    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", default=str(ROOT / "docs" / "figures"))
    parser.add_argument("--only", nargs="+", default=list(SHOTS))
    args = parser.parse_args(argv)
    reason = bp.unavailable()
    if reason:
        print(f"view_screenshots: {reason}", file=sys.stderr)
        return 1
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    with bp.browser() as b:
        for name in args.only:
            print(shoot(b, name, out))
    return 0


if __name__ == "__main__":
    sys.exit(main())

"""Screenshots of ``casmbd view`` (live page, headless Chromium) for docs/view.md.

Each example is simulated (or shown at its initial pose), served live, moved to a chosen time
with ``ViewHandle.set_time`` and photographed with the side panel.  Run
``python -m benchmarks.view_screenshots [--out docs/figures]``: writes ``view_<name>.png`` and
the "3-D views" section of docs/gallery.md (between its ``view:begin``/``view:end`` markers,
which ``examples/gallery.py`` keeps when it rewrites the page).
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
GALLERY = ROOT / "docs" / "gallery.md"
BEGIN, END = "<!-- view:begin -->", "<!-- view:end -->"
#: what each picture shows, for the gallery
ABOUT = {
    "mesh_arm": "A URDF robot with meshes (tests/robots/mesh_arm: STL, OBJ and a DAE in mm, "
                "primitives, named materials), its tool path traced.",
    "ur5_arm": "The UR5 arm of examples/ur5_arm.urdf falling under gravity (shapes from its "
               "joints and inertia: the file has no meshes).",
    "spinup_beam": "The spin-up beam (Simo and Vu-Quoc): the flexible beam's deformed nodes, "
                   "deformation drawn 20 times larger.",
    "bouncing_ball": "The bouncing ball on its contact plane, with the impacts marked on the "
                     "time slider.",
    "bricard": "Bricard's overconstrained mechanism at its initial pose.",
}
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
    if Path(args.out).resolve() == (ROOT / "docs" / "figures").resolve():
        write_gallery_section()
    return 0


def gallery_section() -> str:
    """The "3-D views" section of docs/gallery.md: each screenshot and the commands."""
    lines = [BEGIN, "## 3-D views (`casmbd view`)", "",
             "Screenshots of the live view in headless Chromium (docs/view.md), made by "
             "`python -m benchmarks.view_screenshots`. Each is what these commands show in "
             "the browser at the time given (`--html FILE` writes the same view as one file "
             "that plays offline).", ""]
    for name in SHOTS:
        scene, t_end, steps, t_show, options = SHOTS[name]
        path = (Path("examples") / scene).as_posix().replace("examples/../", "")
        flags = "".join(f" --{k.replace('_', '-')} {v:g}" for k, v in options.items())
        if steps is None:
            cmds = [f"casmbd view {path}{flags}"]
        else:
            cmds = [f"casmbd simulate {path} --t-end {t_end:g} --steps {steps} "
                    f"--out {name}.npz", f"casmbd view {name}.npz{flags}   # t = {t_show:g} s"]
        lines += [f"### {name}", "", ABOUT.get(name, ""), "",
                  f"![{name} in casmbd view](figures/view_{name}.png)", "", "```", *cmds,
                  "```", ""]
    return "\n".join([*lines, END])


def write_gallery_section() -> None:
    """Replace the block between the markers of docs/gallery.md (or add it after the title)."""
    from casmbd.atomic import atomic_write

    text = GALLERY.read_text(encoding="utf-8")
    if BEGIN in text and END in text:
        head, rest = text.split(BEGIN, 1)
        text = head + gallery_section() + rest.split(END, 1)[1]
    else:
        title, rest = text.split("\n", 1)
        text = f"{title}\n\n{gallery_section()}\n{rest}"
    atomic_write(GALLERY, lambda tmp: Path(tmp).write_text(text, encoding="utf-8"))


if __name__ == "__main__":
    sys.exit(main())

"""The ``view`` verb: the 3-D view of a scene, a result or an OCP solution in the browser.

``casmbd view SOURCE`` starts the live view (:func:`casmbd.viz.view_server.serve`, loopback
only) and prints its URL on **stderr** as soon as it listens (stdout keeps the verb's one
summary, or JSON object with ``--json``, printed when the view stops); Ctrl-C stops it
cleanly (exit status 0).  ``--html FILE`` writes one self-contained file instead
(:func:`casmbd.viz.view_html.write_html`) and prints what it holds.
"""

from __future__ import annotations

import sys
import webbrowser

from casmbd.cli.common import check_not_input, check_out_path, scene_files
from casmbd.model import Mechanism
from casmbd.viz.view_html import check_html_file, write_html
from casmbd.viz.view_scene import require_viser, view_summary
from casmbd.viz.view_server import load_source, make_view_model, serve


def _cmd_view(args) -> tuple[dict, str]:
    """Serve the view of ``args.source`` until Ctrl-C, or write it to ``--html``."""
    require_viser()  # before reading anything: the one missing-extra message
    check_out_path(args)  # --html is not the source file
    if args.html:
        check_html_file(args.html)
    source = load_source(args.source)
    if isinstance(source, Mechanism):
        check_not_input(args, scene_files(source, args.source))
    options = dict(deformation_scale=args.deformation_scale, forces=args.forces,
                   max_frames=args.max_frames)
    vm = make_view_model(source, **options)
    if args.html:
        data = write_html(vm, args.html, forces=args.forces)
        text = (f"saved {data['file']} ({data['bytes'] / 1e6:.2f} MB): {data['frames']} frames "
                f"from t = {data['t_start']:g} to {data['t_end']:g} s, {data['bodies']} bodies, "
                f"{data['shapes']} shapes; opens offline in a browser")
        return data, "\n".join([text, *(f"  note: {n}" for n in data["notes"])])
    rebuild = None
    if vm.flexible:
        def rebuild(scale: float):
            return make_view_model(source, **{**options, "deformation_scale": scale})
    handle = serve(vm, port=args.port, forces=args.forces, rebuild=rebuild,
                   deformation_scale=args.deformation_scale)
    try:  # from here on Ctrl-C is the way to stop, not an interrupt
        print(f"casmbd view: {handle.url}  ({vm.title or args.source}; Ctrl-C to stop)",
              file=sys.stderr, flush=True)
        for note in view_summary(vm)["notes"]:
            print(f"note: {note}", file=sys.stderr, flush=True)
        if not args.no_browser:
            try:
                webbrowser.open(handle.url)
            except Exception:  # no browser here: the URL is printed
                pass
        handle.wait()
    except KeyboardInterrupt:
        handle.stop()
    data = {"url": handle.url, **view_summary(vm)}
    return data, f"stopped the view at {handle.url}"

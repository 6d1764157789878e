"""The output room: what a run leaves behind, written atomically.

Modules: ``render`` (frames and the scenario picture) on ``canvas`` (pygame-ce
drawing) and ``playback`` (video timing), ``media`` (GIF, MP4, PNG), ``report`` (the
verdict and the HTML run page, ``templates/``) and ``files`` (output folders that
are replaced whole or not at all).  It imports the scenario and execute rooms.
"""

from ..lazy import lazy_exports

_WHERE = {
    **dict.fromkeys(("draw_scenario", "render_frames"), "render"),
    **dict.fromkeys(("write_gif", "write_mp4", "write_png", "write_video"), "media"),
    **dict.fromkeys(("run_page", "verdict", "write_run_page"), "report"),
    **dict.fromkeys(("OutputSet", "check_out_dir", "check_out_file"), "files"),
}

__all__ = sorted(_WHERE, key=str.lower)

__getattr__, __dir__ = lazy_exports(__name__, _WHERE)

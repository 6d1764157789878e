"""Renderer and video-writer speed on synthetic recordings, and the memory of a long video.

Run ``python -m bench.render_speed``.  Two recordings (11 and 100 robots,
60 s of sim time sampled at 60 Hz, robots on circles and back-and-forth
lines, a few contacts) are rendered with the default render settings, then
encoded as GIF (one shared palette) and MP4.  Times are scaled to 300 frames.
A second table compares the shared-palette GIF encoder with imageio's default
GIF writing (an adaptive palette per frame) on the same frames.

``--long N`` (default 3000) renders a video of about N frames (11 robots, at
real time) straight into GIF and MP4, as ``swarmform run`` does, in a fresh
process, and prints its wall time and peak resident memory; ``--long 0``
skips it.
"""

from __future__ import annotations

import argparse
import os
import platform
import subprocess
import sys
import tempfile
import time
from dataclasses import dataclass, replace
from importlib.metadata import PackageNotFoundError, version
from pathlib import Path

import numpy as np

from planner.problem import Circle, Polygon, Problem
from sim.output.media import has_mp4, write_gif, write_mp4, write_video
from sim.output.render import playback_speedup, render_frames
from sim.scenario.params import RenderParams


@dataclass(frozen=True)
class _Contact:
    time: float
    kind: str
    a: int
    b: int
    depth: float = 0.01
    witness: tuple[float, float] | None = None


def _recording(m: int, seconds: float = 60.0, rate: float = 60.0):
    """A problem and a recording ``(times, positions, contacts)`` of ``m`` moving robots.

    Robots sit on a square grid in a 20 x 20 workspace with two obstacles;
    even robots circle their grid point, odd ones move back and forth on a
    line, with periods between 8 and 20 s.
    """
    side = int(np.ceil(np.sqrt(m)))
    cell = 20.0 / side
    radius = min(0.5, 0.22 * cell)
    gx, gy = np.meshgrid(np.arange(side), np.arange(side))
    home = (np.stack([gx.ravel(), gy.ravel()], 1)[:m] + 0.5) * cell
    amp = 0.3 * cell
    t = np.arange(0.0, seconds + 1e-9, 1.0 / rate)
    period = 8.0 + 12.0 * (np.arange(m) % 7) / 6.0
    phase = 2 * np.pi * t[:, None] / period[None, :] + np.arange(m)[None, :]
    circle = np.stack([np.cos(phase), np.sin(phase)], -1)
    line = np.stack([np.sin(phase), np.zeros_like(phase)], -1)
    odd = (np.arange(m) % 2 == 1)[None, :, None]
    pos = home[None] + amp * np.where(odd, line, circle)
    problem = Problem(
        20.0,
        20.0,
        (
            Polygon(np.array([[9.0, 9.0], [11.0, 9.0], [11.0, 11.0], [9.0, 11.0]])),
            Circle((3.0, 17.0), 0.8),
        ),
        radius,
        0.05,
        pos[0],
        pos[-1],
    )
    contacts = [
        _Contact(12.0, "robot-robot", 0, min(1, m - 1)),
        _Contact(30.0, "robot-wall", m - 1, -1),
        _Contact(45.0, "robot-obstacle", m // 2, 0),
    ]
    return problem, t, pos, contacts


def _versions() -> str:
    def v(name):
        try:
            return version(name)
        except PackageNotFoundError:
            return "not installed"

    load = ", ".join(f"{x:.1f}" for x in os.getloadavg()) if hasattr(os, "getloadavg") else "?"
    return (
        f"platform: {platform.platform()} ({platform.machine()}, {os.cpu_count()} CPUs, "
        f"load average {load})\n"
        f"python: {sys.version.split()[0]}; pygame-ce {v('pygame-ce')}; imageio {v('imageio')}; "
        f"pillow {v('pillow')}; imageio-ffmpeg {v('imageio-ffmpeg')}; numpy {v('numpy')}"
    )


def _timed(fn, *args):
    t0 = time.perf_counter()
    out = fn(*args)
    return out, time.perf_counter() - t0


def _gif_error(path: Path, frames: list[np.ndarray]) -> tuple[float, float]:
    """Mean and 99.9th-percentile colour error (max over channels) of a GIF's frames."""
    import imageio.v3 as iio

    back = iio.imread(path, index=None)
    if len(back) != len(frames):  # identical consecutive frames were merged
        keep = [0] + [k for k in range(1, len(frames)) if not np.array_equal(frames[k], frames[k - 1])]
        frames = [frames[k] for k in keep]
    err = np.concatenate(
        [np.abs(b[..., :3].astype(np.int16) - f).max(axis=-1).ravel() for b, f in zip(back, frames)]
    )
    return float(err.mean()), float(np.percentile(err, 99.9))


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(prog="python -m bench.render_speed", description=__doc__.split("\n\n")[0])
    ap.add_argument("--robots", type=int, nargs="+", default=[11, 100], help="swarm sizes")
    ap.add_argument("--size", type=int, default=480, help="frame size [px]")
    ap.add_argument("--fps", type=int, default=20, help="video frame rate")
    ap.add_argument("--no-default", action="store_true", help="skip the (slow) per-frame palette comparison")
    ap.add_argument("--long", type=int, default=3000, metavar="N",
                    help="frames of the long-video memory run (0: skip; default 3000)")
    ap.add_argument("--child", type=int, default=None, help=argparse.SUPPRESS)
    args = ap.parse_args(argv)
    if args.child is not None:
        _long_child(args.child, args.size, args.fps)
        return

    print(_versions())
    print()
    params = replace(RenderParams(), size=args.size, fps=args.fps)
    rows = []
    kept = None
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        for m in args.robots:
            problem, t, pos, contacts = _recording(m)
            frames, t_render = _timed(
                lambda problem=problem, t=t, pos=pos, contacts=contacts, m=m: list(
                    render_frames(problem, t, pos, contacts, params, title=f"bench m={m}"))
            )  # held in memory here only to time drawing and encoding apart
            n = len(frames)
            per = 300.0 / n
            gif, t_gif = _timed(write_gif, tmp / f"m{m}.gif", frames, args.fps)
            err = _gif_error(gif, frames)
            if has_mp4():
                mp4, t_mp4 = _timed(write_mp4, tmp / f"m{m}.mp4", frames, args.fps)
                mp4_cell, mp4_size = f"{t_mp4 * per:.2f}", f"{mp4.stat().st_size / 1e6:.2f}"
            else:
                mp4_cell = mp4_size = "n/a"
            h, w = frames[0].shape[:2]
            speed = playback_speedup(t[-1] - t[0], params)
            rows.append(
                f"| {m} | {n} (x{speed:g}) | {w}x{h} | {t_render * per:.2f} | {t_gif * per:.2f} | "
                f"{mp4_cell} | {gif.stat().st_size / 1e6:.2f} | {mp4_size} | {err[0]:.2f} / {err[1]:.0f} |"
            )
            if kept is None:
                kept = frames[:300]
        print(f"{args.fps} fps, 60 s of sim time at 60 Hz; times in seconds per 300 frames, sizes in MB")
        print()
        print(
            "| robots | frames | size | render | GIF encode | MP4 encode | GIF MB | MP4 MB | "
            "GIF colour error mean / p99.9 |"
        )
        print("| ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: |")
        for r in rows:
            print(r)

        if not args.no_default and kept:
            import imageio.v3 as iio

            _, t_shared = _timed(write_gif, tmp / "shared.gif", kept, args.fps)
            _, t_default = _timed(
                lambda: iio.imwrite(
                    tmp / "default.gif", np.stack(kept), extension=".gif", duration=1000 / args.fps, loop=0
                )
            )
            print()
            print(f"GIF encoding of the same {len(kept)} frames ({args.robots[0]} robots):")
            print()
            print("| encoder | seconds | MB |")
            print("| --- | ---: | ---: |")
            print(f"| shared palette (write_gif) | {t_shared:.2f} | {(tmp / 'shared.gif').stat().st_size / 1e6:.2f} |")
            print(
                f"| imageio default (palette per frame) | {t_default:.2f} | "
                f"{(tmp / 'default.gif').stat().st_size / 1e6:.2f} |"
            )
            print()
            print(f"shared palette is {t_default / t_shared:.1f}x faster")

    if args.long > 0:
        print()
        print(f"Long video: about {args.long} frames of {args.size} px, 11 robots, rendered straight into GIF "
              f"and MP4 (write_video) in a fresh process:")
        print()
        print(_long_run(args.long, args.size, args.fps))


def _long_run(frames: int, size: int, fps: int) -> str:
    """Run :func:`_long_child` in a fresh process; its one-line result."""
    cmd = [sys.executable, "-m", "bench.render_speed", "--child", str(frames), "--size", str(size),
           "--fps", str(fps)]
    out = subprocess.run(cmd, capture_output=True, text=True, check=True)
    return out.stdout.strip()


def _peak_rss_mb() -> float:
    """This process's peak resident memory [MB] (Linux VmHWM: not inherited from the parent)."""
    try:
        for line in Path("/proc/self/status").read_text().splitlines():
            if line.startswith("VmHWM:"):
                return int(line.split()[1]) / 1024
    except OSError:
        pass
    import resource

    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024


def _long_child(frames: int, size: int, fps: int) -> None:
    problem, t, pos, contacts = _recording(11, seconds=frames / fps, rate=20.0)
    params = replace(RenderParams(), size=size, fps=fps, speedup=1.0)
    before = _peak_rss_mb()
    with tempfile.TemporaryDirectory() as tmp:
        t0 = time.perf_counter()
        fr = render_frames(problem, t, pos, contacts, params, title="long")
        paths = write_video(Path(tmp) / "long", fr, fps, ("gif", "mp4"))
        wall = time.perf_counter() - t0
        sizes = ", ".join(f"{p.suffix[1:].upper()} {p.stat().st_size / 1e6:.1f} MB" for p in paths)
    peak = _peak_rss_mb()
    print("| frames | wall time [s] | peak RSS [MB] | RSS before rendering [MB] | files |")
    print("| ---: | ---: | ---: | ---: | --- |")
    print(f"| {len(fr)} | {wall:.1f} | {peak:.0f} | {before:.0f} | {sizes} |")


if __name__ == "__main__":
    main()

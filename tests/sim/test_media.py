"""Video files: GIF with a shared palette, MP4, atomic writes, one pass over the frames."""

from pathlib import Path

import imageio.v3 as iio
import numpy as np
import pytest

from sim.output import gif, media
from sim.output.media import gif_durations, has_mp4, write_gif, write_mp4, write_png, write_video

needs_mp4 = pytest.mark.skipif(not has_mp4(), reason="imageio-ffmpeg is not installed")

COLOURS = np.array(
    [[248, 248, 244], [40, 40, 48], [230, 20, 20], [60, 120, 200], [90, 200, 110], [250, 200, 160]], np.uint8
)


def _frames(n=12, h=48, w=64):
    """Flat-coloured frames, each different from the one before: a square moving right."""
    out = []
    for k in range(n):
        f = np.empty((h, w, 3), np.uint8)
        f[:] = COLOURS[0]
        f[:4] = COLOURS[1]
        f[10:20, 2 + 3 * k : 12 + 3 * k] = COLOURS[2 + k % 4]
        out.append(f)
    return out


def _failing(frames, after):
    for k, f in enumerate(frames):
        if k == after:
            raise RuntimeError("renderer failed")
        yield f


def _leftovers(folder: Path, keep: set[str]):
    return sorted(p.name for p in folder.iterdir() if p.name not in keep)


def test_gif_round_trip_loops_and_keeps_frames_and_delays(tmp_path):
    frames = _frames()
    path = write_gif(tmp_path / "a.gif", iter(frames), fps=20)
    back = iio.imread(path, index=None)
    assert back.shape[:3] == (len(frames), 48, 64)
    assert np.array_equal(back[..., :3], np.stack(frames))  # few colours: exact
    assert iio.immeta(path, index=0)["loop"] == 0
    for k in range(len(frames)):
        assert iio.immeta(path, index=k)["duration"] == 50


def test_gif_delays_add_up_when_100_over_fps_is_not_whole(tmp_path):
    frames = _frames(n=30, w=128)
    path = write_gif(tmp_path / "b.gif", frames, fps=30)
    delays = [iio.immeta(path, index=k)["duration"] for k in range(30)]
    assert set(delays) <= {30, 40}
    assert sum(delays) == 1000
    assert gif_durations(3, 30) == [30, 40, 30]
    assert sum(gif_durations(301, 7)) == pytest.approx(301 / 7 * 1000, abs=10)


def test_gif_merges_a_held_end_into_one_longer_frame(tmp_path):
    frames = _frames(n=8)
    frames += [frames[-1]] * 10  # the end held for ten more frames
    path = write_gif(tmp_path / "c.gif", frames, fps=10)
    back = iio.imread(path, index=None)
    assert len(back) == 8
    delays = [iio.immeta(path, index=k)["duration"] for k in range(8)]
    assert delays == [100] * 7 + [1100]
    assert sum(delays) == len(frames) * 100


def test_gif_with_many_colours_stays_close(tmp_path):
    h, w = 40, 600
    ramp = np.linspace(0, 255, w)
    frames = []
    for k in range(6):
        f = np.empty((h, w, 3), np.uint8)
        f[..., 0] = ramp[None, :]
        f[..., 1] = ramp[None, ::-1]
        f[..., 2] = (ramp[None, :] * 0.5 + 20 * k) % 256
        frames.append(f)
    path = write_gif(tmp_path / "d.gif", frames, fps=10)
    back = iio.imread(path, index=None)[..., :3].astype(int)
    err = np.abs(back - np.stack(frames)).max(axis=-1)
    assert err.mean() < 6 and np.percentile(err, 99) < 20


def test_shared_palette_has_no_repeated_colour():
    frames = _frames()
    rng = np.random.default_rng(0)
    noisy = [rng.integers(0, 256, (32, 32, 3), dtype=np.uint8) for _ in range(3)]
    four = [np.repeat(COLOURS[:4], 4, axis=0).reshape(4, 4, 3)]
    for frames in (_frames(), noisy, four):
        pal = gif._shared_palette(frames)
        n = len(pal)
        assert n == len(np.unique(pal, axis=0)) <= 255
        assert n & (n - 1) != 0  # index n lies inside the colour table (a power of two)
    assert len(gif._shared_palette(four)) == 5


def test_failing_gif_write_leaves_no_file(tmp_path):
    path = tmp_path / "e.gif"
    with pytest.raises(RuntimeError, match="renderer failed"):
        write_gif(path, _failing(_frames(), after=5), fps=20)
    assert _leftovers(tmp_path, set()) == []


def test_failing_gif_write_keeps_the_older_file(tmp_path, monkeypatch):
    path = write_gif(tmp_path / "f.gif", _frames(n=3), fps=20)
    old = path.read_bytes()
    with pytest.raises(RuntimeError):
        write_gif(path, _failing(_frames(), after=5), fps=20)
    assert path.read_bytes() == old

    real = media._GifWriter._write
    calls = []

    def broken(self, *args):  # the encoder fails half-way through the file
        calls.append(1)
        if len(calls) == 3:
            raise OSError("disk full")
        real(self, *args)

    monkeypatch.setattr(media._GifWriter, "_write", broken)
    with pytest.raises(OSError, match="disk full"):
        write_gif(path, _frames(), fps=20)
    assert path.read_bytes() == old
    assert _leftovers(tmp_path, {"f.gif"}) == []


def test_bad_gif_input_is_named(tmp_path):
    with pytest.raises(ValueError, match="fps"):
        write_gif(tmp_path / "g.gif", _frames(), fps=60)
    with pytest.raises(ValueError, match="fps"):
        write_gif(tmp_path / "g.gif", _frames(), fps=0)
    with pytest.raises(ValueError, match="at least one frame"):
        write_gif(tmp_path / "g.gif", [], fps=10)
    with pytest.raises(ValueError, match=r"frames\[1\]"):
        write_gif(tmp_path / "g.gif", [_frames()[0], np.zeros((48, 64), np.uint8)], fps=10)
    assert _leftovers(tmp_path, set()) == []


@needs_mp4
def test_mp4_round_trip(tmp_path):
    frames = _frames(n=25)
    path = write_mp4(tmp_path / "a.mp4", iter(frames), fps=25)
    assert path == tmp_path / "a.mp4"
    back = list(iio.imiter(path, plugin="FFMPEG"))
    assert len(back) == 25 and back[0].shape == (48, 64, 3)
    meta = iio.immeta(path, plugin="FFMPEG")
    assert meta["fps"] == pytest.approx(25) and meta["codec"] == "h264"
    assert np.abs(back[10].astype(int) - frames[10]).mean() < 8  # lossy but close


@needs_mp4
def test_failing_mp4_write_keeps_the_older_file(tmp_path):
    path = write_mp4(tmp_path / "b.mp4", _frames(n=3), fps=10)
    old = path.read_bytes()
    with pytest.raises(RuntimeError, match="renderer failed"):
        write_mp4(path, _failing(_frames(), after=6), fps=10)
    assert path.read_bytes() == old
    assert _leftovers(tmp_path, {"b.mp4"}) == []
    with pytest.raises(ValueError, match="even"):
        write_mp4(tmp_path / "c.mp4", [np.zeros((47, 64, 3), np.uint8)], fps=10)
    assert _leftovers(tmp_path, {"b.mp4"}) == []


def test_mp4_without_imageio_ffmpeg_does_nothing(tmp_path, monkeypatch):
    monkeypatch.setattr(media, "has_mp4", lambda: False)
    pulled = []

    def frames():
        for f in _frames():
            pulled.append(1)
            yield f

    assert write_mp4(tmp_path / "a.mp4", frames(), fps=10) is None
    assert pulled == [] and _leftovers(tmp_path, set()) == []
    assert write_video(tmp_path / "v", frames(), 10, ["mp4"]) == []
    assert write_video(tmp_path / "v", frames(), 10, ["gif", "mp4"]) == [tmp_path / "v.gif"]


@needs_mp4
def test_write_video_reads_the_frames_once_for_every_format(tmp_path):
    pulled = []

    def frames():
        for f in _frames():
            pulled.append(1)
            yield f

    out = write_video(tmp_path / "run", frames(), 20, ("gif", "mp4"))
    assert out == [tmp_path / "run.gif", tmp_path / "run.mp4"]
    assert len(pulled) == 12
    assert len(iio.imread(out[0], index=None)) == 12
    assert sum(1 for _ in iio.imiter(out[1], plugin="FFMPEG")) == 12
    out = write_video(tmp_path / "only", frames(), 20, ["mp4"])
    assert out == [tmp_path / "only.mp4"]


def test_write_video_checks_formats_before_reading(tmp_path):
    pulled = []

    def frames():
        for f in _frames():
            pulled.append(1)
            yield f

    with pytest.raises(ValueError, match="formats"):
        write_video(tmp_path / "x", frames(), 20, ["gif", "webm"])
    assert pulled == []
    assert write_video(tmp_path / "x", frames(), 20, []) == []


def test_write_png_is_atomic(tmp_path):
    img = _frames(n=1)[0]
    path = write_png(tmp_path / "p.png", img)
    assert np.array_equal(iio.imread(path), img)
    with pytest.raises(TypeError):
        write_png(path, np.zeros((2, 2, 7, 3)))
    assert np.array_equal(iio.imread(path), img)
    assert _leftovers(tmp_path, {"p.png"}) == []


def test_rendered_run_to_gif(tmp_path):
    from planner.problem import Problem
    from sim.output.render import render_frames
    from sim.scenario.params import RenderParams

    p = Problem(6.0, 4.0, (), 0.3, 0.05, [[1, 1], [2, 1]], [[4, 3], [5, 3]])
    t = np.linspace(0.0, 4.0, 241)
    pos = p.start[None] + (t / 4.0)[:, None, None] * (p.target - p.start)[None]
    params = RenderParams(fps=10, size=160, video_seconds=4.0)
    frames = list(render_frames(p, t, pos, [], params))
    out = write_video(tmp_path / "run", iter(frames), params.fps, ["gif"])
    back = iio.imread(out[0], index=None)[..., :3]
    assert back.shape[0] == 41  # 41 drawn frames, the held end merged into the last
    for k in (0, 20, 40):
        err = np.abs(back[k].astype(int) - frames[k]).max(axis=-1)
        assert err.mean() < 0.5 and np.mean(err > 16) < 0.002
    delays = [iio.immeta(out[0], index=k)["duration"] for k in range(41)]
    assert sum(delays) == (41 + 10) * 100


def test_written_files_get_ordinary_permissions(tmp_path):
    import os

    mask = os.umask(0o022)
    os.umask(mask)
    path = write_gif(tmp_path / "m.gif", _frames(n=2), fps=10)
    assert path.stat().st_mode & 0o777 == 0o666 & ~mask


def test_gif_of_one_frame_and_of_one_held_frame(tmp_path):
    still = _frames(n=1)[0]
    one = write_gif(tmp_path / "one.gif", [still], fps=10)
    assert iio.immeta(one, index=0)["duration"] == 100 and iio.immeta(one)["loop"] == 0
    held = write_gif(tmp_path / "held.gif", [still] * 5, fps=10)
    assert len(iio.imread(held, index=None)) == 1
    assert iio.immeta(held, index=0)["duration"] == 500


# ----------------------------------------------------------------------------
# streaming: memory, palette sampling, long stills, progress


def _moving(n, h=96, w=128, late=None):
    """A generator of ``n`` frames (a square moving right); ``late = (k, colour)`` paints a
    small patch in that colour from frame ``k`` on."""
    for k in range(n):
        f = np.empty((h, w, 3), np.uint8)
        f[:] = COLOURS[0]
        f[:6] = COLOURS[1]
        x = 2 + (3 * k) % (w - 20)
        f[20:40, x : x + 12] = COLOURS[2 + k % 4]
        if late is not None and k >= late[0]:
            f[60:70, 60:70] = late[1]
        yield f


def _peak_bytes(fn) -> int:
    import tracemalloc

    tracemalloc.start()
    try:
        fn()
        return tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()


@pytest.mark.parametrize("formats", [("gif",), ("gif", "mp4")])
def test_write_video_memory_does_not_grow_with_the_frame_count(tmp_path, formats):
    if "mp4" in formats and not has_mp4():
        pytest.skip("imageio-ffmpeg is not installed")
    frame_bytes = 96 * 128 * 3
    few = _peak_bytes(lambda: write_video(tmp_path / "few", _moving(80), 20, formats))
    many = _peak_bytes(lambda: write_video(tmp_path / "many", _moving(800), 20, formats))
    assert many < few + 20 * frame_bytes, (few, many)
    assert len(iio.imread(tmp_path / "many.gif", index=None)) == 800
    # negative control: holding the frames is what this measurement sees
    held = _peak_bytes(lambda: list(_moving(800)))
    assert held > 700 * frame_bytes


def test_gif_palette_keeps_known_colours_that_appear_late(tmp_path):
    late = np.array([17, 200, 33], np.uint8)  # only from frame 150 on: after the sampled head
    hint = np.concatenate([COLOURS, late[None]])
    exact = write_gif(tmp_path / "hint.gif", _moving(200, late=(150, late)), 20, colours=hint)
    guessed = write_gif(tmp_path / "guess.gif", _moving(200, late=(150, late)), 20)
    back = iio.imread(exact, index=None)[..., :3]
    assert np.array_equal(back[-1][60:70, 60:70].reshape(-1, 3)[0], late)
    # negative control: from a one-shot stream, the palette never saw the late colour
    back = iio.imread(guessed, index=None)[..., :3]
    assert not np.array_equal(back[-1][60:70, 60:70].reshape(-1, 3)[0], late)
    # a sequence is sampled over its whole length: the late colour is found without a hint
    frames = list(_moving(200, late=(150, late)))
    seq = write_gif(tmp_path / "seq.gif", frames, 20)
    back = iio.imread(seq, index=None)[..., :3]
    assert np.array_equal(back[-1][60:70, 60:70].reshape(-1, 3)[0], late)


def test_gif_still_longer_than_one_delay_field_keeps_its_duration(tmp_path):
    still = _frames(n=1, h=8, w=8)[0]
    path = write_gif(tmp_path / "still.gif", [still] * 700, fps=1)  # 700 s: over 65535 cs
    delays = [iio.immeta(path, index=k)["duration"] for k in range(len(iio.imread(path, index=None)))]
    assert len(delays) == 2 and sum(delays) == 700_000
    back = iio.imread(path, index=None)[..., :3]
    assert all(np.array_equal(b, still) for b in back)


def test_write_video_reports_progress_for_a_sequence(tmp_path):
    seen = []
    write_video(tmp_path / "p", _frames(n=10), 10, ["gif"], progress=seen.append)
    assert seen == pytest.approx([k / 10 for k in range(1, 11)])
    seen.clear()
    write_video(tmp_path / "q", iter(_frames(n=10)), 10, ["gif"], progress=seen.append)
    assert seen == []  # length unknown: no fractions


def test_rendered_frames_stream_into_the_same_gif_as_a_list(tmp_path):
    from planner.problem import Problem
    from sim.output.render import render_frames
    from sim.scenario.params import RenderParams

    p = Problem(6.0, 4.0, (), 0.3, 0.05, [[1, 1], [2, 1]], [[4, 3], [5, 3]])
    t = np.linspace(0.0, 4.0, 241)
    pos = p.start[None] + (t / 4.0)[:, None, None] * (p.target - p.start)[None]
    fr = render_frames(p, t, pos, [], RenderParams(fps=10, size=160, video_seconds=4.0))
    a = write_gif(tmp_path / "a.gif", fr, 10)
    b = write_gif(tmp_path / "b.gif", list(fr), 10, colours=fr.colours)
    assert a.read_bytes() == b.read_bytes()

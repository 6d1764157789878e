"""Grid maps (MovingAI ``.map``, ROS map_server, PNG/PGM) and MovingAI ``.scen`` files.

A map's obstacles must cover every blocked cell and no free cell: blocked
cells lie inside the cover, free cell centres are at least ``cell / 2`` from
it, and the cover's area is the blocked area (so the free area is exactly
the free cells').  The benchmark maps of ``tests/data/maps`` load in bounded
time; small ROS and PNG maps plan and run end to end.
"""

from __future__ import annotations

import time
from pathlib import Path

import numpy as np
import pytest
from PIL import Image

from planner.geometry import Environment
from planner.problem import Polygon
from sim.runner import run_scenario
from sim.scenario import ScenarioError, build_problem, read_scenario
from sim.scenario.maps import MAX_PIECES, Grid, MapError, cover, read_grid

ROOT = Path(__file__).resolve().parents[2]
MAPS = ROOT / "tests" / "data" / "maps"
EXAMPLES = ROOT / "scenarios" / "maps"

TINY = """\
type octile
height 4
width 5
map
@...T
.O.G.
..W.S
@@...
"""
TINY_BLOCKED = np.array([
    [1, 0, 0, 0, 1],
    [0, 1, 0, 0, 0],
    [0, 0, 1, 0, 0],
    [1, 1, 0, 0, 0],
], bool)


def _rect_area(p: np.ndarray) -> float:
    x, y = p[:, 0], p[:, 1]
    return 0.5 * abs(float(np.dot(x, np.roll(y, -1)) - np.dot(np.roll(x, -1), y)))


def _check_cover(grid: Grid, cell: float) -> list[np.ndarray]:
    """The cover holds every blocked cell, keeps every free cell free, and has exactly the blocked area."""
    pieces = cover(grid, cell)
    env = Environment.build(grid.cols * cell, grid.rows * cell, [Polygon(p) for p in pieces])
    rows, cols = np.indices(grid.blocked.shape)
    centres = np.stack([(cols + 0.5) * cell, (grid.rows - rows - 0.5) * cell], axis=-1).reshape(-1, 2)
    blocked = grid.blocked.ravel()
    if pieces:
        inside = env._inside(centres).any(axis=1)
        assert np.array_equal(inside, blocked)
        d = _dist_to_polys(centres[~blocked], pieces)
        assert np.all(d >= cell / 2 - 1e-9), d.min()
    area = sum(_rect_area(p) for p in pieces)
    assert area >= blocked.sum() * cell**2 - 1e-9
    free_area = grid.cols * grid.rows * cell**2 - area  # the rectangles do not overlap
    assert free_area <= (~blocked).sum() * cell**2 + 1e-9
    return pieces


def _dist_to_polys(pts: np.ndarray, pieces: list[np.ndarray]) -> np.ndarray:
    from planner.geometry import point_segment_distance

    a = np.concatenate(pieces)
    b = np.concatenate([np.roll(p, -1, axis=0) for p in pieces])
    return point_segment_distance(pts[:, None, :], a[None], b[None]).min(axis=1)


def test_movingai_cells_and_cover(tmp_path):
    path = tmp_path / "tiny.map"
    path.write_text(TINY)
    grid = read_grid(path)
    assert np.array_equal(grid.blocked, TINY_BLOCKED)
    _check_cover(grid, 1.5)


def test_movingai_header_tabs_and_crlf(tmp_path):
    path = tmp_path / "tabs.map"
    path.write_bytes(b"type\toctile\r\nheight  2\r\nwidth\t3\r\nmap\r\n..@\r\nT..\r\n")
    assert read_grid(path).blocked.tolist() == [[False, False, True], [True, False, False]]


def test_movingai_lenient_forms_read_as_the_standard_one(tmp_path):
    """What converters write besides the standard form: width before height, ``Type Octile``,
    blanks after a row. Each reads as the plain file; a row one cell too long is still refused."""
    path = tmp_path / "odd.map"
    path.write_text("Type Octile\nwidth 3\nheight 2\nMAP\n..@  \nT..\t\n")
    assert read_grid(path).blocked.tolist() == [[False, False, True], [True, False, False]]
    path.write_text("type octile\nwidth 3\nheight 2\nmap\n..@.\nT..\n")
    with pytest.raises(MapError, match=r"row 1 \(line 5\): has 4 cells, but its header declares width 3"):
        read_grid(path)
    path.write_text("type octile\nwidth 3\nwidth 2\nmap\n..@\nT..\n")
    with pytest.raises(MapError, match=r"line 3: expected 'height'"):  # no height at all
        read_grid(path)


def test_movingai_byte_order_mark(tmp_path):
    """A map saved by an editor that writes a UTF-8 byte-order mark reads as without one."""
    path = tmp_path / "bom.map"
    path.write_bytes(b"\xef\xbb\xbftype octile\nheight 1\nwidth 2\nmap\n.@\n")
    assert read_grid(path).blocked.tolist() == [[False, True]]


def test_row_zero_is_the_top(tmp_path):
    path = tmp_path / "top.map"
    path.write_text("type octile\nheight 3\nwidth 2\nmap\n@.\n..\n..\n")
    (piece,) = cover(read_grid(path), 2.0)
    assert piece[:, 0].min() == 0 and piece[:, 0].max() == 2
    assert piece[:, 1].min() == 4 and piece[:, 1].max() == 6  # the top row of a 6-unit-high map


def test_benchmark_maps_cover_exactly():
    for f in sorted(MAPS.glob("*.map")):
        grid = read_grid(f)
        pieces = cover(grid, 1.0)
        assert sum(_rect_area(p) for p in pieces) == pytest.approx(grid.blocked.sum()), f.name


def test_cover_of_random_grids_is_exact():
    rng = np.random.default_rng(3)
    for _ in range(20):
        grid = Grid(rng.random((int(rng.integers(1, 12)), int(rng.integers(1, 12)))) < rng.uniform(0.1, 0.9))
        _check_cover(grid, float(rng.uniform(0.5, 3)))


def test_cover_refuses_too_many_pieces_quickly():
    checker = Grid((np.add.outer(np.arange(1024), np.arange(1024)) % 2) == 0)
    t = time.perf_counter()
    with pytest.raises(MapError, match=f"more than {MAX_PIECES} obstacle rectangles"):
        cover(checker, 0.5)
    assert time.perf_counter() - t < 2.0


def _tiny_scenario(tmp_path, extra: str, map_name="tiny.map", map_text=TINY) -> Path:
    (tmp_path / map_name).write_text(map_text)
    path = tmp_path / "s.yaml"
    path.write_text(f"map: {{file: {map_name}, cell: 3}}\nrobots: {{radius: 1.0, margin: 0.1}}\n{extra}")
    return path


def test_scen_starts_and_targets_are_cell_centres(tmp_path):
    (tmp_path / "a.scen").write_text(
        "version 1\n"
        "0\ttiny.map\t5\t4\t1\t0\t3\t1\t2.0\n"  # start (col 1, row 0) -> goal (col 3, row 1)
        "0\ttiny.map\t5\t4\t4\t3\t0\t1\t5.0\n"
        "0\ttiny.map\t5\t4\t2\t1\t2\t0\t1.0\n"
    )
    path = _tiny_scenario(tmp_path, "start: {scen: a.scen, count: 2}\ntarget: {scen: a.scen, count: 2}\n")
    s = read_scenario(path)
    assert (s.width, s.height) == (15.0, 12.0)
    assert s.count == 2
    assert s.start.points == ((4.5, 10.5), (13.5, 1.5))
    assert s.target.points == ((10.5, 7.5), (1.5, 7.5))
    problem = build_problem(s, np.random.default_rng(0))
    assert len(problem.obstacles) == len(cover(read_grid(tmp_path / "tiny.map"), 3.0))


def test_scen_without_a_version_line(tmp_path):
    """Older ``.scen`` files start with the first agent; a first line that is neither is refused."""
    (tmp_path / "a.scen").write_text("0\ttiny.map\t5\t4\t1\t0\t3\t1\t2.0\n0\ttiny.map\t5\t4\t4\t3\t0\t1\t5.0\n")
    path = _tiny_scenario(tmp_path, "start: {scen: a.scen, count: 2}\ntarget: {scen: a.scen, count: 2}\n")
    s = read_scenario(path)
    assert s.start.points == ((4.5, 10.5), (13.5, 1.5))
    (tmp_path / "a.scen").write_text("Version 1\n0\ttiny.map\t5\t4\t1\t0\t3\t1\t2.0\n")
    path = _tiny_scenario(tmp_path, "start: {scen: a.scen, count: 1}\ntarget: {scen: a.scen, count: 1}\n")
    assert read_scenario(path).start.points == ((4.5, 10.5),)
    (tmp_path / "a.scen").write_text("version 2\n0\ttiny.map\t5\t4\t1\t0\t3\t1\t2.0\n")
    with pytest.raises(ScenarioError, match=r"line 1: expected 'version 1'"):
        read_scenario(path)


def test_scen_checks_blocked_cells_and_sizes(tmp_path):
    (tmp_path / "a.scen").write_text("version 1\n0\ttiny.map\t5\t4\t0\t0\t3\t1\t2.0\n")
    path = _tiny_scenario(tmp_path, "start: {scen: a.scen, count: 1}\ntarget: {scen: a.scen, count: 1}\n")
    with pytest.raises(ScenarioError, match=r"start cell \(0, 0\) \(column, row from the top\) is blocked"):
        read_scenario(path)


def test_map_and_obstacles_add_up(tmp_path):
    path = _tiny_scenario(tmp_path, "obstacles: [{circle: {center: [7.5, 4.5], radius: 0.5}}]\n"
                                    "robots: {count: 2}\nstart: {points: [[4.5, 10.5], [13.5, 1.5]]}\n"
                                    "target: {points: [[10.5, 7.5], [13.5, 4.5]]}\n")
    text = path.read_text().replace("robots: {radius: 1.0, margin: 0.1}\n", "")
    path.write_text(text)
    s = read_scenario(path)
    assert len(s.obstacles) == len(cover(read_grid(tmp_path / "tiny.map"), 3.0)) + 1


def _pgm(path: Path, values: np.ndarray) -> None:
    Image.fromarray(values.astype(np.uint8)).save(path)


def _ros(tmp_path, values, negate=0, occ=0.65, free=0.196) -> Grid:
    _pgm(tmp_path / "m.pgm", values)
    (tmp_path / "m.yaml").write_text(f"image: m.pgm\nresolution: 0.5\norigin: [-1.0, 2.0, 0.0]\n"
                                     f"occupied_thresh: {occ}\nfree_thresh: {free}\nnegate: {negate}\n")
    return read_grid(tmp_path / "m.yaml")


def test_ros_thresholds_and_negate(tmp_path):
    values = np.array([[0, 100, 205, 254, 255]])
    g = _ros(tmp_path, values)
    assert g.cell == 0.5
    # occupancy (255 - p) / 255: 1.0, 0.61 (unknown: blocked), 0.196 (not < free_thresh: blocked), 0.004, 0
    assert g.blocked.tolist() == [[True, True, True, False, False]]
    g = _ros(tmp_path, values, negate=1)  # occupancy p / 255: 0, 0.39, 0.80, 1.0, 1.0
    assert g.blocked.tolist() == [[False, True, True, True, True]]
    g = _ros(tmp_path, values, occ=0.9, free=0.7)  # occupancy 0.61 is now free
    assert g.blocked.tolist() == [[True, False, False, False, False]]


def test_ros_map_saver_extras_and_colour(tmp_path):
    """Keys map_server does not read are ignored; a colour pixel's grey is its channels' mean."""
    rgb = np.full((1, 3, 3), 254, np.uint8)
    rgb[0, 0] = (0, 0, 0)
    rgb[0, 1] = (255, 255, 0)  # yellow: mean 170, occupancy 0.33 (unknown); its luminance 226 would be free
    Image.fromarray(rgb).save(tmp_path / "m.png")
    (tmp_path / "m.yaml").write_text("image: m.png\nmode: trinary\nresolution: 0.05\norigin: [-1.0, 2.0, 0.0]\n"
                                     "negate: 0\noccupied_thresh: 0.65\nfree_thresh: 0.25\n"
                                     "map_name: floor2\nsaved_by: map_saver_cli\n")
    assert read_grid(tmp_path / "m.yaml").blocked.tolist() == [[True, True, False]]
    # the same image read as a plain PNG: luminance against the threshold 128
    assert read_grid(tmp_path / "m.png").blocked.tolist() == [[True, False, False]]


def test_ros_cell_defaults_to_resolution(tmp_path):
    values = np.full((8, 12), 254)
    values[2:4, 3:9] = 0
    _pgm(tmp_path / "m.pgm", values)
    (tmp_path / "m.yaml").write_text("image: m.pgm\nresolution: 0.5\norigin: [0, 0, 0]\n"
                                     "occupied_thresh: 0.65\nfree_thresh: 0.196\nnegate: 0\n")
    path = tmp_path / "s.yaml"
    path.write_text("map: {file: m.yaml}\nrobots: {radius: 0.2, margin: 0.05, count: 2}\n"
                    "start: {points: [[0.5, 0.5], [5.5, 0.5]]}\ntarget: {points: [[0.5, 3.5], [5.5, 3.5]]}\n")
    s = read_scenario(path)
    assert (s.width, s.height) == (6.0, 4.0)
    (piece,) = s.obstacles
    assert piece.vertices[:, 0].min() == 1.5 and piece.vertices[:, 0].max() == 4.5
    assert piece.vertices[:, 1].min() == 2.0 and piece.vertices[:, 1].max() == 3.0  # rows 2-3 of 8, y flipped


@pytest.mark.parametrize("extra, cell, origin", [
    ("", "", (-3.0, 1.5)),                       # the ROS map's own origin
    ("", ", cell: 1.0", (-6.0, 3.0)),            # in workspace units: scaled by cell / resolution
    (", origin: [10, 20]", "", (10.0, 20.0)),    # map.origin wins
])
def test_map_origin_is_kept_for_the_plan_file(tmp_path, extra, cell, origin):
    values = np.full((8, 12), 254)
    _pgm(tmp_path / "m.pgm", values)
    (tmp_path / "m.yaml").write_text("image: m.pgm\nresolution: 0.5\norigin: [-3, 1.5, 0.3]\n"
                                     "occupied_thresh: 0.65\nfree_thresh: 0.196\nnegate: 0\n")
    path = tmp_path / "s.yaml"
    path.write_text(f"map: {{file: m.yaml{cell}{extra}}}\nrobots: {{radius: 0.2, margin: 0.05, count: 2}}\n"
                    "start: {points: [[0.5, 0.5], [5.5, 0.5]]}\ntarget: {points: [[0.5, 3.5], [5.5, 3.5]]}\n")
    s = read_scenario(path)
    assert s.map_origin == origin


def test_movingai_map_has_no_origin(tmp_path):
    (tmp_path / "t.map").write_text(TINY)
    path = tmp_path / "s.yaml"
    path.write_text("map: {file: t.map, cell: 2.4}\nrobots: {count: 1}\n"
                    "start: {points: [[3.6, 8.4]]}\ntarget: {points: [[6.0, 8.4]]}\n")
    assert read_scenario(path).map_origin is None


def test_png_threshold(tmp_path):
    rgb = np.full((2, 3, 3), 255, np.uint8)
    rgb[0, 0] = (0, 0, 0)
    rgb[0, 1] = (120, 120, 120)
    rgb[1, 2] = (200, 200, 200)
    Image.fromarray(rgb).save(tmp_path / "m.png")
    assert read_grid(tmp_path / "m.png").blocked.tolist() == [[True, True, False], [False, False, False]]
    assert read_grid(tmp_path / "m.png", threshold=100).blocked.tolist() == [[True, False, False],
                                                                             [False, False, False]]
    assert read_grid(tmp_path / "m.png", threshold=250).blocked.tolist() == [[True, True, False],
                                                                             [False, False, True]]


def test_huge_image_refused_from_its_header(tmp_path):
    Image.new("L", (8000, 10), 255).save(tmp_path / "wide.png")
    with pytest.raises(MapError, match="8000 x 10 pixels is larger than 4096 x 4096"):
        read_grid(tmp_path / "wide.png")
    Image.new("L", (10, 4097), 255).save(tmp_path / "tall.png")
    with pytest.raises(MapError, match="10 x 4097 pixels is larger than 4096 x 4096"):
        read_grid(tmp_path / "tall.png")


def test_large_ros_map_reads_in_bounded_memory(tmp_path):
    """A 4096 x 4096 ROS map (the largest image) in RGBA reads with its alpha averaged in,
    without a float copy of every channel: numpy's arrays peak under 300 MB (traced), and
    the grid is what map_server reads (a pixel with alpha 0 counts as darker, so blocked,
    because trinary mode averages it in)."""
    import tracemalloc

    a = np.full((4096, 4096, 4), 254, np.uint8)
    a[:, :, 3] = 255
    a[:8, :8, 3] = 0  # transparent: (254 * 3 + 0) / 4 = 190.5, p = 0.25 > free_thresh 0.196
    a[100:200, 300:400, :3] = 0
    Image.fromarray(a, "RGBA").save(tmp_path / "big.png")
    (tmp_path / "big.yaml").write_text("image: big.png\nresolution: 0.01\norigin: [0, 0, 0]\nnegate: 0\n"
                                       "occupied_thresh: 0.65\nfree_thresh: 0.196\n")
    del a
    tracemalloc.start()
    try:
        grid = read_grid(tmp_path / "big.yaml")
        grown = tracemalloc.get_traced_memory()[1] / 2**20
    finally:
        tracemalloc.stop()
    assert grid.blocked.shape == (4096, 4096)
    assert grid.blocked[:8, :8].all() and not grid.blocked[8:100].any()
    assert grid.blocked[100:200, 300:400].all() and grid.blocked.sum() == 64 + 100 * 100
    assert grown < 300, f"{grown:.0f} MB"


@pytest.mark.parametrize("name", ["two-rooms-ros.yaml", "pillars-png.yaml"])
def test_image_maps_plan_and_run(name, tmp_path):
    result = run_scenario(EXAMPLES / name, out_dir=tmp_path, render=False, out=None)
    assert result.exit_code == 0, result.report
    assert result.report["sim"]["contacts"] == 0
    assert result.report["plan"]["valid"] is True


# name, cells, rectangles (measured)
BENCHMARK = [
    ("room-32-32-4", 32 * 32, 134),
    ("maze-32-32-4", 32 * 32, 26),
    ("random-32-32-20", 32 * 32, 141),
    ("den312d", 65 * 81, 147),
    ("warehouse-10-20-10-2-1", 161 * 63, 204),
    ("warehouse-20-40-10-2-2", 340 * 164, 804),
    ("Berlin_1_256", 256 * 256, 1213),
]


@pytest.mark.parametrize("name,cells,pieces", BENCHMARK, ids=[b[0] for b in BENCHMARK])
def test_benchmark_map_loads_quickly(name, cells, pieces, tmp_path):
    scen = MAPS / f"{name}-random-1.scen"
    scen = scen if scen.exists() else MAPS / f"{name}-swarmform-1.scen"
    path = tmp_path / "s.yaml"
    path.write_text(f"map: {{file: {MAPS / (name + '.map')}, cell: 2.4}}\nrobots: {{radius: 1.0, margin: 0.1}}\n"
                    f"start: {{scen: {scen}, count: 10}}\ntarget: {{scen: {scen}, count: 10}}\n")
    t = time.perf_counter()
    s = read_scenario(path)
    problem = build_problem(s, np.random.default_rng(0))
    seconds = time.perf_counter() - t
    assert len(problem.obstacles) == pieces
    assert s.width * s.height == pytest.approx(cells * 2.4**2)
    assert problem.m == 10
    assert seconds < 2.0, seconds  # measured: 0.01 s to 0.1 s


def test_shipped_map_scenarios_show(tmp_path):
    for path in sorted(EXAMPLES.glob("*.yaml")):  # the ROS map_server file is two-rooms-map.yml
        s = read_scenario(path)
        problem = build_problem(s, np.random.default_rng(s.seed))
        assert problem.m == s.count


@pytest.mark.slow
def test_room_100_runs_clean(tmp_path):
    """The 100-robot room scenario: measured 7 s of planning, 20 s in all."""
    result = run_scenario(EXAMPLES / "room-32-32-4-100.yaml", out_dir=tmp_path, render=False, out=None)
    assert result.exit_code == 0, result.report


def test_wide_map_workspace_cap(tmp_path):
    """A map of 1491 columns (orz900d's width) at cell 2.4 is 3578 wide and loads; at
    cell 3 it is 4473 wide and is refused on map.cell, naming the cap."""
    row = "." * 1491
    text = "type octile\nheight 3\nwidth 1491\nmap\n" + "\n".join([row, "@" * 1491, row]) + "\n"
    (tmp_path / "wide.map").write_text(text)
    path = tmp_path / "s.yaml"
    path.write_text("map: {file: wide.map, cell: 2.4}\nrobots: {radius: 1.0, margin: 0.1, count: 2}\n"
                    "start: {points: [[1.2, 6.0], [6.0, 6.0]]}\ntarget: {points: [[3570, 6.0], [3500, 6.0]]}\n")
    s = read_scenario(path)
    assert s.width == pytest.approx(1491 * 2.4)
    path.write_text(path.read_text().replace("cell: 2.4", "cell: 3"))
    with pytest.raises(ScenarioError, match=r"map\.cell.*each side must be in \[1, 4000\]"):
        read_scenario(path)


def test_scattered_robots_on_a_benchmark_map_plan_on_its_cells(tmp_path, capsys):
    """Starts and targets scattered over room-32-32-4 (off every grid): the grid stage snaps
    them onto the map's cells; ``swarmform plan`` prints the bound that respects obstacles."""
    from sim.cli import main

    path = tmp_path / "s.yaml"
    path.write_text(f"name: room-scatter\nmap: {{file: {MAPS / 'room-32-32-4.map'}, cell: 2.4}}\n"
                    "robots: {count: 60, radius: 1.0, margin: 0.1}\n"
                    "start: {formation: scatter}\ntarget: {formation: scatter}\nplanner: {time_limit: 30}\n")
    out = tmp_path / "plan.json"
    assert main(["plan", str(path), "-o", str(out)]) == 0
    text = capsys.readouterr().out
    assert "geo bound" in text, text
    from planner import Plan

    stats = Plan.load(out).stats
    assert stats.extra["direct"] == "grid"
    assert stats.makespan_s <= 2.5 * stats.makespan_lower_bound_geo_s


def _ros_png(tmp_path, im: Image.Image, mode: str = "trinary") -> Grid:
    im.save(tmp_path / "m.png")
    (tmp_path / "m.yaml").write_text(f"image: m.png\nmode: {mode}\nresolution: 0.5\norigin: [0, 0, 0]\n"
                                     "occupied_thresh: 0.65\nfree_thresh: 0.25\nnegate: 0\n")
    return read_grid(tmp_path / "m.yaml")


def test_ros_alpha_is_averaged_in_trinary_mode_and_unknown_in_scale_mode(tmp_path):
    """map_server's rules for an image with alpha: trinary averages it in with red, green
    and blue; scale keeps it out and calls every pixel that is not fully opaque unknown."""
    rgba = np.zeros((1, 4, 4), np.uint8)
    rgba[0, 0] = (0, 0, 0, 255)        # opaque black: mean 63.75 -> occupancy 0.75, occupied
    rgba[0, 1] = (60, 60, 60, 255)     # mean 108.75 -> 0.57 unknown (its RGB mean 60 -> 0.76 would be occupied)
    rgba[0, 2] = (254, 254, 254, 0)    # transparent white: mean 190.5 -> 0.25, not below free: unknown
    rgba[0, 3] = (254, 254, 254, 255)  # opaque white: free
    im = Image.fromarray(rgba, "RGBA")
    assert _ros_png(tmp_path, im).blocked.tolist() == [[True, True, True, False]]
    assert _ros_png(tmp_path, im, "scale").blocked.tolist() == [[True, True, True, False]]
    rgba[0, 2] = (254, 254, 254, 254)  # almost opaque white: free in trinary, unknown in scale
    rgba[0, 1] = (110, 110, 110, 255)  # RGB mean 110 -> 0.57: unknown either way
    im = Image.fromarray(rgba, "RGBA")
    assert _ros_png(tmp_path, im).blocked.tolist() == [[True, True, False, False]]
    assert _ros_png(tmp_path, im, "scale").blocked.tolist() == [[True, True, True, False]]
    # grey with alpha reads as the same RGBA, (3 L + A) / 4 in trinary mode: opaque grey 172
    # is 192.75 there (occupancy 0.244, free) and 172 in scale mode (0.325, unknown)
    la = Image.fromarray(np.array([[[172, 255], [0, 0], [254, 255]]], np.uint8), "LA")
    assert _ros_png(tmp_path, la).blocked.tolist() == [[False, True, False]]
    assert _ros_png(tmp_path, la, "scale").blocked.tolist() == [[True, True, False]]


def test_plain_png_transparency_is_a_white_page(tmp_path):
    rgba = np.zeros((1, 3, 4), np.uint8)
    rgba[0, 0] = (0, 0, 0, 255)      # opaque black: blocked
    rgba[0, 1] = (0, 0, 0, 0)        # transparent: the page shows, free
    rgba[0, 2] = (0, 0, 0, 200)      # mostly opaque black: 255 * 55 / 255 = 55, blocked
    Image.fromarray(rgba, "RGBA").save(tmp_path / "m.png")
    assert read_grid(tmp_path / "m.png").blocked.tolist() == [[True, False, True]]
    # a palette image with a transparent index reads the same way
    p = Image.fromarray(np.array([[0, 1, 2]], np.uint8), "P")
    p.putpalette([0, 0, 0, 255, 255, 255, 10, 10, 10])
    p.info["transparency"] = 2
    p.save(tmp_path / "p.png", transparency=2)
    assert read_grid(tmp_path / "p.png").blocked.tolist() == [[True, False, False]]


@pytest.mark.parametrize("fmt", ["pgm", "png"])
def test_16_bit_images_use_their_full_range(tmp_path, fmt):
    """A 16-bit map whose values are all small is dark, not a bright 8-bit map."""
    for values, blocked in ([[0, 200, 40000, 65535]], [True, True, False, False]), ([[0, 200, 255]], [True] * 3):
        values = np.array(values, np.uint16)
        if fmt == "pgm":
            header = b"P5 %d 1 65535\n" % values.shape[1]
            (tmp_path / "m.pgm").write_bytes(header + values.astype(">u2").tobytes())
        else:
            Image.fromarray(values).save(tmp_path / "m.png")
        assert read_grid(tmp_path / f"m.{fmt}").blocked.tolist() == [blocked]

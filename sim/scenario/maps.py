"""Occupancy grids users already have: MovingAI ``.map``, ROS map_server YAML, plain PNG/PGM.

Each reader returns a :class:`Grid`: a ``(rows, cols)`` boolean array of
blocked cells whose row 0 is the TOP of the map (as in every one of these
formats), and the cell size when the file gives one (ROS ``resolution``).
:func:`cover` turns the blocked cells into obstacle rectangles in workspace
coordinates (y up: row ``r`` spans ``[(rows - r - 1) cell, (rows - r) cell]``).

Formats
  MovingAI: ``type octile``, ``height H``, ``width W``, ``map``, then H rows
  of W characters; ``@ O T W`` are blocked, ``. G S`` free, anything else is
  an error naming its row and column (1-based, row 1 at the top).
  ROS map_server: a YAML mapping of ``image`` (PGM or PNG, relative to the
  YAML), ``resolution``, ``origin``, ``occupied_thresh``, ``free_thresh``,
  ``negate`` and optional ``mode`` (``trinary`` or ``scale``); other keys are
  ignored, as map_server ignores them.  A pixel's grey ``p`` is the mean of
  its red, green and blue, as in map_server; in trinary mode (the default)
  an image's alpha is averaged in too, and in scale mode a pixel that is not
  fully opaque is unknown (both as in Nav2's map_server).  A pixel is
  occupied when ``(255 - p) / 255 > occupied_thresh`` (``p / 255`` with
  ``negate``), free when it is below ``free_thresh``; unknown pixels count
  as blocked (free space is never invented).
  Plain PNG or PGM: a pixel whose grey value (luminance, over a white page
  where the image is transparent) is below ``threshold`` (default 128) is
  blocked.  16-bit images are scaled from 0..65535.

Caps (measured; see tests/sim/test_maps.py)
  :data:`MAX_SIDE_CELLS` cells a side and :data:`MAX_CELLS` cells in all
  (4096 x 4096), checked from the header before any row or pixel is
  decoded; image files at most :data:`MAX_IMAGE_BYTES`, ``.map`` and ROS
  YAML files at most :data:`MAX_MAP_BYTES`.  The cover is at most
  :data:`MAX_PIECES` rectangles (4 vertices each): the planner's exact point
  clearance is dense in the obstacle edges (2000 points cost about 1 s at
  1024 rectangles, 5 s at 4096, 30 s at 16384), and pymunk gets one shape
  per rectangle.  Measured here: Berlin_1_256 (65 536 cells, the largest
  benchmark map) reads and covers in about 0.05 s into 1213 rectangles; a
  1024 x 1024 map with 20 % random blocked cells is refused by the piece cap
  in under 0.1 s; a 4096 x 4096 ROS map in about 1.5 s, its arrays peaking at
  240 MB (RGBA).  The hand-written ``obstacles:`` keep their own caps.

Obstacles are rectangles (each row's runs of blocked cells merged with the same runs
below: convex, easy on pymunk and the planner), whose union is exactly the blocked cells.
"""

from __future__ import annotations

import os
import re
import stat
from dataclasses import dataclass
from pathlib import Path

import numpy as np

__all__ = ["MAX_CELLS", "MAX_IMAGE_BYTES", "MAX_MAP_BYTES", "MAX_PIECES", "MAX_SIDE_CELLS", "Grid", "MapError",
           "cover", "read_grid", "resolve"]

MAX_SIDE_CELLS = 4096
"""The most cells (pixels) one side of a map may have."""
MAX_CELLS = MAX_SIDE_CELLS * MAX_SIDE_CELLS
"""The most cells a map may have (4096 x 4096; a ``.map`` file is held to :data:`MAX_MAP_BYTES` too)."""
MAX_MAP_BYTES = 4 << 20
"""The largest ``.map`` or ROS YAML file read [bytes]."""
MAX_IMAGE_BYTES = 64 << 20
"""The largest PNG or PGM file opened [bytes]; its pixel count is checked from the header."""
MAX_PIECES = 4096
"""The most obstacle rectangles a map may give (Berlin_1_256 gives 1213, warehouse-20-40-10-2-2 804)."""

_BLOCKED, _FREE = "@OTW", ".GS"
_IMAGE_SUFFIXES, _ROS_SUFFIXES = (".png", ".pgm"), (".yaml", ".yml")


class MapError(ValueError):
    """A map file that cannot be used: ``key`` is the ``map.`` key to blame, ``reason`` says why."""

    def __init__(self, reason: str, key: str = "file"):
        self.key, self.reason = key, reason
        super().__init__(reason)


@dataclass(frozen=True, eq=False)
class Grid:
    """Blocked cells (row 0 at the top) and the cell size the file gives, if any [units]."""

    blocked: np.ndarray  # (rows, cols) bool
    cell: float | None = None
    origin: tuple[float, float] | None = None  # a ROS map's lower-left corner in its frame (yaw ignored, as map_server)

    @property
    def rows(self) -> int:
        return int(self.blocked.shape[0])

    @property
    def cols(self) -> int:
        return int(self.blocked.shape[1])

    def centre(self, col: int, row: int, cell: float) -> tuple[float, float]:
        """The workspace centre of cell (``col``, ``row`` from the top)."""
        return ((col + 0.5) * cell, (self.rows - row - 0.5) * cell)


def read_grid(path: Path, threshold: float | None = None) -> Grid:
    """The grid of ``path``, chosen by its suffix (``.map``, ``.yaml``/``.yml``, ``.png``/``.pgm``)."""
    suffix = path.suffix.lower()
    if suffix == ".map":
        if threshold is not None:
            raise MapError("applies to PNG and PGM images only", "threshold")
        return _read_movingai(path)
    if suffix in _ROS_SUFFIXES:
        if threshold is not None:
            raise MapError("applies to PNG and PGM images only (a ROS map has occupied_thresh)", "threshold")
        return _read_ros(path)
    if suffix in _IMAGE_SUFFIXES:
        grey, _ = _read_grey(path)
        return Grid(grey < (128.0 if threshold is None else threshold))
    raise MapError(f"{_name(path)}: unknown map format {suffix or '(no suffix)'!r} "
                   "(known: .map, .yaml/.yml for ROS map_server, .png, .pgm)")


def cover(grid: Grid, cell: float) -> list[np.ndarray]:
    """Rectangles ``(4, 2)`` counter-clockwise whose union is exactly the blocked cells.

    Rectangles beat merged outlines here: on Berlin_1_256 the outlines of the
    hole-free components cut the edges by only a third (4852 to 3292) while
    pymunk's convex split of them takes 6 s instead of 0.5 s.
    """
    rows = grid.rows
    return [np.array([[c0, rows - bottom], [c1, rows - bottom], [c1, rows - top], [c0, rows - top]], float) * cell
            for c0, c1, top, bottom in _rectangles(grid.blocked)]


def _rectangles(blocked: np.ndarray) -> list[tuple[int, int, int, int]]:
    """``(c0, c1, top, bottom)`` rectangles (columns ``[c0, c1)``, rows ``[top, bottom)``): exactly the
    blocked cells.  Each row's maximal runs are merged with the identical runs of the rows below;
    O(cells) with numpy plus O(runs) in Python; refused beyond :data:`MAX_PIECES`.
    """
    b = np.asarray(blocked, bool)
    rows, cols = b.shape
    pad = np.zeros((rows, cols + 2), np.int8)
    pad[:, 1:-1] = b
    d = np.diff(pad, axis=1)
    rs, cs = np.nonzero(d == 1)
    _rows_end, ce = np.nonzero(d == -1)  # both in row-major order: the k-th start pairs with the k-th end
    rects: list[tuple[int, int, int, int]] = []  # (c0, c1, top row, bottom row exclusive)
    open_: dict[tuple[int, int], int] = {}
    bounds = np.searchsorted(rs, np.arange(rows + 1))
    for r in range(rows + 1):
        lo, hi = (bounds[r], bounds[r + 1]) if r < rows else (0, 0)
        here = set(zip(cs[lo:hi].tolist(), ce[lo:hi].tolist()))
        for key in [k for k in open_ if k not in here]:
            rects.append((key[0], key[1], open_.pop(key), r))
            if len(rects) > MAX_PIECES:
                raise MapError(f"gives more than {MAX_PIECES} obstacle rectangles; use a coarser map")
        for key in here:
            open_.setdefault(key, r)
    return sorted(rects, key=lambda t: (t[2], t[0]))


# ----------------------------------------------------------------------------
# MovingAI


def _read_movingai(path: Path) -> Grid:
    text = _text(path)
    lines = text.split("\n")
    name = _name(path)
    header = {}
    for i, want in enumerate(("type", "height", "width", "map")):
        line = lines[i].strip() if i < len(lines) else ""
        word, value = (line.split(None, 1) + ["", ""])[:2]  # any whitespace between (some files use tabs)
        word = word.lower()
        if i == 1 and word == "width":
            want = "width"  # height and width in either order, as some converters write them
        elif i == 2:
            want = "width" if "height" in header else "height"
        if word != want:
            shown = line if len(line) <= 30 else line[:27] + "..."
            raise MapError(f"{name} line {i + 1}: expected {want!r} (a MovingAI map starts with type, height, "
                           f"width, map), got {shown!r}")
        header[want] = value.strip()
    if header["type"].lower() != "octile":
        raise MapError(f"{name} line 1: type must be octile, got {header['type'][:30]!r}")
    rows = _side(header["height"], f"{name} line 2: height")
    cols = _side(header["width"], f"{name} line 3: width")
    _check_cells(rows, cols, name)
    body = [ln.rstrip(" \t\r") for ln in lines[4:]]  # trailing blanks are no cells
    while body and not body[-1].strip():
        body.pop()
    if len(body) != rows:
        raise MapError(f"{name}: has {len(body)} map rows, but its header declares height {rows}")
    for r, ln in enumerate(body):
        if len(ln) != cols:
            raise MapError(f"{name} row {r + 1} (line {r + 5}): has {len(ln)} cells, but its header declares "
                           f"width {cols}")
    raw = np.frombuffer("".join(body).encode("utf-8", "surrogateescape"), np.uint8)
    if len(raw) != rows * cols:  # a multi-byte character: find it
        for r, ln in enumerate(body):
            for c, ch in enumerate(ln):
                if ord(ch) > 127:
                    raise MapError(f"{name} row {r + 1}, column {c + 1}: unknown cell {ch!r} "
                                   f"(blocked: {' '.join(_BLOCKED)}; free: {' '.join(_FREE)})")
    table = np.full(256, 2, np.uint8)
    table[np.frombuffer(_BLOCKED.encode(), np.uint8)] = 1
    table[np.frombuffer(_FREE.encode(), np.uint8)] = 0
    kind = table[raw].reshape(rows, cols)
    bad = np.argwhere(kind == 2)
    if len(bad):
        r, c = (int(v) for v in bad[0])
        raise MapError(f"{name} row {r + 1}, column {c + 1}: unknown cell {body[r][c]!r} "
                       f"(blocked: {' '.join(_BLOCKED)}; free: {' '.join(_FREE)})")
    return Grid(kind == 1)


def _side(value: str, where: str) -> int:
    if not re.fullmatch(r"[0-9]{1,12}", value):
        raise MapError(f"{where} must be a whole number of cells, got {value[:30]!r}")
    n = int(value)
    if not 1 <= n <= MAX_SIDE_CELLS:
        raise MapError(f"{where} must be in [1, {MAX_SIDE_CELLS}] cells, got {n}")
    return n


def _check_cells(rows: int, cols: int, name: str) -> None:
    if rows * cols > MAX_CELLS:
        raise MapError(f"{name}: {cols} x {rows} cells is more than the {MAX_CELLS} "
                       f"({MAX_SIDE_CELLS} x {MAX_SIDE_CELLS}) a map may have")


# ----------------------------------------------------------------------------
# ROS map_server


def _read_ros(path: Path) -> Grid:
    from .yamlfile import YamlRefused, load_yaml

    name = _name(path)
    try:
        doc = load_yaml(_text(path))
    except YamlRefused as exc:
        raise MapError(f"{name}: {exc.where}: {exc.reason}") from None
    if not isinstance(doc, dict):
        raise MapError(f"{name}: must hold a ROS map_server mapping (image, resolution, origin, ...)")
    # other keys (a map_saver's own, a tool's notes) are ignored, as map_server ignores them
    known = ("image", "resolution", "origin", "occupied_thresh", "free_thresh", "negate", "mode")
    for key in known[:-1]:
        if key not in doc:
            raise MapError(f"{name}: {key} is required (a ROS map_server YAML)")
    image = doc["image"]
    if not isinstance(image, str) or not image or "\x00" in image or len(image) > 4096:
        raise MapError(f"{name}: image must be a path to a PGM or PNG file")
    res = _ros_number(doc["resolution"], f"{name}: resolution", 1e-6, 1e6)
    origin = doc["origin"]
    if not isinstance(origin, list) or len(origin) not in (2, 3):
        raise MapError(f"{name}: origin must be [x, y, yaw]")
    ox, oy = (_ros_number(v, f"{name}: origin", -1e9, 1e9) for v in origin[:2])
    for v in origin[2:]:
        _ros_number(v, f"{name}: origin", -1e9, 1e9)
    occ = _ros_number(doc["occupied_thresh"], f"{name}: occupied_thresh", 0, 1)
    free = _ros_number(doc["free_thresh"], f"{name}: free_thresh", 0, 1)
    if free > occ:
        raise MapError(f"{name}: free_thresh {free:g} must not exceed occupied_thresh {occ:g}")
    negate = doc["negate"]
    if negate not in (0, 1) or isinstance(negate, float):
        raise MapError(f"{name}: negate must be 0 or 1 (or true/false), got {str(negate)[:30]!r}")
    mode = doc.get("mode", "trinary")
    if mode not in ("trinary", "scale"):
        raise MapError(f"{name}: mode must be trinary or scale (raw is not supported), got {str(mode)[:30]!r}")
    img = resolve(image, path.parent)
    if img.suffix.lower() not in _IMAGE_SUFFIXES:
        raise MapError(f"{name}: image {_name(img)} must be a PGM or PNG file")
    grey, translucent = _read_grey(img, f"{name}: image {_name(img)}", ros_mode=mode)
    p = grey  # in place: a 4096 x 4096 map's grey values take 134 MB
    if not negate:
        np.subtract(255.0, p, out=p)
    p /= 255.0
    blocked = ~(p < free) | (p > occ)  # unknown (between the thresholds) is blocked
    if mode == "scale" and translucent is not None:
        blocked |= translucent  # scale mode: a pixel not fully opaque is unknown
    return Grid(blocked, cell=res, origin=(ox, oy))


def _ros_number(value, where: str, lo: float, hi: float) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not lo <= value <= hi:
        raise MapError(f"{where} must be a number in [{lo:g}, {hi:g}], got {str(value)[:30]!r}")
    return float(value)


# ----------------------------------------------------------------------------
# images and bounded reads


def _mean(channels: np.ndarray) -> np.ndarray:  # 8-bit channels summed in 16 bits: no float copy of each
    return channels.sum(axis=2, dtype=np.uint16) / float(channels.shape[2])


def _read_grey(path: Path, where: str | None = None, ros_mode: str | None = None
               ) -> tuple[np.ndarray, np.ndarray | None]:
    """Grey values 0..255 ``(rows, cols)`` float, the size checked from the header first,
    and the pixels that are not fully opaque (``None`` when the image has no alpha).

    ``ros_mode`` ``None``: a plain image, seen as on a white page: its luminance
    (Pillow's ``L``) after compositing over white, so a transparent background is
    white.  ``"trinary"``: the mean of red, green and blue, and of alpha too when
    the image has one (map_server's trinary mode, ROS 1 and Nav2 alike).
    ``"scale"``: the mean of red, green and blue (alpha is kept out, and every
    pixel not fully opaque is unknown, as in Nav2's scale mode).  A 16-bit image
    (a PGM of maxval over 255, a 16-bit PNG) is scaled from its full range
    0..65535 (Pillow scales a PGM's maxval to it), whatever values it holds.
    """
    import io

    from PIL import Image

    where = where or _name(path)
    data = _bytes(path, MAX_IMAGE_BYTES, where)
    try:
        with Image.open(io.BytesIO(data)) as im:
            if im.format not in ("PNG", "PPM"):  # PPM: Pillow's name for the PBM/PGM/PPM family
                raise MapError(f"{where}: is a {im.format or 'unknown'} image, not a PNG or PGM (whatever its suffix)")
            cols, rows = im.size  # from the header; nothing decoded yet
            if cols > MAX_SIDE_CELLS or rows > MAX_SIDE_CELLS:
                raise MapError(f"{where}: {cols} x {rows} pixels is larger than {MAX_SIDE_CELLS} x "
                               f"{MAX_SIDE_CELLS}, the largest map image")
            _check_cells(rows, cols, where)
            if im.mode.startswith("I"):  # 16-bit grey (or 32-bit from a mislabelled file): no alpha
                arr = np.asarray(im, np.float64)
                return np.clip(arr * (255.0 / 65535.0), 0.0, 255.0), None
            has_alpha = im.mode in _ALPHA_MODES or "transparency" in im.info
            if not has_alpha:
                if ros_mode is None or im.mode == "L":  # a grey image's red, green and blue are its grey
                    return np.asarray(im.convert("L"), np.float64), None
                return _mean(np.asarray(im.convert("RGB"))), None
            rgba = im.convert("RGBA")
            translucent = np.asarray(rgba.getchannel("A"), np.uint8) < 255
            if ros_mode is None:
                white = Image.new("RGBA", rgba.size, (255, 255, 255, 255))
                return np.asarray(Image.alpha_composite(white, rgba).convert("L"), np.float64), translucent
            arr = np.asarray(rgba)
            return _mean(arr if ros_mode == "trinary" else arr[:, :, :3]), translucent
    except MapError:
        raise
    except Image.DecompressionBombError:  # Pillow's own size check, from the header, before ours
        raise MapError(f"{where}: its header declares more pixels than {MAX_SIDE_CELLS} x {MAX_SIDE_CELLS}, "
                       "the largest map image") from None
    except Exception as exc:  # noqa: BLE001 - any decoder failure on a hostile file is a bad input
        why = re.sub(r"\s*<[^<>]* at 0x[0-9a-fA-F]+>", "", str(exc))[:60] or type(exc).__name__
        raise MapError(f"{where}: is not a readable PNG or PGM image ({why})") from None


_ALPHA_MODES = frozenset({"LA", "La", "PA", "RGBA", "RGBa"})


def _text(path: Path, max_bytes: int = MAX_MAP_BYTES) -> str:
    from planner.inputfile import UnreadableFile, read_text

    try:
        text = read_text(path, max_bytes)
    except UnreadableFile as exc:
        raise MapError(f"{_name(path)}: {exc}") from None
    return text.removeprefix("\ufeff")  # a byte-order mark, as editors on Windows write one


def _bytes(path: Path, max_bytes: int, where: str) -> bytes:
    """A regular file's bytes, refused unread when it is not regular or larger than ``max_bytes``."""
    try:
        fd = os.open(path, os.O_RDONLY | getattr(os, "O_NONBLOCK", 0) | getattr(os, "O_NOCTTY", 0))
    except FileNotFoundError:
        raise MapError(f"{where}: no such file") from None
    except (OSError, ValueError) as exc:
        raise MapError(f"{where}: cannot be read ({type(exc).__name__})") from None
    try:
        st = os.fstat(fd)
        if not stat.S_ISREG(st.st_mode):
            raise MapError(f"{where}: is not a regular file")
        if st.st_size > max_bytes:
            raise MapError(f"{where}: is {st.st_size} bytes, larger than the {max_bytes >> 20} MiB a map image "
                           "may have")
        with os.fdopen(os.dup(fd), "rb") as f:
            data = f.read(max_bytes + 1)
    finally:
        os.close(fd)
    if len(data) > max_bytes:
        raise MapError(f"{where}: is larger than the {max_bytes >> 20} MiB a map image may have")
    return data


def resolve(name: str, base: Path) -> Path:
    """``name`` as a path: ``~`` expanded, relative to ``base`` unless absolute."""
    try:
        path = Path(name).expanduser()
    except RuntimeError:  # ~user of no known user
        path = Path(name)
    return path if path.is_absolute() else base / path


def _name(path: Path) -> str:
    from planner.inputfile import echo_path

    return echo_path(path.name, 60)

"""Reader for wmd's shared-memory export of the occupancy grid and the vector map.

The layout is defined by wire/shm/worldmodel_shm.h (the single source of truth) and tabled in docs/shm.md; this
module reads the same bytes with the standard library (mmap, struct). When numpy can be imported, tile and layer
reads return numpy float32 arrays; otherwise array('f'). Set WM_SHM_NO_NUMPY=1 to force the fallback.

    reader = worldmodel_shm.open_live("http://127.0.0.1:8080")   # or Reader("wm-0b5c...")
    dense = reader.read_layer("bayes")      # values[row * width + col], row 0 at the bottom, NaN = unknown
    world_map = reader.read_map()
    reader = reader.follow("http://127.0.0.1:8080")   # after the server grew the segment: its successor

Trust: the segment is a file the server owns (mode 0644). Only its owner can change or truncate it, and a truncated
mapping kills the reader with SIGBUS: open only names the server gave (GET /api/v1/shm, or the successor written in
its segment), and check Reader.owner_uid when in doubt. Every size and offset in the header is checked against the
mapping at open, and the geometry is kept from then on.

Consistency: each tile slot and the map carry a sequence counter (a seqlock). A read loads the counter, skips when
it is odd (a write in progress), copies the bytes, loads the counter again and accepts the copy when it did not
change; otherwise it copies again, and gives up with ShmError when a counter stays odd for 2 s (a writer that died
mid-write). This is sound from Python on x86-64 only:
- the counters sit at 8-aligned offsets, and an aligned 8-byte load is atomic there (CPython's struct unpacks "<Q"
  on a little-endian host with its native unpacker, a memcpy into a uint64: one load);
- x86-64 does not reorder loads with other loads (TSO), and CPython performs the first load, the copy and the second
  load in separate C calls that the compiler cannot interleave, so the copy happens between the two loads.
On weakly ordered CPUs (ARM, POWER) CPython emits no fence between them and the copy may be observed out of order
with the counters: use the C++ reader (wire/shm/worldmodel_shm.h) there.
"""

from __future__ import annotations

import json
import math
import mmap
import os
import stat
import struct
import time
import urllib.error
import urllib.request
from array import array
from typing import Any, Dict, List, NamedTuple, Optional, Sequence, Tuple, Union

if os.environ.get("WM_SHM_NO_NUMPY", "") not in ("", "0"):
    np: Any = None
else:
    try:
        import numpy as np
    except ImportError:
        np = None

__all__ = [
    "LAYERS",
    "LAYOUT_VERSION",
    "ShmError",
    "SegmentGone",
    "TileKey",
    "Dense",
    "Element",
    "Object",
    "Edge",
    "Map",
    "Reader",
    "from_server",
    "open_segment",
    "open_live",
    "HAVE_NUMPY",
    "known_count",
    "MAX_DENSE_CELLS",
    "shm_info",
]

HAVE_NUMPY = np is not None

MAGIC = b"WMSHM01\0"
LAYOUT_VERSION = 1
HEADER_BYTES = 4096
LAYERS = ("bayes", "ds_belief", "ds_plausibility", "ds_conflict")
NAME_PREFIX = "wm-"
SHM_DIR = "/dev/shm/"

TILES_TRUNCATED = 1
MAP_TRUNCATED = 2
OBJECT_SOLID = 1
OBJECT_NOT_DEFORMABLE = 2
OBJECT_ID_TRUNCATED = 4

_STATES = {0: "live", 1: "retired", 2: "stopped"}

# SegmentHeader offsets (static_asserted in worldmodel_shm.h).
_H_MAGIC = 0
_H_LAYOUT_VERSION = 8
_H_HEADER_BYTES = 12
_H_STATE = 16
_H_TRUNCATED = 20
_H_OWNER_PID = 24
_H_OWNER_START_TICKS = 32
_H_SERVER_INSTANCE = 40
_H_SUCCESSOR = 88
_H_TILE_SIZE_CELLS = 152
_H_RESOLUTION_M = 160
_H_LAYER_COUNT = 168
_H_SLOT_BYTES = 176
_H_TILES_OFFSET = 184
_H_TILE_CAPACITY = 192
_H_TILE_COUNT = 200
_H_GRID_REVISION = 208
_H_MAP_OFFSET = 216
_H_MAP_CAPACITY_BYTES = 224
_H_UPDATED_UNIX_NS = 232
_H_SEGMENT_BYTES = 240

_SLOT_HEADER_BYTES = 64  # TileSlotHeader: sequence, tx, ty, revision, reserved[4]
_MAP_HEADER_BYTES = 64  # MapHeader: sequence, version, element/object/edge counts, reserved[3]

_U32 = struct.Struct("<I")
_U64 = struct.Struct("<Q")
_I64 = struct.Struct("<q")
_F64 = struct.Struct("<d")
_TILE_KEY = struct.Struct("<qq")  # TileSlotHeader.tx, .ty at +8
_MAP_COUNTS = struct.Struct("<qQQQ")  # MapHeader.version .. edge_count at +8
# '<' = no padding: the C structs have none either (sizes 64, 192, 48).
_ELEMENT = struct.Struct("<qddddqqII")
_OBJECT = struct.Struct("<dddIIII128s24s")
_EDGE = struct.Struct("<ddddIIQ")
assert (_ELEMENT.size, _OBJECT.size, _EDGE.size) == (64, 192, 48)

# Largest region read_layer() makes [cells] (1 GiB of float32), as the C++ reader's kMaxDenseCells.
MAX_DENSE_CELLS = 1 << 28

_GIVE_UP_S = 2.0
_SPINS = 64  # retries before the clock starts: a write takes microseconds


class ShmError(RuntimeError):
    """A segment that cannot be opened or is not of this layout, or a slot stuck in an update."""


class SegmentGone(ShmError):
    """The name is not there (ENOENT), or no longer the server's: the segment was unlinked because the server grew
    it again or stopped. Ask GET /api/v1/shm for the current name (open_live, Reader.follow with a URL)."""


class TileKey(NamedTuple):
    tx: int  # tile (tx, ty) holds cells [tx*T, (tx+1)*T) x [ty*T, (ty+1)*T)
    ty: int


class Dense(NamedTuple):
    """A layer over the smallest block of tiles holding every exported one.

    Cell (col, row) is values[row * width + col], row 0 at the bottom; its lower-left corner is at
    ((x0_cells + col) * resolution_m, (y0_cells + row) * resolution_m). NaN = never observed. values is flat, as in
    the C++ reader; with numpy, values.reshape(height, width)[row, col] is the same cell.
    """

    x0_cells: int
    y0_cells: int
    width: int
    height: int
    resolution_m: float
    grid_revision: int  # the tiles read hold every scan up to this one
    values: Any  # numpy float32 array or array('f'), width * height


class Element(NamedTuple):
    """An observed element ("e<number>"), a segment the floor plan does not explain."""

    number: int
    x1: float
    y1: float
    x2: float
    y2: float
    support: int
    updated_version: int
    origin: int  # 0 client, 1 scan, 2 grid, 3 other


class Object(NamedTuple):
    """A CAD object of the floor plan, as placed and posed now."""

    x: float
    y: float
    theta: float
    first_edge: int  # its edges are edges[first_edge : first_edge + edge_count]
    edge_count: int
    flags: int  # OBJECT_SOLID | OBJECT_NOT_DEFORMABLE | OBJECT_ID_TRUNCATED
    id: str
    kind: str


class Edge(NamedTuple):
    x1: float
    y1: float
    x2: float
    y2: float
    object_index: int
    edge_index: int


class Map(NamedTuple):
    version: int
    elements: List[Element]
    objects: List[Object]
    edges: List[Edge]


LayerArg = Union[str, int]


def _layer_index(layer: LayerArg) -> int:
    if isinstance(layer, str):
        try:
            return LAYERS.index(layer)
        except ValueError:
            raise ValueError(f"unknown layer {layer!r}: expected one of {', '.join(LAYERS)}") from None
    index = int(layer)
    if not 0 <= index < len(LAYERS):
        raise ValueError(f"layer index {index} out of range [0, {len(LAYERS)})")
    return index


def _strip_name(name: str) -> str:
    if name.startswith(SHM_DIR):
        name = name[len(SHM_DIR) :]
    return name[1:] if name.startswith("/") else name


def _c_string(raw: bytes) -> str:
    return raw.split(b"\0", 1)[0].decode("utf-8", errors="replace")


def _float_buffer(count: int) -> Any:
    if np is not None:
        return np.empty(count, dtype=np.float32)
    return array("f", bytes(4 * count))


def _nan_buffer(count: int) -> Any:
    if np is not None:
        return np.full(count, np.nan, dtype=np.float32)
    return array("f", [math.nan]) * count


class _Backoff:
    """Retries of a seqlock read: spin a little, then yield, and give up once the counter stayed odd for 2 s."""

    def __init__(self, what: str) -> None:
        self._what = what
        self._attempts = 0
        self._since = 0.0

    def wait(self) -> None:
        self._attempts += 1
        if self._attempts < _SPINS:
            return
        now = time.monotonic()
        if self._attempts == _SPINS:
            self._since = now
        elif now - self._since > _GIVE_UP_S:
            raise ShmError(f"{self._what} stayed in an update for 2 s: has the server died mid-write?")
        time.sleep(0)  # yields the GIL and the CPU to the writer


class Reader:
    """A read-only mapping of one segment ("wm-<uuid>" or "/dev/shm/wm-<uuid>").

    Every read copies out under the seqlock, so the values returned are one whole state of the tile (or the map),
    never a mix of two. The mapping stays valid after the server unlinks the name (on growth or stop).

    Raises SegmentGone when the name does not exist, ShmError when it is not a regular file or not a worldmodel
    segment of this layout (every offset is checked against the mapping here; the geometry is kept from then on:
    whoever owns the file could change the header later).
    """

    def __init__(self, name: str) -> None:
        self._name = _strip_name(name)
        if not self._name or "/" in self._name:
            raise ShmError(f"invalid shared memory name {name!r}")
        self._path = SHM_DIR + self._name
        # Anyone may put a file of that name in /dev/shm: no symlink, and no blocking open (a FIFO).
        flags = os.O_RDONLY | getattr(os, "O_CLOEXEC", 0) | getattr(os, "O_NOFOLLOW", 0) | getattr(os, "O_NONBLOCK", 0)
        try:
            fd = os.open(self._path, flags)
        except FileNotFoundError as error:
            raise SegmentGone(f"cannot open shared memory '{self._name}': {error.strerror}") from error
        except OSError as error:
            raise ShmError(f"cannot open shared memory '{self._name}': {error.strerror}") from error
        try:
            info = os.fstat(fd)
            if not stat.S_ISREG(info.st_mode):
                raise ShmError(f"'{self._name}' is not a regular file")
            size = info.st_size
            self._owner_uid = info.st_uid
            if size < HEADER_BYTES:
                raise ShmError(f"shared memory '{self._name}' is too small to be a worldmodel segment")
            try:
                self._mm = mmap.mmap(fd, size, access=mmap.ACCESS_READ)
            except (OSError, ValueError) as error:
                raise ShmError(f"cannot map '{self._name}': {error}") from error
        finally:
            os.close(fd)  # the mapping stays valid without it
        self._size = size
        # Copies go straight from this view into the caller's buffer (one memcpy); released in close().
        self._view: Optional[memoryview] = memoryview(self._mm)
        try:
            self._check_layout()
        except BaseException:
            self.close()
            raise

    def _check_layout(self) -> None:
        mm = self._mm
        # The geometry is read once, checked, and kept: no read goes by the mapping's copy of it again (its owner
        # could change it afterwards). Python's integers do not overflow, so the sums below are exact.
        t = self._i64(_H_TILE_SIZE_CELLS)
        slot_bytes = self._u64(_H_SLOT_BYTES)
        tiles_offset = self._u64(_H_TILES_OFFSET)
        tile_capacity = self._u64(_H_TILE_CAPACITY)
        map_offset = self._u64(_H_MAP_OFFSET)
        map_capacity = self._u64(_H_MAP_CAPACITY_BYTES)
        resolution = _F64.unpack_from(mm, _H_RESOLUTION_M)[0]
        valid = (
            mm[_H_MAGIC : _H_MAGIC + 8] == MAGIC
            and _U32.unpack_from(mm, _H_LAYOUT_VERSION)[0] == LAYOUT_VERSION
            and _U32.unpack_from(mm, _H_LAYER_COUNT)[0] == len(LAYERS)
            and self._u64(_H_SEGMENT_BYTES) <= self._size
            # As the C++ reader's layout_fits().
            and 1 <= t <= 1024
            and tiles_offset % 64 == 0
            and map_offset % 64 == 0
            and slot_bytes % 64 == 0
            and slot_bytes >= _SLOT_HEADER_BYTES + len(LAYERS) * t * t * 4
            and HEADER_BYTES <= tiles_offset <= self._size
            and tiles_offset + tile_capacity * slot_bytes <= self._size
            and map_capacity >= _MAP_HEADER_BYTES
            and map_offset + map_capacity <= self._size
        )
        if not valid:
            raise ShmError(f"'{self._name}' is not a worldmodel segment of layout version {LAYOUT_VERSION}")
        self._tile_size = t
        self._slot_bytes = slot_bytes
        self._tiles_offset = tiles_offset
        self._tile_capacity = tile_capacity
        self._map_offset = map_offset
        self._map_capacity = map_capacity
        self._resolution = resolution
        self._cells = t * t

    def close(self) -> None:
        if self._view is not None:
            self._view.release()
            self._view = None
        if not self._mm.closed:
            self._mm.close()

    def __enter__(self) -> "Reader":
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def __repr__(self) -> str:
        return f"Reader({self._name!r})"

    # --- header -----------------------------------------------------------------------------------------------

    def _u64(self, offset: int) -> int:
        return _U64.unpack_from(self._mm, offset)[0]

    def _i64(self, offset: int) -> int:
        return _I64.unpack_from(self._mm, offset)[0]

    @property
    def name(self) -> str:
        return self._name

    @property
    def path(self) -> str:
        return self._path

    @property
    def segment_bytes(self) -> int:
        return self._size

    @property
    def owner_uid(self) -> int:
        """The uid owning the file when it was opened: trust a segment only when this is the server's user."""
        return self._owner_uid

    @property
    def state(self) -> str:
        """"live" (the server writes it), "retired" (see successor) or "stopped" (the server's last state)."""
        value = _U32.unpack_from(self._mm, _H_STATE)[0]
        return _STATES.get(value, f"unknown({value})")

    @property
    def successor(self) -> Optional[str]:
        """The segment that replaced this one when retired, else None. Open it to keep reading."""
        if self.state != "retired":
            return None  # state first: the server writes the name before it marks the segment retired
        return _c_string(self._mm[_H_SUCCESSOR : _H_SUCCESSOR + 64])

    @property
    def truncated(self) -> int:
        """TILES_TRUNCATED | MAP_TRUNCATED: what did not fit under the server's size cap."""
        return _U32.unpack_from(self._mm, _H_TRUNCATED)[0]

    @property
    def tiles_truncated(self) -> bool:
        return bool(self.truncated & TILES_TRUNCATED)

    @property
    def map_truncated(self) -> bool:
        return bool(self.truncated & MAP_TRUNCATED)

    @property
    def owner_pid(self) -> int:
        """The wmd process that made the segment (for information: stale segments are told by a lock, not a pid)."""
        return self._i64(_H_OWNER_PID)

    @property
    def owner_start_ticks(self) -> int:
        """Its start time, field 22 of /proc/<pid>/stat (for information)."""
        return self._u64(_H_OWNER_START_TICKS)

    @property
    def server_instance(self) -> str:
        return _c_string(self._mm[_H_SERVER_INSTANCE : _H_SERVER_INSTANCE + 48])

    @property
    def tile_size_cells(self) -> int:
        return self._tile_size

    @property
    def resolution_m(self) -> float:
        return self._resolution

    @property
    def grid_revision(self) -> int:
        """Scans in the grid: the slots hold every scan up to this one. Not comparable with a tile's revision (the
        inserts that changed that tile). Advances even when tiles were left out (tiles_truncated)."""
        return self._u64(_H_GRID_REVISION)

    @property
    def tile_capacity(self) -> int:
        return self._tile_capacity

    @property
    def tile_count(self) -> int:
        """Slots in use, clamped to the capacity."""
        return min(self._u64(_H_TILE_COUNT), self._tile_capacity)

    @property
    def updated_unix_ns(self) -> int:
        return self._i64(_H_UPDATED_UNIX_NS)

    # --- tiles ------------------------------------------------------------------------------------------------

    def _slot_offset(self, slot: int) -> int:
        if not 0 <= slot < self.tile_count:
            raise IndexError(f"no tile slot {slot}")
        return self._tiles_offset + slot * self._slot_bytes

    def tile_key(self, slot: int) -> TileKey:
        """The tile in slot `slot` (< tile_count); a counted slot's key never changes."""
        return TileKey(*_TILE_KEY.unpack_from(self._mm, self._slot_offset(slot) + 8))

    def _read_slot(self, slot: int, first_value: int, count: int) -> Tuple[int, Any]:
        base = self._slot_offset(slot)
        start = base + _SLOT_HEADER_BYTES + 4 * first_value
        out = _float_buffer(count)
        dst = memoryview(out).cast("B")
        src = self._view
        if src is None:
            raise ShmError(f"reader of '{self._name}' is closed")
        backoff = _Backoff(f"tile slot {slot}")
        while True:
            before = _U64.unpack_from(self._mm, base)[0]
            if before % 2 == 0:
                revision = _U64.unpack_from(self._mm, base + 24)[0]
                dst[:] = src[start : start + 4 * count]
                if _U64.unpack_from(self._mm, base)[0] == before:
                    dst.release()
                    return revision, out
            backoff.wait()

    def read_tile(self, slot: int, layer: LayerArg) -> Tuple[int, Any]:
        """One layer of slot `slot`: (the tile's revision, T*T float32 row-major from the lower-left cell)."""
        index = _layer_index(layer)
        return self._read_slot(slot, index * self._cells, self._cells)

    def read_tile_layers(self, slot: int) -> Tuple[int, List[Any]]:
        """All four layers of slot `slot` from one state of it: (revision, [bayes, ds_belief, ...])."""
        revision, values = self._read_slot(slot, 0, len(LAYERS) * self._cells)
        c = self._cells
        return revision, [values[i * c : (i + 1) * c] for i in range(len(LAYERS))]

    def tile_keys(self) -> List[TileKey]:
        return [self.tile_key(i) for i in range(self.tile_count)]

    def read_layer(self, layer: LayerArg) -> Dense:
        """The layer over the smallest block of tiles covering every exported tile, NaN elsewhere.

        Tiles far apart make a large block (width * height floats): over MAX_DENSE_CELLS cells it raises ShmError
        before allocating anything (read the tiles one by one then), as the C++ reader does.
        """
        index = _layer_index(layer)
        resolution = self._resolution
        revision = self.grid_revision  # before the tiles: they hold every scan up to this one
        count = self.tile_count  # later slots are left for the next call
        if count == 0:
            return Dense(0, 0, 0, 0, resolution, revision, _float_buffer(0))
        t = self._tile_size
        # The keys are read once: the region, its bound and the placement below all use these.
        keys = [self.tile_key(i) for i in range(count)]
        min_x = min(k.tx for k in keys)
        min_y = min(k.ty for k in keys)
        span_x = max(k.tx for k in keys) - min_x + 1
        span_y = max(k.ty for k in keys) - min_y + 1
        if span_x * span_y * t * t > MAX_DENSE_CELLS:
            raise ShmError(f"the tiles span more than {MAX_DENSE_CELLS} cells: read them one by one")
        width = span_x * t
        height = span_y * t
        values = _nan_buffer(width * height)
        grid = values.reshape(height, width) if np is not None else None
        for slot, key in enumerate(keys):
            _, tile = self._read_slot(slot, index * self._cells, self._cells)
            col = (key.tx - min_x) * t
            row0 = (key.ty - min_y) * t
            if grid is not None:
                grid[row0 : row0 + t, col : col + t] = tile.reshape(t, t)
            else:
                for row in range(t):
                    start = (row0 + row) * width + col
                    values[start : start + t] = tile[row * t : (row + 1) * t]
        return Dense(min_x * t, min_y * t, width, height, resolution, revision, values)

    # --- successors -------------------------------------------------------------------------------------------

    def follow(self, url: Optional[str] = None, timeout: float = 5.0) -> "Reader":
        """The reader to keep reading with: self while the segment is not retired; else its successor's, and so on.

        When the server grew the segment, it named the next one in `successor` and unlinked this one's name at once.
        A reader that missed two growths (A -> B -> C while it still maps A) finds B's name gone too: then, with
        `url`, this asks GET <url>/api/v1/shm for the current segment (open_live); without, it raises SegmentGone.
        A successor owned by another user than this segment is not followed (a name unlinked may be taken again).
        On success the readers left behind are closed, this one included; on failure this one stays open.

            reader = reader.follow(url)   # in a polling loop, when reader.state == "retired"
        """
        current = self
        try:
            while current.state == "retired":
                name = current.successor or ""
                following = Reader(name)
                if following.owner_uid != current.owner_uid:
                    following.close()
                    raise SegmentGone(
                        f"'{name}' is owned by uid {following.owner_uid}, not by the server's uid {current.owner_uid}"
                    )
                if current is not self:
                    current.close()
                current = following
        except ShmError as error:
            if current is not self:
                current.close()
            if url is None:
                raise type(error)(
                    f"following '{self._name}': {error}; ask GET /api/v1/shm for the current segment"
                ) from error
            fresh = open_live(url, timeout)
            self.close()
            return fresh
        if current is not self:
            self.close()
        return current

    # --- map --------------------------------------------------------------------------------------------------

    def read_map(self) -> Map:
        """A copy of the vector map, one version of it."""
        base = self._map_offset
        records_at = base + _MAP_HEADER_BYTES
        room = self._map_capacity - _MAP_HEADER_BYTES
        backoff = _Backoff("the map")
        while True:
            before = _U64.unpack_from(self._mm, base)[0]
            if before % 2 == 0:
                version, elements, objects, edges = _MAP_COUNTS.unpack_from(self._mm, base + 8)
                n_bytes = elements * _ELEMENT.size + objects * _OBJECT.size + edges * _EDGE.size
                # Counts read mid-update may be garbage: copy only what the region holds, and check afterwards.
                if n_bytes <= room:
                    raw = self._mm[records_at : records_at + n_bytes]
                    if _U64.unpack_from(self._mm, base)[0] == before:
                        return _parse_map(version, elements, objects, edges, raw)
            backoff.wait()


def _parse_map(version: int, elements: int, objects: int, edges: int, raw: bytes) -> Map:
    at = elements * _ELEMENT.size
    element_list = [Element(*r[:8]) for r in _ELEMENT.iter_unpack(raw[:at])]
    object_list = []
    for x, y, theta, first_edge, edge_count, flags, id_length, oid, kind in _OBJECT.iter_unpack(
        raw[at : at + objects * _OBJECT.size]
    ):
        text = oid[: min(id_length, len(oid))].decode("utf-8", errors="replace")
        object_list.append(Object(x, y, theta, first_edge, edge_count, flags, text, _c_string(kind)))
    at += objects * _OBJECT.size
    edge_list = [Edge(*r[:6]) for r in _EDGE.iter_unpack(raw[at : at + edges * _EDGE.size])]
    return Map(version, element_list, object_list, edge_list)


def shm_info(url: str = "http://127.0.0.1:8080", timeout: float = 5.0) -> Dict[str, Any]:
    """GET <url>/api/v1/shm as a dict.

    Raises ShmError when the server cannot be asked or has no segment: 404 when it runs with --no-shm, 503 when the
    segment could not be made; the body then is {"error": code, "detail": text}.
    """
    target = url.rstrip("/") + "/api/v1/shm"
    try:
        with urllib.request.urlopen(target, timeout=timeout) as response:
            info = json.loads(response.read().decode("utf-8"))
    except urllib.error.HTTPError as error:
        reason = str(error.reason)
        try:
            body = json.loads(error.read().decode("utf-8"))
            reason = ": ".join(str(body[k]) for k in ("error", "detail") if k in body) or reason
        except (ValueError, TypeError, OSError):
            pass  # not JSON: the status line's reason will do
        raise ShmError(f"GET {target}: {error.code} {reason}") from error
    except (urllib.error.URLError, OSError, ValueError) as error:
        raise ShmError(f"GET {target}: {error}") from error
    if not isinstance(info, dict):
        raise ShmError(f"GET {target}: expected a JSON object")
    return info


def from_server(url: str = "http://127.0.0.1:8080", timeout: float = 5.0) -> Reader:
    """Asks the wmd at `url` (on this machine) for its segment's name and opens it (once: see open_live)."""
    info = shm_info(url, timeout)
    if info.get("layout_version") != LAYOUT_VERSION:
        version = info.get("layout_version")
        raise ShmError(f"server exports layout version {version}, this reader reads {LAYOUT_VERSION}")
    name = info.get("name")
    if not isinstance(name, str) or not name:
        raise ShmError(f"GET {url.rstrip('/')}/api/v1/shm named no segment")
    return Reader(name)


def open_live(url: str = "http://127.0.0.1:8080", timeout: float = 5.0, attempts: int = 3) -> Reader:
    """Asks the wmd at `url` for its segment and opens it, following successors: the segment the server writes now.

    The name GET /api/v1/shm gives may be gone by the time it is opened (the server grew the segment meanwhile):
    then it asks again, up to `attempts` times, before raising SegmentGone.
    """
    for attempt in range(attempts):
        try:
            reader = from_server(url, timeout)
        except SegmentGone:
            if attempt + 1 == attempts:
                raise
            continue
        try:
            return reader.follow()
        except ShmError as error:
            reader.close()
            if not isinstance(error, SegmentGone) or attempt + 1 == attempts:
                raise
    raise ShmError("open_live: attempts must be at least 1")


def known_count(values: Sequence[float]) -> int:
    """Cells that are not NaN."""
    if np is not None and isinstance(values, np.ndarray):
        return int(np.count_nonzero(~np.isnan(values)))
    return sum(1 for v in values if v == v)


def open_segment(name: Optional[str], url: str) -> "Reader":
    """The segment the server writes now, by name or from the server (the examples' --name / --server).

    With no name, open_live(url). With a name, that segment with its successors followed; when it or a successor
    is gone, SegmentGone says to ask GET /api/v1/shm.
    """
    if not name:
        return open_live(url)
    try:
        reader = Reader(name)
    except SegmentGone as error:
        raise SegmentGone(
            f"{error}: the server replaced or removed it; ask GET /api/v1/shm for the current name (or use --server)"
        ) from error
    try:
        return reader.follow()
    except ShmError:
        reader.close()
        raise

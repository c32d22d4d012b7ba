"""
Scan geometry: an immutable, validated view of one planar laser scan.

Pure numpy; no rclpy. A :class:`Scan` is built from any object with the fields of
``sensor_msgs/msg/LaserScan`` (an rclpy message, a rosbags message)
or directly from numbers, and answers the questions the lab's nodes and controllers ask: whether
it holds any information, the range at a bearing, the minimum range in five fixed bearing bands,
the nearest valid return and the returns as points in the laser frame.

Conventions (REP-103, REP-117):

- Beam ``i`` points at ``angle_min + i * angle_increment`` (rad, CCW from +x). The number of
  beams is ``len(ranges)``; the message's ``angle_max`` is not used, so a value inconsistent with
  the beam count is tolerated.
- A reading is *valid* when it is finite and ``range_min <= r <= range_max``. +inf means no return
  (free space), -inf means an obstacle too close to measure, NaN means no information.
- *Capped* ranges turn readings into distances a controller can use: +inf and readings above the
  cap become the cap, -inf and readings below ``range_min`` become ``range_min`` (an obstacle too
  close is never free space), NaN stays NaN and is ignored by every minimum taken here.
- Bearings are compared modulo 2 pi, so scanners sweeping 0..2 pi and -pi..pi behave the same.
  Two angles closer than ``ANGLE_TOLERANCE`` are equal: beams exactly on a band edge, and two
  beams equally near a bearing, are then treated symmetrically despite rounding.
- An empty scan (no ranges) is a scan: it has no angles and no valid return, it is blind,
  ``index_at`` and ``closest`` answer None, ``range_at`` the cap and every region None.

Derived arrays are computed on first use and kept: the per-geometry ones (angles, beam
directions, bearing bands) are shared by every scan with the same beam count, ``angle_min`` and
``angle_increment``, because a node sees thousands of scans with one geometry.
"""

import array
import functools
import math
import numbers
import sys
from typing import Any

import numpy as np

ANGLE_TOLERANCE = 1e-9
"""Two angles closer than this (rad) are the same angle."""

REGION_NAMES = ('right', 'front_right', 'front', 'front_left', 'left')
"""Names of the five bearing bands of :meth:`Scan.regions`, right to left."""

REGION_CENTRES = tuple(math.radians(degrees) for degrees in (-72.0, -36.0, 0.0, 36.0, 72.0))
"""Bearings (rad) of the centres of the bands named in ``REGION_NAMES``."""

REGION_HALF_WIDTH = math.radians(18.0)
"""Half the width (rad) of each band of :meth:`Scan.regions`."""

_TWO_PI = 2.0 * math.pi
# A scan sweeping more than this many turns (an angle_increment far too large for its beam
# count) is searched beam by beam rather than turn by turn.
_MAX_TURNS_SEARCHED = 4
# Windows of range_at kept per geometry: a node asks a few; a sweep over many angles must not
# grow memory without bound.
_MAX_WINDOWS = 64


def normalize_angle(angle: float) -> float:
    """Return ``angle`` (rad) wrapped into (-pi, pi] (rad)."""
    if -math.pi < angle <= math.pi:
        return angle
    wrapped = math.pi - (math.pi - angle) % _TWO_PI
    return math.pi if wrapped <= -math.pi else wrapped


def _normalize_angles(angles: np.ndarray) -> np.ndarray:
    wrapped = math.pi - np.mod(math.pi - angles, _TWO_PI)
    wrapped[wrapped <= -math.pi] = math.pi
    # Angles already in range are kept exactly, as normalize_angle keeps them.
    return np.where((angles > -math.pi) & (angles <= math.pi), angles, wrapped)


def _angular_distances(angles: np.ndarray, angle: float) -> np.ndarray:
    """Return |angles - angle| modulo 2 pi, in [0, pi] (rad)."""
    return np.abs(np.mod(angles - angle + math.pi, _TWO_PI) - math.pi)


def _read_only(values: np.ndarray) -> np.ndarray:
    values.flags.writeable = False
    return values


class _Layout:
    """
    What depends only on the beam geometry, computed once per geometry.

    The beam angles and directions, the bearing bands of the regions, and the beams read by
    range_at for each bearing and half width asked (a node asks the same few at every scan).
    """

    __slots__ = ('beams', 'angle_min', 'angle_increment', 'angles', 'directions',
                 'segment_starts', 'band_segments', '_windows')

    def __init__(self, beams: int, angle_min: float, angle_increment: float):
        self.beams = beams
        self.angle_min = angle_min
        self.angle_increment = angle_increment
        self.angles = _read_only(angle_min + np.arange(beams) * angle_increment)
        self.directions = _read_only(np.column_stack((np.cos(self.angles), np.sin(self.angles))))
        bearings = _normalize_angles(self.angles)
        # Bands are mirror images about 0: measuring |bearing| from the front and closing each
        # band on its side towards the front keeps a symmetric scan's regions symmetric.
        edges = np.array(REGION_CENTRES[len(REGION_CENTRES) // 2:]) + (
            REGION_HALF_WIDTH + ANGLE_TOLERANCE)
        rings = np.searchsorted(edges, np.abs(bearings), side='left')
        front = REGION_NAMES.index('front')
        bands = np.where(bearings < 0.0, front - rings, front + rings)
        bands[rings == len(edges)] = -1
        # Consecutive beams of one band form a segment; a band is one segment for a scanner
        # whose field of view does not wrap, at most a few for one that does.
        starts = np.flatnonzero(np.diff(bands)) + 1
        self.segment_starts = np.concatenate(([0], starts)) if beams else starts
        segment_bands = bands[self.segment_starts].tolist()
        self.band_segments = tuple(
            tuple(segment for segment, band in enumerate(segment_bands) if band == wanted)
            for wanted in range(len(REGION_NAMES)))
        self._windows = {}

    def window(self, angle: float, half_width: float) -> np.ndarray:
        """
        Return the sorted indices of the beams range_at reads (read-only, cached).

        The beams within ``half_width`` (rad) of ``angle`` (rad) modulo 2 pi, and the beams
        nearest to ``angle``.
        """
        key = (angle, half_width)
        indices = self._windows.get(key)
        if indices is None:
            nearest = self.nearest(angle)
            if half_width > 0.0 and self.beams:
                inside = _angular_distances(self.angles, angle) <= half_width + ANGLE_TOLERANCE
                inside[nearest] = True
                indices = np.flatnonzero(inside)
            else:
                indices = np.array(nearest, dtype=np.intp)
            if len(self._windows) >= _MAX_WINDOWS:
                self._windows.clear()
            self._windows[key] = _read_only(indices)
        return indices

    def nearest(self, angle: float) -> list[int]:
        """
        Return the indices of the beams nearest to ``angle`` (rad), in increasing order.

        More than one beam when several are equally near (within ``ANGLE_TOLERANCE``); none
        when the nearest is more than half an increment (plus the tolerance) away.
        """
        beams = self.beams
        if beams == 0:
            return []
        step = abs(self.angle_increment)
        reach = step / 2.0 + ANGLE_TOLERANCE
        if beams == 1:
            return [0] if abs(normalize_angle(angle - self.angle_min)) <= reach else []
        span = (beams - 1) * step
        if span > _MAX_TURNS_SEARCHED * _TWO_PI:
            distances = _angular_distances(self.angles, angle)
            nearest = float(distances.min())
            if nearest > reach:
                return []
            return np.flatnonzero(distances <= nearest + ANGLE_TOLERANCE).tolist()
        # The bearing recurs every turn: look for the two beams either side of each recurrence
        # within the sweep, from one turn before angle_min to catch beams just past the start.
        offset = (angle - self.angle_min) % _TWO_PI - _TWO_PI
        candidates = []
        while offset <= span + reach:
            if offset >= -reach:
                below = min(max(math.floor(offset / step), 0), beams - 2)
                candidates.append((abs(offset - below * step), below))
                candidates.append((abs(offset - (below + 1) * step), below + 1))
            offset += _TWO_PI
        if not candidates:
            return []
        nearest = min(candidates)[0]
        if nearest > reach:
            return []
        return sorted({index for distance, index in candidates
                       if distance <= nearest + ANGLE_TOLERANCE})


@functools.lru_cache(maxsize=16)
def _layout(beams: int, angle_min: float, angle_increment: float) -> _Layout:
    return _Layout(beams, angle_min, angle_increment)


def _number(field: str, value: Any) -> float:
    if type(value) is not float:
        if isinstance(value, bool) or not isinstance(value, numbers.Real):
            raise ValueError(f'{field} must be a number, got {value!r}')
        value = float(value)
    return value


def _ranges_array(ranges: Any) -> np.ndarray:
    """Return a private float64 copy of ``ranges`` (m), refusing anything but 1-D numbers."""
    if type(ranges) is array.array and ranges.typecode in 'fd':
        return np.array(ranges, dtype=np.float64)
    if isinstance(ranges, np.ndarray):
        values = ranges
    else:
        try:
            values = np.array(ranges)
        except (TypeError, ValueError) as error:
            raise ValueError(f'ranges must be a sequence of numbers: {error}') from None
    if values.ndim != 1 or values.dtype.kind not in 'fiu':
        raise ValueError(
            f'ranges must be a 1-D sequence of numbers, got {type(ranges).__name__} '
            f'of {values.dtype} with shape {values.shape}')
    # The caller's array is copied; one made from a sequence here is already private.
    return values.astype(np.float64, copy=values is ranges)


def _min_ignoring_nan(values: list) -> float:
    """Return the smallest of ``values``, NaN when they are all NaN (or there are none)."""
    smallest = math.nan
    for value in values:
        if value < smallest or smallest != smallest:
            smallest = value
    return smallest


class Scan:
    """
    One planar laser scan, immutable: ranges (m) on beams at evenly spaced bearings (rad).

    ``Scan(ranges, angle_min, angle_increment, range_min, range_max)`` validates the geometry
    and copies the ranges (any 1-D sequence of numbers: list, tuple, array.array, numpy array)
    into a read-only float64 array. It raises ValueError naming the field when the geometry
    cannot be a scan: a non-number or non-finite ``angle_min``/``angle_increment``/
    ``range_min``, an ``angle_increment`` <= 0 with more than one beam, a NaN ``range_max``
    or ``range_max <= range_min``; or when ``ranges`` is not a 1-D sequence of numbers.
    Range values themselves are never refused: inf, -inf, NaN and out-of-range readings are
    what REP-117 says they are.
    """

    __slots__ = ('_ranges', '_angle_min', '_angle_increment', '_range_min', '_range_max',
                 '_layout', '_valid', '_capped', '_blind')

    def __init__(self, ranges: Any, angle_min: float, angle_increment: float,
                 range_min: float, range_max: float):
        values = _ranges_array(ranges)
        angle_min = _number('angle_min', angle_min)
        angle_increment = _number('angle_increment', angle_increment)
        range_min = _number('range_min', range_min)
        range_max = _number('range_max', range_max)
        if not math.isfinite(angle_min):
            raise ValueError(f'angle_min must be finite, got {angle_min}')
        if not math.isfinite(angle_increment):
            raise ValueError(f'angle_increment must be finite, got {angle_increment}')
        if angle_increment <= 0.0 and len(values) > 1:
            raise ValueError(f'angle_increment must be > 0 with {len(values)} beams, '
                             f'got {angle_increment}')
        if not math.isfinite(range_min):
            raise ValueError(f'range_min must be finite, got {range_min}')
        if not range_max > range_min:
            raise ValueError(f'range_max must be greater than range_min ({range_min}), '
                             f'got {range_max}')
        values.flags.writeable = False
        self._ranges = values
        self._angle_min = angle_min
        self._angle_increment = angle_increment
        self._range_min = range_min
        self._range_max = range_max
        self._layout = None
        self._valid = None
        self._capped = {}
        self._blind = None

    @classmethod
    def from_msg(cls, msg: Any) -> 'Scan':
        """
        Build a Scan from any object with the fields of ``sensor_msgs/msg/LaserScan``.

        ``angle_max`` must be finite but is otherwise ignored: the beam count is
        ``len(msg.ranges)``. Raises ValueError naming the field that is missing or cannot be
        part of a scan.
        """
        try:
            angle_max = _number('angle_max', msg.angle_max)
            scan = cls(msg.ranges, msg.angle_min, msg.angle_increment,
                       msg.range_min, msg.range_max)
        except AttributeError as error:
            raise ValueError(f'not a LaserScan: {error}') from None
        if not math.isfinite(angle_max):
            raise ValueError(f'angle_max must be finite, got {angle_max}')
        return scan

    def __len__(self) -> int:
        return len(self._ranges)

    def __repr__(self) -> str:
        return (f'Scan(<{len(self)} ranges>, angle_min={self._angle_min!r}, '
                f'angle_increment={self._angle_increment!r}, range_min={self._range_min!r}, '
                f'range_max={self._range_max!r})')

    @property
    def ranges(self) -> np.ndarray:
        """Return the readings (m) as a read-only float64 array, one per beam."""
        return self._ranges

    @property
    def angle_min(self) -> float:
        """Bearing of beam 0 (rad)."""
        return self._angle_min

    @property
    def angle_increment(self) -> float:
        """Bearing step between consecutive beams (rad)."""
        return self._angle_increment

    @property
    def angle_max(self) -> float:
        """Bearing of the last beam (rad); ``angle_min`` when there is no beam."""
        return self._angle_min + max(len(self._ranges) - 1, 0) * self._angle_increment

    @property
    def range_min(self) -> float:
        """Smallest range (m) the sensor measures."""
        return self._range_min

    @property
    def range_max(self) -> float:
        """Largest range (m) the sensor measures."""
        return self._range_max

    def _geometry(self) -> _Layout:
        layout = self._layout
        if layout is None:
            layout = _layout(len(self._ranges), self._angle_min, self._angle_increment)
            self._layout = layout
        return layout

    def _cap(self, max_range: float | None) -> float:
        if max_range is None:
            return self._range_max
        cap = _number('max_range', max_range)
        if not cap > 0.0:
            raise ValueError(f'max_range must be > 0, got {max_range}')
        return cap

    def _capped_value(self, reading: float, cap: float) -> float:
        """Cap one reading (m) as :meth:`capped` does, except that NaN becomes the cap."""
        if reading != reading:
            return cap
        return min(max(reading, self._range_min), cap)

    def angles(self) -> np.ndarray:
        """
        Return the bearing of every beam, ``angle_min + i * angle_increment`` (rad).

        The array is read-only and shared by scans of the same geometry.
        """
        return self._geometry().angles

    def directions(self) -> np.ndarray:
        """
        Return the unit vector of every beam, ``(cos(a), sin(a))``: an (N, 2) float array.

        ``a`` is the beam's bearing as :meth:`angles` gives it. The array is read-only and shared
        by scans of the same geometry.
        """
        return self._geometry().directions

    def is_blind(self) -> bool:
        """Return True when the scan tells nothing: it has no beam, or only NaN readings."""
        blind = self._blind
        if blind is None:
            blind = bool(np.count_nonzero(np.isnan(self._ranges)) == len(self._ranges))
            self._blind = blind
        return blind

    def valid(self) -> np.ndarray:
        """Return a read-only boolean mask of the valid readings (finite, within the limits)."""
        mask = self._valid
        if mask is None:
            ranges = self._ranges
            # A finite upper limit also rejects +inf when range_max is +inf.
            upper = min(self._range_max, sys.float_info.max)
            mask = _read_only((ranges >= self._range_min) & (ranges <= upper))
            self._valid = mask
        return mask

    def capped(self, max_range: float | None = None) -> np.ndarray:
        """
        Return the ranges as distances (m): a read-only float64 array.

        +inf and readings above the cap (``max_range``, default ``range_max``, m) become the
        cap; -inf and readings below ``range_min`` become ``range_min``; NaN stays NaN.
        Readings between ``range_max`` and a larger cap are kept as they are.
        """
        cap = self._cap(max_range)
        values = self._capped.get(cap)
        if values is None:
            values = _read_only(np.minimum(np.maximum(self._ranges, self._range_min), cap))
            self._capped[cap] = values
        return values

    def index_at(self, angle: float) -> int | None:
        """
        Return the index of the beam nearest to bearing ``angle`` (rad), or None.

        Bearings are compared modulo 2 pi. When two beams are equally near, the lower index.
        None when ``angle`` is more than half an increment outside the field of view (or the
        scan is empty). Raises ValueError when ``angle`` is not a finite number.
        """
        nearest = self._geometry().window(self._bearing('angle', angle), 0.0)
        return int(nearest[0]) if len(nearest) else None

    @staticmethod
    def _bearing(field: str, angle: Any) -> float:
        angle = _number(field, angle)
        if not math.isfinite(angle):
            raise ValueError(f'{field} must be finite, got {angle}')
        return angle

    def range_at(self, angle: float, half_width: float = 0.0,
                 max_range: float | None = None) -> float:
        """
        Return the minimum capped range (m) of the beams around bearing ``angle`` (rad).

        The beams are those within ``half_width`` (rad, >= 0) of ``angle``, modulo 2 pi, and
        always the beam nearest to ``angle`` as :meth:`index_at` finds it — both of them when
        two are equally near (36 beams over +-1.57 rad have no beam at 0). Ranges are capped as
        :meth:`capped` does with ``max_range`` (m, default ``range_max``); NaN readings are
        ignored. With no usable beam (none there, or all NaN) the answer is the cap.
        """
        angle = self._bearing('angle', angle)
        half_width = _number('half_width', half_width)
        if not half_width >= 0.0:
            raise ValueError(f'half_width must be >= 0, got {half_width}')
        cap = self._cap(max_range)
        readings = self._ranges[self._geometry().window(angle, half_width)]
        # A window of a beam or two, the usual one, is read faster without numpy.
        smallest = (_min_ignoring_nan(readings.tolist()) if len(readings) <= 2
                    else float(np.fmin.reduce(readings, initial=math.nan)))
        return self._capped_value(smallest, cap)

    def regions(self, max_range: float | None = 10.0) -> dict[str, float | None]:
        """
        Return the minimum capped range (m) in each of five fixed bearing bands.

        The dict is ordered right to left: ``right``, ``front_right``, ``front``,
        ``front_left``, ``left``, bands 36 deg wide centred on -72, -36, 0, 36 and 72 deg.
        Each beam belongs to at most one band by its bearing normalised to (-pi, pi]; a beam
        on an edge (within ``ANGLE_TOLERANCE``) belongs to the band nearer the front, and beams
        beyond +-90 deg to none. Ranges are capped as :meth:`capped` does with ``max_range``
        (m; None means ``range_max``); NaN readings are ignored. A band with no beam is None;
        a band whose beams are all NaN is the cap, as in :meth:`range_at`.
        """
        cap = self._cap(max_range)
        ranges = self._ranges
        layout = self._geometry()
        # Capping is monotonic, so capping each band's minimum equals the minimum of the capped
        # band; fmin skips NaN.
        minima = np.fmin.reduceat(ranges, layout.segment_starts).tolist() if len(ranges) else []
        range_min = self._range_min
        regions = {}
        for name, segments in zip(REGION_NAMES, layout.band_segments):
            if len(segments) == 1:
                smallest = minima[segments[0]]
            elif segments:
                smallest = _min_ignoring_nan([minima[segment] for segment in segments])
            else:
                regions[name] = None
                continue
            # Most minima need no capping: skip the call for them.
            regions[name] = (smallest if range_min <= smallest <= cap
                             else self._capped_value(smallest, cap))
        return regions

    def closest(self) -> tuple[float, float, int] | None:
        """
        Return ``(range_m, angle_rad, index)`` of the nearest valid return, or None.

        ``angle_rad`` is the beam's bearing normalised to (-pi, pi]. Among equal ranges, the
        lowest index.
        """
        ranges = self._ranges
        if not len(ranges):
            return None
        # The smallest reading is the answer when it is valid; when it is NaN (argmin finds
        # NaN first) or below range_min, look again among the readings not below range_min.
        index = int(ranges.argmin())
        range_m = ranges.item(index)
        if not range_m >= self._range_min:
            candidates = np.where(ranges >= self._range_min, ranges, math.inf)
            index = int(candidates.argmin())
            range_m = candidates.item(index)
        # Every reading not below range_min is at least range_m: all invalid if it is.
        if not range_m <= self._range_max or range_m == math.inf:
            return None
        bearing = normalize_angle(self._angle_min + index * self._angle_increment)
        return range_m, bearing, index

    def points(self) -> np.ndarray:
        """
        Return the valid returns as an (N, 2) float array of x, y (m) in the laser frame.

        Beam ``i`` with range ``r`` is at ``(r cos(a), r sin(a))``, ``a = angle_min +
        i * angle_increment``, as laser_geometry's projectLaser places it.
        """
        mask = self.valid()
        # compress selects rows as [mask] does, faster.
        return self.directions().compress(mask, axis=0) * self._ranges[mask][:, np.newaxis]

"""The marker convention and the table calibration (TOML).

Markers are ArUco tags of OpenCV's ``DICT_4X4_50`` dictionary:

* robot ``j`` (``0 <= j < 46``) carries tag id ``j`` on its middle link (link
  ``N // 2``), centred on the link, read upright when the robot's head is on
  the left: the tag's top edge runs from the head side to the tail side, so
  the edge from its first to its second corner points head -> tail;
* tags 46, 47, 48 and 49 lie fixed on the table, upright (top edge along the
  table's +x, their tops toward +y), at known positions of their centres.

The table frame is right-handed, x along the channel with the robots' heads
toward -x (the simulation's convention), y across it, in metres.  A robot's
heading is the angle of its middle link's head -> tail direction from +x,
rad (0: head toward -x, as :func:`undulate.simulate` records it).

The calibration file (TOML)::

    [markers]          # fixed tag id = [x, y] of its centre, m
    46 = [0.0, 0.0]
    47 = [1.0, 0.0]
    48 = [0.0, 0.25]
    49 = [1.0, 0.25]
    size_m = 0.03      # side of every tag's black square, m (robot tags too)

    [camera]           # optional: the lens's intrinsics (OpenCV calibrateCamera), pixels
    matrix = [[1650.0, 0.0, 960.0], [0.0, 1650.0, 540.0], [0.0, 0.0, 1.0]]
    distortion = [-0.08, 0.02, 0.0, 0.0, 0.0]   # k1, k2, p1, p2[, k3]

Without a file the default layout (:data:`DEFAULT_MARKERS_M`, printed on the
marker sheet) and tag size :data:`DEFAULT_SIZE_M` apply and the lens is taken
as distortion-free.
"""

from __future__ import annotations

import math
import tomllib
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..errors import ParameterError

__all__ = ["DICTIONARY", "FIXED_IDS", "MAX_ROBOTS", "DEFAULT_MARKERS_M", "DEFAULT_SIZE_M", "TrackCalibration",
           "robot_tag_link"]

DICTIONARY = "DICT_4X4_50"
"""The ArUco dictionary (OpenCV name): 4 x 4 bits, ids 0-49."""
FIXED_IDS = (46, 47, 48, 49)
"""Ids of the four tags fixed on the table."""
MAX_ROBOTS = 46
"""Robot tags are ids 0 .. MAX_ROBOTS - 1."""
DEFAULT_MARKERS_M = {46: (0.0, 0.0), 47: (1.0, 0.0), 48: (0.0, 0.25), 49: (1.0, 0.25)}
"""Default fixed-tag centres, m: the corners of a 1 m x 0.25 m rectangle around the channel."""
DEFAULT_SIZE_M = 0.03
"""Default tag side (the black square), m."""


def robot_tag_link(n_links: int) -> int:
    """Index of the link carrying the robot tag: the middle link ``N // 2``
    (head = link 0; for even N the first link behind the middle joint)."""
    return int(n_links) // 2


@dataclass(frozen=True)
class TrackCalibration:
    """Where the fixed tags lie, how big every tag is, and (optionally) the lens.

    ``markers_m``: fixed tag id -> (x, y) of its centre, m (all of
    :data:`FIXED_IDS`).  ``size_m``: side of every tag's black square, m.
    ``camera_matrix`` (3 x 3, px) and ``distortion`` (OpenCV's k1, k2, p1, p2
    [, k3 ...]): the lens, or None for an ideal pinhole.
    """

    markers_m: dict = field(default_factory=lambda: dict(DEFAULT_MARKERS_M))
    size_m: float = DEFAULT_SIZE_M
    camera_matrix: tuple | None = None
    distortion: tuple | None = None
    source: str = "default layout"

    def __post_init__(self):
        m = {}
        for k, v in dict(self.markers_m).items():
            try:
                key = int(k)
            except (TypeError, ValueError):
                raise ParameterError("calibration [markers]", "tag ids 46-49 as keys", k) from None
            if key not in FIXED_IDS:
                raise ParameterError("calibration [markers]", "keys among the fixed tag ids 46, 47, 48, 49", k)
            try:
                xy = tuple(float(c) for c in v)
            except (TypeError, ValueError):
                raise ParameterError(f"calibration [markers] {key}", "[x, y] in metres", v) from None
            if len(xy) != 2 or not all(math.isfinite(c) for c in xy):
                raise ParameterError(f"calibration [markers] {key}", "[x, y]: two finite numbers, m", v)
            m[key] = xy
        missing = [i for i in FIXED_IDS if i not in m]
        if missing:
            raise ParameterError("calibration [markers]", "positions for all four fixed tags 46-49",
                                 f"missing {', '.join(map(str, missing))}")
        object.__setattr__(self, "markers_m", m)
        try:
            s = float(self.size_m)
        except (TypeError, ValueError):
            raise ParameterError("calibration size_m", "a tag side in metres, > 0", self.size_m) from None
        if not (math.isfinite(s) and 0 < s < 1):
            raise ParameterError("calibration size_m", "a tag side in metres, in (0, 1)", self.size_m)
        object.__setattr__(self, "size_m", s)
        pts = np.array([m[i] for i in FIXED_IDS])
        for a in range(4):
            for b in range(a + 1, 4):
                if np.hypot(*(pts[a] - pts[b])) < 1.5 * s:
                    raise ParameterError("calibration [markers]", "fixed tags at least 1.5 tag sides apart",
                                         f"{FIXED_IDS[a]} and {FIXED_IDS[b]}")
        # four centres on one line give no homography
        c = pts - pts.mean(axis=0)
        if np.linalg.svd(c, compute_uv=False)[-1] < 0.05 * np.linalg.svd(c, compute_uv=False)[0]:
            raise ParameterError("calibration [markers]", "four tag centres not on one line", m)
        if (self.camera_matrix is None) != (self.distortion is None):
            raise ParameterError("calibration [camera]", "both matrix and distortion, or neither", None)
        if self.camera_matrix is not None:
            K = np.asarray(self.camera_matrix, dtype=float)
            if K.shape != (3, 3) or not np.all(np.isfinite(K)) or K[0, 0] <= 0 or K[1, 1] <= 0:
                raise ParameterError("calibration [camera] matrix", "a 3 x 3 camera matrix with fx, fy > 0 (px)",
                                     self.camera_matrix)
            d = np.asarray(self.distortion, dtype=float).ravel()
            if d.size not in (4, 5, 8, 12, 14) or not np.all(np.isfinite(d)):
                raise ParameterError("calibration [camera] distortion",
                                     "OpenCV distortion coefficients (k1, k2, p1, p2[, k3 ...]: 4, 5, 8, 12 or 14 numbers)",
                                     self.distortion)
            object.__setattr__(self, "camera_matrix", tuple(tuple(float(v) for v in row) for row in K))
            object.__setattr__(self, "distortion", tuple(float(v) for v in d))

    @classmethod
    def from_toml(cls, path: str | Path) -> "TrackCalibration":
        """Read a calibration file (see the module docstring)."""
        path = Path(path)
        try:
            with open(path, "rb") as f:
                doc = tomllib.load(f)
        except OSError as e:
            raise ParameterError("--calibration", "a readable TOML file", f"{path} ({e.strerror})") from None
        except tomllib.TOMLDecodeError as e:
            raise ParameterError("--calibration", "a valid TOML file", f"{path}: {e}") from None
        markers = doc.get("markers")
        if not isinstance(markers, dict):
            raise ParameterError("--calibration", "a TOML file with a [markers] table (46 = [x, y] ... in m)", str(path))
        markers = dict(markers)
        size = markers.pop("size_m", doc.get("size_m"))
        if size is None:
            raise ParameterError("calibration size_m", "given (the side of every tag, m)", None)
        cam = doc.get("camera") or {}
        return cls(markers_m=markers, size_m=size, camera_matrix=cam.get("matrix"), distortion=cam.get("distortion"),
                   source=str(path))

    def to_toml(self) -> str:
        """The calibration as TOML text (readable by :meth:`from_toml`)."""
        lines = ["[markers]  # fixed tag id = [x, y] of its centre, m (tags upright: top edge along +x)"]
        lines += [f"{i} = [{x!r}, {y!r}]" for i, (x, y) in sorted(self.markers_m.items())]
        lines.append(f"size_m = {self.size_m!r}  # side of every tag's black square, m")
        if self.camera_matrix is not None:
            lines += ["", "[camera]  # lens intrinsics, px (OpenCV calibrateCamera)",
                      "matrix = [" + ", ".join("[" + ", ".join(repr(v) for v in r) + "]" for r in self.camera_matrix) + "]",
                      "distortion = [" + ", ".join(repr(v) for v in self.distortion) + "]"]
        return "\n".join(lines) + "\n"

    def corners_m(self, tag_id: int) -> np.ndarray:
        """Table coordinates of a fixed tag's four corners in ArUco order
        (top-left, top-right, bottom-right, bottom-left, the tag upright), m: (4, 2)."""
        x, y = self.markers_m[int(tag_id)]
        h = self.size_m / 2
        return np.array([[x - h, y + h], [x + h, y + h], [x + h, y - h], [x - h, y - h]])

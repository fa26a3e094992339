"""Overhead video -> the trajectory dataset a simulation produces.

Each frame is searched for ArUco tags (``DICT_4X4_50``, corners refined to
sub-pixel accuracy by fitting lines to each tag's contour).  The four fixed tags (46-49) seen during the first
``calibration_s`` seconds give the homography from (undistorted) image
pixels to table metres: each tag's corners are averaged over those frames and
all 16 corners fitted by least squares (the camera must not move after).
Every robot tag's four corners are then mapped to the table; the robot's
point is their mean (the tag's centre) and its heading the direction of the
tag's top edge (head -> tail, rad from +x), fitted to all four corners.

Nothing is filled in: a robot whose tag is not found in a frame (occluded,
blurred, out of view) or found twice (ambiguous) has ``tracked = False`` and
NaN there; a frame missing from the video (a gap in its timestamps larger
than 1.5 frame intervals) gets rows of its own with ``tracked = False`` and
``frame = -1``.  Identities come from the tag ids only, so they cannot swap.
"""

from __future__ import annotations

import json
import math
import os
import sys
from pathlib import Path

import numpy as np

from ..errors import ParameterError
from ..execution import quiet_opencv_ffmpeg
from .calibration import DICTIONARY, FIXED_IDS, MAX_ROBOTS, TrackCalibration, robot_tag_link

__all__ = ["track_video", "make_detector"]


def make_detector():
    """The ArUco detector the tracker uses: ``DICT_4X4_50``, corners refined by
    fitting lines to the tag's contour (``CORNER_REFINE_CONTOUR``).

    On rendered 1080p video with every degradation at once the contour fit
    gave 0.10 mm RMS centre and 0.29 deg heading error; ``cornerSubPix``
    (``CORNER_REFINE_SUBPIX``, windows of 3-6 px) gave 0.3-0.5 mm and 0.9-1.3 deg.
    """
    import cv2

    aruco = cv2.aruco
    p = aruco.DetectorParameters()
    p.cornerRefinementMethod = aruco.CORNER_REFINE_CONTOUR
    # small, blurred, compressed tags: sample each bit over 8 x 8 px, use all of the dictionary's error
    # correction (ids beyond the robots' and the table's are ignored and a repeated id is dropped, so a
    # misread tag is never taken for a robot silently) and one more, coarser threshold window.
    # Measured on 720p video with every degradation: robot tags found in 8 % -> 98-100 % of frames.
    p.errorCorrectionRate = 1.0
    p.perspectiveRemovePixelPerCell = 8
    p.adaptiveThreshWinSizeMax = 33
    p.minMarkerPerimeterRate = 0.01  # tags are small in a wide view
    return aruco.ArucoDetector(aruco.getPredefinedDictionary(getattr(aruco, DICTIONARY)), p)


def _undistort(pts: np.ndarray, cal: TrackCalibration) -> np.ndarray:
    """Image pixels -> ideal pinhole pixels (identity without a lens model)."""
    if cal.camera_matrix is None:
        return pts
    import cv2

    K = np.asarray(cal.camera_matrix)
    d = np.asarray(cal.distortion)
    out = cv2.undistortPoints(pts.reshape(-1, 1, 2).astype(np.float64), K, d, R=None, P=K,
                              criteria=(cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, 50, 1e-6))
    return out.reshape(pts.shape)


def _apply_h(H: np.ndarray, pts: np.ndarray) -> np.ndarray:
    p = pts.reshape(-1, 2) @ H[:, :2].T + H[:, 2]
    return (p[:, :2] / p[:, 2:]).reshape(pts.shape)


def track_video(video: str | os.PathLike, n_robots: int, calibration: TrackCalibration | None = None, *,
                calibration_s: float = 2.0, start_time_s: float = 0.0, scene=None, progress: bool | None = None):
    """Track ``n_robots`` robot tags (ids 0 .. n_robots-1) through ``video``.

    ``calibration``: fixed-tag layout, tag size and lens (default: the
    default layout, no lens model).  ``calibration_s``: the fixed tags must
    all be seen within this many seconds from the start.  ``start_time_s``:
    the experiment clock's time of the first frame (e.g. the robot log's gait
    time), s; ``time`` = video timestamp + ``start_time_s``.  ``scene``: the
    experiment's :class:`~undulate.params.Scene` (gait, phases, geometry,
    channel), recorded in the ``config`` attribute for ``undulate compare``.
    ``progress``: a progress bar on stderr (default: when it is a terminal).

    Returns an ``xarray.Dataset`` with the simulation's names, dims and units
    (``time`` s, ``swimmer``; ``x``, ``y`` m; ``heading`` rad) plus
    ``tracked`` (bool), ``frame`` (video frame index, -1 = missing) and
    ``tag_side`` (measured tag side, m: a check of the scale).  Raises
    :class:`~undulate.errors.ParameterError` (naming ``VIDEO``, ``--robots``
    or the calibration) for an unreadable video, calibration tags not all
    seen in the first ``calibration_s`` or robots never found.
    """
    import cv2

    video = Path(video)
    cal = calibration or TrackCalibration()
    n = _check_arguments(video, n_robots, calibration_s, start_time_s)
    frames = _read_video(video, n, calibration_s, progress)
    found = np.isfinite(frames.corners[..., 0, 0])
    never = [j for j in range(n) if not found[:, j].any()]
    if never:
        seen = [j for j in range(n) if found[:, j].any()]
        raise ParameterError("--robots", f"at most the number of robots whose tags appear in the video "
                             f"(found tag id(s) {', '.join(map(str, seen)) or 'none'}; never saw "
                             f"{', '.join(map(str, never))})", n)

    # --- image -> table: all four fixed tags' corners, averaged over the calibration window ---------------
    img_pts = np.concatenate([_undistort(np.mean(frames.fixed[i], axis=0), cal) for i in FIXED_IDS])
    tab_pts = np.concatenate([cal.corners_m(i) for i in FIXED_IDS])
    H, _ = cv2.findHomography(img_pts, tab_pts, 0)
    if H is None:
        raise ParameterError("VIDEO", "a video whose four calibration tags give a homography", str(video))
    cal_resid = np.sqrt(np.mean(np.sum((_apply_h(H, img_pts) - tab_pts) ** 2, axis=-1)))

    poses = _tag_poses(frames.corners, found, H, cal)
    step, stamps, frame_idx, (cx, cy, heading, side, found) = _fill_missing_frames(
        frames.stamps, video, poses + (found,), (np.nan, np.nan, np.nan, np.nan, False))
    attrs = {
        **_track_attrs(video, frames, cal, step, frame_idx, start_time_s, calibration_s),
        "homography_image_to_table": json.dumps(H.tolist()),
        "calibration_residual_rms": float(cal_resid),
        "calibration_residual_rms_units": "m (fixed-tag corners after the homography)",
        "ignored_tag_ids": json.dumps(sorted(frames.extra_ids)),
        "duplicate_detections": int(frames.duplicates),
        "conventions": "table frame: x along the channel, heads toward -x; heading = head -> tail direction of "
                       "the middle link from +x; dx = x_upper - x_lower, dphi = phi_upper - phi_lower",
        **{f"provenance_{k}": v for k, v in _provenance(cv2).items()},
    }
    return _tracked_dataset(stamps + start_time_s, n, scene, attrs, cx, cy, heading, side, found, frame_idx)


MAX_START_TIME_S = 1e9
"""The largest ``start_time_s`` magnitude, s (~32 years): the frame times are ``start_time_s`` plus the
video's timestamps in float64, whose spacing there is 1.2e-7 s; at 1e300 every frame had the same
time."""


def _check_arguments(video: Path, n_robots, calibration_s: float, start_time_s: float) -> int:
    """:func:`track_video`'s arguments, validated; the number of robots."""
    try:
        n = int(n_robots)
    except (TypeError, ValueError):
        raise ParameterError("--robots", f"an integer in [1, {MAX_ROBOTS}]", n_robots) from None
    if n != n_robots or not 1 <= n <= MAX_ROBOTS:
        raise ParameterError("--robots", f"an integer in [1, {MAX_ROBOTS}]", n_robots)
    if not (math.isfinite(calibration_s) and calibration_s > 0):
        raise ParameterError("calibration_s", "> 0 s", calibration_s)
    if not (math.isfinite(start_time_s) and abs(start_time_s) <= MAX_START_TIME_S):
        raise ParameterError("--start-time", f"a time within +-{MAX_START_TIME_S:g} s (frame times must "
                             "resolve microseconds)", start_time_s)
    if not video.is_file():
        raise ParameterError("VIDEO", "an existing video file", str(video))
    return n


class _Frames:
    """What the detector saw, frame by frame: video timestamps (s), robot tag corners
    (frame, robot, 4, 2; image px, NaN where not found), the fixed tags' corners over the
    calibration window, ids of other tags, and robot tags seen twice in one frame."""

    def __init__(self, n: int):
        self.n = n
        self.stamps: list[float] = []
        self.corners: list[np.ndarray] | np.ndarray = []
        self.fixed: dict[int, list[np.ndarray]] = {i: [] for i in FIXED_IDS}
        self.extra_ids: set[int] = set()
        self.duplicates = 0
        self.calibrated = False
        self.size_px = (0, 0)

    def add(self, t_s: float, cs, ids) -> None:
        """One frame's detections (``cs``, ``ids`` as OpenCV's ``detectMarkers`` returns them)."""
        self.stamps.append(t_s)
        c = np.full((self.n, 4, 2), np.nan)
        if ids is not None:
            ids = ids.ravel()
            counts = np.bincount(ids, minlength=50)
            for tag_id, quad in zip(ids, cs):
                quad = quad.reshape(4, 2)
                if tag_id < self.n:
                    if counts[tag_id] == 1:
                        c[tag_id] = quad
                    else:
                        self.duplicates += 1
                elif tag_id in self.fixed:
                    if not self.calibrated and counts[tag_id] == 1:
                        self.fixed[int(tag_id)].append(quad.astype(np.float64))
                else:
                    self.extra_ids.add(int(tag_id))
        self.corners.append(c)


def _read_video(video: Path, n: int, calibration_s: float, progress: bool | None) -> _Frames:
    """Detect the tags in every frame of ``video``; the fixed tags are checked once
    ``calibration_s`` of video has been read (or at its end, if shorter)."""
    import cv2

    quiet_opencv_ffmpeg()  # FFmpeg's own messages would add lines to our one-line errors
    cap = cv2.VideoCapture(str(video))
    ok, img = cap.read() if cap.isOpened() else (False, None)
    if not ok or img is None:
        cap.release()
        raise ParameterError("VIDEO", "a video file OpenCV can decode", str(video))
    n_total = int(cap.get(cv2.CAP_PROP_FRAME_COUNT)) or None
    frames = _Frames(n)
    frames.size_px = (int(img.shape[1]), int(img.shape[0]))
    if progress is None:
        progress = sys.stderr.isatty()
    bar = None
    if progress:
        from tqdm import tqdm

        bar = tqdm(total=n_total, unit="frame", desc=f"track {video.name}", file=sys.stderr)
    det = make_detector()
    try:
        while ok:
            t_s = cap.get(cv2.CAP_PROP_POS_MSEC) / 1000.0
            gray = cv2.cvtColor(img, cv2.COLOR_BGR2GRAY) if img.ndim == 3 else img
            cs, ids, _ = det.detectMarkers(gray)
            frames.add(t_s, cs, ids)
            if not frames.calibrated and frames.stamps[-1] - frames.stamps[0] >= calibration_s:
                _check_fixed(frames.fixed, calibration_s, video)
                frames.calibrated = True
            if bar is not None:
                bar.update()
            ok, img = cap.read()
    finally:
        cap.release()
        if bar is not None:
            bar.close()
    if not frames.calibrated:
        _check_fixed(frames.fixed, calibration_s, video)
    frames.corners, frames.stamps = np.asarray(frames.corners), np.asarray(frames.stamps)
    return frames


def _tag_poses(corners: np.ndarray, found: np.ndarray, H: np.ndarray, cal: TrackCalibration):
    """Robot tags' corners -> table: centre ``cx, cy`` (m), ``heading`` (rad, unwrapped over
    the tracked samples only: a gap is not a jump) and mean ``side`` (m), each (frame, robot)."""
    flat = corners.reshape(-1, 2)
    good = np.isfinite(flat[:, 0])
    tab = np.full_like(flat, np.nan)
    tab[good] = _apply_h(H, _undistort(flat[good], cal))
    tab = tab.reshape(corners.shape)
    cx, cy = tab[..., 0].mean(axis=-1), tab[..., 1].mean(axis=-1)
    # heading: the rotation that best maps the upright square onto the four corners (all four edges count)
    q = np.array([[-1.0, 1.0], [1.0, 1.0], [1.0, -1.0], [-1.0, -1.0]])  # TL, TR, BR, BL, top edge along +x
    p = tab - np.stack([cx, cy], axis=-1)[..., None, :]
    heading = np.arctan2((q[:, 0] * p[..., 1] - q[:, 1] * p[..., 0]).sum(axis=-1),
                         (q[:, 0] * p[..., 0] + q[:, 1] * p[..., 1]).sum(axis=-1))
    side = np.linalg.norm(np.roll(tab, -1, axis=2) - tab, axis=-1).mean(axis=-1)
    for j in range(corners.shape[1]):
        f = found[:, j]
        heading[f, j] = np.unwrap(heading[f, j])
    return cx, cy, heading, side


def _fill_missing_frames(stamps: np.ndarray, video: Path, arrays: tuple, fills: tuple):
    """Time from the video's timestamps, with a row of its own for every frame missing from the
    video (gaps of whole frame intervals): ``(frame interval s, times s, frame index (-1: missing),
    arrays spread onto those rows with their fill values)``."""
    frame_idx = np.arange(len(stamps))
    if len(stamps) <= 1:
        return float("nan"), stamps, frame_idx, arrays
    d = np.diff(stamps)
    step = float(np.median(d))
    if not step > 0:
        raise ParameterError("VIDEO", "a video with increasing frame timestamps", str(video))
    missing = np.maximum(np.round(d / step).astype(int) - 1, 0)
    if not missing.any():
        return step, stamps, frame_idx, arrays
    rows = np.concatenate([[0], np.cumsum(missing + 1)])
    t_full = np.empty(rows[-1] + 1)
    t_full[:] = np.nan
    t_full[rows] = stamps
    for i in np.flatnonzero(missing):
        k = missing[i]
        t_full[rows[i] + 1:rows[i + 1]] = stamps[i] + step * np.arange(1, k + 1)

    def spread(a, fill):
        out = np.full((len(t_full),) + a.shape[1:], fill, dtype=a.dtype)
        out[rows] = a
        return out

    return step, t_full, spread(frame_idx, -1), tuple(spread(a, f) for a, f in zip(arrays, fills))


def _provenance(cv2) -> dict:
    from ..provenance import package_version, provenance

    prov = provenance()
    prov["opencv_version"] = package_version("opencv-python-headless", cv2.__version__)
    return prov


def _track_attrs(video: Path, frames: _Frames, cal: TrackCalibration, step: float, frame_idx: np.ndarray,
                 start_time_s: float, calibration_s: float) -> dict:
    """The tracked dataset's attributes about the video, the tags and the calibration."""
    return {
        "title": "undulate tracked experiment",
        "source": "video",
        "video": video.name,
        "video_size_px": list(frames.size_px),
        "frame_interval": step,
        "frame_interval_units": "s",
        "frames_in_video": int(len(frames.corners)),
        "frames_missing": int((frame_idx < 0).sum()),
        "start_time": float(start_time_s),
        "start_time_units": "s (time of the video's first frame on the experiment clock)",
        "body_point": "robot tag centre = centre of the middle link (link N // 2)",
        "dictionary": DICTIONARY,
        "fixed_tags": json.dumps({str(k): list(v) for k, v in cal.markers_m.items()}),
        "tag_size": cal.size_m,
        "tag_size_units": "m",
        "lens_model": "OpenCV pinhole + distortion (calibration [camera])" if cal.camera_matrix is not None
                      else "none (ideal pinhole)",
        "calibration_source": cal.source,
        "calibration_window": float(calibration_s),
        "calibration_window_units": "s",
    }


def _tracked_dataset(t, n, scene, attrs, cx, cy, heading, side, found, frame_idx):
    """The tracked ``xarray.Dataset`` (names, dims and units of :mod:`undulate.schema`), with the
    experiment's scene (for ``undulate compare``) when one is given."""
    import xarray as xr

    dims = ("time", "swimmer")
    link_note = "the robot tag's centre (middle link)"
    coords = {"time": ("time", t, {"units": "s", "long_name": "time (video timestamp + start_time)"}),
              "swimmer": ("swimmer", np.arange(n), {"long_name": "robot = tag id"})}
    if scene is not None:
        if scene.n_swimmers != n:
            raise ParameterError("--phases", f"{n} values, one per robot (--robots {n})", len(scene.phases_rad))
        from ..schema import scene_attrs

        g = scene.geometry
        attrs.update({
            **scene_attrs(scene),
            "controller": scene.controller.kind, "tag_link": robot_tag_link(g.n_links),
            "config": json.dumps({"scene": scene.to_dict()}),
        })
        coords["phase"] = ("swimmer", np.asarray(scene.phases_rad), {"units": "rad", "long_name": "gait phase phi"})
    return xr.Dataset(
        {"x": (dims, cx, {"units": "m", "long_name": f"x of {link_note}"}),
         "y": (dims, cy, {"units": "m", "long_name": f"y of {link_note}"}),
         "heading": (dims, heading, {"units": "rad", "long_name": "middle-link orientation: head -> tail direction "
                                                                  "from +x (0: head toward -x)"}),
         "tracked": (dims, found, {"units": "1", "long_name": "robot tag found (False: occluded, not detected, "
                                                             "ambiguous or frame missing; x, y, heading NaN)"}),
         "frame": (("time",), frame_idx.astype(np.int64), {"units": "1", "long_name": "video frame index (-1: missing "
                                                                                       "from the video)"}),
         "tag_side": (dims, side, {"units": "m", "long_name": "measured side of the robot tag (scale check)"})},
        coords=coords, attrs=attrs)


def _check_fixed(fixed: dict, calibration_s: float, video: Path) -> None:
    missing = [i for i in FIXED_IDS if not fixed[i]]
    if missing:
        raise ParameterError("VIDEO", f"a video showing the four calibration tags 46-49 within its first "
                             f"{calibration_s:g} s", f"{video.name}: tag(s) {', '.join(map(str, missing))} not seen")

"""Synthetic overhead videos of simulated runs, degraded as a real camera would film them.

Ground truth for the tracker (:func:`undulate.track.track_video`): a run's
bodies are drawn from above on a textured table with the four fixed
calibration tags and, on every middle link, its robot tag at the link's true
pose (:func:`~undulate.observables.middle_link_pose`); a pinhole camera
with lens distortion films the table plane, then blur, uneven lighting,
sensor noise and H.264 compression degrade the frames.  Frames can be dropped
(the video then has gaps in its timestamps) and tags occluded by a passing
"hand".

The table is one plane: bodies, robot tags, walls and fixed tags lie in it
(the set-up docs/tracking.md asks for: fixed tags at the height of the robot
tags).  The simulation's frame maps into the table frame by a shift
(``placement_m``: where the simulation's origin lies), axes unchanged.

Frames are built by one ``cv2.remap`` per frame from a supersampled top view
of the table (1.5 table pixels per camera pixel) through the exact inverse of
the camera (undistortion, then the plane's homography), so tag edges land at
sub-pixel accurate positions.  Deterministic: the same run, options and seed
give the same video bytes.
"""

from __future__ import annotations

import math
import os
import subprocess
from dataclasses import dataclass
from fractions import Fraction
from pathlib import Path

import numpy as np

from ..errors import ParameterError
from ..observables import middle_link_pose
from .calibration import DICTIONARY, FIXED_IDS, TrackCalibration

__all__ = ["CameraSetup", "Degradation", "Occluder", "DEGRADATIONS", "render_video", "plane_homography"]


@dataclass(frozen=True)
class CameraSetup:
    """The camera: resolution, field of view and pose above the table.

    The camera looks at the centre of the fixed tags' layout from the
    distance that makes the layout plus ``margin_m`` fill the frame;
    ``tilt_rad`` pitches it about the table's x axis (perspective: the far
    side of the table appears smaller), ``roll_rad`` turns it about its
    optical axis.  ``distortion``: OpenCV's k1, k2, p1, p2, k3 of the lens.
    """

    width_px: int = 1920
    height_px: int = 1080
    hfov_rad: float = math.radians(60.0)
    tilt_rad: float = 0.0
    roll_rad: float = 0.0
    distortion: tuple[float, ...] = (0.0, 0.0, 0.0, 0.0, 0.0)
    margin_m: float = 0.06


@dataclass(frozen=True)
class Degradation:
    """Image degradations after the optics.

    ``blur_px``: Gaussian blur sigma, px (focus and motion); ``noise_dn``:
    sensor noise standard deviation in 8-bit digital numbers; ``lighting``:
    uneven illumination, the gain falls by this fraction from the brightest
    spot to the darkest corner; ``crf``: H.264 constant rate factor
    (0 = lossless luma, 18 = visually transparent, the default; 23 = x264's
    default, higher = harder compression).
    """

    blur_px: float = 0.0
    noise_dn: float = 0.0
    lighting: float = 0.0
    crf: int = 18


@dataclass(frozen=True)
class Occluder:
    """A hand-sized disc over the table from ``t_start_s`` to ``t_end_s``
    (simulation time, s), centred at table ``(x_m, y_m)``, radius ``radius_m``."""

    t_start_s: float
    t_end_s: float
    x_m: float
    y_m: float
    radius_m: float = 0.04


DEGRADATIONS: dict[str, tuple[dict, Degradation]] = {
    "ideal": ({}, Degradation()),
    "perspective": ({"tilt_rad": math.radians(20.0), "roll_rad": math.radians(4.0)}, Degradation()),
    "distortion": ({"distortion": (-0.12, 0.05, 0.0, 0.0, 0.0)}, Degradation()),
    "blur": ({}, Degradation(blur_px=1.5)),
    "noise": ({}, Degradation(noise_dn=8.0)),
    "lighting": ({}, Degradation(lighting=0.6)),
    "compression": ({}, Degradation(crf=28)),
    "all": ({"tilt_rad": math.radians(20.0), "roll_rad": math.radians(4.0), "distortion": (-0.12, 0.05, 0.0, 0.0, 0.0)},
            Degradation(blur_px=1.5, noise_dn=8.0, lighting=0.6, crf=28)),
}
"""Named camera cases: (CameraSetup overrides, Degradation).  ``all`` combines every one."""


def _look_at(camera: CameraSetup, aim: np.ndarray, distance_m: float) -> tuple[np.ndarray, np.ndarray]:
    """Rotation (rows: camera x, y, z axes in table coordinates) and centre of the camera."""
    t, r = camera.tilt_rad, camera.roll_rad
    centre = aim + distance_m * np.array([0.0, -math.sin(t), math.cos(t)])
    z = (aim - centre) / np.linalg.norm(aim - centre)
    hint = np.array([math.cos(r), math.sin(r), 0.0])
    x = hint - hint.dot(z) * z
    x /= np.linalg.norm(x)
    y = np.cross(z, x)
    return np.stack([x, y, z]), centre


def plane_homography(K: np.ndarray, R: np.ndarray, centre: np.ndarray) -> np.ndarray:
    """Homography from table coordinates (m, z = 0) to ideal (undistorted) image pixels."""
    t = -R @ centre
    return K @ np.column_stack([R[:, 0], R[:, 1], t])


def _camera(camera: CameraSetup, region: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Camera matrix and table->image homography framing ``region`` ((2, 2): [[x0, y0], [x1, y1]], m)."""
    W, H = camera.width_px, camera.height_px
    f = 0.5 * W / math.tan(0.5 * camera.hfov_rad)
    K = np.array([[f, 0.0, 0.5 * W - 0.5], [0.0, f, 0.5 * H - 0.5], [0.0, 0.0, 1.0]])
    aim = np.array([region[:, 0].mean(), region[:, 1].mean(), 0.0])
    corners = np.array([[x, y, 1.0] for x in region[:, 0] for y in region[:, 1]])
    d = 1.0
    for _ in range(20):  # the distance at which the region fills 94 % of the frame
        R, c = _look_at(camera, aim, d)
        p = (plane_homography(K, R, c) @ corners.T).T
        p = p[:, :2] / p[:, 2:]
        fill = max(np.abs(p[:, 0] - K[0, 2]).max() / (0.5 * W), np.abs(p[:, 1] - K[1, 2]).max() / (0.5 * H))
        d *= fill / 0.94
    R, c = _look_at(camera, aim, d)
    return K, plane_homography(K, R, c)


def _marker_image(aruco, dictionary, tag_id: int, cell_px: int) -> np.ndarray:
    """The tag with a one-cell white quiet zone: (8 cells)^2, uint8."""
    core = aruco.generateImageMarker(dictionary, int(tag_id), 6 * cell_px)
    return np.pad(core, cell_px, constant_values=255)


def _texture(rng: np.random.Generator, shape: tuple[int, int], ppm: float) -> np.ndarray:
    """A table top: wood-grain-like low-frequency mottling plus fine grain, BGR uint8."""
    import cv2

    h, w = shape
    base = np.zeros((h, w), np.float32)
    for scale_m, amp in ((0.08, 18.0), (0.02, 10.0), (0.004, 6.0)):
        s = max(1, int(round(scale_m * ppm)))
        small = rng.standard_normal((h // s + 2, w // s + 2)).astype(np.float32)
        base += amp * cv2.resize(small, (w, h), interpolation=cv2.INTER_CUBIC)
    grain = np.sin(np.linspace(0, 90 * np.pi, w, dtype=np.float32))[None, :] * 5.0
    v = 150.0 + base + grain
    img = np.stack([0.62 * v, 0.80 * v, v], axis=-1)  # warm wood colour (B, G, R)
    return np.clip(img, 0, 255).astype(np.uint8)


def _put_tag(cv2, img: np.ndarray, tag: np.ndarray, T: np.ndarray, centre_m, heading_rad: float,
             side_m: float) -> None:
    """Draw ``tag`` (square image, white quiet zone included, ``side_m`` wide) on the
    table image ``img`` centred at ``centre_m``, its top edge along ``heading_rad``."""
    n = tag.shape[0]
    s = side_m / n  # m per tag pixel
    c, si = math.cos(heading_rad), math.sin(heading_rad)
    # tag pixel (u right, v down) -> table m: top edge along (c, si), "down" along (si, -c)
    A = np.array([[s * c, s * si, 0.0], [s * si, -s * c, 0.0], [0.0, 0.0, 1.0]])
    A[:2, 2] = np.asarray(centre_m) - A[:2, :2] @ np.array([n / 2, n / 2])
    M = T @ A  # tag pixel -> table-image pixel (pixel centres at integer coordinates in both)
    # pixel-centre convention: tag pixel k covers [k, k+1) -> its centre is k + 0.5
    shift = np.array([[1, 0, 0.5], [0, 1, 0.5], [0, 0, 1]])
    M = M @ shift
    corners = (M @ np.array([[0, 0, 1], [n, 0, 1], [n, n, 1], [0, n, 1]], float).T).T[:, :2]
    x0, y0 = np.floor(corners.min(axis=0)).astype(int) - 2
    x1, y1 = np.ceil(corners.max(axis=0)).astype(int) + 2
    x0, y0 = max(x0, 0), max(y0, 0)
    x1, y1 = min(x1, img.shape[1]), min(y1, img.shape[0])
    if x1 <= x0 or y1 <= y0:
        return
    roi = img[y0:y1, x0:x1]
    Mr = M.copy()
    Mr[0, 2] -= x0
    Mr[1, 2] -= y0
    tag3 = cv2.cvtColor(tag, cv2.COLOR_GRAY2BGR)
    cv2.warpAffine(tag3, Mr[:2], (x1 - x0, y1 - y0), dst=roi, flags=cv2.INTER_LINEAR,
                   borderMode=cv2.BORDER_TRANSPARENT)


def render_video(ds, path: str | os.PathLike, *, calibration: TrackCalibration | None = None,
                 camera: CameraSetup | None = None, degradation: Degradation | None = None,
                 placement_m: tuple[float, float] | None = None, start_s: float = 0.0, stride: int = 1,
                 occluders: tuple[Occluder, ...] = (), drop_frames: tuple[int, ...] = (), seed: int = 0,
                 progress: bool = False):
    """Film the run ``ds`` (from :func:`undulate.simulate`, with ``node_x``/``node_y``)
    from above and write an H.264 ``.mp4`` to ``path``.

    One frame per ``stride`` recorded samples from ``start_s`` (s, simulation
    time) on; the video starts at time 0 (its first frame is the sample at
    ``start_s``), at ``sample rate / stride`` frames per second.
    ``placement_m``: table coordinates of the simulation's origin (default:
    the centre of the fixed tags' layout).  ``drop_frames``: indices of
    frames left out of the file (their timestamps are missing).

    Returns the ground truth as an ``xarray.Dataset`` over the video's frames
    (dropped ones included): ``x``, ``y`` (m, table frame) and ``heading``
    (rad) of each robot tag, ``occluded`` (time, swimmer), ``dropped``
    (time), ``time`` = simulation time; attrs: the camera matrix, distortion,
    homography and scale (px per m) used.
    """
    import cv2

    cal = calibration or TrackCalibration()
    camera = camera or CameraSetup()
    deg = degradation or Degradation()
    path = Path(path)
    _check_arguments(ds, path, stride)
    rng = np.random.default_rng(seed)
    dictionary = cv2.aruco.getPredefinedDictionary(getattr(cv2.aruco, DICTIONARY))
    view = _table_view(cv2, cal, camera, _ds_geometry(ds), placement_m, rng, dictionary)
    run = _FilmedRun(ds, start_s, stride, view.off)
    tags = [_marker_image(cv2.aruco, dictionary, j, 16) for j in range(run.n_sw)]
    drop = set(int(k) for k in drop_frames)
    occluded = _film(cv2, path, view, run, tags, occluders, drop, deg, rng, progress)
    dropped = np.zeros(run.idx.size, bool)
    dropped[[k for k in drop if 0 <= k < run.idx.size]] = True
    return _truth_dataset(view, run.t, run.tx, run.ty, run.th, occluded, dropped, run.fps)


class _FilmedRun:
    """The samples filmed (every ``stride``-th from ``start_s``) in table coordinates (the simulation's
    origin at ``off``): their times, the frame rate, the robot tags' poses and the body nodes."""

    def __init__(self, ds, start_s: float, stride: int, off):
        t_all = ds["time"].values
        idx = np.flatnonzero(t_all >= start_s - 1e-9)[::int(stride)]
        if idx.size < 2:
            raise ParameterError("start_s", "a time leaving at least two frames", start_s)
        self.idx, self.t = idx, t_all[idx]
        self.fps = Fraction(1.0 / float(t_all[idx[1]] - t_all[idx[0]])).limit_denominator(1001)
        tx, ty, th_ = middle_link_pose(ds)
        self.tx, self.ty, self.th = tx[idx] + off[0], ty[idx] + off[1], th_[idx]
        self.nx, self.ny = ds["node_x"].values[idx] + off[0], ds["node_y"].values[idx] + off[1]
        self.n_sw = self.nx.shape[1]
        if self.n_sw > 46:
            raise ParameterError("ds", "a run of at most 46 swimmers (robot tag ids 0-45)", self.n_sw)


def _film(cv2, path: Path, view, run: _FilmedRun, tags, occluders, drop: set, deg: Degradation, rng,
          progress: bool) -> np.ndarray:
    """Draw, distort and degrade every frame and encode them (ffmpeg) into ``path``, whole or not at
    all; returns which tags each frame's occluders hid (frame, swimmer)."""
    from .._io import atomic_output

    mapx, mapy = _camera_maps(cv2, view)
    gain = _lighting_gain(deg, view.W, view.H)
    occluded = np.zeros((run.idx.size, run.n_sw), bool)
    cmd = _ffmpeg_command(view.W, view.H, run.fps, drop, deg)
    bar = None
    if progress:
        from tqdm import tqdm

        bar = tqdm(total=run.idx.size, unit="frame", desc="render")
    with atomic_output(path) as tmp:
        proc = subprocess.Popen(cmd + [str(tmp)], stdin=subprocess.PIPE, stderr=subprocess.PIPE)
        try:
            for k in range(run.idx.size):
                table = _draw_table(cv2, view, run.nx[k], run.ny[k], tags, (run.tx[k], run.ty[k], run.th[k]))
                occluded[k] = _draw_occluders(cv2, view, table, occluders, float(run.t[k]), run.tx[k], run.ty[k])
                frame = cv2.remap(table, mapx, mapy, cv2.INTER_LINEAR, borderMode=cv2.BORDER_REPLICATE)
                proc.stdin.write(_degrade(cv2, frame, deg, gain, rng).tobytes())
                if bar is not None:
                    bar.update()
            proc.stdin.close()
            err = proc.stderr.read().decode(errors="replace")
            if proc.wait() != 0:
                raise RuntimeError(f"ffmpeg failed: {err.strip()[-500:]}")
        except BaseException:
            proc.kill()
            proc.wait()
            raise
        finally:
            if bar is not None:
                bar.close()
    return occluded


def _check_arguments(ds, path: Path, stride) -> None:
    if path.suffix.lower() != ".mp4":
        raise ParameterError("path", "a path ending in .mp4", str(path))
    for v in ("node_x", "node_y"):
        if v not in ds:
            raise ParameterError("ds", "a run recorded with node_x and node_y", sorted(ds.data_vars))
    if int(stride) != stride or stride < 1:
        raise ParameterError("stride", "a positive integer", stride)


@dataclass
class _View:
    """The camera and the supersampled top view of the table it films."""

    K: np.ndarray  # camera matrix, px
    Hcam: np.ndarray  # table m -> ideal camera pixel
    dist: np.ndarray  # lens distortion (OpenCV)
    px_per_m: float  # camera pixels per m on the table
    ppm: float  # top-view pixels per m
    T: np.ndarray  # table m -> top-view pixel (column, row), pixel centres at integers
    background: np.ndarray  # the top view without the bodies: texture, walls, fixed tags
    off: np.ndarray  # table coordinates of the simulation's origin, m
    plate: float  # side of a tag's white plate, m
    geometry: dict  # the run's widths (_ds_geometry)
    W: int
    H: int


def _table_view(cv2, cal: TrackCalibration, camera: CameraSetup, g: dict, placement_m, rng, dictionary) -> _View:
    """The camera looking at the tags' layout, and the top view of everything it sees: the
    table's texture (drawn from ``rng``), the channel walls and the four fixed tags."""
    pts = np.array(list(cal.markers_m.values()))
    lay_lo, lay_hi = pts.min(axis=0), pts.max(axis=0)
    if placement_m is None:
        placement_m = tuple(0.5 * (lay_lo + lay_hi))
    off = np.asarray(placement_m, float)
    m = camera.margin_m + cal.size_m
    region = np.array([lay_lo - m, lay_hi + m])
    K, Hcam = _camera(camera, region)
    dist = np.asarray(camera.distortion, float)
    px_per_m = float(K[0, 0] / np.linalg.norm(np.linalg.inv(K) @ Hcam @ np.array([0, 0, 1.0])))
    ppm = 1.5 * px_per_m  # supersampled top view
    # the top view covers everything the camera sees (its frame's border traced back onto the table)
    W, H = camera.width_px, camera.height_px
    b = np.linspace(0.0, 1.0, 65)
    border = np.concatenate([np.column_stack([b * (W - 1), 0 * b]), np.column_stack([b * (W - 1), 0 * b + H - 1]),
                             np.column_stack([0 * b, b * (H - 1)]), np.column_stack([0 * b + W - 1, b * (H - 1)])])
    if np.any(dist != 0):
        border = cv2.undistortPoints(border.reshape(-1, 1, 2), K, dist, R=None, P=K).reshape(-1, 2)
    seen = np.column_stack([border, np.ones(len(border))]) @ np.linalg.inv(Hcam).T
    seen = seen[:, :2] / seen[:, 2:]
    (x0, y0), (x1, y1) = (np.clip(seen.min(axis=0) - 0.01, region[0] - 0.5, None),
                          np.clip(seen.max(axis=0) + 0.01, None, region[1] + 0.5))
    tw, th = int(math.ceil((x1 - x0) * ppm)), int(math.ceil((y1 - y0) * ppm))
    T = np.array([[ppm, 0.0, -x0 * ppm - 0.5], [0.0, -ppm, y1 * ppm - 0.5], [0.0, 0.0, 1.0]])
    background = _texture(rng, (th, tw), ppm)
    wall_t = 0.012
    for sgn in (-1, 1):  # channel walls (dark strips just outside the channel)
        yw = off[1] + sgn * (g["channel_width"] / 2 + wall_t / 2)
        poly = np.array([[x0, yw - wall_t / 2], [x1, yw - wall_t / 2], [x1, yw + wall_t / 2], [x0, yw + wall_t / 2]])
        _fill(cv2, background, T, poly, (70, 75, 80))
    plate = cal.size_m * 8 / 6
    for i in FIXED_IDS:
        _put_tag(cv2, background, _marker_image(cv2.aruco, dictionary, i, 16), T, cal.markers_m[i], 0.0, plate)
    return _View(K, Hcam, dist, px_per_m, ppm, T, background, off, plate, g, W, H)


def _camera_maps(cv2, v: _View) -> tuple[np.ndarray, np.ndarray]:
    """camera pixel (distorted) -> ideal pixel -> table m -> top-view pixel: one remap per frame."""
    W, H = v.W, v.H
    uu, vv = np.meshgrid(np.arange(W, dtype=np.float64), np.arange(H, dtype=np.float64))
    pix = np.stack([uu.ravel(), vv.ravel()], axis=-1)
    if np.any(v.dist != 0):
        pix = cv2.undistortPoints(pix.reshape(-1, 1, 2), v.K, v.dist, R=None, P=v.K,
                                  criteria=(cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, 50, 1e-6)).reshape(-1, 2)
    hom = np.column_stack([pix, np.ones(len(pix))]) @ (v.T @ np.linalg.inv(v.Hcam)).T
    mapx = (hom[:, 0] / hom[:, 2]).reshape(H, W).astype(np.float32)
    mapy = (hom[:, 1] / hom[:, 2]).reshape(H, W).astype(np.float32)
    return mapx, mapy


def _lighting_gain(deg: Degradation, W: int, H: int) -> np.ndarray | None:
    """Uneven lighting: a lamp off to one side, brightest there, falling off smoothly (None: even)."""
    if not deg.lighting > 0:
        return None
    yy, xx = np.mgrid[0:H, 0:W].astype(np.float32)
    r2 = ((xx - 0.3 * W) / W) ** 2 + ((yy - 0.25 * H) / H) ** 2
    gain = np.exp(-r2 / 0.35)
    gain = 1.0 - deg.lighting * (gain.max() - gain) / (gain.max() - gain.min())
    return np.repeat(gain[..., None], 3, axis=-1).astype(np.float32)


def _ffmpeg_command(W: int, H: int, fps: Fraction, drop: set, deg: Degradation) -> list[str]:
    """FFmpeg reading raw BGR frames on stdin and writing H.264 (the output path follows)."""
    cmd = [_ffmpeg(), "-hide_banner", "-loglevel", "error", "-y", "-f", "rawvideo", "-pix_fmt", "bgr24",
           "-s", f"{W}x{H}", "-r", f"{fps.numerator}/{fps.denominator}", "-i", "-"]
    if drop:  # ffmpeg drops them, keeping every other frame's timestamp: gaps in the file's timeline
        sel = "+".join(f"eq(n\\,{k})" for k in sorted(drop))
        cmd += ["-vf", f"select='not({sel})'", "-fps_mode", "vfr"]
    cmd += ["-c:v", "libx264", "-preset", "veryfast", "-crf", str(int(deg.crf)), "-pix_fmt", "yuv420p",
            "-threads", "2", "-movflags", "+faststart", "-f", "mp4"]
    return cmd


def _draw_table(cv2, v: _View, nx: np.ndarray, ny: np.ndarray, tags: list, pose) -> np.ndarray:
    """The top view at one sample: every body's links, then every robot's tag on top."""
    table = v.background.copy()
    w = v.geometry["width"]
    n_sw = nx.shape[0]
    for j in range(n_sw):
        for li in range(nx.shape[1] - 1):
            p0 = np.array([nx[j, li], ny[j, li]])
            p1 = np.array([nx[j, li + 1], ny[j, li + 1]])
            d = (p1 - p0) / np.linalg.norm(p1 - p0)
            nrm = np.array([-d[1], d[0]]) * w / 2
            _fill(cv2, table, v.T, np.array([p0 - nrm, p1 - nrm, p1 + nrm, p0 + nrm]), (85, 60, 45))
    tx, ty, th_ = pose
    for j in range(n_sw):  # tags on top of every body
        _put_tag(cv2, table, tags[j], v.T, (tx[j], ty[j]), th_[j], v.plate)
    return table


def _draw_occluders(cv2, v: _View, table: np.ndarray, occluders, t_s: float, tx, ty) -> np.ndarray:
    """Draw the occluders present at ``t_s``; which robots' tags they (partly) cover."""
    occluded = np.zeros(len(tx), bool)
    half_diag = v.plate / math.sqrt(2)
    for oc in occluders:
        if oc.t_start_s - 1e-9 <= t_s <= oc.t_end_s + 1e-9:
            c = v.T @ np.array([oc.x_m, oc.y_m, 1.0])
            cv2.circle(table, (int(round(c[0] * 16)), int(round(c[1] * 16))), int(round(oc.radius_m * v.ppm * 16)),
                       (120, 150, 205), -1, cv2.LINE_AA, 4)
            dd = np.hypot(tx - oc.x_m, ty - oc.y_m)
            occluded |= dd < oc.radius_m + half_diag
    return occluded


def _degrade(cv2, frame: np.ndarray, deg: Degradation, gain, rng) -> np.ndarray:
    """Blur, uneven lighting and sensor noise (drawn from ``rng``) on one camera frame."""
    if deg.blur_px > 0:
        frame = cv2.GaussianBlur(frame, (0, 0), deg.blur_px)
    if gain is not None or deg.noise_dn > 0:
        f = frame.astype(np.float32)
        if gain is not None:
            f *= gain
        if deg.noise_dn > 0:
            f += rng.standard_normal(f.shape, dtype=np.float32) * np.float32(deg.noise_dn)
        frame = np.clip(f + 0.5, 0, 255).astype(np.uint8)
    return frame


def _truth_dataset(v: _View, t, tx, ty, th_, occluded, dropped, fps: Fraction):
    """The ground truth over the video's frames (see :func:`render_video`)."""
    import xarray as xr

    dims = ("time", "swimmer")
    return xr.Dataset(
        {"x": (dims, tx, {"units": "m", "long_name": "true robot-tag centre x (table frame)"}),
         "y": (dims, ty, {"units": "m", "long_name": "true robot-tag centre y (table frame)"}),
         "heading": (dims, th_, {"units": "rad", "long_name": "true middle-link heading (head -> tail from +x)"}),
         "occluded": (dims, occluded, {"units": "1", "long_name": "tag (partly) under an occluder"}),
         "dropped": (("time",), dropped, {"units": "1", "long_name": "frame left out of the video"})},
        coords={"time": ("time", t, {"units": "s", "long_name": "simulation time"}),
                "swimmer": ("swimmer", np.arange(tx.shape[1]))},
        attrs={"camera_matrix": v.K.ravel().tolist(), "distortion": v.dist.tolist(), "homography": v.Hcam.ravel().tolist(),
               "px_per_m": v.px_per_m, "placement_m": v.off.tolist(), "fps": float(fps), "video_start_time": float(t[0]),
               "width_px": v.W, "height_px": v.H},
    )


def _fill(cv2, img: np.ndarray, T: np.ndarray, poly_m: np.ndarray, colour) -> None:
    """Fill a polygon given in table metres, anti-aliased at 1/16-pixel precision."""
    p = (np.column_stack([poly_m, np.ones(len(poly_m))]) @ T.T)[:, :2]
    cv2.fillPoly(img, [np.round(p * 16).astype(np.int32)], colour, cv2.LINE_AA, 4)


def _ds_geometry(ds) -> dict:
    import json

    cfg = json.loads(ds.attrs["config"])["scene"]
    return {"width": float(cfg["geometry"]["width_m"]), "channel_width": float(cfg["channel"]["width_m"])}


def _ffmpeg() -> str:
    import imageio_ffmpeg

    return imageio_ffmpeg.get_ffmpeg_exe()

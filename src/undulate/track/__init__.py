"""Robot tracking from overhead video (optional extra ``undulate[track]``: OpenCV).

Public surface; OpenCV is imported only when a function that needs it runs,
so ``import undulate.track`` stays cheap.
"""

from .calibration import (DEFAULT_MARKERS_M, DEFAULT_SIZE_M, DICTIONARY, FIXED_IDS, TrackCalibration,
                          robot_tag_link)

__all__ = ["track_video", "render_video", "marker_sheet", "TrackCalibration", "robot_tag_link",
           "DICTIONARY", "FIXED_IDS", "DEFAULT_MARKERS_M", "DEFAULT_SIZE_M"]


def track_video(*args, **kwargs):
    """See :func:`undulate.track.tracker.track_video`."""
    from .tracker import track_video as f

    return f(*args, **kwargs)


def render_video(*args, **kwargs):
    """See :func:`undulate.track.render.render_video`."""
    from .render import render_video as f

    return f(*args, **kwargs)


def marker_sheet(*args, **kwargs):
    """See :func:`undulate.track.markers.marker_sheet`."""
    from .markers import marker_sheet as f

    return f(*args, **kwargs)

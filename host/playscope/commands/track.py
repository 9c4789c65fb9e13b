"""`playscope track`: a session's video.* + frames.csv -> marker.csv (coloured marker)."""

from __future__ import annotations

import sys

from . import argtypes as T
from ..base.errors import InputError
from ..pipeline import track_session
from ..io.marker_track import HUE_PRESETS, TrackConfig
from .common import add_command, add_json_arg, emit, progress


DESCRIPTION = """\
HSV colour threshold, largest blob within area bounds and circular enough, sub-pixel centroid
from image moments (soft rim weights); ROI around the last position, whole-frame search (1/4
scale) when lost. Lost frames get empty u_px,v_px. A truncated video gives marker.csv up to the
last decoded frame and a one-line warning.
"""


def add_parser(sub) -> None:
    p = add_command(sub, "track", "find the coloured marker in a session's video -> marker.csv", DESCRIPTION,
                    examples=["playscope track sessions/s1 --marker green"])
    p.add_argument("session", help="session folder holding video.* and frames.csv")
    p.add_argument("-o", "--out", type=T.file_path, help="marker CSV to write (default: <session>/marker.csv)")
    p.add_argument("--marker", choices=sorted(HUE_PRESETS), default="green",
                   help="marker colour preset (OpenCV hue ranges %s); default green" %
                   ", ".join(f"{k} {a}-{b}" for k, (a, b) in HUE_PRESETS.items()))
    p.add_argument("--hue", type=T.int_range(0, 179), nargs=2, metavar=("LO", "HI"),
                   help="hue range in OpenCV units 0-179 (overrides --marker; LO > HI wraps through red)")
    p.add_argument("--s-min", type=T.int_range(0, 255), default=80, help="minimum saturation 0-255 (default 80; highlights are below)")
    p.add_argument("--v-min", type=T.int_range(0, 255), default=40, help="minimum value 0-255 (default 40)")
    p.add_argument("--area", type=T.float_range(0.0, 1e8, lo_open=True), nargs=2, metavar=("MIN", "MAX"),
                   help="blob area bounds in px^2 (default 12 and 5%% of the frame)")
    p.add_argument("--circ-min", type=T.float_range(0.0, 1.0), default=0.45, help="minimum circularity 4 pi A/P^2 (default 0.45)")
    p.add_argument("--roi", type=T.int_range(4, 4096), default=48, help="ROI half-size around the last position, px (default 48)")
    p.add_argument("--force", "--overwrite", dest="force", action="store_true", help="replace an existing marker CSV")
    add_json_arg(p, "marker_csv (path), video (path), frames_listed, frames_decoded, frames_tracked, lost, "
                 "lost_fraction, truncated (bool), reasons {reason: count}, seconds, fps, warning (str|null)")
    p.set_defaults(func=run, own_progress=True)


def run(a) -> int:
    lo, hi = a.hue if a.hue else HUE_PRESETS[a.marker]
    try:
        cfg = TrackConfig(lo, hi, a.s_min, a.v_min, *(a.area or (12.0, None)), a.circ_min, a.roi)
    except ValueError as e:
        raise InputError(None, f"track options: {e}") from None
    res = track_session(a.session, a.out, cfg, a.force, progress=lambda **kw: progress(**kw))
    if res.warning:
        print(f"playscope: warning: {res.warning}", file=sys.stderr)
    return emit(a, res)

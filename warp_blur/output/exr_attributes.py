"""OpenEXR's standard attributes that compositors and review tools read (ImfStandardAttributes):
camera matrices at the shutter centre, the primaries of the linear pixels, software, capture date,
frames per second, owner and comments.

Conventions (OpenEXR's, row vectors as in Imath and USD: p' = p · M):
  worldToCamera: world -> a left-handed camera space, origin at the eye, +x right, +y up, +z the
      viewing direction (USD's camera space with z flipped);
  worldToNDC: world -> homogeneous NDC, (0, 0) the display window's upper-left corner, (1, 1) its
      lower-right (x right, y down), after division by w; z/w is 0 at the near and 1 at the far plane.
"""

from __future__ import annotations

import datetime
import fractions
import getpass
import os

import numpy as np

from ..core.camera import Projection
from ..core.version import __version__

#: CIE xy of the Rec.709 / sRGB primaries and D65 white point: the renderer's linear RGB.
REC709_CHROMATICITIES = (0.64, 0.33, 0.30, 0.60, 0.15, 0.06, 0.3127, 0.3290)
_FLIP_Z = np.diag([1.0, 1.0, -1.0, 1.0])


def world_to_camera(cam_from_world: np.ndarray) -> np.ndarray:
    """(4, 4) float64: USD's world -> camera (looking down -z) made OpenEXR's left-handed +z view."""
    return np.asarray(cam_from_world, np.float64) @ _FLIP_Z


def camera_to_ndc(proj: Projection) -> np.ndarray:
    """(4, 4) float64 from USD camera space (looking down -z) to OpenEXR's homogeneous NDC."""
    x0, y0, x1, y1 = proj.window
    n, f = proj.near, proj.far
    m = np.zeros((4, 4))
    if proj.orthographic:   # ndc = ((x - x0) / (x1 - x0), (y1 - y) / (y1 - y0)), w = 1
        m[0, 0] = 1.0 / (x1 - x0)
        m[3, 0] = -x0 / (x1 - x0)
        m[1, 1] = -1.0 / (y1 - y0)
        m[3, 1] = y1 / (y1 - y0)
        m[2, 2] = -1.0 / (f - n)
        m[3, 2] = -n / (f - n)
        m[3, 3] = 1.0
        return m
    # w = -z (the view depth); x/w = (x/(-z) - x0) / (x1 - x0), y/w = (y1 - y/(-z)) / (y1 - y0)
    m[0, 0] = 1.0 / (x1 - x0)
    m[2, 0] = x0 / (x1 - x0)
    m[1, 1] = -1.0 / (y1 - y0)
    m[2, 1] = -y1 / (y1 - y0)
    a = f / (n - f)            # z/w: 0 at depth n, 1 at depth f
    m[2, 2] = a
    m[3, 2] = a * n
    m[2, 3] = -1.0
    return m


def exr_frame_rate(frames_per_second: float) -> fractions.Fraction | None:
    """The rate as the EXR rational it is written as (an int32 numerator over a denominator up to
    1001), or None when it is no positive number such a rational holds (a stage's `framesPerSecond
    = inf` or `1e300`, whose numerator overflows, or `1e-300`, which rounds to 0): left out."""
    if not (np.isfinite(frames_per_second) and frames_per_second > 0):
        return None
    fps = fractions.Fraction(frames_per_second).limit_denominator(1001)
    return fps if 0 < fps.numerator <= 2**31 - 1 else None


def standard_attributes(proj: Projection, cam_from_world: np.ndarray, frames_per_second: float,
                        scene_path: str, frame: float) -> dict:
    """The standard attributes of one frame, typed as the OpenEXR binding writes them."""
    now = datetime.datetime.now().astimezone()
    offset = now.utcoffset()
    fps = exr_frame_rate(frames_per_second)
    try:
        owner = getpass.getuser()
    except (KeyError, OSError):
        owner = str(os.getuid()) if hasattr(os, "getuid") else "unknown"
    attrs = {
        "worldToCamera": world_to_camera(cam_from_world).astype(np.float32),
        "worldToNDC": (np.asarray(cam_from_world, np.float64) @ camera_to_ndc(proj)).astype(np.float32),
        "chromaticities": REC709_CHROMATICITIES,
        "software": f"warp_blur {__version__}",
        "capDate": now.strftime("%Y:%m:%d %H:%M:%S"),
        # OpenEXR: seconds to add to local time for UTC (the opposite sign of the UTC offset)
        "utcOffset": float(-(offset.total_seconds() if offset else 0.0)),
        "owner": owner,
        "comments": f"{os.path.abspath(scene_path)} frame {frame:g}",
    }
    if fps is not None:
        attrs["framesPerSecond"] = fps
    return attrs

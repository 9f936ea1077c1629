"""Camera projection: SPEC §1 (pixel centres) and §3 (window, conform, clipping) in one place.

Camera space is USD's: the eye at the origin looking down -Z, +Y up. View depth is -z.
The *window* is the image rectangle on the plane at distance 1 (perspective) or in scene units
(orthographic), after the aperture is conformed to the image aspect.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class Projection:
    """Camera intrinsics at the frame time, conformed to the image.

    window: (xmin, ymin, xmax, ymax) on the reference plane (distance 1, or scene units if ortho).
    """

    orthographic: bool
    window: tuple[float, float, float, float]
    near: float
    far: float
    width: int
    height: int

    def pixel_window_coords(self, px: np.ndarray, py: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Window coordinates of pixel positions (px, py in pixels, y down; centres at +0.5)."""
        x0, y0, x1, y1 = self.window
        wx = x0 + (px / self.width) * (x1 - x0)
        wy = y1 - (py / self.height) * (y1 - y0)
        return wx, wy

    def project(self, p_cam: np.ndarray) -> np.ndarray:
        """Camera-space points (..., 3) -> raster positions (..., 2) in pixels (x right, y down)."""
        p = np.asarray(p_cam, dtype=np.float64)
        depth = -p[..., 2]
        if self.orthographic:
            wx, wy = p[..., 0], p[..., 1]
        else:
            with np.errstate(divide="ignore", invalid="ignore"):
                wx, wy = p[..., 0] / depth, p[..., 1] / depth
        x0, y0, x1, y1 = self.window
        rx = (wx - x0) / (x1 - x0) * self.width
        ry = (y1 - wy) / (y1 - y0) * self.height
        return np.stack([rx, ry], axis=-1)

    @property
    def pixels_per_unit(self) -> float:
        """Pixels per window unit along x (screen-error bounds use it)."""
        return self.width / (self.window[2] - self.window[0])


def conform_window(window: tuple[float, float, float, float], image_aspect: float,
                   policy: str = "expandAperture") -> tuple[float, float, float, float]:
    """Conform a window to the image aspect (width/height) as UsdRenderSettings' policies say.

    expandAperture grows the smaller side about its centre; cropAperture shrinks the larger;
    adjustApertureWidth keeps the height; adjustApertureHeight keeps the width.
    """
    x0, y0, x1, y1 = window
    w, h = x1 - x0, y1 - y0
    cx, cy = (x0 + x1) / 2, (y0 + y1) / 2
    aspect = w / h
    if policy == "adjustApertureWidth":
        w = h * image_aspect
    elif policy == "adjustApertureHeight":
        h = w / image_aspect
    elif policy == "cropAperture":
        if aspect > image_aspect:
            w = h * image_aspect
        else:
            h = w / image_aspect
    else:  # expandAperture (USD's default); adjustPixelAspectRatio is treated the same
        if aspect > image_aspect:
            h = w / image_aspect
        else:
            w = h * image_aspect
    return (cx - w / 2, cy - h / 2, cx + w / 2, cy + h / 2)

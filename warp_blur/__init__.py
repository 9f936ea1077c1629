"""warp_blur: motion blur for animated USD stages, as NVIDIA Warp kernels.

    import warp_blur as wb
    result = wb.render("scene.usda", frame=1, method="analytic", resolution=(640, 360))
    wb.write_exr("out.exr", result)
"""

from .api import Renderer, RenderResult, __version__, render
from .batch import render_frames
from .errors import InvalidGeometryError, SettingsError, StageError, UserError
from .output import read_exr, write_exr, write_image, write_png
from .settings import METHODS, RenderSettings

__all__ = ["render", "render_frames", "Renderer", "RenderResult", "RenderSettings", "write_exr", "write_png", "write_image",
           "read_exr", "METHODS", "UserError", "StageError", "SettingsError", "InvalidGeometryError", "__version__"]

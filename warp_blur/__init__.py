"""warp_blur: motion blur for animated USD stages, as NVIDIA Warp kernels.

    import warp_blur as wb
    result = wb.render("scene.usda", frame=1, method="analytic", resolution=(640, 360))
    wb.write_exr("out.exr", result)

The names below are imported on first use (PEP 562), so `import warp_blur` and `warp-blur --help`
do not pay for Warp and USD until something renders.
"""

from __future__ import annotations

import importlib

from .core.version import __version__

_EXPORTS = {
    "render": ".api", "Renderer": ".api", "RenderResult": ".api",
    "render_frames": ".tools.batch",
    "UserError": ".core.errors", "StageError": ".core.errors", "SettingsError": ".core.errors",
    "InvalidGeometryError": ".core.errors",
    "read_exr": ".output.files", "write_exr": ".output.files", "write_image": ".output.files", "write_png": ".output.files",
    "METHODS": ".core.settings", "RenderSettings": ".core.settings",
}

__all__ = ["render", "render_frames", "Renderer", "RenderResult", "RenderSettings", "write_exr", "write_png", "write_image",
           "read_exr", "METHODS", "UserError", "StageError", "SettingsError", "InvalidGeometryError", "__version__"]


def __getattr__(name: str):
    if name in _EXPORTS:
        value = getattr(importlib.import_module(_EXPORTS[name], __name__), name)
        globals()[name] = value
        return value
    raise AttributeError(f"module 'warp_blur' has no attribute '{name}'")


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(__all__))

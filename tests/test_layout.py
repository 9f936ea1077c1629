"""The package's layout (issue 16): subpackages are layers of the pipeline and imports only run
downward (a module imports its own layer or lower ones), so each part can be read on its own."""

import ast
import os

PACKAGE = os.path.join(os.path.dirname(os.path.dirname(os.path.abspath(__file__))), "warp_blur")
#: lowest first: core, then reading USD, device code, the host side of the raster core, shadows,
#: the methods (with the frame they share), files, the pipeline (api.py), and what users run
LAYERS = ["core", "output", "usd", "kernels", "raster", "shadows", "methods", "api", "tools"]


def _layer(module_parts: list[str]) -> int | None:
    if not module_parts or module_parts[0] in ("__init__", "__main__"):
        return None   # the facade and `python -m warp_blur` sit above everything
    return LAYERS.index(module_parts[0])


def test_imports_run_downward():
    wrong = []
    for folder, _, files in os.walk(PACKAGE):
        for name in files:
            if not name.endswith(".py"):
                continue
            path = os.path.join(folder, name)
            parts = os.path.relpath(path, PACKAGE)[:-3].split(os.sep)
            own = _layer(parts)
            if own is None:
                continue
            package = parts[:-1]
            for node in ast.walk(ast.parse(open(path).read())):
                if isinstance(node, ast.ImportFrom) and node.level:
                    base = package[:len(package) - (node.level - 1)] if node.level > 1 else package
                    target = base + (node.module.split(".") if node.module else [node.names[0].name])
                    layer = _layer(target)
                    if layer is not None and layer > own:
                        wrong.append(f"{'/'.join(parts)} imports {'.'.join(target)}")
    assert not wrong, wrong


def test_every_subpackage_is_a_layer_and_modules_stay_small():
    subpackages = {d for d in os.listdir(PACKAGE) if os.path.isdir(os.path.join(PACKAGE, d)) and d != "__pycache__"}
    assert subpackages == set(LAYERS) - {"api"}
    for folder, _, files in os.walk(PACKAGE):
        for name in files:
            if name.endswith(".py"):
                with open(os.path.join(folder, name)) as f:
                    assert sum(1 for _ in f) <= 560, name   # "about 500 lines": shadows/maps.py is the largest

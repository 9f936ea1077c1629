"""Struct arguments of this package's @wp.func and CPU kernels passed by reference in the
generated C++.

Warp (1.19) passes every struct argument of a @wp.func by value (NVIDIA/warp#878, #1277). Each
call the compiler keeps out of line copies the whole struct: Shading is over a kilobyte, and LLVM
keeps shading, interval and radiance helpers out of line once a kernel grows. On demo those copies
were a quarter of the analytic frame and a third of the stochastic one. This package's functions
never assign to a struct argument, so passing it as `T&` changes nothing but the copies.

A CPU kernel's body runs once per thread index, and Warp's generated body starts by copying each
argument out of the launch's argument block (`View var_view = _wp_args->view;`): per pixel, the
View, Geometry, Shading and Bins structs (2.3 KB in render_sharp), which were 11% of an
accumulation frame's CPU time on demo (memcpy called from render_sharp). Those lines bind
references instead (`View& var_view = _wp_args->view;`); the kernels never assign to them either.

Only functions and kernels defined in warp_blur get references (other Warp code in the process
keeps Warp's semantics). warp_blur's modules carry an extra option, so their cache key differs
from that of binaries built without references. WARP_BLUR_STRUCT_REFS=0 switches it off (for A/B
timing).
"""

from __future__ import annotations

import os
import re

#: a parameter line of a generated function header whose type is a Warp struct (Name_hash8)
_STRUCT_PARAM = re.compile(r"^(\s+)([A-Za-z_]\w*_[0-9a-f]{8}) (var_\w+)(,|\))$", re.M)
#: a CPU kernel's copy of a struct argument out of its launch's argument block
_STRUCT_ARG_COPY = re.compile(r"^(\s+)([A-Za-z_]\w*_[0-9a-f]{8}) (var_\w+) = _wp_args->(\w+);$", re.M)
#: module option marking binaries built with references (part of Warp's module hash)
OPTION = "warp_blur_struct_refs"
#: its value: 2 since the CPU kernels' arguments are references too (a new hash: binaries built
#: before, with per-thread copies, are not taken from the kernel cache)
LEVEL = 2
_installed = False


def by_reference(source: str) -> str:
    """Generated C++ of a function with its struct parameters declared `T&` instead of `T`."""
    return _STRUCT_PARAM.sub(r"\1\2& \3\4", source)


def kernel_args_by_reference(source: str) -> str:
    """Generated C++ of a CPU kernel with its struct arguments bound as references into the
    launch's argument block instead of copied out of it per thread index (the adjoint block's
    are left as they are)."""
    return _STRUCT_ARG_COPY.sub(r"\1\2& \3 = _wp_args->\4;", source)


def _ours(name: str | None) -> bool:
    return bool(name) and (name == "warp_blur" or name.startswith("warp_blur."))


def install() -> bool:
    """Wrap Warp's function code generator and module constructor (once per process). False when
    switched off by the environment or when this Warp lacks the hooks (then nothing changes)."""
    global _installed
    if _installed:
        return True
    if os.environ.get("WARP_BLUR_STRUCT_REFS", "1") == "0":
        return False
    try:
        import warp._src.codegen as codegen
        import warp._src.context as context
        generate, generate_kernel, module_init = codegen.codegen_func, codegen.codegen_kernel, context.Module.__init__
    except (ImportError, AttributeError):
        return False

    def codegen_func(adj, *args, **kwargs):
        source = generate(adj, *args, **kwargs)
        func = getattr(adj, "func", None)
        return by_reference(source) if _ours(getattr(func, "__module__", None)) else source

    def codegen_kernel(kernel, device, options):
        source = generate_kernel(kernel, device=device, options=options)
        ours = _ours(getattr(getattr(kernel, "module", None), "name", None))
        return kernel_args_by_reference(source) if ours and device == "cpu" else source

    def init(self, name, *args, **kwargs):
        module_init(self, name, *args, **kwargs)
        if _ours(name):
            self.options[OPTION] = LEVEL

    codegen.codegen_func = codegen_func
    codegen.codegen_kernel = codegen_kernel
    context.Module.__init__ = init
    _installed = True
    return True


def installed() -> bool:
    return _installed

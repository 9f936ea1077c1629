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
A kernel whose arrays are all one-dimensional also gets, from Warp, a copy of its whole argument
block per thread index when they are contiguous (so that their strides read as constants): in
classify_samples that is View, Geometry and two Bins per pixel. There the constant strides are
set on the kernel's own copies of its array arguments instead (`var_listed.strides[0] = ...`),
and the block is not copied.

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
#: a CPU kernel's per-thread copy of its argument block where its arrays are contiguous, and the
#: constant strides the copy is made for
_CONTIGUOUS_COPY = re.compile(
    r"^\s+wp_args_\w+ wp_contiguous_args;\n"
    r"\s+if constexpr \(wp_linear_contiguous\)\n"
    r"\s+\{\n"
    r"\s+wp_contiguous_args = \*_wp_args;\n"
    r"((?:\s+wp_contiguous_args\.\w+\.strides\[\d+\] = [^;\n]+;\n)*)"
    r"\s+_wp_args = &wp_contiguous_args;\n"
    r"\s+\}\n", re.M)
_STRIDE = re.compile(r"wp_contiguous_args\.(\w+)\.(strides\[\d+\]) = ([^;\n]+);")
#: module option marking binaries built with references (part of Warp's module hash)
OPTION = "warp_blur_struct_refs"
#: its value: 3 since contiguous kernels set their arrays' strides instead of copying their argument
#: block per thread (2: the CPU kernels' struct arguments are references; a new value is a new hash,
#: so binaries built before are not taken from the kernel cache)
LEVEL = 3
_installed = False


def by_reference(source: str) -> str:
    """Generated C++ of a function with its struct parameters declared `T&` instead of `T`."""
    return _STRUCT_PARAM.sub(r"\1\2& \3\4", source)


def kernel_args_by_reference(source: str) -> str:
    """Generated C++ of a CPU kernel with its struct arguments bound as references into the
    launch's argument block instead of copied out of it per thread index (the adjoint block's
    are left as they are)."""
    return _STRUCT_ARG_COPY.sub(r"\1\2& \3 = _wp_args->\4;", source)


def contiguous_strides_in_place(source: str) -> str:
    """Generated C++ of a CPU kernel whose contiguous launch copied its whole argument block per
    thread index to give its arrays constant strides: the strides are set on the kernel's own
    copies of those arrays instead (`var_a.strides[0] = sizeof(...)`, under the same
    `if constexpr (wp_linear_contiguous)`), and the block is read in place. Unchanged when the
    pattern is not found."""
    match = _CONTIGUOUS_COPY.search(source)
    if match is None:
        return source
    strides = _STRIDE.findall(match.group(1))
    out = source[:match.start()] + source[match.end():]
    for name, which, value in strides:
        line = re.search(rf"^(\s+)[^\n]* var_{name} = _wp_args->{name};\n", out, re.M)
        if line is None:
            return source   # an array argument not bound where expected: leave Warp's code as it is
        out = (out[:line.end()] + f"{line.group(1)}if constexpr (wp_linear_contiguous) var_{name}.{which} = {value};\n"
               + out[line.end():])
    return out


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
        if not ours or device != "cpu":
            return source
        return contiguous_strides_in_place(kernel_args_by_reference(source))

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

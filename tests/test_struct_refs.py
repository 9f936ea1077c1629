"""Struct arguments of warp_blur's @wp.func pass by reference in the generated C++
(core/struct_refs.py); Warp code outside the package keeps Warp's by-value semantics."""

from __future__ import annotations

import os

import numpy as np
import pytest
import warp as wp

import warp_blur as wb
from warp_blur.core import struct_refs

HEADER = """static wp::vec_t<3u, float> shade_0(
    View_a6a9bfbf var_view,
    Shading_b2017e80 var_sh,
    wp::int32 var_e,
    Moving_ddbbaefb var_m)
{
    Shading_b2017e80 var_12;
    shade_1(var_view, var_sh);
}
static void adj_shade_0(
    Shading_b2017e80 var_sh,
    Shading_b2017e80 & adj_sh,
    wp::float32 & adj_ret)
"""


def test_struct_parameters_become_references_and_nothing_else_changes():
    out = struct_refs.by_reference(HEADER)
    assert "    View_a6a9bfbf& var_view,\n    Shading_b2017e80& var_sh,\n    wp::int32 var_e,\n" in out
    assert "    Moving_ddbbaefb& var_m)\n" in out
    assert "    Shading_b2017e80 var_12;" in out                      # a local stays a value
    assert "shade_1(var_view, var_sh);" in out                        # calls are unchanged
    assert "    Shading_b2017e80 & adj_sh,\n    wp::float32 & adj_ret)" in out
    assert out.count("& var_") == 4


def test_the_package_modules_are_built_with_references(tmp_path):
    """After a render, the sharp rasterizer's module (a still scene: every method renders it
    sharp) carries the option, so its cache key differs from a by-value build, and its generated
    C++ takes Shading by reference."""
    if os.environ.get("WARP_BLUR_STRUCT_REFS") == "0":
        pytest.skip("struct references switched off for this run (WARP_BLUR_STRUCT_REFS=0)")
    from scenes import shadow_stage
    path = shadow_stage(str(tmp_path / "s.usda"))
    wb.render(path, frame=1, method="stochastic", samples=2, resolution=(32, 24), aovs=())
    assert struct_refs.installed()   # by warp_blur.kernels, before any of its modules was defined
    module = wp.get_module("warp_blur.kernels.raster")
    assert module.options.get(struct_refs.OPTION) == struct_refs.LEVEL
    block_dim = next(iter(module.execs))[1]          # the CPU build's (one thread per block)
    ident = module.get_module_identifier(block_dim=block_dim)
    source = open(os.path.join(wp.config.kernel_cache_dir, ident, ident + ".cpp")).read()
    assert "& var_sh," in source and " var_sh," in source


@wp.struct
class Box:
    value: float


@wp.func
def overwrite(b: Box) -> float:
    b.value = 20.0
    return b.value


@wp.kernel
def overwrite_kernel(out: wp.array(dtype=float)):
    b = Box()
    b.value = 10.0
    inner = overwrite(b)
    out[0] = b.value
    out[1] = inner


def test_warp_code_outside_the_package_keeps_passing_structs_by_value():
    out = wp.zeros(2, dtype=float, device="cpu")
    wp.launch(overwrite_kernel, 1, inputs=[out], device="cpu")
    assert list(out.numpy()) == [10.0, 20.0]
    assert struct_refs.OPTION not in wp.get_module(__name__).options
    assert np.isfinite(out.numpy()).all()


KERNEL_ARGS = """    //---------
    // argument vars
    View_a6a9bfbf var_view = _wp_args->view;
    Shading_1aa40241 var_sh = _wp_args->sh;
    wp::float32 var_u = _wp_args->u;
    wp::array_t<wp::float32> var_rgba = _wp_args->rgba;
    Shading_1aa40241 adj_sh = _wp_adj_args->sh;
    Shading_1aa40241 var_12;
"""


def test_a_cpu_kernels_struct_arguments_are_bound_by_reference_not_copied_per_thread():
    """A CPU kernel's body copied each struct argument out of the launch's argument block once per
    thread index (per pixel); they are bound as references now, and nothing else changes."""
    out = struct_refs.kernel_args_by_reference(KERNEL_ARGS)
    assert "    View_a6a9bfbf& var_view = _wp_args->view;\n    Shading_1aa40241& var_sh = _wp_args->sh;\n" in out
    assert "    wp::float32 var_u = _wp_args->u;\n    wp::array_t<wp::float32> var_rgba = _wp_args->rgba;\n" in out
    assert "    Shading_1aa40241 adj_sh = _wp_adj_args->sh;\n    Shading_1aa40241 var_12;\n" in out
    assert out.count("&") == 2


def test_the_package_kernels_bind_their_struct_arguments_by_reference(tmp_path):
    """In the sharp rasterizer's generated C++ (a render builds it), render_sharp binds View,
    Geometry, Shading and Bins by reference; the module carries the level that says so."""
    if os.environ.get("WARP_BLUR_STRUCT_REFS") == "0":
        pytest.skip("struct references switched off for this run (WARP_BLUR_STRUCT_REFS=0)")
    from scenes import shadow_stage
    path = shadow_stage(str(tmp_path / "s.usda"))
    wb.render(path, frame=1, method="accumulation", samples=2, resolution=(32, 24), aovs=())
    module = wp.get_module("warp_blur.kernels.raster")
    block_dim = next(iter(module.execs))[1]
    ident = module.get_module_identifier(block_dim=block_dim)
    source = open(os.path.join(wp.config.kernel_cache_dir, ident, ident + ".cpp")).read()
    body = source[source.index("render_sharp_"):]
    body = body[body.index("// argument vars"):body.index("// primal vars")]
    for name in ("view", "geo", "sh", "bins"):
        assert f"& var_{name} = _wp_args->{name};" in body


CONTIGUOUS_BODY = """{
    static constexpr bool wp_linear_tid = wp_linear_contiguous;
    wp_args_classify_samples_0f029478 wp_contiguous_args;
    if constexpr (wp_linear_contiguous)
    {
        wp_contiguous_args = *_wp_args;
        wp_contiguous_args.listed.strides[0] = sizeof(wp::int32);
        wp_contiguous_args.rgba.strides[1] = sizeof(wp::float32);
        _wp_args = &wp_contiguous_args;
    }
    //---------
    // argument vars
    View_a6a9bfbf& var_view = _wp_args->view;
    wp::int32 var_first = _wp_args->first;
    wp::array_t<wp::int32> var_listed = _wp_args->listed;
    wp::array_t<wp::float32> var_rgba = _wp_args->rgba;
    //---------
"""


def test_a_contiguous_launch_sets_its_arrays_strides_instead_of_copying_its_argument_block():
    """Warp's contiguous specialization copied the whole argument block (structs included) per
    thread index to give the arrays constant strides; the strides are set on the kernel's own
    array copies instead, under the same condition, and the block is read in place."""
    out = struct_refs.contiguous_strides_in_place(CONTIGUOUS_BODY)
    assert "wp_contiguous_args" not in out
    assert ("    wp::array_t<wp::int32> var_listed = _wp_args->listed;\n"
            "    if constexpr (wp_linear_contiguous) var_listed.strides[0] = sizeof(wp::int32);\n"
            "    wp::array_t<wp::float32> var_rgba = _wp_args->rgba;\n"
            "    if constexpr (wp_linear_contiguous) var_rgba.strides[1] = sizeof(wp::float32);\n") in out
    assert "    View_a6a9bfbf& var_view = _wp_args->view;\n    wp::int32 var_first = _wp_args->first;\n" in out
    # an array argument bound some other way: Warp's code is left as it is
    odd = CONTIGUOUS_BODY.replace("var_rgba = _wp_args->rgba", "var_rgba = other")
    assert struct_refs.contiguous_strides_in_place(odd) == odd
    assert struct_refs.contiguous_strides_in_place(KERNEL_ARGS) == KERNEL_ARGS


def test_classify_samples_reads_its_argument_block_in_place(tmp_path):
    """The analytic classify pass (all its arrays one-dimensional: Warp gives it the contiguous
    specialization) no longer copies View, Geometry and two Bins per pixel; its image is the
    one the pass always gave (the analytic-vs-accumulation tests check that)."""
    if os.environ.get("WARP_BLUR_STRUCT_REFS") == "0":
        pytest.skip("struct references switched off for this run (WARP_BLUR_STRUCT_REFS=0)")
    from scenes import shadow_stage
    path = shadow_stage(str(tmp_path / "s.usda"))
    wb.render(path, frame=1, method="analytic", resolution=(32, 24), aovs=())
    module = wp.get_module("warp_blur.methods.analytic.intervals")
    block_dim = next(iter(module.execs))[1]
    ident = module.get_module_identifier(block_dim=block_dim)
    source = open(os.path.join(wp.config.kernel_cache_dir, ident, ident + ".cpp")).read()
    body = source[source.index("classify_samples_"):]
    body = body[:body.index("// primal vars")]
    assert "wp_contiguous_args" not in body
    assert "if constexpr (wp_linear_contiguous) var_listed.strides[0] = sizeof(wp::int32);" in body

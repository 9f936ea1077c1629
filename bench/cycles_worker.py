"""Render one USD stage through Blender Cycles (CPU) with motion blur, for bench/bench_peers.py.

Runs in a Python that has `bpy` (pip install 'bpy==4.5.*', e.g. in a separate venv); prints one JSON
line per render: {"spp", "seconds", "exr"}. The conversions (stated in bench_peers.py): USD importer
(cameras and meshes, lights not imported), every material replaced by an Emission shader of the
colour the importer put in its Principled BSDF's emission, the dome's colour as a constant world,
shutter mapped to Cycles' (length in frames, centred on the frame), a 0.01-px Gaussian pixel filter
(the pixel centre: Blender's sync forces a box filter's width to 1 px, so a "0.01-px box" is really
a 1-px box and antialiases every edge), no denoising, no adaptive sampling, no bounces, transparent
film (the background is added back by the caller).
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import time


def setup(scene_path: str, frame: int, res: tuple[int, int], dome: tuple[float, float, float], shutter: float,
          motion_steps: int, threads: int):
    import bpy
    bpy.ops.wm.read_factory_settings(use_empty=True)
    bpy.ops.wm.usd_import(filepath=scene_path, import_cameras=True, import_lights=False, import_materials=True)
    scene = bpy.context.scene
    cams = [o for o in scene.objects if o.type == "CAMERA"]
    if not cams:
        raise SystemExit("cycles_worker: the stage has no camera")
    scene.camera = cams[0]
    for mat in bpy.data.materials:
        if not mat.use_nodes:
            continue
        nodes, links = mat.node_tree.nodes, mat.node_tree.links
        bsdf = next((n for n in nodes if n.type == "BSDF_PRINCIPLED"), None)
        out = next((n for n in nodes if n.type == "OUTPUT_MATERIAL"), None)
        if bsdf is None or out is None:
            continue
        colour = list(bsdf.inputs["Emission Color"].default_value)[:3]
        strength = bsdf.inputs["Emission Strength"].default_value
        emission = nodes.new("ShaderNodeEmission")
        emission.inputs["Color"].default_value = (*colour, 1.0)
        emission.inputs["Strength"].default_value = strength if strength > 0 else 1.0
        links.new(emission.outputs["Emission"], out.inputs["Surface"])
    world = bpy.data.worlds.new("dome")
    world.use_nodes = True
    world.node_tree.nodes["Background"].inputs["Color"].default_value = (*dome, 1.0)
    world.node_tree.nodes["Background"].inputs["Strength"].default_value = 1.0
    scene.world = world
    scene.render.engine = "CYCLES"
    scene.cycles.device = "CPU"
    scene.cycles.use_adaptive_sampling = False
    scene.cycles.use_denoising = False
    scene.cycles.max_bounces = 0
    scene.cycles.pixel_filter_type = "GAUSSIAN"  # not BOX: Blender syncs a box filter at width 1 px
    scene.cycles.filter_width = 0.01
    scene.render.film_transparent = True
    scene.render.resolution_x, scene.render.resolution_y = res
    scene.render.resolution_percentage = 100
    scene.render.use_motion_blur = shutter > 0
    scene.render.motion_blur_shutter = max(shutter, 1e-3)
    if hasattr(scene.render, "motion_blur_position"):
        scene.render.motion_blur_position = "CENTER"
    else:
        scene.cycles.motion_blur_position = "CENTER"
    for obj in scene.objects:
        if hasattr(obj, "cycles"):
            obj.cycles.motion_steps = motion_steps
    scene.render.threads_mode = "FIXED"
    scene.render.threads = threads
    scene.view_settings.view_transform = "Standard"
    scene.render.image_settings.file_format = "OPEN_EXR"
    scene.render.image_settings.color_depth = "32"
    scene.render.image_settings.color_mode = "RGBA"
    scene.frame_set(frame)
    return scene


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("scene")
    ap.add_argument("--frame", type=int, required=True)
    ap.add_argument("--resolution", required=True)
    ap.add_argument("--dome", default="0,0,0")
    ap.add_argument("--shutter", type=float, default=1.0, help="shutter length in frames (0: sharp)")
    ap.add_argument("--motion-steps", type=int, default=3)
    ap.add_argument("--threads", type=int, default=os.cpu_count() or 1)
    ap.add_argument("--spp", default="16,64,256")
    ap.add_argument("--out", required=True)
    args = ap.parse_args()
    import bpy
    res = tuple(int(v) for v in args.resolution.split("x"))
    dome = tuple(float(v) for v in args.dome.split(","))
    os.makedirs(args.out, exist_ok=True)
    scene = setup(os.path.abspath(args.scene), args.frame, res, dome, args.shutter, args.motion_steps, args.threads)
    for spp in (int(v) for v in args.spp.split(",")):
        scene.cycles.samples = spp
        scene.cycles.seed = 0
        path = os.path.join(args.out, f"cycles_{spp}.exr")
        scene.render.filepath = path
        t0 = time.perf_counter()
        bpy.ops.render.render(write_still=True)
        seconds = time.perf_counter() - t0
        print(json.dumps({"spp": spp, "seconds": seconds, "exr": path}), flush=True)
    sys.stdout.flush()


if __name__ == "__main__":
    main()

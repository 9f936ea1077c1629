"""Command line (SPEC §6): `warp-blur render | compare | info`. main(argv) -> exit status.

Exit 0 on success, 1 when frames of a range failed (or compare exceeded --fail), 2 on bad input
with one line on stderr naming the problem.
"""

from __future__ import annotations

import argparse
import hashlib
import json
import logging
import os
import sys

from typing import TYPE_CHECKING

from .errors import UserError

if TYPE_CHECKING:
    from .settings import RenderSettings


class _Parser(argparse.ArgumentParser):
    def error(self, message: str):  # one line, exit 2
        raise UserError(message)


def _build_parser() -> argparse.ArgumentParser:
    p = _Parser(prog="warp-blur", description="Motion-blur renderer for animated USD stages (NVIDIA Warp).")
    sub = p.add_subparsers(dest="command", required=True, parser_class=_Parser)

    r = sub.add_parser("render", help="render frames of a stage to EXR or PNG")
    r.add_argument("scene")
    r.add_argument("-o", "--output", required=True, help="output path; a run of # is the frame number")
    g = r.add_mutually_exclusive_group()
    g.add_argument("--frames", help="usdrecord frame spec: 1:24, 1:24x2, 1,5,9")
    g.add_argument("--frame", type=float)
    r.add_argument("--camera")
    r.add_argument("--resolution", help="WxH")
    r.add_argument("--method", default="accumulation", choices=["accumulation", "stochastic", "analytic", "velocity"])
    r.add_argument("--samples", type=int)
    r.add_argument("--time-bits", type=int)
    r.add_argument("--quality", choices=["draft", "preview", "final"])
    r.add_argument("--aov", default="", help="comma-separated AOVs: Z, motion, coverage")
    r.add_argument("--shutter", help="OPEN:CLOSE offsets overriding the camera's shutter")
    r.add_argument("--seed", type=int)
    r.add_argument("--spatial-samples", type=int, default=1, help="n -> n×n sub-pixel positions")
    r.add_argument("--threads", type=int)
    sg = r.add_argument_group("shadows")
    sg.add_argument("--shadows", default="auto", choices=["auto", "warped", "direct", "off"],
                    help="shadow maps warped from key maps, rendered per instant (reference), none, or auto "
                         "(per light: rendered unless warping is measured cheaper for this frame)")
    sg.add_argument("--shadow-map-size", type=int, help="texels per shadow-map side (power of two; 512)")
    sg.add_argument("--light-samples", type=int, help="point samples per area light: soft shadows (1)")
    sg.add_argument("--shadow-times", type=int, default=8, help="shadow-map instants over the shutter (8)")
    sg.add_argument("--shadow-grid", type=int, default=128, help="warp control-point cells per map side (128)")
    r.add_argument("--resume", action="store_true", help="skip frames already rendered with the same settings")
    r.add_argument("--fail-fast", action="store_true")
    r.add_argument("--skip-invalid", action="store_true", help="drop prims with invalid geometry (warned)")
    r.add_argument("--device", default="cpu")
    r.add_argument("--compression", default="zip", choices=["zip", "zips", "piz", "none", "rle", "dwaa"])
    r.add_argument("--json", action="store_true", help="print per-frame stats as JSON lines")
    r.add_argument("--workers", type=int, default=1, help="render frames in N local processes")
    r.add_argument("--cluster", help="render frames on a Dask cluster (scheduler address, e.g. tcp://host:8786)")
    r.add_argument("--quiet", action="store_true")

    c = sub.add_parser("compare", help="compare two EXR images (RMSE over all RGBA values)")
    c.add_argument("a")
    c.add_argument("b")
    c.add_argument("--fail", type=float, help="exit 1 when RMSE exceeds this")
    c.add_argument("--threshold", type=float, default=0.01, help="per-pixel error counted as 'above'")
    c.add_argument("--diff", help="write the absolute difference image here (EXR)")
    c.add_argument("--json", action="store_true")

    i = sub.add_parser("info", help="what a scene requires to render")
    i.add_argument("scene")
    i.add_argument("--camera")
    i.add_argument("--frame", type=float)
    i.add_argument("--resolution")
    i.add_argument("--json", action="store_true")
    return p


def settings_from_args(args) -> "RenderSettings":
    from .settings import RenderSettings
    from .stage import parse_shutter
    aovs = tuple(a.strip() for a in args.aov.split(",") if a.strip())
    return RenderSettings(
        method=args.method, samples=args.samples, time_bits=args.time_bits, quality=args.quality,
        seed=args.seed, spatial_samples=args.spatial_samples,
        shutter=parse_shutter(args.shutter) if args.shutter else None, threads=args.threads,
        aovs=aovs or (), skip_invalid=args.skip_invalid, device=args.device, shadows=args.shadows,
        shadow_map_size=args.shadow_map_size, light_samples=args.light_samples, shadow_times=args.shadow_times,
        shadow_grid=args.shadow_grid)


def fingerprint(scene: str, camera: str, resolution, frame: float, settings) -> str:
    """What decides a frame's pixels; --resume skips outputs carrying the same fingerprint."""
    st = os.stat(scene)
    blob = json.dumps([os.path.abspath(scene), st.st_size, st.st_mtime_ns, camera, list(resolution), frame,
                       settings.describe(), sorted(settings.aovs)], sort_keys=True, default=str)
    return hashlib.sha256(blob.encode()).hexdigest()[:32]


def _existing_fingerprint(path: str) -> str | None:
    if not os.path.exists(path):
        return None
    try:
        if path.lower().endswith(".exr"):
            import OpenEXR
            with OpenEXR.File(path, header_only=True) as f:
                return f.header().get("warp_blur.fingerprint")
        from PIL import Image
        with Image.open(path) as im:
            return im.info.get("warp_blur.fingerprint")
    except Exception:
        return None


def _cmd_render(args) -> int:
    import dataclasses

    from tqdm import tqdm

    from .api import Renderer
    from .batch import FrameTask, execute, remove_stale_temporaries
    from .stage import output_path_for_frame, parse_frames, parse_resolution

    settings = settings_from_args(args)
    resolution = parse_resolution(args.resolution) if args.resolution else None
    ext = os.path.splitext(args.output)[1].lower()
    if ext not in (".exr", ".png"):
        raise UserError(f"output {args.output}: unsupported extension '{ext}' (use .exr or .png)")
    if args.workers < 1:
        raise UserError(f"--workers must be at least 1, got {args.workers}")
    frames = parse_frames(args.frames) if args.frames is not None else None
    # open the stage here: bad input (stage, camera, resolution, frames) fails before any work
    renderer = Renderer(args.scene, camera=args.camera, resolution=resolution, settings=settings)
    if frames is None:
        frames = [args.frame if args.frame is not None else renderer.default_frame()]
    for f in frames:
        renderer.check_frame(f)
    paths = [output_path_for_frame(args.output, f, len(frames)) for f in frames]
    cam = str(renderer.camera.GetPath())
    settings_dict = {f.name: getattr(settings, f.name) for f in dataclasses.fields(settings)}
    remove_stale_temporaries(paths)
    from .output import check_writable
    for folder_path in {os.path.dirname(os.path.abspath(p)): p for p in paths}.values():
        check_writable(folder_path)   # a read-only or missing folder fails before any frame renders
    tasks, skipped = [], 0
    for frame, path in zip(frames, paths):
        fp = fingerprint(args.scene, cam, renderer.resolution, frame, settings)
        if args.resume and _existing_fingerprint(path) == fp:
            skipped += 1
            if args.json:
                print(json.dumps({"frame": frame, "output": path, "skipped": True}), flush=True)
            continue
        tasks.append(FrameTask(scene=args.scene, camera=cam, resolution=renderer.resolution, settings=settings_dict,
                               frame=frame, output=path, compression=args.compression, fingerprint=fp))
    if args.workers == 1 and not args.cluster:
        from . import batch
        batch._renderers.clear()
        key = (args.scene, cam, renderer.resolution, tuple(sorted((k, repr(v)) for k, v in settings_dict.items())))
        batch._renderers[key] = renderer  # reuse the stage already opened
    failures: list[tuple[float, str]] = []
    bar = tqdm(total=len(frames), initial=skipped, unit="frame", disable=args.quiet or len(frames) < 2,
               file=sys.stderr, dynamic_ncols=True)
    single = len(frames) == 1
    try:
        user_errors = list_results(execute(tasks, workers=args.workers, cluster=args.cluster,
                                           fail_fast=args.fail_fast), bar, args, failures, single)
    except KeyboardInterrupt:
        bar.close()
        remove_stale_temporaries(paths)   # workers ended: their temporaries are a dead owner's
        raise
    bar.close()
    if single and failures and user_errors:
        raise UserError(failures[0][1])  # one frame of bad input: exit 2, one line
    if failures:
        print(f"warp-blur: {len(failures)} of {len(frames)} frames failed: "
              + "; ".join(f"frame {f:g}: {m}" for f, m in sorted(failures)), file=sys.stderr)
        return 1
    return 0


def list_results(results, bar, args, failures: list, single: bool) -> int:
    """Consume frame results as they end (bar, JSON lines, failures); returns the user errors."""
    user_errors = 0
    for res in results:
        if "error" in res:
            failures.append((res["frame"], res["error"]))
            user_errors += bool(res.get("user_error"))
            if not single:
                logging.getLogger("warp_blur").error(f"frame {res['frame']:g} failed: {res['error']}")
        else:
            bar.set_postfix_str(f"{res['seconds']:.2f}s/frame")
            if args.json:
                print(json.dumps(res, default=str), flush=True)
        bar.update(1)
    return user_errors


def _cmd_compare(args) -> int:
    import numpy as np

    from .metrics import compare_images
    from .output import read_exr, write_exr_channels
    a, b = read_exr(args.a), read_exr(args.b)
    if "RGBA" not in a or "RGBA" not in b:
        raise UserError("compare needs RGB(A) channels in both images")
    if a["RGBA"].shape != b["RGBA"].shape:
        raise UserError(f"images differ in size: {a['RGBA'].shape[1]}x{a['RGBA'].shape[0]} vs "
                        f"{b['RGBA'].shape[1]}x{b['RGBA'].shape[0]}")
    report = compare_images(a["RGBA"], b["RGBA"], threshold=args.threshold)
    if args.diff:
        write_exr_channels(args.diff, {"RGBA": np.abs(a["RGBA"] - b["RGBA"]).astype(np.float32)})
    if args.json:
        print(json.dumps(report))
    else:
        print("  ".join(f"{k}={v:.6g}" if isinstance(v, float) else f"{k}={v}" for k, v in report.items()))
    if args.fail is not None and report["rmse"] > args.fail:
        print(f"warp-blur: RMSE {report['rmse']:.6g} exceeds {args.fail:g}", file=sys.stderr)
        return 1
    return 0


def _cmd_info(args) -> int:
    from .info import scene_report
    from .stage import parse_resolution
    report = scene_report(args.scene, camera=args.camera, frame=args.frame,
                          resolution=parse_resolution(args.resolution) if args.resolution else None)
    if args.json:
        print(json.dumps(report, indent=2, default=str))
    else:
        from .info import format_report
        print(format_report(report))
    return 0


#: Options whose value may start with '-' (a negative shutter offset or resolution): argparse
#: would take `--shutter -0.25:0.25` for two options, so such pairs are joined as `--shutter=…`.
_DASH_VALUE_OPTIONS = ("--shutter", "--resolution", "--frame", "--frames")


def _join_dash_values(argv: list[str]) -> list[str]:
    out: list[str] = []
    i = 0
    while i < len(argv):
        if argv[i] in _DASH_VALUE_OPTIONS and i + 1 < len(argv) and argv[i + 1].startswith("-"):
            out.append(f"{argv[i]}={argv[i + 1]}")
            i += 2
        else:
            out.append(argv[i])
            i += 1
    return out


def main(argv: list[str] | None = None) -> int:
    log = logging.getLogger("warp_blur")
    for h in list(log.handlers):
        log.removeHandler(h)
    handler = logging.StreamHandler(sys.stderr)  # this call's stderr (tests swap it)
    handler.setFormatter(logging.Formatter("warp-blur: %(levelname)s: %(message)s"))
    log.addHandler(handler)
    log.setLevel(logging.WARNING)
    log.propagate = False
    try:
        args = _build_parser().parse_args(_join_dash_values(sys.argv[1:] if argv is None else list(argv)))
        if getattr(args, "quiet", False):
            log.setLevel(logging.ERROR)
        if args.command == "render":
            return _cmd_render(args)
        if args.command == "compare":
            return _cmd_compare(args)
        return _cmd_info(args)
    except UserError as exc:
        print(f"warp-blur: error: {exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print("warp-blur: interrupted", file=sys.stderr)
        return 130


if __name__ == "__main__":
    sys.exit(main())

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
import time

from typing import TYPE_CHECKING

from . import native_stderr
from ..core.errors import UserError

if TYPE_CHECKING:
    from ..core.settings import RenderSettings


class _Parser(argparse.ArgumentParser):
    def error(self, message: str):  # one line, exit 2
        raise UserError(message)


class _HelpFormatter(argparse.ArgumentDefaultsHelpFormatter):
    """Every flag's default in its help, except where there is none to show (None, off flags),
    whose help says what applies (method-dependent defaults are spelt out in the text)."""

    def _get_help_string(self, action):
        if action.default in (None, False, "", argparse.SUPPRESS) or "default" in (action.help or ""):
            return action.help
        return super()._get_help_string(action)


def _version() -> str:
    from importlib.metadata import PackageNotFoundError, version

    from ..core.version import __version__

    def of(dist: str) -> str:
        try:
            return version(dist)
        except PackageNotFoundError:
            return "not installed"
    return f"warp-blur {__version__} (warp-lang {of('warp-lang')}, usd-core {of('usd-core')}, Python {sys.version.split()[0]})"


def _devices_here() -> str:
    """The Warp devices this machine can have, without initialising Warp (kept cheap for --help)."""
    import ctypes
    try:
        ctypes.CDLL("libcuda.so.1")
        return "cpu, cuda"
    except OSError:
        return "cpu"


def _build_parser() -> argparse.ArgumentParser:
    p = _Parser(prog="warp-blur", description="Motion-blur renderer for animated USD stages (NVIDIA Warp kernels).",
                epilog="Exit status: 0 success, 1 some frames failed (or compare over --fail), 2 bad input, "
                       "130 interrupted. `warp-blur COMMAND --help` for each command.")
    p.add_argument("--version", action="version", version=_version())
    sub = p.add_subparsers(dest="command", required=True, parser_class=_Parser, metavar="COMMAND")
    fmt = _HelpFormatter

    r = sub.add_parser("render", help="render frames of a stage to EXR or PNG", formatter_class=fmt,
                       description="Render frames of a USD stage with motion blur over each frame's shutter.")
    r.add_argument("scene", help="the USD stage (.usd, .usda, .usdc, .usdz)")
    r.add_argument("-o", "--output", required=True,
                   help="output .exr (float RGBA + AOVs + metadata) or .png (8-bit sRGB preview); a run of "
                        "# is the zero-padded frame number, ###.### for sub-frames")

    fr = r.add_argument_group("frames")
    g = fr.add_mutually_exclusive_group()
    g.add_argument("--frames", metavar="SPEC", help="usdrecord frame spec: 1:24, 1:24x2, 1,5,9 "
                                                   "(default: the stage's startTimeCode)")
    g.add_argument("--frame", type=float, metavar="F", help="one frame (time code; default: the stage's startTimeCode)")
    fr.add_argument("--shutter", metavar="OPEN:CLOSE",
                    help="shutter offsets from the frame in time codes, overriding the camera's "
                         "(e.g. -0.25:0.25; default: the camera's shutter:open/close)")

    cg = r.add_argument_group("camera")
    cg.add_argument("--camera", metavar="PATH", help="camera prim path (default: the render settings' camera, "
                                                     "else the first camera, else one computed to frame the stage)")

    ig = r.add_argument_group("image")
    ig.add_argument("--resolution", metavar="WxH",
                    help="image size in pixels (default: UsdRenderSettings' resolution, else 640x480)")
    ig.add_argument("--aov", default="", metavar="NAMES",
                    help="comma-separated AOVs written beside RGBA in EXR: Z, motion, coverage (default: none)")
    ig.add_argument("--spatial-samples", type=int, default=1, metavar="N",
                    help="N×N stratified sub-pixel positions per pixel (box filter)")

    mg = r.add_argument_group("method and quality")
    mg.add_argument("--method", default="accumulation", choices=["accumulation", "stochastic", "analytic", "velocity"],
                    help="accumulation: N sharp instants averaged (the reference); stochastic: N jittered time "
                         "samples per pixel; analytic: exact coverage intervals (noise-free); velocity: post-process "
                         "blur of one sharp render")
    mg.add_argument("--quality", choices=["draft", "preview", "final"],
                    help="preset of samples, time bits and shadow quality; an explicit flag wins (default: none, "
                         "the per-method defaults below)")
    mg.add_argument("--samples", type=int, metavar="N",
                    help="instants (accumulation, default 64), samples per pixel (stochastic, 64), shading samples "
                         "per interval at most (analytic, 16) or gather samples (velocity, 8)")
    mg.add_argument("--time-bits", type=int, metavar="B",
                    help="analytic only: time slots per pixel, 32, 64, 128, 256, 512 or 1024, or 0 for exact spans "
                         "(default 128)")
    mg.add_argument("--seed", type=int, metavar="S", help="stochastic only: random seed (default 0)")

    sg = r.add_argument_group("shadows")
    sg.add_argument("--shadows", default="auto", choices=["auto", "warped", "direct", "off"],
                    help="shadow maps warped from key maps, rendered per instant (reference), none, or auto "
                         "(per light: rendered unless warping is measured cheaper for this frame)")
    sg.add_argument("--shadow-map-size", type=int, metavar="S",
                    help="texels per shadow-map side, a power of two (default 512; presets 256/512/1024)")
    sg.add_argument("--light-samples", type=int, metavar="M",
                    help="point samples per area light, for soft shadows (default 1; presets 1/4/9)")
    sg.add_argument("--shadow-times", type=int, default=8, metavar="B", help="shadow-map instants over the shutter")
    sg.add_argument("--shadow-grid", type=int, default=128, metavar="G",
                    help="warp control-point cells per map side (--shadows warped)")

    og = r.add_argument_group("output")
    og.add_argument("--compression", default="zip", choices=["zip", "zips", "piz", "none", "rle", "dwaa"],
                    help="EXR compression")
    og.add_argument("--resume", action="store_true",
                    help="skip frames whose output exists with the same settings fingerprint")
    og.add_argument("--skip-invalid", action="store_true",
                    help="drop prims with invalid geometry (non-finite points, bad indices) with a warning "
                         "instead of failing")
    og.add_argument("--json", action="store_true", help="print each frame's stats as a JSON line on stdout")
    og.add_argument("--quiet", action="store_true", help="no progress, no warnings, no closing line: errors only")
    og.add_argument("--verbose", action="store_true",
                    help="also show USD's and Warp's own diagnostics and Python warnings (hidden otherwise)")

    eg = r.add_argument_group("execution and farm")
    eg.add_argument("--device", default="cpu", metavar="DEVICE",
                    help=f"Warp device: cpu, or cuda / cuda:N with a GPU (here: {_devices_here()})")
    eg.add_argument("--threads", type=int, metavar="N", help="worker threads for tiles (default: every core)")
    eg.add_argument("--memory-limit", type=float, metavar="MB",
                    help="refuse a frame whose buffers are estimated above this many MiB, before any work "
                         "(default: three quarters of physical memory)")
    eg.add_argument("--workers", type=int, default=1, metavar="N", help="render frames in N local processes")
    eg.add_argument("--cluster", metavar="ADDRESS",
                    help="render frames on a Dask cluster (scheduler address, e.g. tcp://host:8786)")
    eg.add_argument("--fail-fast", action="store_true", help="stop a range at its first failed frame")

    c = sub.add_parser("compare", help="compare two EXR images (RMSE over all RGBA values)", formatter_class=fmt,
                       description="RMSE, PSNR, max error, share of pixels above a threshold and SSIM of two EXRs.")
    c.add_argument("a", help="first EXR")
    c.add_argument("b", help="second EXR (same size)")
    c.add_argument("--fail", type=float, metavar="RMSE", help="exit 1 when RMSE exceeds this (default: never)")
    c.add_argument("--threshold", type=float, default=0.01, metavar="T", help="per-pixel error counted as 'above'")
    c.add_argument("--diff", metavar="D.exr", help="write the absolute difference image here (EXR)")
    c.add_argument("--json", action="store_true", help="print the report as JSON")
    c.add_argument("--verbose", action="store_true", help=argparse.SUPPRESS)

    i = sub.add_parser("info", help="what a scene requires to render", formatter_class=fmt,
                       description="Camera, shutter, frame range, what moves (object and camera motion), lights, "
                                   "triangles and a memory estimate per method.")
    i.add_argument("scene", help="the USD stage")
    i.add_argument("--camera", metavar="PATH", help="camera prim path (default: as render chooses it)")
    i.add_argument("--frame", type=float, metavar="F", help="time code (default: the stage's startTimeCode)")
    i.add_argument("--resolution", metavar="WxH", help="image size (default: as render chooses it)")
    i.add_argument("--json", action="store_true", help="print the report as JSON")
    i.add_argument("--verbose", action="store_true", help="also show USD's own diagnostics")
    return p


def settings_from_args(args) -> "RenderSettings":
    from ..core.settings import RenderSettings
    from ..usd.stage import parse_shutter
    aovs = tuple(a.strip() for a in args.aov.split(",") if a.strip())
    return RenderSettings(
        method=args.method, samples=args.samples, time_bits=args.time_bits, quality=args.quality,
        seed=args.seed, spatial_samples=args.spatial_samples,
        shutter=parse_shutter(args.shutter) if args.shutter else None, threads=args.threads,
        aovs=aovs or (), skip_invalid=args.skip_invalid, device=args.device, shadows=args.shadows,
        shadow_map_size=args.shadow_map_size, light_samples=args.light_samples, shadow_times=args.shadow_times,
        shadow_grid=args.shadow_grid, frame_memory_limit_mb=args.memory_limit)


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

    from ..api import Renderer
    from .batch import FrameTask, execute, remove_stale_temporaries
    from ..usd.stage import output_path_for_frame, parse_frames, parse_resolution

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
    from ..output.files import check_writable
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
    single = len(frames) == 1
    frame_bar = None
    if single and tasks and not args.quiet and sys.stdout.isatty() and args.workers == 1 and not args.cluster:
        from ..core import progress   # one frame on a terminal: its stages and pixel bands
        frame_bar = tqdm(total=0, unit="band", file=sys.stderr, dynamic_ncols=True, leave=False,
                         bar_format="{desc}: {percentage:3.0f}%|{bar}| {n_fmt}/{total_fmt} bands [{elapsed}]")
        progress.listen(progress.TqdmFrameProgress(frame_bar))
    bar = tqdm(total=len(frames), initial=skipped, unit="frame", disable=args.quiet or len(frames) < 2,
               file=sys.stderr, dynamic_ncols=True)
    t0 = time.perf_counter()
    try:
        user_errors = list_results(execute(tasks, workers=args.workers, cluster=args.cluster,
                                           fail_fast=args.fail_fast), bar, args, failures, single)
    except KeyboardInterrupt:
        bar.close()
        remove_stale_temporaries(paths)   # workers ended: their temporaries are a dead owner's
        raise
    finally:
        if frame_bar is not None:
            from ..core import progress
            progress.listen(None)
            frame_bar.close()
    bar.close()
    written = len(tasks) - len(failures)
    if not args.quiet and not args.json and written:
        where = paths[0] if single else args.output
        print(f"wrote {where}" + ("" if single else f" ({written} frames)")
              + f" in {time.perf_counter() - t0:.2f} s"
              + (f", {skipped} skipped (--resume)" if skipped else ""), flush=True)
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

    from ..output.metrics import compare_images
    from ..output.files import read_exr, write_exr_channels
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
    from ..usd.stage import parse_resolution
    report = scene_report(args.scene, camera=args.camera, frame=args.frame,
                          resolution=parse_resolution(args.resolution) if args.resolution else None)
    if args.json:
        print(json.dumps(report, indent=2, default=str))
    else:
        from .info import format_report
        print(format_report(report))
    sys.stdout.flush()   # a closed pipe is met here, inside main's handling, not at exit
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
    argv = _join_dash_values(sys.argv[1:] if argv is None else list(argv))
    verbose = "--verbose" in argv
    with native_stderr.captured(verbose=verbose):   # USD's/Warp's C++ diagnostics: only with --verbose
        return _main(argv, verbose)


def _main(argv: list[str], verbose: bool) -> int:
    import warnings
    log = logging.getLogger("warp_blur")
    for h in list(log.handlers):
        log.removeHandler(h)
    handler = logging.StreamHandler(sys.stderr)  # this call's stderr (tests swap it)
    handler.setFormatter(logging.Formatter("warp-blur: %(levelname)s: %(message)s"))
    log.addHandler(handler)
    log.setLevel(logging.INFO if verbose else logging.WARNING)
    log.propagate = False
    try:
        with warnings.catch_warnings():
            if not verbose:   # numpy's and other libraries' RuntimeWarnings are not the user's business
                warnings.simplefilter("ignore")
            args = _build_parser().parse_args(argv)
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
    except BrokenPipeError:   # `warp-blur info X --json | head -1`: the reader has gone, which is fine
        _silence_stdout()
        return 0


def _silence_stdout() -> None:
    """Point stdout at /dev/null so that the interpreter's last flush into a closed pipe is quiet."""
    try:
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())
        os.close(devnull)
    except (OSError, ValueError, AttributeError):
        pass


if __name__ == "__main__":
    sys.exit(main())

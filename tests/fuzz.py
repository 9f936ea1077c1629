"""A seeded mutation fuzzer for the SPEC §6 contract: every mutant of a shipped stage, rendered
with the CLI, exits 0 with finite pixels in its output, or 2 with one error line and no output;
never a traceback, a signal or a hang.

Used by tests/test_fuzz.py (a few dozen mutants in-process, every CI run) and, as a script, for
soaks in subprocesses (signals and hangs are seen there):

    python tests/fuzz.py --many 2000 [--seed 1] [--timeout 120] [--start N] [--skip-invalid]
                         [--stage PATH ...]

`--stage` soaks other .usda files instead of the shipped stages (real assets: materials, texture
graphs, subsets, references); each mutant is written to a folder of links to the file's siblings,
so its relative asset paths resolve as they do beside the original.
"""

from __future__ import annotations

import argparse
import collections
import os
import random
import re
import subprocess
import sys
import tempfile

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
STAGES = ["crossing", "demo", "near_plane", "rotation", "shadows", "skinned", "large"]
METHODS = ["accumulation", "stochastic", "analytic", "velocity"]
_NUMBER = re.compile(rb"(?<![\w.])-?\d+(?:\.\d+)?(?:e[-+]?\d+)?(?![\w.])")
_HOSTILE_NUMBERS = [b"nan", b"inf", b"-inf", b"1e300", b"-1e300", b"1e9", b"-1e9", b"0", b"-1", b"1e-300",
                    b"2147483648", b"-2147483649"]
_ATTRS = [b"focalLength", b"horizontalAperture", b"verticalAperture", b"horizontalApertureOffset",
          b"clippingRange", b"shutter:open", b"shutter:close", b"inputs:intensity", b"inputs:diffuseColor",
          b"inputs:roughness", b"inputs:color", b"faceVertexIndices", b"faceVertexCounts", b"protoIndices",
          b"inputs:radius", b"xformOp:translate", b"points", b"inputs:st", b"primvars:st", b"inputs:scale",
          b"inputs:bias", b"inputs:opacity", b"inputs:opacityThreshold", b"indices", b"inputs:metallic",
          b"creaseSharpnesses", b"xformOp:rotateZXY"]


def mutate(data: bytes, rng: random.Random) -> tuple[bytes, str]:
    """One mutant of a .usda's bytes and a name for what was done."""
    kind = rng.choice(["delete_line", "delete_bytes", "garbage", "truncate", "number", "attr_number",
                       "attr_number", "duplicate_line", "swap_lines"])
    lines = data.split(b"\n")
    if kind == "delete_line":
        del lines[rng.randrange(len(lines))]
        return b"\n".join(lines), kind
    if kind == "duplicate_line":
        i = rng.randrange(len(lines))
        lines.insert(i, lines[i])
        return b"\n".join(lines), kind
    if kind == "swap_lines":
        i, j = rng.randrange(len(lines)), rng.randrange(len(lines))
        lines[i], lines[j] = lines[j], lines[i]
        return b"\n".join(lines), kind
    if kind == "delete_bytes":
        i = rng.randrange(len(data))
        return data[:i] + data[i + rng.randint(1, 64):], kind
    if kind == "garbage":
        i = rng.randrange(len(data))
        return data[:i] + bytes(rng.randrange(256) for _ in range(rng.randint(1, 16))) + data[i:], kind
    if kind == "truncate":
        return data[:rng.randrange(len(data))], kind
    numbers = list(_NUMBER.finditer(data))
    if kind == "attr_number":
        attr = rng.choice(_ATTRS)
        at = [m.start() for m in re.finditer(re.escape(attr), data)]
        if at:
            start = rng.choice(at)
            numbers = [m for m in numbers if start < m.start() < start + 400] or numbers
            kind = f"attr_number:{attr.decode()}"
    m = rng.choice(numbers)
    return data[:m.start()] + rng.choice(_HOSTILE_NUMBERS) + data[m.end():], kind


def stage_paths(paths: list[str] | None = None) -> dict[str, str]:
    """name -> .usda path of the stages to mutate: `paths`, or the shipped stages."""
    if paths:
        return {os.path.splitext(os.path.basename(p))[0]: os.path.abspath(p) for p in paths}
    return {name: os.path.join(ROOT, "usd_scenes", f"{name}.usda") for name in STAGES}


def mutants(count: int, seed: int, paths: list[str] | None = None):
    """(index, stage name, method, mutant bytes, mutation) for `count` seeded mutants (of the
    shipped stages, or of the .usda files `paths`)."""
    rng = random.Random(seed)
    sources = {name: open(path, "rb").read() for name, path in stage_paths(paths).items()}
    names = list(sources)
    for i in range(count):
        name = names[i % len(names)]
        method = METHODS[(i // len(names)) % len(METHODS)]
        data, kind = mutate(sources[name], rng)
        yield i, name, method, data, kind


def render_args(scene: str, out: str, method: str, skip_invalid: bool = False) -> list[str]:
    """The CLI arguments a mutant renders with (with --skip-invalid: invalid prims are dropped,
    so the renders go past them and through what drops them); with the Z and motion AOVs, which
    the API renders by default (beside the method, on a helper thread)."""
    return ["render", scene, "-o", out, "--method", method, "--resolution", "32x24", "--samples", "2",
            "--shadow-map-size", "64", "--aov", "Z,motion", "--quiet"] + (["--skip-invalid"] if skip_invalid else [])


def judge(code: int, stderr: str, out: str) -> str:
    """The contract's verdict: 'ok-render', 'ok-error', or what broke it."""
    if code == 0:
        if not os.path.exists(out):
            return "exit 0 without output"
        import numpy as np

        from warp_blur.output.files import read_exr
        layers = read_exr(out)
        if not np.isfinite(layers["RGBA"]).all():
            return "non-finite pixels"
        if not {"Z", "motion.X", "motion.Y"} <= set(layers):
            return "an AOV asked for is missing"
        # Z is inf where nothing is seen (SPEC §1); motion is 0 there, finite everywhere
        if not (np.isfinite(layers["motion.X"]).all() and np.isfinite(layers["motion.Y"]).all()):
            return "non-finite motion"
        return "ok-render"
    if code == 2:
        if os.path.exists(out):
            return "exit 2 left an output"
        errors = [ln for ln in stderr.splitlines() if ln.strip() and "WARNING" not in ln]
        if len(errors) != 1 or not errors[0].startswith("warp-blur: error:"):
            return "exit 2 without exactly one error line"
        return "ok-error"
    if "Traceback" in stderr:
        return "traceback"
    if code < 0:
        return f"signal {-code}"
    return f"exit {code}"


def _linked_folder(tmp: str, name: str, source: str) -> str:
    """A folder in tmp holding links to the siblings of `source` (its relative asset paths
    resolve there as beside it); the shipped stages need none and share tmp itself."""
    if os.path.dirname(source) == os.path.join(ROOT, "usd_scenes"):
        return tmp
    folder = os.path.join(tmp, f"_{name}")
    if not os.path.isdir(folder):
        os.mkdir(folder)
        for entry in os.listdir(os.path.dirname(source)):
            if entry != os.path.basename(source):
                os.symlink(os.path.join(os.path.dirname(source), entry), os.path.join(folder, entry))
    return folder


def soak(count: int, seed: int, timeout: float, start: int = 0, skip_invalid: bool = False,
         paths: list[str] | None = None) -> collections.Counter:
    """Each mutant in its own process (signals and hangs are outcomes too); prints the bad ones.
    Mutants before `start` are generated (the sequence is seeded) but not run: a soak resumes."""
    from tqdm import tqdm
    counts: collections.Counter = collections.Counter()
    sources = stage_paths(paths)
    with tempfile.TemporaryDirectory() as tmp:
        for i, name, method, data, kind in tqdm(list(mutants(count, seed, paths))[start:], unit="mutant"):
            folder = _linked_folder(tmp, name, sources[name])
            scene = os.path.join(folder, f"m{i}.usda")
            out = os.path.join(folder, f"m{i}.exr")
            with open(scene, "wb") as f:
                f.write(data)
            try:
                p = subprocess.run([sys.executable, "-m", "warp_blur", *render_args(scene, out, method, skip_invalid)],
                                   capture_output=True, text=True, timeout=timeout, errors="replace")
                verdict = judge(p.returncode, p.stderr, out)
            except subprocess.TimeoutExpired:
                verdict, p = "timeout", None
            counts[verdict] += 1
            if not verdict.startswith("ok"):
                tqdm.write(f"{verdict}: mutant {i} ({name}, {method}, {kind}): "
                           f"{(p.stderr.strip().splitlines() or [''])[-1][:160] if p else ''}")
            for path in (scene, out):
                if os.path.exists(path):
                    os.unlink(path)
    return counts


if __name__ == "__main__":
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--many", type=int, default=200, help="mutants to run")
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--timeout", type=float, default=120.0, help="seconds before a mutant counts as a hang")
    ap.add_argument("--start", type=int, default=0, help="skip the first mutants of the seeded sequence (resume a soak)")
    ap.add_argument("--skip-invalid", action="store_true", help="render with --skip-invalid (invalid prims dropped)")
    ap.add_argument("--stage", action="append", help=".usda files to mutate instead of the shipped stages")
    a = ap.parse_args()
    missing = [p for p in a.stage or [] if not os.path.isfile(p)]
    if missing:
        ap.error(f"--stage {missing[0]}: no such file (one .usda per --stage)")
    result = soak(a.many, a.seed, a.timeout, a.start, a.skip_invalid, a.stage)
    for verdict, n in result.most_common():
        print(f"{n:6d}  {verdict}")

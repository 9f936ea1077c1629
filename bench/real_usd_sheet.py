"""A contact sheet of ../shared/real_usd: each asset rendered by warp_blur beside its own thumbnail.

    python bench/real_usd_sheet.py [--method accumulation] [--size 240x180]   # -> bench/out/real_usd_sheet.png
"""

from __future__ import annotations

import argparse
import glob
import os

import numpy as np
from PIL import Image, ImageDraw
from tqdm import tqdm

import warp_blur as wb

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.join(HERE, "..", "..", "shared", "real_usd")


def thumbnail_for(path: str) -> str | None:
    """The asset's thumbnails/<name>.png (beside it or one folder up), if any."""
    name = os.path.splitext(os.path.basename(path))[0]
    for folder in (os.path.dirname(path), os.path.dirname(os.path.dirname(path))):
        hits = glob.glob(os.path.join(folder, "thumbnails", f"{name}.png"))
        if hits:
            return hits[0]
    return None


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--method", default="accumulation")
    ap.add_argument("--size", default="240x180")
    a = ap.parse_args()
    w, h = (int(v) for v in a.size.split("x"))
    files = [p for p in sorted(glob.glob(os.path.join(ROOT, "**", "*.usd*"), recursive=True)) if thumbnail_for(p)]
    sheet = Image.new("RGB", (2 * w, (h + 14) * len(files)), "white")
    draw = ImageDraw.Draw(sheet)
    for i, path in enumerate(tqdm(files, unit="asset")):
        y = i * (h + 14)
        draw.text((4, y + 1), os.path.relpath(path, ROOT), fill="black")
        thumb = Image.open(thumbnail_for(path)).convert("RGB")
        thumb.thumbnail((w, h))
        sheet.paste(thumb, (w, y + 14))
        r = wb.render(path, method=a.method, resolution=(w, h), samples=8)
        rgb = np.clip(r.rgba[..., :3], 0, 1) ** (1 / 2.2)
        sheet.paste(Image.fromarray((rgb * 255).astype(np.uint8)), (0, y + 14))
    os.makedirs(os.path.join(HERE, "out"), exist_ok=True)
    out = os.path.join(HERE, "out", "real_usd_sheet.png")
    sheet.save(out)
    print(f"wrote {out} ({len(files)} assets: warp_blur left, the asset's thumbnail right)")


if __name__ == "__main__":
    main()

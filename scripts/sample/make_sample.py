"""Rebuild the demo sample shipped in src/darksynth/data/sample from ../shared/data (run once, by hand).

Makes: no doc figure. It writes the files ``darksynth demo`` runs on (src/darksynth/data/sample: a 320-px Kodak
crop, a 12-frame Set8 clip, a LOL low-light reference), whose provenance src/darksynth/data/sample/LICENSES.md
gives. Kept: the only record of how the sample was made.

Run from the repo root::

    .venv/bin/python scripts/sample/make_sample.py

Only permissively licensed sources are used (see ../shared/data/README.md and the sample's LICENSES.md).
"""

from __future__ import annotations

import sys
from fractions import Fraction
from pathlib import Path

import av
import numpy as np
from PIL import Image

DATA = Path(__file__).resolve().parents[3] / "shared" / "data"
SAMPLE = Path(__file__).resolve().parents[2] / "src" / "darksynth" / "data" / "sample"


def main() -> int:
    if not DATA.is_dir():
        print(f"{DATA}: shared data not found", file=sys.stderr)
        return 1
    SAMPLE.mkdir(parents=True, exist_ok=True)
    kodak = np.asarray(Image.open(DATA / "clean/images/kodak24/kodim23.png").convert("RGB"))
    top, left = (kodak.shape[0] - 320) // 2, (kodak.shape[1] - 320) // 2
    Image.fromarray(kodak[top : top + 320, left : left + 320]).save(SAMPLE / "clean.png", optimize=True)

    frames = sorted((DATA / "clean/videos/motorbike").glob("*.png"))[:12]
    with av.open(str(SAMPLE / "clean_clip.mp4"), "w") as container:
        stream = container.add_stream("libx264", rate=Fraction(25))
        first = np.asarray(Image.open(frames[0]).convert("RGB"))
        stream.width, stream.height = first.shape[1], first.shape[0]
        stream.pix_fmt = "yuv444p"
        stream.options = {"crf": "20"}
        for path in frames:
            rgb = np.asarray(Image.open(path).convert("RGB"))
            for packet in stream.encode(av.VideoFrame.from_ndarray(rgb, format="rgb24")):
                container.mux(packet)
        for packet in stream.encode():
            container.mux(packet)

    Image.open(DATA / "real-lowlight/images/lol/1.png").convert("RGB").save(SAMPLE / "reference.png", optimize=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())

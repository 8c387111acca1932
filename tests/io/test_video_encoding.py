"""VideoEncoding: the codec, CRF and pixel format as one choice, resolved by the codec's rules and recorded under
the names the command line gives them."""

from __future__ import annotations

from pathlib import Path

import pytest

from darksynth.apply import ApplyOptions
from darksynth.apply_outputs import UNRECORDED_OPTIONS, VIDEO_OPTIONS, changed_options, options_fingerprint
from darksynth.io.video_encoding import DEFAULT_CODEC, DEFAULT_CRF, VideoEncoding
from darksynth.profile import load_profile
from darksynth.recipe import ClipRecipe


@pytest.mark.parametrize(
    ("chosen", "size", "resolved"),
    [
        (VideoEncoding(), (64, 48), VideoEncoding(DEFAULT_CODEC, DEFAULT_CRF, "yuv420p")),
        (VideoEncoding(codec="", pix_fmt=""), (64, 48), VideoEncoding(DEFAULT_CODEC, DEFAULT_CRF, "yuv420p")),
        (VideoEncoding(codec="h264", crf=0), (64, 48), VideoEncoding("libx264", 0, "yuv420p")),
        (VideoEncoding(), (63, 48), VideoEncoding(DEFAULT_CODEC, DEFAULT_CRF, "yuv444p")),
        (VideoEncoding(codec="ffv1"), (64, 48), VideoEncoding("ffv1", None, "bgr0")),
        (VideoEncoding(codec="libx264rgb"), (64, 48), VideoEncoding("libx264rgb", DEFAULT_CRF, "rgb24")),
    ],
)
def test_resolving_makes_every_choice_by_the_codecs_rules_and_keeps_them(
    chosen: VideoEncoding, size: tuple[int, int], resolved: VideoEncoding
) -> None:
    width, height = size
    made = chosen.resolved(Path("clip.mp4"), width, height)
    assert made == resolved
    assert made.resolved(Path("clip.mp4"), width, height) == made


def test_the_fingerprint_records_each_choice_under_its_option_name(profile_file: Path) -> None:
    options = ApplyOptions(
        recipe=ClipRecipe(load_profile(profile_file)), seed=1, encoding=VideoEncoding(codec="ffv1", pix_fmt="bgr0")
    )
    fingerprint = options_fingerprint(options, left_out=UNRECORDED_OPTIONS)
    assert {k: fingerprint[k] for k in ("codec", "crf", "pix_fmt")} == {"codec": "ffv1", "crf": None, "pix_fmt": "bgr0"}
    assert "encoding" not in fingerprint
    without_videos = options_fingerprint(options, left_out=UNRECORDED_OPTIONS | VIDEO_OPTIONS)
    assert set(fingerprint) - set(without_videos) == {"codec", "crf", "pix_fmt"}
    # An earlier run that left the codec's defaults differs by those two choices alone, named as the flags are.
    earlier = options_fingerprint(
        ApplyOptions(recipe=ClipRecipe(load_profile(profile_file)), seed=1), left_out=UNRECORDED_OPTIONS
    )
    assert changed_options(options, fingerprint, earlier) == ["codec", "pix_fmt"]
    assert changed_options(options, fingerprint, {k: v for k, v in fingerprint.items() if k != "crf"}) == []

"""The I/O edge: images, videos, folders and atomic writes. Nothing else in darksynth touches files directly."""

from __future__ import annotations

from darksynth.io.atomic import atomic_output, write_text_atomic
from darksynth.io.discover import FolderListing, InputKind, check_output_location, classify_input, scan_folder
from darksynth.io.images import IMAGE_SUFFIXES, Image, read_image, write_image
from darksynth.io.video import (
    DEFAULT_CODEC,
    DEFAULT_CRF,
    VIDEO_SUFFIXES,
    VideoEncoding,
    VideoInfo,
    VideoWriter,
    iter_video_frames,
    probe_video,
)

__all__ = [
    "DEFAULT_CODEC",
    "DEFAULT_CRF",
    "IMAGE_SUFFIXES",
    "VIDEO_SUFFIXES",
    "FolderListing",
    "Image",
    "InputKind",
    "VideoEncoding",
    "VideoInfo",
    "VideoWriter",
    "atomic_output",
    "check_output_location",
    "classify_input",
    "iter_video_frames",
    "probe_video",
    "read_image",
    "scan_folder",
    "write_image",
    "write_text_atomic",
]

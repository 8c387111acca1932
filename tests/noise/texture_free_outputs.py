"""The spectral model's outputs without texture, as digests: what main drew before ``texture_gain`` existed.

:func:`texture_free_digests` draws three fixed cases (the 8-bit spectral path of
:func:`darksynth.synthesize.synthesize`, the general composer on a float clip with JPEG, a float stream through
:class:`darksynth.synthesize.ClipSynthesizer`) and returns the SHA-256 of each output's 8-bit levels.
``texture_free_outputs.json`` holds them as main drew them, per processor: FFT and reduction bits depend on the
torch version, the CPU capability its kernels use and the processor itself (an Intel and an AMD AVX-512 machine with
the same torch and reported capability drew different float-stream bits). Run this module to print the digests of
the code as it is with the processor they were drawn on: ``python tests/noise/texture_free_outputs.py``.
"""

from __future__ import annotations

import hashlib
import json
import math
import platform as pyplatform
from pathlib import Path

import torch

from darksynth.light.darkening import Darkening
from darksynth.noise.simulate import add_noise
from darksynth.noise.values import NoiseValues
from darksynth.profile import Profile
from darksynth.recipe import ClipParameters
from darksynth.synthesize import ClipSynthesizer, synthesize

SPECTRAL_VALUES: dict[str, object] = {
    "level_curve": [0.004 + 0.01 * math.sqrt(k / 7) + 0.002 * c for c in range(3) for k in range(8)],
    "octave_power": [1.5, 0.8, 0.8, 1.0, 2.0, 3.0, 0.7, 4.0, 5.0, 0.5, 8.0, 6.0, 0.4, 9.0, 7.0, 0.3, 9.0, 9.0],
    "octave_correlation": [0.1, -0.05, 0.2] * 6,
    "temporal_correlation": [0.6, 0.5, 0.4, 0.3, 0.2, 0.1],
}


def scene(frames: int, height: int, width: int) -> torch.Tensor:
    """A (frames, 3, H, W) float scene in [0, 1]: smooth shading with a fine grating on its right half, moving."""
    y = torch.arange(height, dtype=torch.float32)[:, None]
    x = torch.arange(width, dtype=torch.float32)[None, :]
    clips = []
    for t in range(frames):
        shading = 0.5 + 0.3 * torch.sin((x + 2 * t) / 17.0) * torch.cos(y / 23.0)
        grating = 0.2 * torch.sin(1.7 * (x + t)) * (x > width / 2)
        clips.append(torch.stack([(shading + grating) * g for g in (1.0, 0.9, 0.8)]).clamp(0.0, 1.0))
    return torch.stack(clips)


def _digest(image: torch.Tensor) -> str:
    levels = image if image.dtype == torch.uint8 else (image.clamp(0.0, 1.0) * 255.0).round().to(torch.uint8)
    return hashlib.sha256(levels.contiguous().numpy().tobytes()).hexdigest()


def texture_free_digests(extra: dict[str, object] | None = None) -> dict[str, str]:
    """The three cases' digests, with ``extra`` values added to the spectral ones (texture parameters)."""
    values = NoiseValues.from_values(SPECTRAL_VALUES | (extra or {}))  # type: ignore[arg-type]
    image = (scene(1, 72, 96)[0] * 255.0).round().to(torch.uint8)
    profile = Profile(noise=values, darkening=Darkening(0.4, 1.0))
    eight_bit = synthesize(image, profile, generator=torch.Generator().manual_seed(11)).image
    assert isinstance(eight_bit, torch.Tensor)
    compressed = values.replace(compression=0.3)
    clip = add_noise(0.3 * scene(3, 64, 80)[None], compressed, generator=torch.Generator().manual_seed(12))
    stream = ClipSynthesizer(ClipParameters(values, Darkening(0.3, 1.0)), generator=torch.Generator().manual_seed(13))
    frames = torch.stack([stream(frame) for frame in scene(3, 64, 80)])
    return {"spectral_8bit_image": _digest(eight_bit), "general_clip": _digest(clip), "float_stream": _digest(frames)}


def platform() -> dict[str, str]:
    """What the digests depend on beyond the code: the torch version, the CPU capability its kernels use and the
    processor (vendor and model, from /proc/cpuinfo where there is one)."""
    return {
        "torch": torch.__version__,
        "cpu_capability": torch.backends.cpu.get_cpu_capability(),
        "processor": _processor(),
    }


def _processor() -> str:
    try:
        lines = Path("/proc/cpuinfo").read_text(encoding="utf-8").splitlines()
    except OSError:
        return pyplatform.processor() or "unknown"
    fields = dict(line.split(":", 1) for line in lines if ":" in line)
    found = {key.strip(): value.strip() for key, value in fields.items()}
    return f"{found.get('vendor_id', 'unknown')} {found.get('model name', 'unknown')}"


if __name__ == "__main__":
    print(json.dumps({"platform": platform(), "digests": texture_free_digests()}, indent=2))

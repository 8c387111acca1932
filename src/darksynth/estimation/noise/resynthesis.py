"""What every simulation of the blind spectral fit shares, and what the readings after the fit are given.

The fit (:mod:`darksynth.estimation.noise.spectrum`) simulates noise of candidate parameters on the reference's denoised
frames, denoises the result again and measures it as it measured the reference (indirect inference). The readings
that follow the fit (:mod:`darksynth.estimation.noise.readings`) read the same frames with the fitted parameters.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field

import torch

from darksynth.estimation.findings import Findings
from darksynth.estimation.noise.camera_conditional import CameraPriorUse
from darksynth.estimation.noise.nonlocal_means import nlm_denoise
from darksynth.estimation.noise.spectral_fit import SpectralParameters, quantised, uncensored_signal
from darksynth.estimation.noise.spectral_statistics import (
    KnotBinning,
    SpectralStatistics,
    knot_binning,
    measure,
    measure_weight,
)
from darksynth.noise.simulate import add_noise
from darksynth.noise.spectral import level_std
from darksynth.noise.values import NoiseValues


@dataclass
class Resynthesis:
    """What every simulation of the fit shares: the analysed frames (T, 3, H, W), their denoised version, the
    measured pixels, the denoiser's strength and the seed; the knot binning of each frame count, found once."""

    analysed: torch.Tensor
    denoised: torch.Tensor
    mask: torch.Tensor
    strength: float
    seed: int
    binnings: dict[int, KnotBinning] = field(default_factory=dict)
    _signal: tuple[tuple[bytes, int], torch.Tensor] | None = None

    def signal(self, curve: torch.Tensor, count: int) -> torch.Tensor:
        """The signal under the first ``count`` denoised frames for the level ``curve`` (3, 8): the camera clipped
        its noise about the signal, not about the denoised (clipped) mean. Kept for the next call: the draws of a
        step share it."""
        key = (curve.detach().to("cpu", torch.float64).numpy().tobytes(), count)
        if self._signal is None or self._signal[0] != key:
            denoised = self.denoised[:count]
            std = level_std(denoised, curve.reshape(-1).to(denoised))
            self._signal = (key, uncensored_signal(denoised, std))
        return self._signal[1]

    def simulator(
        self, compression: float, frame_count: int | None = None
    ) -> Callable[[SpectralParameters, int], SpectralStatistics]:
        """Simulate and measure on the first ``frame_count`` frames (all by default) with JPEG ``compression``."""
        count = self.analysed.shape[0] if frame_count is None else frame_count
        denoised = self.denoised[:count]
        if count not in self.binnings:
            # Every simulation is measured on the same denoised frames and mask: their knots are found once.
            height, width = denoised.shape[-2:]
            weight = measure_weight(count, height, width, self.mask, denoised.device)
            self.binnings[count] = knot_binning(denoised, weight)
        binning = self.binnings[count]

        def simulate_and_measure(parameters: SpectralParameters, draw: int) -> SpectralStatistics:
            values = NoiseValues.from_values(parameters.as_values() | {"compression": compression}, dtype=torch.float32)
            generator = torch.Generator(device=denoised.device).manual_seed(self.seed * 1009 + draw)
            signal = self.signal(parameters.curve, count)
            synthetic = quantised(add_noise(signal[None], values, generator=generator)[0])
            again = nlm_denoise(synthetic, self.strength)
            return measure(synthetic - again, denoised, self.mask, binning=binning)

        return simulate_and_measure


@dataclass(frozen=True)
class FittedReference:
    """What a reading after the fit is given: the analysed reference and the fit.

    Attributes:
        resynthesis: the analysed frames, their denoised version, the measured pixels, the strength and the seed.
        fitted: the fitted spectral parameters (the level curve checked).
        compression: the JPEG strength the fit chose.
        still: the analysed pixels stay still through the frames (a clip's frame-to-frame statistics are read).
        clip: the reference is a clip (two frames or more).
        name: the reference, as warnings name it.
        camera_prior: what one reference cannot show, from the prior over real cameras; None without it.
    """

    resynthesis: Resynthesis
    fitted: SpectralParameters
    compression: float
    still: bool
    clip: bool
    name: str
    camera_prior: CameraPriorUse | None


@dataclass
class MeasuredValues:
    """A reading's result: the table's parameters it sets, by name, and its findings."""

    values: dict[str, torch.Tensor] = field(default_factory=dict)
    findings: Findings = field(default_factory=Findings)

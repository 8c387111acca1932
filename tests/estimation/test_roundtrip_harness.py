"""A few cases of the randomized round trip of ``estimate`` (benchmarks/estimate_roundtrip.py): known noise on a
darkened shared clean image, estimated blind with the shipped network, applied again; the noise std must come back.
The whole distribution (hundreds of cases) is the benchmark's; these fixed seeds keep the test to a minute."""

from __future__ import annotations

import sys
from pathlib import Path

import pytest

BENCHMARKS = Path(__file__).resolve().parents[2] / "benchmarks"
SHARED_DATA = Path(__file__).resolve().parents[3] / "shared" / "data"


@pytest.mark.slow
@pytest.mark.skipif(not (SHARED_DATA / "real-pairs").is_dir(), reason="needs ../shared/data (clean images and pairs)")
@pytest.mark.parametrize("seed", [0, 1, 7, 8])
def test_the_noise_std_comes_back_through_estimate_and_apply(seed: int) -> None:
    # Seeds 0 and 1 are very dark (mean level 0.02 and 0.04, 34 % and 21 % of the pixels clipped at 0): before the
    # measurement left clipped blocks out and denoised in RGB they came back at 0.11 and 0.10 of the true std.
    sys.path.insert(0, str(BENCHMARKS))
    try:
        import estimate_roundtrip
    finally:
        sys.path.remove(str(BENCHMARKS))
    from darksynth.training.weights import default_weights_path, load_weights

    case = estimate_roundtrip.run_case(SHARED_DATA, load_weights(default_weights_path()), seed)
    assert 0.75 < case["std_ratio"] < 1.33, case

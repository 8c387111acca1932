"""The noise of a reference, measured (:mod:`~darksynth.estimation.noise.noise_estimate`, the stage ``estimate``
runs):

- the DEN on the crop grid (:mod:`~darksynth.estimation.noise.network_reading`: median and 10-90th percentile
  ranges) and whether the reference shows column patterns (:mod:`~darksynth.estimation.noise.columns`);
- the spectral model measured on the reference itself (:mod:`~darksynth.estimation.noise.spectrum`: level curve,
  octave covariances, JPEG strength), fitted by re-synthesis (``resynthesis``, ``spectral_statistics``,
  ``spectral_fit``, ``nonlocal_means``, ``flat_blocks``, ``coarse_anchor``, ``still_blocks``, ``spectrum_checks``),
  then the readings after the fit (``readings``: the persistence from frame to frame, ``persistence_fit``; the
  texture dependence a camera prior expects, ``camera_conditional``);
- the level checked on the reference's own denoised version (:mod:`~darksynth.estimation.noise.self_check`);
- the clean-aided texture fit the evaluation's oracle uses (``texture_fit``).
"""

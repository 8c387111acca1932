"""Estimation of a noise profile from one real low-light reference, one module per stage.

- :mod:`~darksynth.estimation.reference`: reading the reference (image, video, frame folder) as frames, and
  what every stage measures of them (spread frames, uniform frames, scene cuts, the crop grid);
- :mod:`~darksynth.estimation.network`: the DEN on the crop grid, median and 10-90th percentile ranges;
- :mod:`~darksynth.estimation.columns`: whether the reference shows column patterns (banding decisions);
- :mod:`~darksynth.estimation.spectrum`: the spectral model measured on the reference itself (level curve, octave
  covariances, persistence from frame to frame), which replaces the network's heteroscedastic values;
- :mod:`~darksynth.estimation.darkening`: alpha and gamma read off the reference's tone distribution
  (:mod:`darksynth.light.tones`, :mod:`darksynth.light.tone_fit`, below ``apply``, which also matches each input's
  exposure to the reference with them) and the tone target the profile keeps;
- :mod:`~darksynth.estimation.motion`: the shutter's exposure fraction and the flicker of a clip (with
  ``cross_spectra``, ``shutter_fit``, ``shutter_confidence`` and ``flicker``);
- :mod:`~darksynth.estimation.assemble`: ``estimate``, which runs the stages in order and assembles the profile.
"""

"""Estimation of a noise profile from one real low-light reference: the reference read once, three measurements
that do not read each other's results, and the profile assembled from them.

- :mod:`~darksynth.estimation.reference`: reading the reference (image, video, frame folder) as frames into the
  record every measurement reads (the frames to measure, uniform frames, scene cuts), and the crop grid;
- the noise, :mod:`~darksynth.estimation.noise_estimate`: the DEN on the crop grid
  (:mod:`~darksynth.estimation.network_reading`: median and 10-90th percentile ranges), whether the reference shows
  column patterns (:mod:`~darksynth.estimation.columns`), and the spectral model measured on the reference itself
  (:mod:`~darksynth.estimation.spectrum`: level curve, octave covariances, persistence from frame to frame, with
  ``spectral_statistics``, ``spectral_fit``, ``flat_blocks``, ``coarse_anchor``, ``still_blocks``,
  ``persistence_fit`` and ``spectrum_checks``), which replaces the network's heteroscedastic values;
- the darkening, :mod:`~darksynth.estimation.darkening_reading`: alpha and gamma read off the reference's tone
  distribution (:mod:`darksynth.light.tones`, :mod:`darksynth.light.tone_fit`, below ``apply``, which also matches
  each input's exposure to the reference with them) and the tone target the profile keeps;
- the light, :mod:`~darksynth.estimation.light`: the shutter's exposure fraction and the flicker of a clip
  (:mod:`~darksynth.estimation.motion`, with ``cross_spectra``, ``shutter_fit``, ``shutter_confidence`` and
  ``flicker``), held within the table's bounds;
- :mod:`~darksynth.estimation.assemble`: ``estimate``, which reads the reference, runs the three and assembles the
  profile.
"""

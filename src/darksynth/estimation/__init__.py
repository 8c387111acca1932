"""Estimation of a noise profile from one real low-light reference: the reference read once, three measurements
that do not read each other's results, and the profile assembled from them. The package is split by what is
measured:

- :mod:`~darksynth.estimation.reference`: reading the reference (image, video, frame folder) as frames into the
  record every measurement reads (the frames to measure, uniform frames, scene cuts), and the crop grid;
- the noise, :mod:`darksynth.estimation.noise` (its stage :mod:`~darksynth.estimation.noise.noise_estimate`): the
  DEN on the crop grid, the column patterns, and the spectral model measured on the reference itself, checked on
  its own denoised version;
- the darkening, :mod:`~darksynth.estimation.darkening_reading`: alpha and gamma read off the reference's tone
  distribution (:mod:`darksynth.light.tones`, :mod:`darksynth.light.tone_fit`, below ``apply``, which also matches
  each input's exposure to the reference with them) and the tone target the profile keeps;
- the light, :mod:`darksynth.estimation.light` (its stage :mod:`~darksynth.estimation.light.light_reading`): the
  shutter's exposure fraction and the flicker of a clip, held within the table's bounds;
- :mod:`~darksynth.estimation.assemble`: ``estimate``, which reads the reference, runs the three and assembles the
  profile; :mod:`~darksynth.estimation.findings`: what each stage says about itself (``meta`` entries, warnings).
"""

"""Estimation of a noise profile from one real low-light reference, one module per stage.

- :mod:`~darksynth.estimation.reference`: reading the reference (image, video, frame folder) as frames, and
  what every stage measures of them (spread frames, uniform frames, scene cuts, the crop grid);
- :mod:`~darksynth.estimation.network`: the DEN on the crop grid, median and 10-90th percentile ranges;
- :mod:`~darksynth.estimation.columns`: whether the reference shows column patterns (banding decisions);
- :mod:`~darksynth.estimation.refine_statistics` and :mod:`~darksynth.estimation.refine`: the analysis-by-synthesis
  refinement of the network's values on the reference itself;
- the darkening is read from the reference's tone distribution by :mod:`darksynth.light.tones` (below ``apply``, which
  also matches each input's exposure to the reference with it);
- :mod:`~darksynth.estimation.assemble`: ``estimate``, which runs the stages in order and assembles the profile.
"""

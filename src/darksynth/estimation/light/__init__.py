"""The light of a clip, measured (:mod:`~darksynth.estimation.light.light_reading`, the stage ``estimate`` runs):
the shutter's exposure fraction from the blur of moving blocks (:mod:`~darksynth.estimation.light.motion`, with
``cross_spectra``, ``shutter_fit`` and ``shutter_confidence``) and the flicker of the still parts
(``flicker_reading``).
"""

"""Real cameras: the bank of clean-aided fits on real pairs, the prior over cameras fitted on it, and named presets."""

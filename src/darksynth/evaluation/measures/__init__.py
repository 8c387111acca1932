"""What an evaluation measures of a method's synthetic noise against the real: histogram divergences, the noise's
structure (octave bands, channel and frame-to-frame correlation), Inception features, a downstream denoiser."""

"""darksynth evaluate: real noise pairs, noise-generation methods, metrics and reports."""

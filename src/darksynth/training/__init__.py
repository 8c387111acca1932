"""Self-supervised training of the DEN on clean images and clips: crop -> darken -> sample v -> f(v) -> DEN."""

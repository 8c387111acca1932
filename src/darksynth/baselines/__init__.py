"""Noise generators that darksynth is compared against, re-implemented and trained here."""

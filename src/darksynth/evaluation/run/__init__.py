"""An evaluation run: its options, every method on every pair set, and the job that writes its three files."""

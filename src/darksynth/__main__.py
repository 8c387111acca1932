"""``python -m darksynth``: the command line."""

from darksynth.cli import main

main()

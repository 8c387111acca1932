"""``python -m darksynth``: the command line."""

from darksynth.main import main

main()

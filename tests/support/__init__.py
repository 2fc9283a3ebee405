"""Test and benchmark tooling, kept out of the installed package (two-host link, raw stream helpers, frame
stamps, link probe, ...). bench/ and scripts/ import it with the repository root on ``sys.path``."""

"""Test and benchmark tooling, kept out of the installed package: the two-host link (``link``) and raw
MJPEG/image helpers for the simulator (``sim``). bench/ and scripts/ import it with the repository root on
``sys.path``."""

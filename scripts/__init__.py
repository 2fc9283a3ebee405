"""Developer scripts of the repository (not installed). A package so that ``python -m scripts.demo`` and the
tests can import the demo launcher (:mod:`scripts.demo`) from the repository root."""

"""Test and bench support: not part of the installed package."""

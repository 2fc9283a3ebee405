"""The property-based / fuzz tier: generated inputs at every input boundary (issue 25).

``hypothesis`` profiles: ``ci`` (the default, part of ``./scripts/test``: each property a few hundred inputs,
seconds per boundary) and ``long`` for a nightly run: ``AXIS_FUZZ=long ./scripts/test tests/fuzz`` (thousands
of inputs per property; ``AXIS_FUZZ_EXAMPLES=N`` sets the count). The database is off: a CI run is repeatable
from its printed seed (``--hypothesis-seed``), never from a file left by an earlier run.
"""

from __future__ import annotations

import os

from hypothesis import HealthCheck, settings

_COMMON = {"database": None, "deadline": None, "suppress_health_check": [HealthCheck.too_slow]}
settings.register_profile("ci", max_examples=int(os.environ.get("AXIS_FUZZ_EXAMPLES", "300")), **_COMMON)
settings.register_profile("long", max_examples=int(os.environ.get("AXIS_FUZZ_EXAMPLES", "20000")), **_COMMON)
settings.load_profile(os.environ.get("AXIS_FUZZ", "ci"))

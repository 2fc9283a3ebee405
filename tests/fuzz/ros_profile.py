"""The hypothesis settings of the fuzz properties that run over DDS (one service call or message per example).

Fewer examples than the byte-level properties (``AXIS_FUZZ_ROS_EXAMPLES``; 40 in CI, 2,000 with ``AXIS_FUZZ=long``)
and no shrinking: each step would be another round trip, and a failing example is reported as generated.
"""

from __future__ import annotations

import os

from hypothesis import Phase, settings

EXAMPLES = int(os.environ.get("AXIS_FUZZ_ROS_EXAMPLES", "2000" if os.environ.get("AXIS_FUZZ") == "long" else "40"))
ros_settings = settings(max_examples=EXAMPLES, phases=(Phase.explicit, Phase.reuse, Phase.generate))

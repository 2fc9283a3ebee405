"""Machine-readable lines every benchmark prints beside its human-readable output.

``scripts/gen_readme_bench.py`` builds the README's "Measured" table from ``bench/results/<name>.txt`` alone:

- ``BENCH-INPUTS <path> <path> ...`` (once): the files and directories whose changes can move this bench's
  figures. A results file measured at a commit older than the last change to any of them is reported stale.
- ``README-ROW {"what": ..., "figure": ..., "target": ..., "ok": true|false|null}`` (one per README row, in
  table order; ``ok`` false = the figure misses its target, and the table says so).

Import it from a bench script (``bench/`` is on ``sys.path`` when the script runs): ``from report import row``.
"""

from __future__ import annotations

import json

ROW_PREFIX = "README-ROW "
INPUTS_PREFIX = "BENCH-INPUTS "
#: the files the simulator reads its cameras' facts from (zoom, limits, head: issue 38): an input of every bench that
#: runs the simulator, beside ``axis_ptz_ros2/axis_ptz_ros2/sim``
SIM_CONFIG = ("config/axis214.yaml", "config/q6075.yaml")


def inputs(*paths: str) -> None:
    """Declare the repository paths this bench measures (relative to the repository root)."""
    print(INPUTS_PREFIX + " ".join(paths), flush=True)


def row(what: str, figure: str, target: str = "—", ok: bool | None = None) -> None:
    """One row of the README's "Measured" table: what was measured, the figure, the target it is held to and
    whether the figure meets it (None: no pass/fail target)."""
    fields = {"what": what, "figure": figure, "target": target, "ok": ok}
    print(ROW_PREFIX + json.dumps(fields, ensure_ascii=False), flush=True)

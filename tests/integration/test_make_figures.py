"""scripts/make_figures.py makes its pictures from the simulated camera over HTTP (a quick run: two zooms, one
resolution), so the guide's figures can always be regenerated."""

from __future__ import annotations

import csv
import subprocess
import sys
from pathlib import Path

import cv2
import pytest

pytestmark = [pytest.mark.integration, pytest.mark.timeout(240)]

ROOT = Path(__file__).resolve().parents[2]


def test_make_figures_quick(tmp_path):
    r = subprocess.run(
        [sys.executable, str(ROOT / "scripts" / "make_figures.py"), "--quick", "--out", str(tmp_path)],
        capture_output=True,
        text=True,
        timeout=200,
    )
    assert r.returncode == 0, r.stderr[-3000:]
    for name in ("zoom_montage.png", "bitrate.png"):
        img = cv2.imread(str(tmp_path / name))
        assert img is not None, name
        assert img.shape[0] > 200
        assert img.shape[1] > 300
    rows = list(csv.DictReader((tmp_path / "bitrate.csv").open(encoding="utf-8")))
    assert {(r["fps"], r["compression"]) for r in rows} == {
        (f, c) for f in ("1", "15", "30") for c in ("0", "30", "100")
    }
    kbps = {(int(r["fps"]), int(r["compression"])): float(r["sim_kbit_s"]) for r in rows}
    # the stream's cost follows the settings: less compression and more frames cost more
    assert kbps[(15, 0)] > kbps[(15, 30)] > kbps[(15, 100)] > 0
    assert kbps[(1, 30)] < kbps[(15, 30)] < kbps[(30, 30)]

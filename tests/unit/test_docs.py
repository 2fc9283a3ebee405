"""The guide stays true to the repository: its links and pictures exist, it covers every executable, and the
bitrate data behind its plot is complete and carries the thesis's numbers unchanged."""

from __future__ import annotations

import csv
import re
import tomllib
from pathlib import Path

import pytest

pytestmark = pytest.mark.unit

ROOT = Path(__file__).resolve().parents[2]
GUIDE = ROOT / "docs" / "guide.md"
LINK = re.compile(r"\]\(([^)#\s]+)(?:#[^)]*)?\)")
THESIS = {  # thesis Tables 6.2-6.4, kbit/s: (resolution, compression) -> (1, 15, 30 fps)
    ("704x576", 0): (239, 2190, 3440),
    ("704x576", 30): (118, 1350, 2340),
    ("704x576", 100): (43, 540, 950),
    ("352x288", 0): (87, 1020, 2040),
    ("352x288", 30): (43, 530, 820),
    ("352x288", 100): (8, 104, 180),
    ("176x144", 0): (26, 250, 400),
    ("176x144", 30): (7, 65, 180),
    ("176x144", 100): (1.3, 19, 30),
}


def links(path: Path) -> list[str]:
    return [m.group(1) for m in LINK.finditer(path.read_text(encoding="utf-8")) if "://" not in m.group(1)]


def test_the_readme_links_the_guide():
    assert "docs/guide.md" in links(ROOT / "README.md")


@pytest.mark.parametrize("doc", [GUIDE, ROOT / "README.md"], ids=lambda p: p.name)
def test_relative_links_resolve(doc):
    missing = [link for link in links(doc) if not (doc.parent / link).exists()]
    assert not missing, f"{doc.name}: broken links {missing}"


def test_guide_pictures_are_there_and_small():
    # scripts/make_figures.py: kept small; console*.png: the browser tests (AXIS_WRITE_DOCS_IMAGES=1)
    for name, limit in (("zoom_montage.png", 400_000), ("bitrate.png", 400_000), ("console.png", None)):
        p = ROOT / "docs" / "images" / name
        assert p.exists(), f"{name} missing (see the guide's 'Regenerating the pictures')"
        assert p.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
        if limit is not None:
            assert p.stat().st_size < limit, f"{name} is {p.stat().st_size} bytes: keep committed pictures small"


def test_guide_covers_every_executable():
    scripts = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]["scripts"]
    text = GUIDE.read_text(encoding="utf-8")
    absent = [s for s in scripts if s not in text]
    assert not absent, f"the guide never mentions {absent}"


def test_bitrate_data_is_complete_and_quotes_the_thesis_exactly():
    rows = list(csv.DictReader((ROOT / "docs" / "images" / "bitrate.csv").open(encoding="utf-8")))
    seen = {}
    for r in rows:
        key = (r["resolution"], int(r["compression"]))
        fps = int(r["fps"])
        assert float(r["thesis_printed"]) == THESIS[key][(1, 15, 30).index(fps)]
        # the tables print "kBit/s" but are kB/s (docs/simulator.md, "What the simulated camera's pictures are made of")
        assert float(r["thesis_kbit_s"]) == pytest.approx(8 * float(r["thesis_printed"]))
        assert float(r["sim_kbit_s"]) > 0.0
        seen[(key, fps)] = float(r["sim_kbit_s"])
    assert len(seen) == 27
    for (res, comp), _ in THESIS.items():  # more frames per second cost more, for every setting
        assert seen[((res, comp), 1)] < seen[((res, comp), 15)] < seen[((res, comp), 30)]

"""The acuity chart of the simulated scene (issue 39): its layout, its answer key and its picture.

A white board 800 mm × 700 mm (the world file gives its size in metres: 0.80 × 0.70) with

* 12 rows of 5 tumbling-E optotypes, largest at the top. An E is 5 strokes tall and wide (three bars and a spine);
  row ``k`` has strokes of ``STROKE0_MM · 10^(−0.1 k)`` mm (12.6 mm … 1.0 mm: rows in 0.1 log steps, as a
  logMAR chart's). Optotypes are one optotype apart in a row (a row is 9 optotypes wide); the gap under a row is
  the next row's optotype height (the ETDRS chart's spacing);
* each optotype opens right, up, left or down (``ORIENTATIONS``), drawn from ``numpy.random.default_rng(SEED)``:
  a fixed, known answer key (:func:`orientations`);
* four ArUco markers (4×4 dictionary, ids 0 … 3, 72 mm) at the corners: the fiducials by which a scorer
  finds the chart in a picture (``bench/acuity.py``).

Dark ink is grey 20, paper grey 240 (print, not an ideal black and white). The picture is ``PX_PER_MM`` texels a
millimetre (0.4 mm texels: the smallest row's strokes are 2.5 texels), grey PNG, anti-aliased (each texel the
exact ink coverage, from 8×8 sub-samples).

    python bench/acuity_chart.py            # writes axis_ptz_ros2/axis_ptz_ros2/sim/assets/acuity_chart.png
    python bench/acuity_chart.py --check    # exits 1 if the committed picture differs from the layout's

The simulated world places it as ``image`` targets (config/sim_world.yaml: ``acuity_10m`` … ``acuity_35m``).
"""

from __future__ import annotations

import argparse
import sys
from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np
import numpy.typing as npt

ROOT = Path(__file__).resolve().parents[1]
ASSET = ROOT / "axis_ptz_ros2" / "axis_ptz_ros2" / "sim" / "assets" / "acuity_chart.png"

WIDTH_MM = 800.0
HEIGHT_MM = 700.0
PX_PER_MM = 2.5
N_ROWS = 12
PER_ROW = 5
STROKE0_MM = 10.0**1.1  #: the top row's stroke (12.59 mm); row k: STROKE0_MM · 10^(−0.1 k)
TOP_MM = 40.0  #: the top row's upper edge
SEED = 39  #: the orientations' random generator seed (issue 39)
ORIENTATIONS = ("right", "up", "left", "down")  #: where an E's opening faces; index = quarter turns anticlockwise
MARKER_MM = 72.0
MARKER_MARGIN_MM = 20.0
MARKER_IDS = (0, 1, 2, 3)  #: top-left, top-right, bottom-right, bottom-left
ARUCO_DICT = cv2.aruco.DICT_4X4_50
INK, PAPER = 20, 240

#: The E opening to the right on its 5×5 stroke grid (1 = ink).
E_GRID = np.array(
    [[1, 1, 1, 1, 1], [1, 0, 0, 0, 0], [1, 1, 1, 1, 1], [1, 0, 0, 0, 0], [1, 1, 1, 1, 1]],
    dtype=np.uint8,
)


@dataclass(frozen=True)
class Optotype:
    row: int
    col: int
    x_mm: float  #: left edge on the chart
    y_mm: float  #: top edge on the chart
    stroke_mm: float
    orientation: int  #: index into ORIENTATIONS

    @property
    def size_mm(self) -> float:
        return 5.0 * self.stroke_mm


def grid(orientation: int) -> npt.NDArray[np.uint8]:
    """The 5×5 ink grid of an E opening towards ``ORIENTATIONS[orientation]``."""
    return np.ascontiguousarray(np.rot90(E_GRID, orientation))


def stroke_mm(row: int) -> float:
    return float(STROKE0_MM * 10.0 ** (-0.1 * row))


def orientations() -> npt.NDArray[np.int64]:
    """The answer key: N_ROWS × PER_ROW orientation indices (fixed by SEED)."""
    return np.asarray(np.random.default_rng(SEED).integers(0, 4, size=(N_ROWS, PER_ROW)), dtype=np.int64)


def layout() -> list[list[Optotype]]:
    """Every optotype's place on the chart (mm from the top-left corner) and orientation, row by row."""
    key = orientations()
    rows: list[list[Optotype]] = []
    y = TOP_MM
    for r in range(N_ROWS):
        s = stroke_mm(r)
        size = 5.0 * s
        x0 = WIDTH_MM / 2 - 4.5 * size  # 5 optotypes and 4 gaps of one optotype: 9 wide, centred
        rows.append([Optotype(r, c, x0 + 2 * c * size, y, s, int(key[r, c])) for c in range(PER_ROW)])
        if r + 1 < N_ROWS:
            y += size + 5.0 * stroke_mm(r + 1)
    return rows


def marker_corners_mm() -> dict[int, npt.NDArray[np.float64]]:
    """Per marker id its 4 corners (mm; top-left, top-right, bottom-right, bottom-left: ArUco's order)."""
    m, a = MARKER_MARGIN_MM, MARKER_MM
    origins = {
        MARKER_IDS[0]: (m, m),
        MARKER_IDS[1]: (WIDTH_MM - m - a, m),
        MARKER_IDS[2]: (WIDTH_MM - m - a, HEIGHT_MM - m - a),
        MARKER_IDS[3]: (m, HEIGHT_MM - m - a),
    }
    return {
        i: np.array([[x, y], [x + a, y], [x + a, y + a], [x, y + a]], dtype=np.float64) for i, (x, y) in origins.items()
    }


def _paint_coverage(
    ink: npt.NDArray[np.float32], x_mm: float, y_mm: float, cells: npt.NDArray[np.uint8], cell_mm: float
) -> None:
    """Add the exact coverage (8×8 sub-samples a texel) of a grid of square ink cells to ``ink`` (texels, 0…1)."""
    ss = 8
    n = cells.shape[0]
    x0, y0 = x_mm * PX_PER_MM, y_mm * PX_PER_MM
    size = n * cell_mm * PX_PER_MM
    c0, r0 = int(np.floor(x0)), int(np.floor(y0))
    c1, r1 = int(np.ceil(x0 + size)), int(np.ceil(y0 + size))
    sub = (np.arange((r1 - r0) * ss) + 0.5) / ss + r0  # sub-sample centres in texels
    subx = (np.arange((c1 - c0) * ss) + 0.5) / ss + c0
    gi = np.floor((sub - y0) / (cell_mm * PX_PER_MM)).astype(np.int64)
    gj = np.floor((subx - x0) / (cell_mm * PX_PER_MM)).astype(np.int64)
    vi, vj = (gi >= 0) & (gi < n), (gj >= 0) & (gj < n)
    hit = cells[np.clip(gi, 0, n - 1)][:, np.clip(gj, 0, n - 1)].astype(np.float32) * vi[:, None] * vj[None, :]
    cov = hit.reshape(r1 - r0, ss, c1 - c0, ss).mean(axis=(1, 3))
    region = ink[r0:r1, c0:c1]
    np.maximum(region, cov, out=region)


def render(px_per_mm: float = PX_PER_MM) -> npt.NDArray[np.uint8]:
    """The chart's grey picture (rows = HEIGHT_MM · px_per_mm, columns = WIDTH_MM · px_per_mm)."""
    if px_per_mm != PX_PER_MM:
        raise ValueError("the chart is drawn at PX_PER_MM only")
    h, w = int(round(HEIGHT_MM * PX_PER_MM)), int(round(WIDTH_MM * PX_PER_MM))
    ink = np.zeros((h, w), np.float32)
    for row in layout():
        for o in row:
            _paint_coverage(ink, o.x_mm, o.y_mm, grid(o.orientation), o.stroke_mm)
    dictionary = cv2.aruco.getPredefinedDictionary(ARUCO_DICT)
    for i, corners in marker_corners_mm().items():
        bits = cv2.aruco.generateImageMarker(dictionary, i, 6)  # 6 px: one a module (4×4 bits + black border)
        cells = (bits < 128).astype(np.uint8)
        _paint_coverage(ink, float(corners[0, 0]), float(corners[0, 1]), cells, MARKER_MM / 6.0)
    img = PAPER - (PAPER - INK) * ink
    return np.asarray(np.clip(np.round(img), 0, 255), dtype=np.uint8)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--out", type=Path, default=ASSET)
    ap.add_argument("--check", action="store_true", help="compare the committed picture with the layout's")
    args = ap.parse_args(argv)
    img = render()
    if args.check:
        have = cv2.imread(str(args.out), cv2.IMREAD_UNCHANGED)
        same = have is not None and have.shape == img.shape and bool(np.array_equal(have, img))
        print(f"{args.out}: {'matches' if same else 'DIFFERS FROM'} the layout")
        return 0 if same else 1
    args.out.parent.mkdir(parents=True, exist_ok=True)
    if not cv2.imwrite(str(args.out), img, [cv2.IMWRITE_PNG_COMPRESSION, 9]):
        raise SystemExit(f"cannot write {args.out}")
    print(f"wrote {args.out}: {img.shape[1]}x{img.shape[0]} px, {args.out.stat().st_size} bytes")
    return 0


if __name__ == "__main__":
    sys.exit(main())

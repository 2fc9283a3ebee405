"""Reads the acuity chart (``bench/acuity_chart.py``) in a picture: how many rows of tumbling Es it resolves.

:func:`score` takes a picture (BGR or grey numpy array, or JPEG bytes) and

1. finds the chart by its four ArUco markers (:func:`locate`: corners refined to sub-pixel; a homography from the
   chart's millimetres to picture pixels from all four, an affine map from three), or takes a homography the
   caller knows (the simulator's, from the camera's pose: :func:`pose_homography`);
2. for each optotype samples the picture over the optotype and one stroke of paper around it on a grid in chart
   coordinates (at least 4 samples a stroke) and correlates it (normalised, zero mean) with the four ideal Es; the
   best is its reading. An optotype whose samples are flat (standard deviation < ``FLAT_GREY`` grey levels:
   nothing there to read) is *undecided*;
3. a row is read when at least 3 of its 5 are right (P = 10.4 % for a guesser); **rows read** counts the rows
   read from the top down to the first that is not (line-by-line termination, as a clinical chart is scored);
4. the **fraction correct** counts every optotype, an undecided one as a quarter (the expected score of a guess),
   and the **chance-corrected** fraction is (p − 1/4) / (3/4): 0 for a picture that shows nothing, 1 for a
   perfect reading. ``letter_rows`` = corrected fraction × rows (ETDRS letter-by-letter scoring, chance-free).

Acuity in angle: row ``k``'s stroke subtends ``stroke_mm(k) / distance``; with the distance given,
:class:`Score` gives the smallest row read as logMAR (log10 of the stroke in arc minutes) and in pixels.

    python bench/acuity.py picture.jpg [--distance 35]

Needs OpenCV's ArUco detector (``cv2.aruco.ArucoDetector``: OpenCV 4.7 or later, as the main environment's); the
simulator itself (``kind: image`` targets) needs no more than the declared minimum.
"""

from __future__ import annotations

import argparse
import math
import sys
from dataclasses import dataclass, field
from pathlib import Path

import cv2
import numpy as np
import numpy.typing as npt

sys.path.insert(0, str(Path(__file__).resolve().parent))
import acuity_chart as chart  # noqa: E402

FloatArray = npt.NDArray[np.float64]
FLAT_GREY = 2.0  #: grey levels: an optotype's samples flatter than this are undecided (a blank patch)
MIN_MARKERS = 3  #: markers needed to locate the chart
ROW_PASS = 3  #: of 5 right: the row is read
CHANCE = 0.25  #: four orientations


@dataclass(frozen=True)
class Row:
    index: int
    stroke_mm: float
    stroke_px: float  #: the stroke's length in the picture (mean of its two directions)
    answers: tuple[int, ...]  #: orientation read per optotype (-1 undecided)
    correct: int

    @property
    def read(self) -> bool:
        return self.correct >= ROW_PASS


@dataclass(frozen=True)
class Score:
    found: bool  #: the chart was located (or a homography given)
    rows: tuple[Row, ...] = ()
    homography: FloatArray | None = field(default=None, repr=False)
    markers: int = 0  #: markers found

    @property
    def rows_read(self) -> int:
        """Rows read from the top, down to the first one not read."""
        n = 0
        for r in self.rows:
            if not r.read:
                break
            n += 1
        return n

    @property
    def smallest_row(self) -> Row | None:
        return self.rows[self.rows_read - 1] if self.rows_read else None

    @property
    def fraction_correct(self) -> float:
        """Right answers over all optotypes, an undecided one counted as a guess (1/4)."""
        total = chart.N_ROWS * chart.PER_ROW
        if not self.rows:
            return CHANCE
        right = sum(r.correct for r in self.rows)
        undecided = sum(a < 0 for r in self.rows for a in r.answers)
        return (right + CHANCE * undecided) / total

    @property
    def corrected_fraction(self) -> float:
        """(p − 1/4) / (1 − 1/4): 0 at chance, 1 for a perfect reading."""
        return (self.fraction_correct - CHANCE) / (1.0 - CHANCE)

    @property
    def letter_rows(self) -> float:
        """Chance-corrected optotypes right, in rows (5 optotypes a row)."""
        return self.corrected_fraction * chart.N_ROWS

    def logmar(self, distance_m: float) -> float | None:
        """logMAR of the smallest row read at ``distance_m`` (log10 of its stroke in arc minutes)."""
        r = self.smallest_row
        if r is None:
            return None
        return math.log10(math.degrees(math.atan2(r.stroke_mm / 1000.0, distance_m)) * 60.0)

    def summary(self, distance_m: float | None = None) -> str:
        if not self.found:
            return "chart not found (0 rows read, corrected fraction 0)"
        r = self.smallest_row
        text = f"{self.rows_read}/{chart.N_ROWS} rows read"
        if r is not None:
            text += f" (smallest: row {r.index}, stroke {r.stroke_mm:.2f} mm = {r.stroke_px:.2f} px"
            if distance_m is not None:
                text += f", logMAR {self.logmar(distance_m):+.2f} at {distance_m:.1f} m"
            text += ")"
        text += f"; fraction correct {self.fraction_correct:.3f}, chance-corrected {self.corrected_fraction:.3f}"
        text += f" ({self.letter_rows:.1f} rows by letters)"
        return text


def to_grey(picture: npt.NDArray[np.uint8] | bytes) -> npt.NDArray[np.uint8]:
    """A grey picture from a BGR/grey array or JPEG/PNG bytes."""
    if isinstance(picture, bytes | bytearray | memoryview):
        img = cv2.imdecode(np.frombuffer(bytes(picture), np.uint8), cv2.IMREAD_GRAYSCALE)
        if img is None:
            raise ValueError("cannot decode the picture")
        return np.asarray(img, dtype=np.uint8)
    a = np.asarray(picture)
    if a.ndim == 3:
        return np.asarray(cv2.cvtColor(a, cv2.COLOR_BGR2GRAY), dtype=np.uint8)
    return np.asarray(a, dtype=np.uint8)


def locate(grey: npt.NDArray[np.uint8]) -> tuple[FloatArray | None, int]:
    """(homography chart mm → picture px, markers found), or (None, n) with fewer than MIN_MARKERS markers."""
    params = cv2.aruco.DetectorParameters()
    params.cornerRefinementMethod = cv2.aruco.CORNER_REFINE_SUBPIX
    detector = cv2.aruco.ArucoDetector(cv2.aruco.getPredefinedDictionary(chart.ARUCO_DICT), params)
    corners, ids, _ = detector.detectMarkers(grey)
    if ids is None:
        return None, 0
    known = chart.marker_corners_mm()
    src, dst, seen = [], [], set()
    for c, i in zip(corners, ids.ravel(), strict=True):
        i = int(i)
        if i in known and i not in seen:
            seen.add(i)
            src.append(known[i])
            dst.append(np.asarray(c, dtype=np.float64).reshape(4, 2))
    if len(seen) < MIN_MARKERS:
        return None, len(seen)
    a, b = np.concatenate(src), np.concatenate(dst)
    if len(seen) == 4:
        H, _ = cv2.findHomography(a, b, 0)
        return (None if H is None else np.asarray(H, dtype=np.float64)), len(seen)
    # Three markers: an affine map (a homography from three corners' points extrapolates badly to the fourth).
    A = np.concatenate([a, np.ones((len(a), 1))], axis=1)
    sol, *_ = np.linalg.lstsq(A, b, rcond=None)
    return np.vstack([sol.T, [0.0, 0.0, 1.0]]), len(seen)


def _apply(H: FloatArray, pts: FloatArray) -> FloatArray:
    p = np.concatenate([pts, np.ones((len(pts), 1))], axis=1) @ H.T
    return np.asarray(p[:, :2] / p[:, 2:3], dtype=np.float64)


HIGH_PASS_STROKES = 0.35  #: σ of the Gaussian the high-pass subtracts (twice), in strokes (:func:`_high_pass`)


def _high_pass(patch: FloatArray, n: int) -> FloatArray:
    """``patch`` high-passed twice: x − G∗x with G a Gaussian of σ = HIGH_PASS_STROKES strokes (``n`` samples a
    stroke), applied two times (a response ∝ f⁴ at low frequencies).

    Keeps 20 % of the E's bars (period 2 strokes) and 0.23 % of the blob an E becomes below the resolution limit
    (its ink centroid sits 0.24 strokes towards the spine, a cue at periods of 7 strokes and more): a reading then
    needs the strokes resolved, not a sub-pixel shift of a blurred blob, which a correlator with exact registration
    would otherwise detect (it read 1.25 mm strokes at 0.5 px with one plain high-pass)."""
    sigma = HIGH_PASS_STROKES * n
    out = np.asarray(patch, dtype=np.float64)
    for _ in range(2):
        out = out - cv2.GaussianBlur(out, (0, 0), sigma, borderType=cv2.BORDER_REPLICATE)
    return out


_TEMPLATES: dict[int, list[FloatArray]] = {}


def _templates(n: int) -> list[FloatArray]:
    """The four Es on a (5 + 2)·n grid (one stroke of paper around), ink 1, high-passed, zero mean, unit norm."""
    if n not in _TEMPLATES:
        out = []
        for k in range(4):
            g = np.pad(chart.grid(k).astype(np.float64), 1)
            t = _high_pass(np.kron(g, np.ones((n, n))), n)
            t -= t.mean()
            out.append(t / np.linalg.norm(t))
        _TEMPLATES[n] = out
    return _TEMPLATES[n]


def read_optotype(grey: npt.NDArray[np.float32], H: FloatArray, o: chart.Optotype) -> tuple[int, float]:
    """(orientation read, -1 if undecided; the stroke's length in picture pixels)."""
    s = o.stroke_mm
    x0, y0 = o.x_mm - s, o.y_mm - s  # one stroke of paper around the E
    probe = _apply(H, np.array([[x0, y0], [x0 + 7 * s, y0], [x0, y0 + 7 * s]]))
    stroke_px = 0.5 * (np.linalg.norm(probe[1] - probe[0]) + np.linalg.norm(probe[2] - probe[0])) / 7.0
    n = int(min(24, max(4, math.ceil(stroke_px))))  # samples a stroke: at least every picture pixel
    u = x0 + (np.arange(7 * n) + 0.5) * (s / n)
    v = y0 + (np.arange(7 * n) + 0.5) * (s / n)
    uu, vv = np.meshgrid(u, v)
    xy = _apply(H, np.stack([uu.ravel(), vv.ravel()], axis=1)).astype(np.float32)
    h, w = grey.shape
    if xy[:, 0].min() < 0 or xy[:, 1].min() < 0 or xy[:, 0].max() > w - 1 or xy[:, 1].max() > h - 1:
        return -1, float(stroke_px)  # (partly) outside the picture: nothing to read
    mx, my = xy[:, 0].reshape(uu.shape), xy[:, 1].reshape(uu.shape)
    patch = cv2.remap(grey, mx, my, cv2.INTER_LINEAR).astype(np.float64)
    if float(patch.std()) < FLAT_GREY:
        return -1, float(stroke_px)
    ink = -_high_pass(patch, n)  # ink is dark
    scores = [float((ink * t).sum()) for t in _templates(n)]
    return int(np.argmax(scores)), float(stroke_px)


def score(picture: npt.NDArray[np.uint8] | bytes, homography: FloatArray | None = None) -> Score:
    """Read the chart in ``picture`` (located by its markers unless ``homography``, chart mm → px, is given)."""
    grey = to_grey(picture)
    markers = 0
    if homography is None:
        homography, markers = locate(grey)
        if homography is None:
            return Score(False, markers=markers)
    g = grey.astype(np.float32)
    rows = []
    for row in chart.layout():
        answers, strokes = [], []
        for o in row:
            a, sp = read_optotype(g, homography, o)
            answers.append(a)
            strokes.append(sp)
        correct = sum(a == o.orientation for a, o in zip(answers, row, strict=True))
        rows.append(Row(row[0].row, row[0].stroke_mm, float(np.mean(strokes)), tuple(answers), correct))
    return Score(True, tuple(rows), homography, markers)


# ---------------------------------------------------------------------------------------------------------------
# The simulated camera (used by bench/bench_acuity.py and tests/unit/test_acuity.py)
# ---------------------------------------------------------------------------------------------------------------
def aim(world: object, point: npt.ArrayLike) -> tuple[float, float]:
    """VAPIX (pan, tilt) degrees that put ``point`` (base_link) on the simulated head's optical axis."""
    from axis_ptz_ros2.sim.ptz import ros_to_vapix

    T = world.T_base_ptz  # type: ignore[attr-defined]
    pan, tilt = world.kinematics.look_at(T.inverse().apply(np.asarray(point, dtype=np.float64)))  # type: ignore[attr-defined]
    return ros_to_vapix(pan, tilt)


def pose_homography(
    renderer: object, target: object, pan: float, tilt: float, zoom: float, w: int, h: int
) -> FloatArray:
    """Chart mm → picture px of the simulated view (pan, tilt, zoom, w×h), from the camera's true pose."""
    T = renderer.camera_pose(pan, tilt)  # type: ignore[attr-defined]
    K = renderer.intrinsics(zoom, w, h)  # type: ignore[attr-defined]
    mm = np.array([[0, 0], [chart.WIDTH_MM, 0], [chart.WIDTH_MM, chart.HEIGHT_MM], [0, chart.HEIGHT_MM]], np.float64)
    pts = target.uv_to_point(mm[:, 0] / chart.WIDTH_MM, mm[:, 1] / chart.HEIGHT_MM)  # type: ignore[attr-defined]
    px = K.project(T.inverse().apply(pts))
    H = cv2.getPerspectiveTransform(mm.astype(np.float32), np.asarray(px, dtype=np.float32))
    return np.asarray(H, dtype=np.float64)


def fit_zoom(renderer: object, target: object, pan: float, tilt: float, w: int, h: int, margin: float = 1.1) -> float:
    """The largest zoom (zoom units, at most the tele limit) whose w×h view holds the whole chart ``margin``× over."""
    zm = renderer.world.zoom_model  # type: ignore[attr-defined]
    lo, hi = float(zm.min_zoom), float(zm.max_zoom)
    for _ in range(40):
        mid = 0.5 * (lo + hi)
        H = pose_homography(renderer, target, pan, tilt, mid, w, h)
        c = _apply(H, np.array([[0, 0], [chart.WIDTH_MM, 0], [chart.WIDTH_MM, chart.HEIGHT_MM], [0, chart.HEIGHT_MM]]))
        cx, cy = w / 2, h / 2
        fits = np.all(np.abs(c[:, 0] - cx) * margin <= cx) and np.all(np.abs(c[:, 1] - cy) * margin <= cy)
        lo, hi = (mid, hi) if fits else (lo, mid)
    return lo


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description="read the acuity chart in a picture")
    ap.add_argument("picture", type=Path)
    ap.add_argument("--distance", type=float, default=None, help="chart distance (m), for logMAR")
    args = ap.parse_args(argv)
    result = score(args.picture.read_bytes())
    print(result.summary(args.distance))
    for r in result.rows:
        print(f"  row {r.index:2d} stroke {r.stroke_mm:5.2f} mm {r.stroke_px:5.2f} px: {r.correct}/5 {r.answers}")
    return 0 if result.found else 1


if __name__ == "__main__":
    sys.exit(main())

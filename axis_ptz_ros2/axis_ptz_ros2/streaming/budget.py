"""The bandwidth budget: a pure controller that keeps the measured bitrate under a budget by stepping
compression, then fps, then resolution down, and back up with hysteresis. ROS-free.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, replace

from axis_ptz_ros2.vapix.models import COMPRESSION_RANGE, Resolution, VideoParams

# Relative JPEG size against compression, from the thesis's Table 6.2 (704x576 @ 30 fps: 3440, 2340 and
# 950 kbit/s at compression 0, 30 and 100). Only a prior: observed sizes replace it as soon as known.
_COMPRESSION_PRIOR: tuple[tuple[int, float], ...] = ((0, 1.0), (30, 0.68), (100, 0.276))


#: Resolutions of the PAL Axis 214 PTZ (``vapix.md`` §5.5), used until the camera reports its own list.
AXIS214_PAL_RESOLUTIONS: tuple[Resolution, ...] = (
    Resolution(704, 576),
    Resolution(704, 288),
    Resolution(352, 288),
    Resolution(176, 144),
)


def compression_size_factor(compression: int) -> float:
    """Prior relative frame size at ``compression`` (1.0 at 0), piecewise linear through Table 6.2."""
    c = min(max(compression, COMPRESSION_RANGE[0]), COMPRESSION_RANGE[1])
    for (c0, f0), (c1, f1) in zip(_COMPRESSION_PRIOR, _COMPRESSION_PRIOR[1:], strict=False):
        if c <= c1:
            return f0 + (f1 - f0) * (c - c0) / (c1 - c0)
    return _COMPRESSION_PRIOR[-1][1]


def same_aspect(a: Resolution, b: Resolution, tolerance: float = 0.02) -> bool:
    """True if ``a`` and ``b`` have the same width:height within ``tolerance`` (relative): 1280x720 and 640x360
    do, 1280x720 and 640x480 do not, nor 704x576 and 704x288 (the 214's half-height 2CIF)."""
    return abs(a.width * b.height - b.width * a.height) <= tolerance * b.width * a.height


@dataclass(frozen=True, slots=True)
class BudgetConfig:
    """How the :class:`BandwidthController` steps (times in seconds, fractions of the budget)."""

    compression_step: int = 10
    max_compression: int = 60  # thesis §6: "values greater than 60 should not be used"
    fps_steps: tuple[int, ...] = (25, 20, 15, 10, 5, 2, 1)
    min_fps: int = 1  # lower fps only down to this before lowering the resolution (then below it)
    down_fraction: float = 0.9  # after stepping down, aim at a predicted rate below this
    up_fraction: float = 0.8  # step up only if the prediction stays below this ...
    up_hold_s: float = 3.0  # ... for this long
    settle_s: float = 0.8  # measure at least this long after a change before judging
    min_frames: int = 3
    scene_change: float = 0.3  # a frame-size jump of this fraction at fixed settings forgets what was learned
    memory_s: float = 30.0  # observations of other settings older than this are forgotten


class BandwidthController:
    """Keep the measured bitrate under ``budget_kbps`` by degrading the requested parameters in steps.

    The ladder starts at the requested parameters (level 0) and degrades one knob at a time:
    compression in steps of ``compression_step`` up to ``max_compression``, then fps through
    ``fps_steps`` down to ``min_fps``, then resolution through the smaller supported sizes, then fps below
    ``min_fps``. Over budget, it jumps straight
    to the first level predicted under ``down_fraction`` of the budget; with room, it climbs one level
    once the prediction for it has stayed under ``up_fraction`` for ``up_hold_s``. Predictions scale
    the observed bytes per frame (per resolution and compression, learned as it goes) by pixel count
    and the compression prior (raised to an exponent fitted to the camera's own sizes), times the fps the
    camera actually delivers. Climbing goes as far as the prediction leaves room.
    """

    def __init__(
        self,
        requested: VideoParams,
        budget_kbps: float = 0.0,
        resolutions: Sequence[Resolution] = AXIS214_PAL_RESOLUTIONS,
        config: BudgetConfig | None = None,
    ) -> None:
        """Start at level 0 (the request) with no observations."""
        self._config = config or BudgetConfig()
        self._requested = requested
        self._budget = float(budget_kbps)
        self._resolutions = tuple(resolutions)
        self._observed: dict[tuple[Resolution, int], float] = {}
        self._observed_at: dict[tuple[Resolution, int], float] = {}
        self._alpha = 1.0  # exponent on the compression prior, fitted to what this camera does
        self._ladder = self._build_ladder()
        self._level = 0
        self._changed_at: float | None = None
        self._up_since: float | None = None
        self._fps_cap: dict[Resolution, float] = {}

    # -- configuration -------------------------------------------------------------------------------------
    @property
    def budget_kbps(self) -> float:
        """0 = off."""
        return self._budget

    @property
    def level(self) -> int:
        """0 = the request; higher = more degraded."""
        return self._level

    @property
    def ladder(self) -> tuple[VideoParams, ...]:
        """Every parameter set the controller may choose, best first."""
        return self._ladder

    @property
    def changed_at(self) -> float | None:
        """When the level last changed (the ``now`` of that call), None before the first judgement."""
        return self._changed_at

    @property
    def current(self) -> VideoParams:
        """The parameters to stream with now."""
        return self._ladder[self._level]

    def configure(
        self,
        requested: VideoParams | None = None,
        budget_kbps: float | None = None,
        resolutions: Sequence[Resolution] | None = None,
        now: float | None = None,
    ) -> VideoParams:
        """Change the request, budget or resolution list; restarts from level 0 (re-judged by ``update``)."""
        if requested is not None:
            self._requested = requested
        if budget_kbps is not None:
            self._budget = float(budget_kbps)
        if resolutions is not None:
            self._resolutions = tuple(resolutions)
        self._ladder = self._build_ladder()
        self._level = 0
        self._changed_at = now
        self._up_since = None
        return self.current

    def set_budget(self, budget_kbps: float, now: float) -> None:
        """Change the budget but keep the level (the next :meth:`update` re-judges it): for a budget that
        follows the link, where restarting from the request at every change would flood the link."""
        budget = float(budget_kbps)
        if budget == self._budget:
            return
        if budget < self._budget or self._budget <= 0:
            self._up_since = None  # less room: the hold for climbing starts again (more room keeps it)
        self._budget = budget
        if self._changed_at is None:
            self._changed_at = now

    def fit_from(self, ref: VideoParams, ref_bytes_per_frame: float, now: float) -> VideoParams:
        """Start at the first level predicted under ``down_fraction`` of the budget from what another stream of
        the same camera measured (``ref`` at ``ref_bytes_per_frame``), before a byte of this one is sent: a stream
        that shares a link must not open at its request and swamp it for the first judgement. Without a budget or
        a measurement, level 0; with a budget but no measurement, the bottom of the ladder (it climbs on its own
        measurements)."""
        if self._budget <= 0:
            return self._go(0, now)
        if ref_bytes_per_frame <= 0:
            return self._go(len(self._ladder) - 1, now)
        target = self._config.down_fraction * self._budget
        level = 0
        while level < len(self._ladder) - 1:
            p = self._ladder[level]
            kbps = self._bytes_per_frame(p, ref, ref_bytes_per_frame) * p.fps * 8.0 / 1000.0
            if kbps <= target:
                break
            level += 1
        return self._go(level, now)

    def _build_ladder(self) -> tuple[VideoParams, ...]:
        cfg = self._config
        p = self._requested
        ladder = [p]
        comp = p.compression
        while comp < cfg.max_compression:
            comp = min(comp + cfg.compression_step, cfg.max_compression)
            ladder.append(replace(p, compression=comp))
        last = ladder[-1]
        for fps in cfg.fps_steps:
            if cfg.min_fps <= fps < last.fps:
                last = replace(last, fps=fps)
                ladder.append(last)
        pixels = p.resolution.width * p.resolution.height
        smaller = sorted(
            (r for r in self._resolutions if r.width * r.height < pixels),
            key=lambda r: r.width * r.height,
            reverse=True,
        )
        # keep the requested shape: a 16:9 request never steps to 4:3 (a camera crops or squeezes for those, and
        # the operator's layout and camera_info change with it); sizes of another shape only if none is left
        same_shape = [r for r in smaller if same_aspect(r, p.resolution)]
        smaller = same_shape or smaller
        for res in smaller:
            last = replace(last, resolution=res)
            ladder.append(last)
        for fps in cfg.fps_steps:
            if fps < min(cfg.min_fps, last.fps):
                last = replace(last, fps=fps)
                ladder.append(last)
        return tuple(ladder)

    # -- prediction ----------------------------------------------------------------------------------------
    def _q(self, compression: int) -> float:
        """Relative frame size at ``compression``: the prior raised to the fitted exponent."""
        return float(compression_size_factor(compression) ** self._alpha)

    def _bytes_per_frame(self, p: VideoParams, ref: VideoParams, ref_bpf: float) -> float:
        known = self._observed.get((p.resolution, p.compression))
        if known is not None:
            return known
        # nearest observation at the same resolution, else the reference
        same_res = [(c, b) for (r, c), b in self._observed.items() if r == p.resolution]
        if same_res:
            c, b = min(same_res, key=lambda cb: abs(cb[0] - p.compression))
            return b * self._q(p.compression) / self._q(c)
        pixel_ratio = (p.resolution.width * p.resolution.height) / (ref.resolution.width * ref.resolution.height)
        return ref_bpf * pixel_ratio * self._q(p.compression) / self._q(ref.compression)

    def _fitted(self, resolution: Resolution) -> bool:
        """Whether two compressions at least one step apart were observed at ``resolution``."""
        comps = [c for (r, c) in self._observed if r == resolution]
        return len(comps) >= 2 and max(comps) - min(comps) >= self._config.compression_step

    def _fit_alpha(self) -> None:
        """Fit the compression exponent to the two most distant observations at one resolution."""
        best: tuple[int, float] | None = None
        by_res: dict[Resolution, list[tuple[int, float]]] = {}
        for (r, c), b in self._observed.items():
            by_res.setdefault(r, []).append((c, b))
        for points in by_res.values():
            if len(points) < 2:
                continue
            (c1, b1), (c2, b2) = min(points), max(points)
            p1, p2 = compression_size_factor(c1), compression_size_factor(c2)
            if c2 - c1 < 10 or b1 <= 0 or b2 <= 0 or p1 <= p2 * 1.01:
                continue
            alpha = math.log(b2 / b1) / math.log(p2 / p1)
            if best is None or c2 - c1 > best[0]:
                best = (c2 - c1, min(max(alpha, 0.2), 8.0))
        if best is not None:
            self._alpha = best[1]

    def predict_kbps(self, level: int, ref_bpf: float) -> float:
        """Predicted kbit/s at ``level``, from the current level's measured bytes per frame."""
        p = self._ladder[level]
        ref = self.current
        fps = float(p.fps)
        cap = self._fps_cap.get(p.resolution)
        if cap is not None:
            fps = min(fps, cap)
        return self._bytes_per_frame(p, ref, ref_bpf) * fps * 8.0 / 1000.0

    # -- control -------------------------------------------------------------------------------------------
    def update(
        self, now: float, kbps: float, fps: float, bytes_per_frame: float, frames: int, reserve_kbps: float = 0.0
    ) -> VideoParams | None:
        """Feed one measurement of the current level; return new parameters when the level changes.

        ``reserve_kbps``: of the budget, what other traffic on the link takes for now (a still on demand): the live
        stream is judged against what is left, so one judgement jumps to the level predicted under it (no cascade
        of steps while the other traffic lasts), and the climb back follows once the reserve is gone."""
        cfg = self._config
        if self._budget <= 0:
            if self._level != 0:
                self._level = 0
                self._changed_at = now
                return self.current
            return None
        if self._changed_at is None:
            self._changed_at = now
        if now - self._changed_at < cfg.settle_s or frames < cfg.min_frames or bytes_per_frame <= 0:
            return None
        cur = self._learn(now, bytes_per_frame)
        if fps < 0.85 * cur.fps:  # the camera delivers less than asked at this size: remember its ceiling
            self._fps_cap[cur.resolution] = fps
        elif self._fps_cap.get(cur.resolution, 0.0) < fps:
            self._fps_cap.pop(cur.resolution, None)
        budget = self._budget - max(0.0, min(reserve_kbps, self._budget))
        if kbps > budget:
            self._up_since = None
            target = cfg.down_fraction * budget
            level = self._level + 1
            if level >= len(self._ladder):
                return None  # already at the bottom
            nxt = self._ladder[level]
            probe = not self._fitted(cur.resolution) and (nxt.resolution, nxt.fps) == (cur.resolution, cur.fps)
            # With nothing learned about this camera's compression yet, take one compression step and
            # measure (cheap, and it calibrates the prior); otherwise jump to the first level predicted
            # under the target.
            while not probe and level < len(self._ladder) - 1 and self.predict_kbps(level, bytes_per_frame) > target:
                level += 1
            return self._go(level, now)
        if self._level == 0:
            self._up_since = None
            return None
        room = cfg.up_fraction * budget
        if self.predict_kbps(self._level - 1, bytes_per_frame) < room:
            if self._up_since is None:
                self._up_since = now
            if now - self._up_since >= cfg.up_hold_s:
                level = self._level - 1  # climb as far as the prediction leaves room
                while level > 0 and self.predict_kbps(level - 1, bytes_per_frame) < room:
                    level -= 1
                return self._go(level, now)
        else:
            self._up_since = None
        return None

    def _learn(self, now: float, bytes_per_frame: float) -> VideoParams:
        """Record the current level's frame size; forget others when the scene changed or they aged."""
        cfg = self._config
        cur = self.current
        key = (cur.resolution, cur.compression)
        previous = self._observed.get(key)
        if previous is not None and abs(bytes_per_frame - previous) > cfg.scene_change * previous:
            self._observed.clear()
            self._observed_at.clear()
            self._alpha = 1.0
        for k, t in list(self._observed_at.items()):
            if now - t > cfg.memory_s:
                del self._observed[k], self._observed_at[k]
        self._observed[key] = bytes_per_frame
        self._observed_at[key] = now
        self._fit_alpha()
        return cur

    def _go(self, level: int, now: float) -> VideoParams:
        self._level = level
        self._changed_at = now
        self._up_since = None
        return self.current

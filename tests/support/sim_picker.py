"""The simulated scene's calibration boards as an automatic picker for ``axis_calibrate capture`` (test and
bench tooling: the product's calibration tool does not import the simulator).

A :class:`~axis_ptz_ros2.calibration.capture.PickerFactory`: ``axis_calibrate capture --picker
tests/support/sim_picker.py:SimBoardPicker [--picker-arg world_file=config/sim_world.yaml]`` (or
``tests.support.sim_picker:SimBoardPicker`` with the repository root on ``sys.path``, as in the tests), or passed
in directly to :func:`~axis_ptz_ros2.calibration.capture.capture_views` (``bench/bench_calibration_e2e.py``).
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import numpy as np

from axis_ptz_ros2.calibration.capture import CapturedView
from axis_ptz_ros2.calibration.picking import Feature, PickedPoint, PickMode, pick_view
from axis_ptz_ros2.config import CameraModel
from axis_ptz_ros2.sim.scene import Scene
from axis_ptz_ros2.sim.world import load_world
from axis_ptz_ros2.transforms import Transform


def scene_dot_features(scene: Scene, *, kinds: Sequence[str] = ("calib",)) -> list[Feature]:
    """The coloured dots of the simulated scene's boards as :class:`Feature` s (labels ``board/dot_colour``);
    their true positions, for choosing the click and for measuring the picking noise only."""
    out: list[Feature] = []
    for t in scene.targets:
        if t.spec.kind not in kinds:
            continue
        for name, p in t.features().items():
            if name.startswith("dot_"):
                x, y, z = np.asarray(p, dtype=np.float64).reshape(3)
                out.append(Feature(f"{t.name}/{name}", name[4:], (float(x), float(y), float(z)), 0.08 * t.width))
    return out


class SimBoardPicker:
    """Automatic picking for the simulated scene's calibration boards (:mod:`axis_ptz_ros2.calibration.picking`).

    The scene's true dot positions are used only to choose the laser point an operator would click (and to
    report the 3-D picking noise); which board a dot belongs to is decided with ``T_base_ptz_guess`` (the
    nominal mount), and nothing here ever sees the simulator's true mount.
    """

    def __init__(
        self,
        camera_model: CameraModel,
        T_base_ptz_guess: Transform,
        *,
        mode: PickMode = "blob",
        world_file: str | Path | None = None,
        max_angle_deg: float | str = 3.0,
    ) -> None:
        """Picker for the world in ``world_file`` (default: the simulator's built-in world)."""
        self.features = scene_dot_features(Scene(load_world(world_file or None)))
        self.camera_model = camera_model
        self.T_base_ptz_guess = T_base_ptz_guess
        self.mode: PickMode = mode
        self.max_angle_deg = float(max_angle_deg)

    def __call__(self, cap: CapturedView) -> list[PickedPoint]:
        """Pick the pairs of one captured view."""
        return pick_view(
            cap.image(),
            cap.cloud,
            cap.pan,
            cap.tilt,
            cap.zoom,
            self.features,
            self.camera_model,
            self.T_base_ptz_guess,
            mode=self.mode,
            max_angle_deg=self.max_angle_deg,
        )

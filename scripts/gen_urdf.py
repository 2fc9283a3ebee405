#!/usr/bin/env python3
"""Write urdf/axis_214.urdf from config/axis214.yaml (camera model) and config/mount.yaml (mount).

Usage: .venv/bin/python scripts/gen_urdf.py [--check] [--camera-model FILE] [--mount FILE] [--out FILE]
``--check`` exits 1 when the committed URDF differs from what the configuration gives (tests/unit/test_urdf.py).
After `axis_calibrate solve ... --out config/mount.yaml`, run it again (or use urdf/axis_214.urdf.xacro, which
reads the YAML files itself).
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent


def main(argv: list[str] | None = None) -> int:
    from axis_ptz_ros2.config import load_camera_model, load_mount
    from axis_ptz_ros2.urdf import urdf_from_config

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--camera-model", default=str(ROOT / "config" / "axis214.yaml"))
    ap.add_argument("--mount", default=str(ROOT / "config" / "mount.yaml"))
    ap.add_argument("--out", default=str(ROOT / "urdf" / "axis_214.urdf"))
    ap.add_argument("--check", action="store_true", help="exit 1 if --out is not up to date")
    a = ap.parse_args(argv)
    text = urdf_from_config(load_camera_model(a.camera_model), load_mount(a.mount))
    out = Path(a.out)
    if a.check:
        if not out.exists() or out.read_text(encoding="utf-8") != text:
            print(f"{out} is out of date: run scripts/gen_urdf.py")
            return 1
        return 0
    out.write_text(text, encoding="utf-8")
    print(f"wrote {out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())

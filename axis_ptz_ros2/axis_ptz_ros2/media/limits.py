"""The x264 encoder's settings bounds (ROS-free, and free of PyAV so that settings can be checked, and the stream
node can start, on a machine without PyAV; :mod:`.encoder` enforces them)."""

from __future__ import annotations

from typing import Final

PRESETS: Final = ("ultrafast", "superfast", "veryfast", "faster", "fast", "medium")
#: H.264 profiles the encoder makes: ``baseline`` (x264's Constrained Baseline: CAVLC, 4x4 transform) and ``high``
#: (CABAC, 8x8 transform; still no B-frames, so no reordering)
PROFILES: Final = ("baseline", "high")
#: how a decoder gets a clean picture again without asking: ``idr``: an IDR every keyframe interval; ``intra``:
#: x264's periodic intra refresh (a column of intra blocks sweeps the picture once per keyframe interval, no IDR
#: after the first: IDRs only on request)
REFRESH_MODES: Final = ("idr", "intra")
MIN_BITRATE_BPS: Final = 50_000
MAX_BITRATE_BPS: Final = 50_000_000
MAX_KEYFRAME_INTERVAL: Final = 600
MAX_DIMENSION: Final = 4096
#: s: the VBV buffer in seconds of the bitrate. bitrate/10 (the issue's prototype) starved every IDR and the
#: frames after it (PSNR 5th percentile 33.4 dB at 1000 kbit/s, 837 kbit/s used, against the simulated camera's
#: still view before noise); 0.15 s: 34.8 dB, 871 kbit/s, largest IDR 15 kB. A live step down spends what is
#: left of the old rate's buffer first (~8 frames from 2000 to 300 kbit/s).
VBV_BUFFER_S: Final = 0.15
#: a VBV buffer asked for live that differs from the open one by less than this fraction is not worth a re-open
VBV_REOPEN_SLACK: Final = 0.2
MIN_VBV_BITS: Final = 1000

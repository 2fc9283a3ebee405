"""Which video a consumer watches: its own ``codec`` choice, or the codec the stream node announces (ROS-free).

The operator-side tools (``axis_link_monitor``, ``axis_web_console``, ``axis_republish``) each subscribe to either
the JPEG topic (``image_raw/compressed``) or the H.264 topic (``image_raw/ffmpeg``). Chosen on their own, they can
disagree with the stream: a monitor left at MJPEG while the robot streams H.264 pulls the transcoder's
compression-0 JPEGs at full rate over the link and starves the H.264 viewer (issue 40: on 2 Mbit/s + 2 %, 331
access units in 20 s and not one IDR among them). With the choice ``auto`` (their default) they follow the codec
the stream node announces on ``video/params`` instead (``VideoParams.codec``, latched: a late joiner gets the
value in effect), and switch when it changes.

:class:`CodecFollower` is that decision and nothing else; the ROS side feeds it the announced codec
(:mod:`axis_ptz_ros2.nodes.codec_follow`) and subscribes to what :attr:`CodecFollower.codec` says.
"""

from __future__ import annotations

from typing import Final

from axis_ptz_ros2.media.limits import CODECS

#: follow the stream node's ``video/params``
AUTO: Final = "auto"
#: a consumer's ``codec`` parameter: ``auto`` or one of the stream's codecs
CHOICES: Final = (AUTO, *CODECS)
#: what a consumer in ``auto`` waits for, in its log line and its state
WAITING_TEXT: Final = "waiting for the stream node's video/params to tell its codec: no video subscribed until then"


def check_choice(choice: str) -> str | None:
    """The reason ``choice`` is no codec choice, or None."""
    if choice not in CHOICES:
        return f"codec={choice!r} is not one of {', '.join(CHOICES)}"
    return None


class CodecFollower:
    """The codec to watch: ``choice`` when it names one, else (``auto``) the one the stream last announced.

    :attr:`codec` is ``""`` while there is nothing to watch: in ``auto`` before the first announcement, or after
    one that names a codec this consumer cannot follow (see :attr:`problem`). Not thread-safe: one caller
    (the node's executor) feeds it.
    """

    def __init__(self, choice: str) -> None:
        """``choice``: ``auto``, ``mjpeg`` or ``h264`` (anything else: ValueError with the reason)."""
        reason = check_choice(choice)
        if reason:
            raise ValueError(reason)
        self.choice = choice
        self.announced = ""  # the codec the stream node announced last ('' = nothing heard)
        self.problem = ""  # why the announced codec is not followed ('' = it is, or nothing heard)
        self._codec = "" if choice == AUTO else choice

    @property
    def follows(self) -> bool:
        """True in ``auto``: the codec comes from the stream's announcements."""
        return self.choice == AUTO

    @property
    def codec(self) -> str:
        """``mjpeg`` or ``h264``: the video to subscribe to; ``""``: none (waiting, or :attr:`problem`)."""
        return self._codec

    def announce(self, codec: str) -> bool:
        """The stream node announced ``codec`` (``video/params``); True when :attr:`codec` changed with it (the
        caller then drops its old subscription and makes the new one). Ignored unless following."""
        self.announced = codec
        if not self.follows:
            return False
        if codec in CODECS:
            new, self.problem = codec, ""
        else:  # a stream node of another version, or a message filled by hand: watch nothing rather than guess
            new, self.problem = "", f"the stream announced codec {codec!r}, not one of {', '.join(CODECS)}"
        changed = new != self._codec
        self._codec = new
        return changed

    def describe(self) -> str:
        """One line for logs and the console's state: what is watched and why."""
        if not self.follows:
            return f"codec {self.choice} (set explicitly)"
        if self.problem:
            return f"watching nothing: {self.problem}"
        if not self._codec:
            return WAITING_TEXT
        return f"codec {self._codec} (following the stream node's video/params)"

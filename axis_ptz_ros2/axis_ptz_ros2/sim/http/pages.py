"""The HTML pages a real Axis camera answers errors with (vapix.md §11), as format strings (ROS-free)."""

from __future__ import annotations

NOT_FOUND_HTML = (
    "<HTML><HEAD><TITLE>404 Not Found</TITLE></HEAD>\n<BODY><H1>404 Not Found</H1>\n"
    "The requested URL {path} was not found on this server.\n</BODY></HTML>\n"
)
UNAUTHORIZED_HTML = (
    "<HTML><HEAD><TITLE>401 Unauthorized</TITLE></HEAD>\n<BODY><H1>401 Unauthorized</H1>\n"
    "Your client does not have permission to get URL {path} from this server.\n</BODY></HTML>\n"
)
ERROR_HTML = "<HTML><HEAD><TITLE>{code} {reason}</TITLE></HEAD>\n<BODY><H1>{code} {reason}</H1>\n</BODY></HTML>\n"

"""Real device replies quoted in the shared reference ``vapix.md`` (sources in brackets), plus helpers.

Only strings that were observed on devices or printed in Axis documentation are used as replies.
"""

from __future__ import annotations

from collections.abc import Callable

import httpx

# §4.4 [V-obs S5: Kane610 fixture, Sony camblock dome]
POSITION_RESPONSE = (
    "pan=51.2891\ntilt=46.1914\nzoom=1\niris=6427\nfocus=8265\nbrightness=4999\nautofocus=off\nautoiris=on\n"
)
# §4.4 [V-obs S6: Clearpath comment, modern camera]
POSITION_RESPONSE_CLEARPATH = (
    "pan=-0.01\r\ntilt=-45.03\r\nzoom=1\r\niris=5748\r\nfocus=4642\r\n"
    "brightness=4999\r\nautofocus=on\r\nautoiris=on\r\n"
)
# §4.4 official template [V S1]: no iris/focus/brightness.
POSITION_RESPONSE_MINIMAL = "pan=10\ntilt=-15\nzoom=3000\nautofocus=on\nautoiris=on\n"

# §4.4 [V S1 template; V-obs S5 values]
LIMITS_RESPONSE = (
    "MinPan=-170\nMaxPan=170\nMinTilt=-20\nMaxTilt=90\nMinZoom=1\nMaxZoom=9999\nMinIris=1\nMaxIris=9999\n"
    "MinFocus=770\nMaxFocus=9999\nMinFieldAngle=22\nMaxFieldAngle=623\nMinBrightness=1\nMaxBrightness=9999\n"
)

# §4.7 [V-obs S8: AXIS P5512, fw 5.51.7] as a param.cgi listing with root. prefix.
P5512_PTZ_LIMIT_PARAMS = (
    "root.PTZ.Limit.L1.MinPan=-180\nroot.PTZ.Limit.L1.MaxPan=180\nroot.PTZ.Limit.L1.MinTilt=-180\n"
    "root.PTZ.Limit.L1.MaxTilt=0\nroot.PTZ.Limit.L1.MinZoom=1\nroot.PTZ.Limit.L1.MaxZoom=19999\n"
    "root.PTZ.Limit.L1.MinFieldAngle=44\nroot.PTZ.Limit.L1.MaxFieldAngle=516\n"
    "root.PTZ.Limit.L1.MinFocus=1\nroot.PTZ.Limit.L1.MaxFocus=9999\n"
)

# §4.4 [V S1, V-obs S5]
SPEED_RESPONSE = "speed=100\n"
PRESETPOSCAM_RESPONSE = "Preset Positions for camera 1\npresetposno1=Home\n"
PRESETPOSCAM_RESPONSE_TWO = "Preset Positions for camera 1\npresetposno2=Door\npresetposno1=Home\n"

# §4.5 [V-obs S5]
INFO_RESPONSE = """Available commands
:
{camera=[n]}
whoami=yes
center=[x],[y]
   imagewidth=[n]
   imageheight=[n]
areazoom=[x],[y],[z]
   imagewidth=[n]
   imageheight=[n]
move={ home | up | down | left | right | upleft | upright | downleft | downright | stop }
pan=[abspos]
tilt=[abspos]
zoom=[n]
focus=[n]
iris=[n]
brightness=[offset]
rpan=[offset]
rtilt=[offset]
rzoom=[offset]
rfocus=[offset]
riris=[offset]
rbrightness=[offset]
autofocus={ on | off }
autoiris={ on | off }
ircutfilter={ on | off | auto }
backlight={ on | off }
continuouspantiltmove=[x-speed],[y-speed]
continuouszoommove=[speed]
continuousfocusmove=[speed]
auxiliary=[function]
setserverpresetname=[name]
setserverpresetno=[n]
removeserverpresetname=[name]
removeserverpresetno=[n]
gotoserverpresetname=[name]
gotoserverpresetno=[n]
speed=[n]
query={ speed | position | limits | presetposcam | presetposall }
"""

# §4.3 [V S1, S7]: next-line form (most likely wire form) and the scraped same-line form.
ERROR_UNKNOWN_QUERY_NEXT_LINE = "Error:\nquery: unknown value: foo\n"
ERROR_UNKNOWN_QUERY_SAME_LINE = "Error: query: unknown value: foo"
# §4.3 [V S10]: 2007-era firmware embeds the error in HTML.
ERROR_HTML = "<html><body>Error: Unknown command</body></html>"

# §3 [V-obs S8: authentication.rs], [V S5: Kane610 tests]
DIGEST_CHALLENGE = (
    'Digest realm="AXIS_ACCC8EF7DE6B", nonce="h20V+wGvBQA=b6c0ce8666d2d4b2688858d7a31386d9d337e072", '
    'algorithm=MD5, qop="auth"'
)
BASIC_CHALLENGE = 'Basic realm="AXIS"'

# §6 param.cgi listings: with root. (group=root.X) [V-obs S5/S8] and without [V S1].
PARAM_PROPERTIES_214 = (
    "root.Properties.API.HTTP.Version=2\n"
    "root.Properties.Firmware.Version=4.49\n"
    "root.Properties.PTZ.PTZ=yes\n"
    "root.Properties.Image.Resolution=4CIF,2CIFEXP,2CIF,CIF,QCIF\n"
    "root.Properties.Image.Format=jpeg,mjpeg,mpeg4\n"
)
PARAM_BRAND_214 = "root.Brand.ProdShortName=AXIS 214 PTZ\nroot.Brand.ProdFullName=AXIS 214 PTZ Network Camera\n"
PARAM_RESOLUTION_P5512_NO_ROOT = "Properties.Image.Resolution=4CIF,2CIF,CIF,QCIF\n"
PARAM_RESOLUTION_BULLET = "root.Properties.Image.Resolution=1920x1080,1280x960,1280x720,640x480,160x90\n"
PARAM_PTZ_SUPPORT = (
    "root.PTZ.Support.S1.AbsolutePan=true\nroot.PTZ.Support.S1.AbsoluteTilt=true\n"
    "root.PTZ.Support.S1.AbsoluteZoom=true\nroot.PTZ.Support.S1.DigitalZoom=false\n"
    "root.PTZ.Support.S1.AreaZoom=true\nroot.PTZ.Support.S1.ContinuousPan=true\n"
)
PARAM_ERROR = "# Error: Error -1 getting param in group 'Foo.Bar'\n"
# §2.2 [V-obs S8]
NOT_FOUND_HTML = (
    "<HTML><HEAD><TITLE>404 Not Found</TITLE></HEAD>\n<BODY><H1>404 Not Found</H1>\n"
    "The requested URL /axis-cgi/param.cgi was not found on this server.\n</BODY></HTML>\n"
)
# §5.3 [V S2]
IMAGESIZE_4CIF_NTSC = "image width = 704\nimage height = 480\n"
IMAGESIZE_4CIF_PAL = "image width = 704\nimage height = 576\n"

MULTIPART = "multipart/x-mixed-replace;boundary=myboundary"  # §5.1 thesis wire dump [V S9]


def jpeg(payload: bytes = b"frame") -> bytes:
    """A byte string with JPEG SOI/EOI markers (the parser checks markers, not pixels)."""
    return b"\xff\xd8" + payload + b"\xff\xd9"


def part(body: bytes, *, boundary: bytes = b"myboundary", length: int | None = -1) -> bytes:
    """One multipart part as an Axis camera writes it (§5.1); ``length=None`` omits Content-Length."""
    headers = b"Content-Type: image/jpeg\r\n"
    if length is not None:
        headers += b"Content-Length: %d\r\n" % (len(body) if length == -1 else length)
    return b"--" + boundary + b"\r\n" + headers + b"\r\n" + body + b"\r\n"


class Recorder:
    """An ``httpx.MockTransport`` handler that records requests and replies from a route table."""

    def __init__(self, routes: dict[str, Callable[[httpx.Request], httpx.Response]] | None = None) -> None:
        """``routes`` maps a path (or path+query) to a reply function."""
        self.routes = routes or {}
        self.requests: list[httpx.Request] = []

    def __call__(self, request: httpx.Request) -> httpx.Response:
        """Record; dispatch on exact path+query first, then path; 404 otherwise."""
        self.requests.append(request)
        full = request.url.raw_path.decode()
        handler = self.routes.get(full) or self.routes.get(request.url.path)
        if handler is None:
            return httpx.Response(404, text=NOT_FOUND_HTML, headers={"Content-Type": "text/html; charset=ISO-8859-1"})
        return handler(request)

    @property
    def paths(self) -> list[str]:
        """Path+query of every request, in order."""
        return [r.url.raw_path.decode() for r in self.requests]

    def transport(self) -> httpx.MockTransport:
        """The transport to inject into ``VapixClient``."""
        return httpx.MockTransport(self)


def text(body: str, status: int = 200) -> Callable[[httpx.Request], httpx.Response]:
    """Reply ``text/plain`` with ``body``."""
    return lambda _req: httpx.Response(status, text=body, headers={"Content-Type": "text/plain"})


def no_content() -> Callable[[httpx.Request], httpx.Response]:
    """Reply 204 No Content (a successful PTZ command, §4.2)."""
    return lambda _req: httpx.Response(204)


def parse_auth_params(header: str) -> dict[str, str]:
    """``Digest a="b", c=d`` → ``{"a": "b", "c": "d"}`` (test-side, simple values only)."""
    _, _, rest = header.partition(" ")
    params: dict[str, str] = {}
    for item in rest.split(", "):
        key, _, value = item.partition("=")
        params[key.strip()] = value.strip().strip('"')
    return params


def digest_is_valid(request: httpx.Request, username: str, password: str, realm: str, nonce: str) -> bool:
    """Server-side RFC 2617 check (MD5, qop=auth) of the request's Authorization header."""
    import hashlib  # noqa: PLC0415 - test helper

    header = request.headers.get("authorization", "")
    if not header.startswith("Digest "):
        return False
    p = parse_auth_params(header)

    def md5(s: str) -> str:
        return hashlib.md5(s.encode()).hexdigest()  # noqa: S324 - MD5 is what the camera uses

    ha1 = md5(f"{username}:{realm}:{password}")
    ha2 = md5(f"{request.method}:{p['uri']}")
    expected = md5(f"{ha1}:{nonce}:{p['nc']}:{p['cnonce']}:{p['qop']}:{ha2}")
    return (
        p.get("username") == username
        and p.get("realm") == realm
        and p.get("nonce") == nonce
        and p.get("uri") == request.url.raw_path.decode()
        and p.get("response") == expected
    )

"""A simulated weak link between two hosts: network namespaces ``robot`` and ``operator`` joined by a veth
pair, shaped in both directions (``tc`` token bucket for the rate, nftables for random loss, the veth taken
down for a cut). Used by the two-host test tier (``tests/netns``) and ``bench/bench_link.py``. ROS-free.

Needs root (``ip netns``), ``iproute2`` and ``nftables`` (installed with ``apt-get`` on first use when
missing: :func:`ensure_tools`). Nothing can leave the namespaces: they hold only ``lo`` and their end of the
veth, an address in :data:`LINK_SUBNET`, a multicast route on the veth (DDS discovery) and no default route.

Each side also has its own ``/dev/shm`` (a directory bind-mounted over it in a private mount namespace of
every process started there): two real hosts share no memory, so Fast DDS's shared-memory transport cannot
short-cut the link, while processes on one side still share theirs. Every namespace name starts with
:data:`PREFIX` and carries the creating process's id, so concurrent runs never collide and
:func:`cleanup_stale` removes those whose creator died.
"""

from __future__ import annotations

import ipaddress
import os
import shlex
import shutil
import subprocess
import sys
import tempfile
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path

#: Addresses that exist only inside the namespaces created here (never routed anywhere).
LINK_SUBNET = ipaddress.IPv4Network("10.213.0.0/24")
#: Every namespace created here is named ``<PREFIX><pid>-<tag>-robot`` / ``...-operator``.
PREFIX = "axisptz-"
SIDES = ("robot", "operator")


class LinkError(RuntimeError):
    """A namespace/link command failed (with the command and its output)."""


def _run(cmd: Sequence[str], check: bool = True, stdin: str | None = None) -> subprocess.CompletedProcess[str]:
    proc = subprocess.run(list(cmd), capture_output=True, text=True, input=stdin, check=False)
    if check and proc.returncode != 0:
        raise LinkError(f"{' '.join(cmd)} failed ({proc.returncode}): {proc.stderr.strip() or proc.stdout.strip()}")
    return proc


def missing_tools() -> list[str]:
    """Commands the link needs that are not installed (``ip``, ``tc``, ``nft``, ``unshare``)."""
    return [t for t in ("ip", "tc", "nft", "unshare", "mount") if shutil.which(t) is None]


def ensure_tools() -> None:
    """Install what is missing (Debian packages ``iproute2``, ``nftables``, ``util-linux``); idempotent."""
    missing = missing_tools()
    if not missing:
        return
    if os.geteuid() != 0:
        raise LinkError(f"missing {', '.join(missing)} and not root: cannot install them")
    packages = {"ip": "iproute2", "tc": "iproute2", "nft": "nftables", "unshare": "util-linux", "mount": "mount"}
    wanted = sorted({packages[t] for t in missing})
    env = {**os.environ, "DEBIAN_FRONTEND": "noninteractive"}
    proc = subprocess.run(
        ["apt-get", "install", "-y", "--no-install-recommends", *wanted], capture_output=True, text=True, env=env
    )
    if proc.returncode != 0:  # the package lists may be missing on a fresh machine
        subprocess.run(["apt-get", "update"], capture_output=True, text=True, env=env, check=False)
        proc = subprocess.run(
            ["apt-get", "install", "-y", "--no-install-recommends", *wanted], capture_output=True, text=True, env=env
        )
    if proc.returncode != 0 or missing_tools():
        raise LinkError(f"could not install {', '.join(wanted)}: {proc.stderr.strip()[-500:]}")


def available() -> str | None:
    """None when namespaces can be created here, else the reason (not root, no netns support)."""
    if sys.platform != "linux":
        return "network namespaces need Linux"
    if os.geteuid() != 0:
        return "network namespaces need root"
    if shutil.which("ip") is None:
        return "iproute2 is not installed"
    return None


def _pid_alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True
    return True


def list_namespaces() -> list[str]:
    """Names of the network namespaces created by this module (any process)."""
    out = _run(["ip", "netns", "list"], check=False).stdout
    return [line.split()[0] for line in out.splitlines() if line.startswith(PREFIX)]


def cleanup_stale() -> list[str]:
    """Delete namespaces of ours whose creating process is gone; returns their names."""
    removed = []
    for name in list_namespaces():
        try:
            pid = int(name[len(PREFIX) :].split("-", 1)[0])
        except ValueError:
            continue
        if not _pid_alive(pid):
            _run(["ip", "netns", "delete", name], check=False)
            removed.append(name)
    for d in Path("/dev/shm").glob(f"{PREFIX}*-shm-*"):
        try:
            pid = int(d.name[len(PREFIX) :].split("-", 1)[0])
        except ValueError:
            continue
        if not _pid_alive(pid):
            shutil.rmtree(d, ignore_errors=True)
            removed.append(str(d))
    return removed


@dataclass(frozen=True)
class LinkState:
    """What the link does now, in both directions."""

    rate_kbit: float = 0.0  # 0 = unshaped
    loss_percent: int = 0
    up: bool = True


class Link:
    """Two namespaces joined by a veth pair; :meth:`close` (or the context manager) removes everything.

    Shaping applies to both directions: each side's egress has a token bucket of ``rate_kbit`` whose queue
    holds at most ``queue_ms`` of data (like a Wi-Fi driver's buffer; more is dropped), and each side's
    ingress drops ``loss_percent`` % of the packets at random (per IP packet, i.e. per fragment, as radio
    loss would).
    """

    _count = 0

    def __init__(self, tag: str = "t", queue_ms: float = 100.0) -> None:
        """Create the namespaces and the veth pair (raises :class:`LinkError`; nothing is left on failure)."""
        reason = available()
        if reason:
            raise LinkError(reason)
        ensure_tools()
        cleanup_stale()
        if not tag or not all(c.isalnum() for c in tag) or len(tag) > 20:
            raise ValueError(f"tag must be 1-20 letters/digits, not {tag!r}")
        self.tag = tag
        self.queue_ms = float(queue_ms)
        base = f"{PREFIX}{os.getpid()}-{tag}"
        self.ns = {side: f"{base}-{side}" for side in SIDES}
        Link._count += 1
        uid = f"{os.getpid() % 100000:05d}{Link._count % 100:02d}"
        self.dev = {"robot": f"axr{uid}", "operator": f"axo{uid}"}  # at most 15 characters
        hosts = list(LINK_SUBNET.hosts())
        self.address = {"robot": str(hosts[0]), "operator": str(hosts[1])}
        self.state = LinkState()
        self._closed = False
        # each "host" has its own /dev/shm, shared by its processes (Fast DDS shared memory works on a host,
        # never between the two)
        self._shm_root = Path(tempfile.mkdtemp(prefix=f"{base}-shm-", dir="/dev/shm"))
        self.shm = {side: self._shm_root / side for side in SIDES}
        for d in self.shm.values():
            d.mkdir(mode=0o1777)
            d.chmod(0o1777)
        try:
            self._create()
        except BaseException:
            self.close()
            raise

    # -- set-up / tear-down --------------------------------------------------------------------------------
    def _create(self) -> None:
        for side in SIDES:
            _run(["ip", "netns", "add", self.ns[side]])
        r, o = self.dev["robot"], self.dev["operator"]
        _run(
            [
                "ip",
                "link",
                "add",
                r,
                "netns",
                self.ns["robot"],
                "type",
                "veth",
                "peer",
                "name",
                o,
                "netns",
                self.ns["operator"],
            ]
        )
        for side in SIDES:
            ns, dev = self.ns[side], self.dev[side]
            _run(["ip", "-n", ns, "link", "set", "lo", "up"])
            _run(["ip", "-n", ns, "addr", "add", f"{self.address[side]}/{LINK_SUBNET.prefixlen}", "dev", dev])
            _run(["ip", "-n", ns, "link", "set", dev, "up"])
            # DDS discovery is multicast: route it onto the veth (the namespace has no default route).
            _run(["ip", "-n", ns, "route", "add", "224.0.0.0/4", "dev", dev])
            self._nft(side, self._ruleset(side, 0))

    def close(self) -> None:
        """Delete both namespaces (the veth pair goes with them); idempotent, never raises."""
        if self._closed:
            return
        self._closed = True
        for side in SIDES:
            _run(["ip", "netns", "delete", self.ns[side]], check=False)
        shutil.rmtree(self._shm_root, ignore_errors=True)

    def __enter__(self) -> Link:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    # -- shaping -------------------------------------------------------------------------------------------
    def _ruleset(self, side: str, loss_percent: int) -> str:
        table = "axislink"
        rule = f"numgen random mod 100 < {int(loss_percent)} drop" if loss_percent > 0 else "accept"
        return (
            f"table netdev {table}\n"
            f"delete table netdev {table}\n"
            f"table netdev {table} {{\n"
            f"  chain ingress {{ type filter hook ingress device {self.dev[side]} priority 0; policy accept;\n"
            f"    {rule}\n"
            f"  }}\n"
            f"}}\n"
        )

    def _nft(self, side: str, ruleset: str) -> None:
        _run(["ip", "netns", "exec", self.ns[side], "nft", "-f", "-"], stdin=ruleset)

    def set_rate(self, kbit: float) -> None:
        """Token-bucket rate limit of both directions (kbit/s; 0 = unshaped)."""
        for side in SIDES:
            ns, dev = self.ns[side], self.dev[side]
            _run(["ip", "netns", "exec", ns, "tc", "qdisc", "del", "dev", dev, "root"], check=False)
            if kbit > 0:
                burst = max(int(kbit * 1000 / 8 * 0.01), 3000)  # 10 ms of data, at least two packets
                _run(
                    ["ip", "netns", "exec", ns, "tc", "qdisc", "add", "dev", dev, "root", "tbf"]
                    + ["rate", f"{int(kbit)}kbit", "burst", str(burst), "latency", f"{int(self.queue_ms)}ms"]
                )
        self.state = LinkState(float(kbit), self.state.loss_percent, self.state.up)

    def set_loss(self, percent: int) -> None:
        """Random loss of ``percent`` % of the packets entering each side (0…100)."""
        if not 0 <= percent <= 100:
            raise ValueError(f"loss must be 0…100 %, not {percent}")
        for side in SIDES:
            self._nft(side, self._ruleset(side, percent))
        self.state = LinkState(self.state.rate_kbit, int(percent), self.state.up)

    def set_up(self, up: bool) -> None:
        """Cut (``False``) or heal (``True``) the link: both ends of the veth down/up."""
        for side in SIDES:
            _run(["ip", "-n", self.ns[side], "link", "set", self.dev[side], "up" if up else "down"])
            if up:  # a link taken down loses its multicast route
                _run(["ip", "-n", self.ns[side], "route", "replace", "224.0.0.0/4", "dev", self.dev[side]])
        self.state = LinkState(self.state.rate_kbit, self.state.loss_percent, up)

    # -- processes -----------------------------------------------------------------------------------------
    def command(self, side: str, argv: Sequence[str]) -> list[str]:
        """``argv`` run in ``side``'s namespace with a private ``/dev/shm`` (as on another host)."""
        if side not in self.ns:
            raise ValueError(f"side must be one of {SIDES}, not {side!r}")
        inner = f'mount --bind {shlex.quote(str(self.shm[side]))} /dev/shm && exec "$@"'
        return ["ip", "netns", "exec", self.ns[side], "unshare", "--mount", "--propagation", "private"] + [
            "sh",
            "-c",
            inner,
            "sh",
            *argv,
        ]

    def popen(
        self,
        side: str,
        argv: Sequence[str],
        env: Mapping[str, str] | None = None,
        **kwargs: object,
    ) -> subprocess.Popen[bytes]:
        """Start ``argv`` in ``side``'s namespace (its own process group, so it can be stopped as one)."""
        return subprocess.Popen(  # type: ignore[call-overload, no-any-return]
            self.command(side, argv), env=dict(env) if env is not None else None, start_new_session=True, **kwargs
        )

    def counters(self, side: str) -> dict[str, int]:
        """Bytes and packets sent/received by ``side``'s veth end (from its statistics in sysfs)."""
        names = ("rx_bytes", "tx_bytes", "rx_packets", "tx_packets", "tx_dropped")
        paths = [f"/sys/class/net/{self.dev[side]}/statistics/{n}" for n in names]
        out = _run(["ip", "netns", "exec", self.ns[side], "cat", *paths]).stdout.split()
        return {n: int(v) for n, v in zip(names, out, strict=True)}


def main(argv: list[str] | None = None) -> int:
    """``python -m tests.support.link check|cleanup|list``: tools and leftovers (the tests/bench build links)."""
    args = list(sys.argv[1:] if argv is None else argv)
    cmd = args[0] if args else "check"
    if cmd == "check":
        reason = available()
        if reason:
            print(reason, file=sys.stderr)  # noqa: T201
            return 1
        ensure_tools()
        print("ok: ip, tc, nft, unshare present; root")  # noqa: T201
        return 0
    if cmd == "cleanup":
        for name in cleanup_stale():
            print(f"removed {name}")  # noqa: T201
        return 0
    if cmd == "list":
        for name in list_namespaces():
            print(name)  # noqa: T201
        return 0
    print(f"unknown command {cmd!r} (check | cleanup | list)", file=sys.stderr)  # noqa: T201
    return 2


if __name__ == "__main__":
    raise SystemExit(main())

"""A network lab on one machine: each participant on its own host, faults on demand (root only).

For the fault tests (``tests/netfaults``) and the network benchmark
(``scripts/bench_runtime.py``).  Not used by missions.

* :class:`Netns` builds one Linux network namespace per participant
  (``eamos-t-<pid>-<i>``), each with a veth pair to a bridge in a private hub
  namespace, addresses from the benchmarking range ``198.18.0.0/15`` (RFC 2544,
  never routed), and nothing connected to the host's own network.  It injects
  faults: random loss with ``iptables -m statistic`` (the kernel here has no
  ``netem`` qdisc, so loss is done by iptables and delay/jitter by
  :func:`serve_delay_proxy`), a partition by taking a participant's link down,
  and it runs processes inside a namespace.  :meth:`Netns.down` deletes
  everything, including processes left inside, and is idempotent; namespaces
  left by a crashed earlier run are removed by :func:`cleanup_stale`.
* :func:`write_fleet` writes what a fleet of ``eamos-node`` processes needs: the
  programs, fresh keys (or plain sockets on loopback), one config per
  participant (the ground station's too: ``eamos-node`` runs it).
* :func:`serve_delay_proxy` (``python -m tests.support.netlab proxy ...``) forwards TCP
  connections with a delay and jitter per chunk, keeping each stream in order.

Every wait here is bounded.
"""

from __future__ import annotations

import argparse
import asyncio
import json
import os
import random
import shutil
import signal
import subprocess
import sys
import time
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from eamos.config import NodeConfig
from eamos.net.keys import create_fleet_keys
from eamos.net.link import LinkSettings
from eamos.program.uniform import GROUND_STATION

__all__ = [
    "FleetFiles",
    "Netns",
    "cleanup_stale",
    "lab_unavailable",
    "node_argv",
    "serve_delay_proxy",
    "wait_file_lines",
    "write_fleet",
]

PREFIX = "eamos-t-"
SUBNET = "198.18.0"  # /24 inside the RFC 2544 benchmarking range
HUB_HOST = 254  # the hub's own address on the bridge (the delay proxy listens there)
CMD_TIMEOUT_S = 30.0


def lab_unavailable() -> str | None:
    """Why the lab cannot run here (None when it can): root, iproute2 and iptables needed."""
    if os.geteuid() != 0:
        return "network namespaces need root"
    for tool in ("ip", "iptables"):
        if shutil.which(tool) is None:
            return f"`{tool}` is not installed (apt-get install iproute2 iptables)"
    return None


def _run(argv: Sequence[str], check: bool = True) -> subprocess.CompletedProcess[str]:
    proc = subprocess.run(list(argv), capture_output=True, text=True, timeout=CMD_TIMEOUT_S)
    if check and proc.returncode != 0:
        raise RuntimeError(f"{' '.join(argv)}: {proc.stderr.strip() or proc.stdout.strip()}")
    return proc


def _namespaces() -> list[str]:
    out = _run(["ip", "netns", "list"], check=False).stdout
    return [line.split()[0] for line in out.splitlines() if line.strip()]


def _kill_inside(ns: str) -> None:
    """SIGKILL the processes still inside namespace ``ns`` (ours: we started them there)."""
    out = _run(["ip", "netns", "pids", ns], check=False).stdout
    for pid in (int(p) for p in out.split() if p.isdigit()):
        try:
            os.kill(pid, signal.SIGKILL)
        except ProcessLookupError:
            pass


def cleanup_stale() -> list[str]:
    """Delete lab namespaces whose creating process is gone (a crashed earlier run)."""
    removed = []
    for ns in _namespaces():
        if not ns.startswith(PREFIX):
            continue
        owner = ns[len(PREFIX) :].split("-", 1)[0]
        if owner.isdigit() and not Path(f"/proc/{owner}").exists():
            _kill_inside(ns)
            _run(["ip", "netns", "del", ns], check=False)
            removed.append(ns)
    return removed


@dataclass
class Netns:
    """One namespace ("host") per participant on a private bridge; see the module docstring."""

    names: Sequence[str]
    tag: str = ""
    prefix: str = field(init=False)
    hub: str = field(init=False)
    ns: dict[str, str] = field(init=False)
    addr: dict[str, str] = field(init=False)
    _up: bool = field(init=False, default=False)

    def __post_init__(self) -> None:
        if len(self.names) > 200:
            raise ValueError("at most 200 hosts")
        self.prefix = f"{PREFIX}{os.getpid()}-{self.tag or 'x'}"
        self.hub = f"{self.prefix}-hub"
        self.ns = {n: f"{self.prefix}-{i}" for i, n in enumerate(self.names)}
        self.addr = {n: f"{SUBNET}.{i + 1}" for i, n in enumerate(self.names)}

    @property
    def hub_addr(self) -> str:
        """The hub's address on the bridge (reachable from every host)."""
        return f"{SUBNET}.{HUB_HOST}"

    def up(self) -> Netns:
        """Create the hub with its bridge, then each host with its veth pair and address."""
        self._up = True  # from here on, down() has something to clean
        hub = self.hub
        _run(["ip", "netns", "add", hub])
        _run(["ip", "-n", hub, "link", "set", "lo", "up"])
        _run(["ip", "-n", hub, "link", "add", "br0", "type", "bridge"])
        _run(["ip", "-n", hub, "addr", "add", f"{self.hub_addr}/24", "dev", "br0"])
        _run(["ip", "-n", hub, "link", "set", "br0", "up"])
        for i, name in enumerate(self.names):
            ns = self.ns[name]
            _run(["ip", "netns", "add", ns])
            _run(["ip", "-n", ns, "link", "set", "lo", "up"])
            # Created inside the hub, so no interface ever appears in the host's namespace.
            _run(
                [
                    "ip",
                    "-n",
                    hub,
                    "link",
                    "add",
                    f"h{i}",
                    "type",
                    "veth",
                    "peer",
                    "name",
                    "eth0",
                    "netns",
                    ns,
                ]
            )
            _run(["ip", "-n", hub, "link", "set", f"h{i}", "master", "br0"])
            _run(["ip", "-n", hub, "link", "set", f"h{i}", "up"])
            _run(["ip", "-n", ns, "addr", "add", f"{self.addr[name]}/24", "dev", "eth0"])
            _run(["ip", "-n", ns, "link", "set", "eth0", "up"])
        return self

    def __enter__(self) -> Netns:
        return self.up()

    def __exit__(self, *exc: object) -> None:
        self.down()

    def down(self) -> None:
        """Kill what runs inside, delete every namespace; idempotent, never raises."""
        if not self._up:
            return
        for ns in [*self.ns.values(), self.hub]:
            try:
                _kill_inside(ns)
                _run(["ip", "netns", "del", ns], check=False)
            except (OSError, subprocess.SubprocessError):
                pass
        self._up = False

    # -- running things inside -----------------------------------------------------

    def argv(self, name: str, argv: Sequence[str]) -> list[str]:
        """``argv`` run in ``name``'s namespace (``name`` may be ``"hub"``)."""
        ns = self.hub if name == "hub" else self.ns[name]
        return ["ip", "netns", "exec", ns, *argv]

    def run(self, name: str, *argv: str, check: bool = True) -> subprocess.CompletedProcess[str]:
        """Run a short command in ``name``'s namespace (bounded)."""
        return _run(self.argv(name, argv), check=check)

    def popen(self, name: str, argv: Sequence[str], **kw: Any) -> subprocess.Popen[bytes]:
        """Start a process in ``name``'s namespace (``ip netns exec`` execs: same pid)."""
        return subprocess.Popen(self.argv(name, argv), **kw)

    # -- faults -----------------------------------------------------------------------

    def loss(self, name: str, probability: float) -> None:
        """Drop incoming packets of ``name`` at random with ``probability`` (iptables)."""
        if not 0 <= probability <= 1:
            raise ValueError("probability must be within [0, 1]")
        self.clear_loss(name)
        self.run(
            name,
            "iptables",
            "-A",
            "INPUT",
            "-m",
            "statistic",
            "--mode",
            "random",
            "--probability",
            f"{probability:.4f}",
            "-j",
            "DROP",
        )

    def clear_loss(self, name: str) -> None:
        """Remove the loss rules of ``name``."""
        self.run(name, "iptables", "-F", "INPUT")

    def partition(self, name: str) -> None:
        """Cut ``name`` off (its link on the bridge goes down; its processes keep running)."""
        i = list(self.names).index(name)
        _run(["ip", "-n", self.hub, "link", "set", f"h{i}", "down"])

    def heal(self, name: str) -> None:
        """Undo :meth:`partition`."""
        i = list(self.names).index(name)
        _run(["ip", "-n", self.hub, "link", "set", f"h{i}", "up"])


# -- fleet files ----------------------------------------------------------------------


@dataclass(frozen=True)
class FleetFiles:
    """What :func:`write_fleet` wrote."""

    run_dir: Path
    configs: dict[str, Path]
    log_dirs: dict[str, Path]
    keys_dir: Path | None

    def summary(self) -> dict[str, Any] | None:
        """The ground station's ``summary.json`` (None until written)."""
        path = self.log_dirs[GROUND_STATION] / "summary.json"
        return json.loads(path.read_text()) if path.exists() else None


def write_fleet(
    programs: Mapping[str, Any],
    run_dir: Path,
    bind: Mapping[str, str],
    connect: Mapping[str, str] | None = None,
    *,
    hal: Mapping[str, Mapping[str, Any]] | None = None,
    secure: bool = True,
    net: Mapping[str, Any] | None = None,
    ground_net: Mapping[str, Any] | None = None,
    ready_timeout_s: float = 120.0,
    mission_timeout_s: float = 300.0,
) -> FleetFiles:
    """Write programs, keys and one ``eamos-node`` config per participant under ``run_dir``.

    ``programs`` maps participant -> :class:`~eamos.program.format.DroneProgram`;
    ``bind`` is where each binds its Out-Bridge, ``connect`` where the others
    reach it (default: ``bind``; differs behind a proxy).  ``secure=False``
    writes ``plain = true`` (loopback only).  ``net`` adds ``[net]`` settings
    for everyone, ``ground_net`` for the ground station only.
    """
    run_dir = Path(run_dir)
    connect = dict(connect or bind)
    hal = dict(hal or {})
    (run_dir / "programs").mkdir(parents=True, exist_ok=True)
    (run_dir / "configs").mkdir(exist_ok=True)
    names = list(programs)
    keys_dir = create_fleet_keys(run_dir / "keys", names, force=True) if secure else None
    configs: dict[str, Path] = {}
    log_dirs: dict[str, Path] = {}
    for name in names:
        programs[name].save(run_dir / "programs" / f"{name}.program.json")
        log_dirs[name] = run_dir / "logs" / name
        extra = dict(net or {})
        if name == GROUND_STATION:
            extra.update(ground_net or {})
        default_hal = {"adapter": "ground"} if name == GROUND_STATION else {"adapter": "sim"}
        give_up = extra.pop("peer_give_up_s", None)
        config = NodeConfig(
            path=run_dir / "configs" / f"{name}.toml",
            drone=name,
            program=run_dir / "programs" / f"{name}.program.json",
            log_dir=log_dirs[name],
            bind=bind[name],
            peers={p: connect[p] for p in names if p != name},
            hal=dict(hal.get(name) or default_hal),
            ready_timeout_s=ready_timeout_s,
            mission_timeout_s=mission_timeout_s,
            keys_dir=run_dir / "keys" / name if secure else None,
            link=LinkSettings(**extra),  # the [net] settings: heartbeat_s, peer_timeout_s, ...
            peer_give_up_s=give_up,
        )
        configs[name] = config.write()
    return FleetFiles(run_dir, configs, log_dirs, keys_dir)


def node_argv(config: Path) -> list[str]:
    """The command running ``eamos-node`` with ``config`` in this Python environment."""
    return [sys.executable, "-m", "eamos.cli.node", "--config", str(config)]


# -- delay proxy ------------------------------------------------------------------------


async def _pump(
    reader: asyncio.StreamReader,
    writer: asyncio.StreamWriter,
    delay_s: float,
    jitter_s: float,
    rng: random.Random,
) -> None:
    """Copy one direction of a stream, each chunk held for delay +- jitter, in order."""
    queue: asyncio.Queue[tuple[float, bytes]] = asyncio.Queue()
    loop = asyncio.get_running_loop()

    async def release() -> None:
        while True:
            due, chunk = await queue.get()
            if not chunk:
                break
            wait = due - loop.time()
            if wait > 0:
                await asyncio.sleep(wait)  # the delay being injected, not synchronisation
            writer.write(chunk)
            await writer.drain()
        writer.close()

    task = asyncio.create_task(release())
    last = 0.0
    try:
        while True:
            chunk = await reader.read(65536)
            # Never earlier than the previous chunk: TCP streams stay in order.
            last = max(last, loop.time() + max(0.0, delay_s + rng.uniform(-jitter_s, jitter_s)))
            await queue.put((last, chunk))
            if not chunk:
                break
    except (ConnectionError, OSError):
        await queue.put((0.0, b""))
    await task


async def _proxy_main(
    forwards: Sequence[tuple[str, int, str, int]], delay_s: float, jitter_s: float, max_s: float
) -> None:
    rng = random.Random()

    def handler(host: str, port: int) -> Any:
        async def handle(reader: asyncio.StreamReader, writer: asyncio.StreamWriter) -> None:
            try:
                up_reader, up_writer = await asyncio.wait_for(
                    asyncio.open_connection(host, port), timeout=5
                )
            except (OSError, TimeoutError):
                writer.close()
                return
            await asyncio.gather(
                _pump(reader, up_writer, delay_s, jitter_s, rng),
                _pump(up_reader, writer, delay_s, jitter_s, rng),
                return_exceptions=True,
            )

        return handle

    servers = [await asyncio.start_server(handler(th, tp), lh, lp) for lh, lp, th, tp in forwards]
    print("proxy ready", flush=True)
    try:
        await asyncio.sleep(max_s)  # a bound on the proxy's life, in case nobody stops it
    finally:
        for server in servers:
            server.close()


def serve_delay_proxy(
    forwards: Sequence[tuple[str, int, str, int]],
    delay_s: float,
    jitter_s: float,
    max_s: float = 1800.0,
) -> None:
    """Forward ``(listen_host, listen_port, target_host, target_port)`` with delay and jitter.

    Runs until killed, or ``max_s`` at most.  Each chunk read from one side is
    written to the other ``delay_s`` +- ``jitter_s`` later, never before the
    previous chunk (jitter reorders nothing inside a TCP stream, as on a real
    link it delays whole bursts).
    """
    asyncio.run(_proxy_main(forwards, delay_s, jitter_s, max_s))


def _parse_forward(text: str) -> tuple[str, int, str, int]:
    listen, _, target = text.partition("=")
    lh, _, lp = listen.rpartition(":")
    th, _, tp = target.rpartition(":")
    return lh, int(lp), th, int(tp)


def wait_file_lines(path: Path, needle: str, count: int, timeout_s: float) -> bool:
    """Wait (bounded; checks every 0.1 s) until ``path`` has ``count`` lines containing ``needle``.

    For tests watching another process's log; not for product code.
    """
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        try:
            text = path.read_text(errors="replace")
        except OSError:
            text = ""
        if sum(needle in line for line in text.splitlines()) >= count:
            return True
        time.sleep(0.1)
    return False


def main(argv: list[str] | None = None) -> int:
    """``python -m tests.support.netlab proxy --forward HOST:PORT=HOST:PORT ... --delay-ms D``."""
    parser = argparse.ArgumentParser(prog="python -m tests.support.netlab")
    sub = parser.add_subparsers(dest="command", required=True)
    proxy = sub.add_parser("proxy", help="TCP forwarder with delay and jitter")
    proxy.add_argument(
        "--forward",
        action="append",
        required=True,
        type=_parse_forward,
        metavar="LISTEN_HOST:PORT=TARGET_HOST:PORT",
    )
    proxy.add_argument("--delay-ms", type=float, default=50.0)
    proxy.add_argument("--jitter-ms", type=float, default=0.0)
    proxy.add_argument("--max-s", type=float, default=1800.0)
    args = parser.parse_args(argv)
    signal.signal(signal.SIGTERM, lambda *_: sys.exit(0))
    serve_delay_proxy(args.forward, args.delay_ms / 1e3, args.jitter_ms / 1e3, args.max_s)
    return 0


if __name__ == "__main__":
    sys.exit(main())

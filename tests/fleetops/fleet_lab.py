"""A small drone lab of network namespaces, each drone host running OpenSSH's sshd.

Topology (all addresses from the benchmark range 198.18.0.0/15, inside the
lab's namespaces only)::

    <tag>o  operator   198.18.0.1 --+
    <tag>1  drone host 198.18.0.2 --+-- bridge in <tag>h (the hub)
    <tag>2  drone host 198.18.0.3 --+
    ...

The test commands (``eamos rollout`` ...) run in the operator namespace with
``ip netns exec``.  A drone host's "installed eamos" is this repository's venv,
reached through a wrapper script (``node_command`` in the fleet file), which a
test can swap for a fake one.  A host may get a tiny tmpfs as its deploy folder
(its sshd then runs in its own mount namespace) to fill its disk.

Teardown kills the sshd processes this lab started and every process left in
its namespaces (nodes started over SSH), by pid, then deletes the namespaces.
"""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
import textwrap
import time
from dataclasses import dataclass, field
from pathlib import Path

REPO = Path(__file__).resolve().parents[2]
VENV_BIN = Path(sys.executable).parent
SUBNET = "198.18.0"


def sh(*argv: str, check: bool = True, timeout: float = 30) -> subprocess.CompletedProcess[str]:
    return subprocess.run(argv, capture_output=True, text=True, check=check, timeout=timeout)


def missing_tools() -> str:
    """Why the lab cannot run here ('' when it can)."""
    if os.geteuid() != 0:
        return "needs root (network namespaces)"
    for tool in ("ip", "ssh", "scp", "ssh-keygen", "/usr/sbin/sshd", "unshare", "mount"):
        if shutil.which(tool) is None:
            return f"needs {tool} (CI installs openssh-server, openssh-client, iproute2)"
    return ""


@dataclass
class Host:
    """One drone computer: a namespace, an address, maybe an sshd."""

    name: str
    ns: str
    addr: str
    home: Path
    folder: Path
    wrapper: Path
    sshd: subprocess.Popen[bytes] | None = None
    tmpfs_kb: int | None = None


@dataclass
class Lab:
    root: Path
    tag: str
    hosts: dict[str, Host] = field(default_factory=dict)
    namespaces: list[str] = field(default_factory=list)
    key: Path = field(init=False)
    other_key: Path = field(init=False)
    known_hosts: Path = field(init=False)
    operator_ns: str = field(init=False)
    operator_addr: str = f"{SUBNET}.1"

    def __post_init__(self) -> None:
        self.root.mkdir(parents=True, exist_ok=True)
        self.key = self.root / "id_ed25519"
        self.other_key = self.root / "id_other"
        self.known_hosts = self.root / "known_hosts"
        for key in (self.key, self.other_key):
            sh("ssh-keygen", "-q", "-t", "ed25519", "-N", "", "-f", str(key))
        Path("/run/sshd").mkdir(parents=True, exist_ok=True)  # sshd's privilege-separation dir
        self.hub = f"{self.tag}h"
        self._netns(self.hub)
        sh("ip", "-n", self.hub, "link", "add", "br0", "type", "bridge")
        sh("ip", "-n", self.hub, "link", "set", "br0", "up")
        self.operator_ns = f"{self.tag}o"
        self._attach(self.operator_ns, self.operator_addr, "o")

    # -- building ----------------------------------------------------------------------------

    def _netns(self, name: str) -> None:
        sh("ip", "netns", "add", name)
        self.namespaces.append(name)
        sh("ip", "-n", name, "link", "set", "lo", "up")

    def _attach(self, ns: str, addr: str, suffix: str) -> None:
        """A namespace with one veth into the hub's bridge."""
        self._netns(ns)
        outer, inner = f"{self.tag}{suffix}a", f"{self.tag}{suffix}b"
        sh("ip", "link", "add", outer, "type", "veth", "peer", "name", inner)
        sh("ip", "link", "set", outer, "netns", self.hub)
        sh("ip", "link", "set", inner, "netns", ns)
        sh("ip", "-n", self.hub, "link", "set", outer, "master", "br0", "up")
        sh("ip", "-n", ns, "addr", "add", f"{addr}/24", "dev", inner)
        sh("ip", "-n", ns, "link", "set", inner, "up")

    def add_host(
        self, name: str, index: int, *, sshd: bool = True, tmpfs_kb: int | None = None
    ) -> Host:
        ns = f"{self.tag}{index}"
        addr = f"{SUBNET}.{index + 1}"
        self._attach(ns, addr, str(index))
        home = self.root / name
        home.mkdir()
        folder = home / "eamos"
        folder.mkdir()
        wrapper = home / "eamos-node"
        host = Host(name, ns, addr, home, folder, wrapper, tmpfs_kb=tmpfs_kb)
        self.set_node(host)
        if sshd:
            self.start_sshd(host)
        self.hosts[name] = host
        return host

    def set_node(self, host: Host, script: str | None = None) -> None:
        """The host's ``eamos-node``: this venv's, or a fake shell script body."""
        body = script or f'exec {VENV_BIN / "eamos-node"} "$@"'
        host.wrapper.write_text(f"#!/bin/sh\n{body}\n")
        host.wrapper.chmod(0o755)

    def start_sshd(self, host: Host) -> None:
        hostkey = host.home / "ssh_host_ed25519_key"
        if not hostkey.exists():
            sh("ssh-keygen", "-q", "-t", "ed25519", "-N", "", "-f", str(hostkey))
        config = host.home / "sshd_config"
        config.write_text(
            textwrap.dedent(
                f"""\
                ListenAddress {host.addr}
                Port 22
                HostKey {hostkey}
                AuthorizedKeysFile {self.key}.pub
                PermitRootLogin prohibit-password
                PasswordAuthentication no
                KbdInteractiveAuthentication no
                UsePAM no
                StrictModes no
                PidFile {host.home}/sshd.pid
                Subsystem sftp internal-sftp
                LogLevel INFO
                """
            )
        )
        log = host.home / "sshd.log"
        log.write_text("")
        sshd = ["/usr/sbin/sshd", "-D", "-f", str(config), "-E", str(log)]
        if host.tmpfs_kb is not None:
            # ip netns exec gives every command its own mount namespace, so the tmpfs
            # is mounted in a namespace that sshd (and its sessions) then keep.
            script = (
                f"mount -t tmpfs -o size={host.tmpfs_kb}k eamos-lab {host.folder} && "
                f"exec {' '.join(sshd)}"
            )
            argv = ["unshare", "-m", "--propagation", "private", "sh", "-c", script]
        else:
            argv = sshd
        host.sshd = subprocess.Popen(["ip", "netns", "exec", host.ns, *argv])
        deadline = time.monotonic() + 15
        while "Server listening" not in log.read_text():
            if host.sshd.poll() is not None or time.monotonic() > deadline:
                raise RuntimeError(f"sshd on {host.name} did not start: {log.read_text()}")
            time.sleep(0.05)

    def stop_sshd(self, host: Host) -> None:
        if host.sshd is not None and host.sshd.poll() is None:
            host.sshd.terminate()
            try:
                host.sshd.wait(10)
            except subprocess.TimeoutExpired:
                host.sshd.kill()
                host.sshd.wait(10)
        host.sshd = None

    # -- using ----------------------------------------------------------------------------------

    def eamos(self, *args: str, timeout: float = 240) -> subprocess.CompletedProcess[str]:
        """``eamos ARGS`` on the operator's machine (its namespace)."""
        env = dict(os.environ, PYTHONUNBUFFERED="1")
        return subprocess.run(
            ["ip", "netns", "exec", self.operator_ns, sys.executable, "-m", "eamos.cli", *args],
            capture_output=True,
            text=True,
            timeout=timeout,
            cwd=REPO,
            env=env,
        )

    def rollout_sh(self, run_dir: Path, *args: str) -> subprocess.CompletedProcess[str]:
        """``scripts/rollout.sh ARGS`` on the operator's machine, with this Python's eamos."""
        env = dict(
            os.environ,
            PYTHONUNBUFFERED="1",
            RUN_DIR=str(run_dir),
            EAMOS=f"{sys.executable} -m eamos.cli",
        )
        return subprocess.run(
            [
                "ip",
                "netns",
                "exec",
                self.operator_ns,
                "bash",
                str(REPO / "scripts" / "rollout.sh"),
                *args,
            ],
            capture_output=True,
            text=True,
            timeout=300,
            cwd=REPO,
            env=env,
        )

    def popen_eamos(self, *args: str) -> subprocess.Popen[str]:
        env = dict(os.environ, PYTHONUNBUFFERED="1")
        return subprocess.Popen(
            ["ip", "netns", "exec", self.operator_ns, sys.executable, "-m", "eamos.cli", *args],
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
            text=True,
            cwd=REPO,
            env=env,
        )

    def fleet_file(
        self,
        path: Path,
        drones: dict[str, str],
        *,
        keys: Path | None = None,
        key: Path | None = None,
        ready_timeout_s: float = 30,
        drone_extra: dict[str, str] | None = None,
        ssh_extra: dict[str, str] | None = None,
    ) -> Path:
        """A fleet file for ``drones`` (mission drone name -> lab host name).

        ``drone_extra`` adds TOML lines to a drone's ``[drones.NAME]`` table,
        ``ssh_extra`` to its ``[drones.NAME.ssh]`` table.
        """
        lines = [
            "[ground]",
            f'bind = "tcp://{self.operator_addr}:6000"',
            f"ready_timeout_s = {ready_timeout_s}",
        ]
        if keys is not None:
            lines.append(f'keys = "{keys}"')
        lines += [
            "",
            "[defaults.ssh]",
            'user = "root"',
            f'identity = "{key or self.key}"',
            f'known_hosts = "{self.known_hosts}"',
            "connect_timeout_s = 3",
            "",
            "[defaults.hal]",
            'adapter = "sim"',
            "",
        ]
        for drone, host_name in drones.items():
            host = self.hosts[host_name]
            extra = (drone_extra or {}).get(drone)
            if extra:
                lines += [f"[drones.{drone}]", extra, ""]
            lines += [
                f"[drones.{drone}.ssh]",
                f'host = "{host.addr}"',
                f'folder = "{host.folder}"',
                f'node_command = "{host.wrapper}"',
                *([(ssh_extra or {})[drone]] if drone in (ssh_extra or {}) else []),
                "",
            ]
        path.write_text("\n".join(lines) + "\n")
        return path

    def pids_in(self, ns: str) -> list[int]:
        out = sh("ip", "netns", "pids", ns, check=False).stdout
        return [int(p) for p in out.split()]

    def node_pids(self, host: Host) -> list[int]:
        """eamos-node processes on a host (not its sshd)."""
        sshd = host.sshd.pid if host.sshd else -1
        found = []
        for pid in self.pids_in(host.ns):
            try:
                cmd = Path(f"/proc/{pid}/cmdline").read_bytes()
            except OSError:
                continue
            if pid != sshd and b"--config" in cmd:
                found.append(pid)
        return found

    def wait_no_nodes(self, host: Host, timeout_s: float) -> bool:
        """Wait until no eamos-node runs on ``host`` (a node exits shortly after its report)."""
        deadline = time.monotonic() + timeout_s
        while self.node_pids(host):
            if time.monotonic() > deadline:
                return False
            time.sleep(0.1)
        return True

    def reset(self, *names: str) -> None:
        """End the nodes on these hosts and empty their deploy folders (between tests)."""
        for name in names:
            host = self.hosts[name]
            for pid in self.node_pids(host):
                try:
                    os.kill(pid, 9)
                except ProcessLookupError:
                    pass
            for child in host.folder.iterdir():
                if child.is_dir():
                    shutil.rmtree(child)
                else:
                    child.unlink()

    def close(self) -> None:
        for host in self.hosts.values():
            self.stop_sshd(host)
        # Nodes started over SSH outlive sshd (nohup): end them by pid, namespace by namespace.
        for ns in self.namespaces:
            for pid in self.pids_in(ns):
                try:
                    os.kill(pid, 9)
                except ProcessLookupError:
                    pass
        for ns in reversed(self.namespaces):
            sh("ip", "netns", "del", ns, check=False)

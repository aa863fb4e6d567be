"""A fleet of ``eamos-node`` processes, each in its own network namespace (its own host).

Built on :mod:`tests.support.netlab`: one namespace per participant on a private
bridge (addresses in 198.18.0.0/24, nothing on the host's network), fresh
fleet keys, one config per participant (the ground station is an
``eamos-node`` too), optionally a delaying TCP proxy in the hub namespace that
every connection goes through.  Everything is torn down by :meth:`close`, also
after a failure; every wait has a deadline.
"""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from eamos.compiler import compile_file, compile_mission
from eamos.logs import read_log
from eamos.program.uniform import GROUND_STATION
from tests.support.netlab import FleetFiles, Netns, node_argv, write_fleet

REPO = Path(__file__).resolve().parents[2]
PORT = 6000
PROXY_PORT = 7000


class LabFleet:
    """One mission's participants as processes on separate (namespace) hosts."""

    def __init__(
        self,
        tmp: Path,
        mission: str | Path,
        *,
        speedup: float,
        extra_hosts: Sequence[str] = (),
        net: dict[str, Any] | None = None,
        ground_net: dict[str, Any] | None = None,
        delay_ms: float = 0.0,
        jitter_ms: float = 0.0,
        mission_timeout_s: float = 240.0,
        tag: str = "f",
    ) -> None:
        self.tmp = tmp
        if isinstance(mission, Path):
            self.compiled = compile_file(mission)
        else:
            self.compiled = compile_mission(mission, "lab.go")
        self.names = list(self.compiled.programs)
        self.drones = [n for n in self.names if n != GROUND_STATION]
        self.lab = Netns([*self.names, *extra_hosts], tag=tag)
        self.procs: dict[str, subprocess.Popen[bytes]] = {}
        self.proxy: subprocess.Popen[bytes] | None = None
        try:
            self.lab.up()
            bind = {n: f"tcp://{self.lab.addr[n]}:{PORT}" for n in self.names}
            connect = dict(bind)
            if delay_ms or jitter_ms:
                connect = self._start_proxy(delay_ms, jitter_ms)
            hal: dict[str, dict[str, Any]] = {
                n: {"adapter": "sim", "speedup": speedup} for n in self.drones
            }
            hal[GROUND_STATION] = {"adapter": "ground", "speedup": speedup}
            self.files: FleetFiles = write_fleet(
                self.compiled.programs,
                tmp / "run",
                bind,
                connect,
                hal=hal,
                net=net,
                ground_net=ground_net,
                mission_timeout_s=mission_timeout_s,
            )
        except BaseException:
            self.close()
            raise

    def _start_proxy(self, delay_ms: float, jitter_ms: float) -> dict[str, str]:
        hub = self.lab.hub_addr
        forwards = []
        connect = {}
        for i, name in enumerate(self.names):
            forwards += ["--forward", f"{hub}:{PROXY_PORT + i}={self.lab.addr[name]}:{PORT}"]
            connect[name] = f"tcp://{hub}:{PROXY_PORT + i}"
        self.proxy = self.lab.popen(
            "hub",
            [
                sys.executable,
                "-m",
                "tests.support.netlab",
                "proxy",
                *forwards,
                "--delay-ms",
                str(delay_ms),
                "--jitter-ms",
                str(jitter_ms),
                "--max-s",
                "900",
            ],
            stdout=subprocess.PIPE,
            stderr=subprocess.STDOUT,
            cwd=REPO,
        )
        assert self.proxy.stdout is not None
        line = self.proxy.stdout.readline()  # "proxy ready" (or its error, then EOF)
        assert b"proxy ready" in line, line
        return connect

    # -- processes -----------------------------------------------------------------------

    def start(self, names: Sequence[str] | None = None) -> None:
        """Start ``eamos-node`` for each participant (default: all), each in its own host."""
        for name in names or self.names:
            log_dir = self.files.log_dirs[name]
            log_dir.mkdir(parents=True, exist_ok=True)
            with (log_dir / "node.out").open("wb") as out:
                self.procs[name] = self.lab.popen(
                    name,
                    node_argv(self.files.configs[name]),
                    stdout=out,
                    stderr=subprocess.STDOUT,
                    stdin=subprocess.DEVNULL,
                    cwd=REPO,
                    env={**os.environ, "PYTHONUNBUFFERED": "1"},
                )

    def kill(self, name: str) -> None:
        """``kill -9`` one participant's process (no goodbye, no report)."""
        self.procs[name].send_signal(signal.SIGKILL)
        self.procs[name].wait(30)

    def finish(self, timeout_s: float = 300.0) -> dict[str, Any]:
        """Wait for the ground station to end the mission; return its summary."""
        gcs = self.procs[GROUND_STATION]
        try:
            gcs.wait(timeout_s)
        except subprocess.TimeoutExpired as exc:
            raise AssertionError(
                f"the ground station did not finish in {timeout_s} s:\n"
                + self.output(GROUND_STATION)
            ) from exc
        for proc in self.procs.values():
            try:
                proc.wait(60)
            except subprocess.TimeoutExpired:
                proc.kill()
                proc.wait(10)
        summary = self.files.summary()
        assert summary is not None, self.output(GROUND_STATION)
        return summary

    def close(self) -> None:
        """Kill whatever still runs and delete every namespace (idempotent)."""
        for proc in [*self.procs.values(), *([self.proxy] if self.proxy else [])]:
            if proc.poll() is None:
                proc.kill()
                try:
                    proc.wait(10)
                except subprocess.TimeoutExpired:
                    pass
        if self.proxy is not None and self.proxy.stdout is not None:
            self.proxy.stdout.close()
        self.lab.down()

    # -- logs ----------------------------------------------------------------------------

    def output(self, name: str) -> str:
        path = self.files.log_dirs[name] / "node.out"
        return path.read_text(errors="replace")[-3000:] if path.exists() else ""

    def events(self, name: str, log: str = "mission") -> list[dict[str, Any]]:
        return read_log(self.files.log_dirs[name] / f"{log}.log")

    def wait_event(
        self,
        name: str,
        event: str,
        count: int = 1,
        timeout_s: float = 120.0,
        log: str = "mission",
        **fields: Any,
    ) -> bool:
        """Wait (polling the other process's log every 0.1 s, bounded) for ``count`` events."""
        deadline = time.monotonic() + timeout_s
        while True:
            found = [
                e
                for e in self.events(name, log)
                if e.get("event") == event and all(e.get(k) == v for k, v in fields.items())
            ]
            if len(found) >= count:
                return True
            if time.monotonic() > deadline:
                return False
            time.sleep(0.1)


def not_ok(summary: dict[str, Any]) -> str:
    """Why a run was not ok, for an assertion's message: its outcome and each report not ok."""
    parts: dict[str, Any] = {"outcome": summary.get("outcome"), "result": summary.get("result")}
    reports = {**summary.get("drones", {}), GROUND_STATION: summary.get("ground_station") or {}}
    for name, report in reports.items():
        if not report.get("ok"):
            shown = {k: v for k, v in report.items() if k not in ("actions", "net")}
            shown["actions not ok"] = [
                a for a in report.get("actions", []) if a.get("result") != "ok"
            ]
            parts[name] = shown
    return json.dumps(parts, default=str)[:6000]


def check_table7(summary: dict[str, Any], names: Sequence[str]) -> None:
    """Every trigger delivered exactly once: sent/received equal the MDG's external arcs."""
    for name in names:
        report = summary["drones"].get(name) or summary["ground_station"]
        if name == GROUND_STATION:
            report = summary["ground_station"]
        assert report["ok"], (name, json.dumps(report)[:2000])
        assert report["triggers_sent"] == report["external_out"], name
        assert report["triggers_received"] == report["external_in"], name
